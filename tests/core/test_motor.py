"""
The DC motor between the voltage and the helix (docs/motor.md): closed forms, energy, batches.

k = 1 / (2 pi hz_per_volt); J dw/dt = k i - tau_f sign(w) - tau_load; i = (V - k w) / R.
"""
import math

import numpy as np
import pytest

from saw_ros.core import Scenario, simulate, Simulator
from saw_ros.core.kinematics import link_geometry, tip_rates, TipRateTable
from saw_ros.core.metrics import analyse, analyse_run
from saw_ros.core.motor import MotorLaw
from saw_ros.core.params import MotorParams

CLIMB = math.radians(20.0)


def motor_run(volts, slope, duration=3.0, **motor):
    values = {'motor.voltage': volts, 'conditions.slope': slope}
    values.update({f'motor.{k}': v for k, v in motor.items()})
    scenario = Scenario().with_values(values)
    return scenario, simulate(scenario, duration)


def mean_frequency(tr, since=1.5, column=0):
    return float(tr.omega[tr.t > since, column].mean()) / (2 * math.pi)


def test_tip_rates_are_the_phase_derivative_of_the_tip_positions():
    robot = Scenario().robot
    phase = np.linspace(0.0, 2 * math.pi, 97)
    h = 1e-6
    ahead, behind = link_geometry(robot, phase + h), link_geometry(robot, phase - h)
    difference = np.concatenate([ahead.down_tips - behind.down_tips,
                                 ahead.up_tips - behind.up_tips], axis=-1) / (2 * h)
    exact = tip_rates(robot, phase)
    # Tips sweep at up to A k (1 + r k) ~ 2 cm/rad: agreement to 1e-9 of that.
    assert np.abs(exact).max() > 0.01
    np.testing.assert_allclose(exact, difference, rtol=0, atol=1e-9)
    table = TipRateTable(robot).at(phase[:-1])
    np.testing.assert_allclose(table, exact[:-1], rtol=0, atol=1e-6)


@pytest.mark.parametrize('friction', [0.0, 0.02])
def test_no_load_speed_is_hz_per_volt_times_the_voltage_above_the_friction(friction):
    # Vertical and 10 cm wide: gravity along the surfaces, nothing ever touches a tip.
    s = Scenario().with_values({'motor.voltage': 5.0, 'conditions.slope': math.pi / 2,
                                'conditions.gap': 0.1, 'motor.friction_torque': friction})
    sim = Simulator(s)
    tr = sim.run(2.0)
    assert np.all(sim.contacts.free)
    m = s.motor
    expected = m.hz_per_volt * (5.0 - m.resistance * friction / m.torque_constant)
    # (2 s is 18 mechanical time constants: within e^-18 of the final speed)
    assert tr.omega[-1, 0] / (2 * math.pi) == pytest.approx(expected, rel=1e-7)
    assert s.frequency == pytest.approx(expected, rel=1e-12)
    if friction == 0.0:
        assert expected == pytest.approx(5.0 * m.hz_per_volt, rel=1e-12)
    # Spinning up from rest with the mechanical time constant J R / k^2 (~0.11 s).
    tau = m.inertia * m.resistance / m.torque_constant ** 2
    at_tau = tr.omega[int(round(tau / s.integration.dt)), 0] / (2 * math.pi)
    assert at_tau == pytest.approx(expected * (1 - math.exp(-1)), rel=0.02)
    # Current: only the friction is left to carry.
    assert tr.current[-1, 0] == pytest.approx(friction / m.torque_constant, abs=1e-7)


@pytest.mark.parametrize('inertia', [0.0, 0.006])
@pytest.mark.parametrize('load', [0.0, 0.03, -0.01])
def test_steady_speed_under_a_constant_load_is_the_closed_form(inertia, load):
    motor = MotorParams(voltage=6.0, resistance=8.0, friction_torque=0.02, inertia=inertia)
    law = MotorLaw([motor], 0.001)
    omega = np.zeros(1)
    for _ in range(3000):
        omega, torque, friction = law.step(omega, np.array([load]))
    k, R = motor.torque_constant, motor.resistance
    assert omega[0] == pytest.approx((6.0 - R * (load + 0.02) / k) / k, rel=1e-9)
    assert friction[0] == pytest.approx(0.02, rel=1e-9)
    assert torque[0] == pytest.approx(load + 0.02, rel=1e-9, abs=1e-12)
    assert torque[0] / k == pytest.approx((6.0 - k * omega[0]) / R, rel=1e-9, abs=1e-12)


