import numpy as np
import pytest

from saw_ros.core import ParameterError, RobotParams
from saw_ros.core.kinematics import (backbone, base_link_angle, check_no_interference,
                                     interference, link_geometry, TipTable, v_theory)

ROBOT = RobotParams()
PHASES = np.linspace(0, 2 * np.pi, 721)


def test_links_keep_their_length():
    geo = link_geometry(ROBOT, PHASES)
    lengths = np.abs(geo.joints[..., 1:] - geo.joints[..., :-1])
    # Each link is a rigid segment from its front end to its rear end.
    front = geo.centres + 0.5 * ROBOT.link * np.exp(1j * geo.angles)
    rear = geo.centres - 0.5 * ROBOT.link * np.exp(1j * geo.angles)
    np.testing.assert_allclose(np.abs(front - rear), ROBOT.link, rtol=1e-12)
    assert lengths.shape[-1] == ROBOT.wave_links


def test_tips_sit_at_r_along_the_backbone_normal():
    geo = link_geometry(ROBOT, PHASES)
    y, psi = backbone(ROBOT, geo.centres.real, PHASES[:, None])
    np.testing.assert_allclose(geo.centres.imag, y, atol=1e-15)   # centres ride the backbone
    normal = (-psi + 1j) / np.sqrt(1 + psi ** 2)
    np.testing.assert_allclose(geo.up_tips, geo.centres + ROBOT.tip_distance * normal, atol=1e-15)
    np.testing.assert_allclose(geo.down_tips, geo.centres - ROBOT.tip_distance * normal,
                               atol=1e-15)


def test_tip_speed_at_a_crest_is_v_theory_and_tips_sweep_backwards():
    f = 1.3
    omega = 2 * np.pi * f
    phases = np.linspace(0, 2 * np.pi, 20001)
    geo = link_geometry(ROBOT, phases)
    i = np.unravel_index(np.argmax(geo.up_tips.imag), geo.up_tips.shape)
    h = 1e-6
    ahead = link_geometry(ROBOT, phases[i[0]] + omega * h).up_tips[i[1]]
    behind = link_geometry(ROBOT, phases[i[0]] - omega * h).up_tips[i[1]]
    speed = (ahead.real - behind.real) / (2 * h)
    expected = 4 * np.pi ** 2 * ROBOT.amplitude * ROBOT.tip_distance * f / ROBOT.wavelength
    assert v_theory(ROBOT, f) == pytest.approx(expected)
    # At the crest the tip touching the top surface moves tail-wards: the robot goes head-first.
    assert speed == pytest.approx(-expected, rel=1e-4)


def test_base_link_solves_the_papers_equation():
    theta = base_link_angle(ROBOT, PHASES)
    k = 2 * np.pi / ROBOT.wavelength
    b0, A = ROBOT.base_link_width, ROBOT.amplitude
    np.testing.assert_allclose(np.sin(theta), A / b0 * np.cos(k * b0 * np.cos(theta) + PHASES),
                               atol=1e-12)


def test_links_never_interfere_at_defaults_and_a_crowded_robot_is_refused():
    assert interference(ROBOT) > 0.002     # m of clearance between neighbouring tips
    check_no_interference(ROBOT)
    crowded = RobotParams(tip_distance=0.02)
    assert interference(crowded) < 0
    with pytest.raises(ParameterError, match='interfere'):
        check_no_interference(crowded)


def test_tip_table_interpolates_the_exact_kinematics():
    table = TipTable(ROBOT)
    phases = np.random.default_rng(1).uniform(0, 2 * np.pi, 200)
    geo = link_geometry(ROBOT, phases)
    exact = np.concatenate([geo.down_tips, geo.up_tips], axis=-1)
    assert np.max(np.abs(table.at(phases) - exact)) < 2e-7    # m


def test_tip_table_holds_phases_that_round_up_to_a_full_turn():
    table = TipTable(ROBOT)
    last = np.nextafter(2 * np.pi, 0.0)
    np.testing.assert_allclose(table.at(last), table.at(0.0), atol=1e-9)
    np.testing.assert_allclose(table.at(np.array([last, 1.0])), table.at(np.array([0.0, 1.0])),
                               atol=1e-9)