def test_a_load_beyond_the_stall_torque_holds_the_helix_still():
    motor = MotorParams(voltage=4.0)
    k, R = motor.torque_constant, motor.resistance
    stall = k * 4.0 / R
    law = MotorLaw([motor], 0.001)
    # Up to the friction beyond the stall torque the helix neither turns nor turns back.
    omega, _, friction = law.step(np.zeros(1), np.array([stall + 0.5 * motor.friction_torque]))
    assert omega[0] == 0.0 and friction[0] == pytest.approx(-0.5 * motor.friction_torque)
    omega, _, _ = law.step(np.zeros(1), np.array([stall + 2.0 * motor.friction_torque]))
    assert omega[0] < 0.0


def test_zero_resistance_turns_the_helix_exactly_as_the_constant_frequency():
    motor_s = Scenario().with_values({'motor.voltage': 4.0, 'motor.resistance': 0.0,
                                      'conditions.slope': CLIMB})
    constant_s = Scenario().with_values({'conditions.frequency': 4.0 * motor_s.motor.hz_per_volt,
                                         'conditions.slope': CLIMB})
    assert motor_s.frequency == constant_s.frequency
    driven, constant = simulate(motor_s, 2.0), simulate(constant_s, 2.0)
    np.testing.assert_array_equal(driven.q, constant.q)
    # (a motor starts at rest: the first sample, before any step, differs)
    np.testing.assert_allclose(driven.omega[1:], constant.omega[1:], rtol=1e-15, atol=0)
    # The ideal source supplies what the load and the friction take.
    assert np.nanmean(driven.torque[1000:, 0]) > motor_s.motor.friction_torque
    assert constant.torque is None and constant.current is None


def world_tips(robot, phase, theta):
    """Tip offsets from the COM in world axes, (steps, P), at the phases and pitches given."""
    g = link_geometry(robot, phase)
    return np.concatenate([g.down_tips, g.up_tips], axis=-1) * np.exp(1j * theta)[:, None]


def test_electrical_energy_is_copper_friction_tip_work_and_kinetic_energy():
    """
    Over a run from rest, sum V i dt = sum R i^2 dt + friction + work on the tips + J w^2 / 2.

    The work on the tips is measured from the contact forces and the tips' displacement relative
    to the body over the step's turn of the helix (exact link geometry half a step either side
    of the phase the forces were found at: forward differences would carry an O(dt) bias, 8 %
    at 1 ms, from the curvature of the tips' paths under their large normal forces), not from
    the load torque the simulator computes.
    """
    s = Scenario().with_values({'motor.voltage': 4.0, 'conditions.slope': CLIMB})
    m = s.motor
    sim = Simulator(s)
    dt, steps = s.integration.dt, 1500
    side = sim.table.side
    phase, turn, theta = np.empty(steps), np.empty(steps), np.empty(steps)
    fx, fy = np.empty((steps, side.size)), np.empty((steps, side.size))
    electric = copper = friction = 0.0
    for j in range(steps):
        phase[j], theta[j] = sim.phase[0], sim.q[2, 0]
        sim.step()
        turn[j] = sim.omega[0] * dt
        fx[j] = sim.contacts.tangential[0]
        fy[j] = -side * sim.contacts.normal[0]
        i, w = sim.current[0], sim.omega[0]
        electric += m.voltage * i * dt
        copper += m.resistance * i * i * dt
        friction += sim.friction_torque[0] * w * dt
    moved = (world_tips(s.robot, phase + turn / 2, theta)
             - world_tips(s.robot, phase - turn / 2, theta))
    tip_work = -float(np.sum(fx * moved.real + fy * moved.imag))
    kinetic = 0.5 * m.inertia * sim.omega[0] ** 2
    assert tip_work > 0.2 * electric          # the tips take a real share, it is no rounding
    assert electric == pytest.approx(copper + friction + tip_work + kinetic, rel=0.005)


def test_the_motor_slows_more_climbing_than_descending():
    """Paper Section 6.4: the slower 4 V runs come from the motor slowing under load."""
    up_s, up = motor_run(4.0, CLIMB)
    _, down = motor_run(4.0, -CLIMB)
    no_load = up_s.frequency
    f_up, f_down = mean_frequency(up), mean_frequency(down)
    assert f_up < f_down < no_load
    # Noticeable at the defaults: 5-20 % below the no-load speed climbing 20 deg at 4 V.
    assert 0.80 < f_up / no_load < 0.95
    # The current the trajectory reports is the resistor's (V - k w) / R.
    k, R = up_s.motor.torque_constant, up_s.motor.resistance
    np.testing.assert_allclose(up.current[1:, 0], (4.0 - k * up.omega[1:, 0]) / R, rtol=1e-9,
                               atol=1e-12)


def test_advance_ratio_uses_the_helix_frequency_the_motor_reached():
    s, tr = motor_run(4.0, CLIMB, duration=4.0)
    m = analyse(tr.t, tr.q[:, 0], s.robot, s.frequency, omega=tr.omega[:, 0])
    nominal = analyse(tr.t, tr.q[:, 0], s.robot, s.frequency)
    # One helix turn later, the motion repeats (the clock's mean period would not: module
    # docstring of core.metrics): steady, and converged as the paper's Figure 8.
    assert m.steady_from is not None and m.steady_from < 2.0
    assert m.cci_2pct_after is not None and m.cci_2pct_after < 2.0
    assert m.frequency == pytest.approx(mean_frequency(tr, 2.0), rel=0.01)
    assert m.frequency < 0.95 * s.frequency
    assert m.v_mean == pytest.approx(nominal.v_mean, rel=0.02)
    assert m.advance_ratio == pytest.approx(m.v_mean / (m.v_theory), rel=1e-12)
    assert m.advance_ratio > nominal.advance_ratio * 1.05
    assert analyse_run(tr) == m


def test_scenarios_with_and_without_motor_stepped_together_match_each_alone():
    scenarios = [Scenario().with_values(v) for v in (
        {'motor.voltage': 4.0, 'conditions.slope': CLIMB},
        {'conditions.slope': -CLIMB},
        {'motor.voltage': 7.0, 'motor.resistance': 3.0, 'motor.inertia': 0.0,
         'conditions.slope': -CLIMB},
        {'motor.voltage': 6.0, 'motor.friction_torque': 0.0, 'surface.friction_coefficient': 0.5})]
    together = simulate(scenarios, 1.0)
    for i, s in enumerate(scenarios):
        alone = simulate(s, 1.0)
        np.testing.assert_allclose(together.q[:, i], alone.q[:, 0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(together.omega[:, i], alone.omega[:, 0], rtol=0, atol=1e-12)
        if alone.current is None:
            assert np.isnan(together.current[:, i]).all()
        else:
            np.testing.assert_allclose(together.current[:, i], alone.current[:, 0], rtol=0,
                                       atol=1e-12)


def test_switching_the_motor_on_and_off_mid_run_keeps_the_helix_speed_continuous():
    """The simulator node changes motor.voltage at run time: the helix speed is a state."""
    constant = Scenario().with_values({'conditions.slope': CLIMB})
    driven = constant.with_values({'motor.voltage': 4.0})
    sim = Simulator(constant)
    sim.run(0.5)
    assert np.isnan(sim.motor_torque[0]) and sim.omega[0] == pytest.approx(2 * math.pi)
    sim.set_scenarios([driven])
    sim.step()
    # From 2 pi rad/s, not from rest: the rotor's inertia carries the speed over.
    assert abs(sim.omega[0] - 2 * math.pi) < 0.1
    sim.run(1.5)
    assert sim.omega[0] < 2 * math.pi * driven.frequency and sim.current[0] > 0.0
    sim.set_scenarios([constant])
    sim.step()
    assert sim.omega[0] == pytest.approx(2 * math.pi) and np.isnan(sim.current[0])
