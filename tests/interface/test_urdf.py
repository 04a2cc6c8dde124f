"""The robot's URDF: generated from the core's parameters, parsed by ROS's URDF reader."""
from pathlib import Path

import numpy as np
import pytest
from saw_ros.core.kinematics import link_geometry
from saw_ros.core.params import RobotParams
from saw_ros.interface import urdf
from urdf_parser_py.urdf import URDF

ROOT = Path(__file__).resolve().parents[2]


def test_the_checked_in_urdf_is_the_generators_output():
    """urdf/saw.urdf (installed to share/saw_ros/urdf) is regenerated, never edited."""
    text = (ROOT / 'urdf' / 'saw.urdf').read_text(encoding='utf-8')
    assert text == urdf.urdf(RobotParams()), \
        'regenerate: python -m saw_ros.interface.urdf --write urdf/saw.urdf'


@pytest.mark.parametrize('robot', [RobotParams(), RobotParams(wave_links=7, length=0.25)])
def test_its_joints_are_the_joint_states_names_each_moving_its_link(robot):
    model = URDF.from_xml_string(urdf.urdf(robot))
    links = [f'link_{i:02d}' for i in range(robot.wave_links)]
    names = (['helix', 'base_link_joint'] + links + [f'{n}_x' for n in links]
             + [f'{n}_y' for n in links] + [f'{n}_flex' for n in links])
    assert urdf.joint_names(robot) == names
    assert sorted(j.name for j in model.joints) == sorted(names)
    # One value per joint of the simulator's JointState after the helix (its phase).
    values, rates = urdf.JointStateTable(robot).values_and_rates(0.3, 2.0)
    assert len(values) + 1 == len(rates) + 1 == len(names)
    assert model.get_root() == 'base_link'
    for joint in model.joints:
        assert joint.child == joint.name
    # Each wave link hangs from base_link through its position along x, along y, its
    # deflection on its flexure (along y too), then its angle.
    for name in links:
        chain = [f'{name}_x', f'{name}_y', f'{name}_flex', name]
        assert model.get_chain('base_link', name, links=False) == chain
        assert [model.joint_map[j].type for j in chain] == \
            ['prismatic', 'prismatic', 'prismatic', 'revolute']
        assert model.joint_map[f'{name}_flex'].axis == [0.0, 1.0, 0.0]


def test_the_joint_state_table_is_the_cores_geometry_within_its_stated_error():
    """Per step, /saw/joint_states from the table: 1e-5 rad and 1e-8 m of link_geometry."""
    robot = RobotParams()
    table = urdf.JointStateTable(robot)
    phases = np.linspace(0.0, 4.0 * np.pi, 1001)
    geo = link_geometry(robot, phases)
    n = robot.wave_links
    values = np.array([table.values_and_rates(p)[0] for p in phases])
    assert np.abs(values[:, 0] - geo.base_angle).max() < 1e-5
    assert np.abs(values[:, 1:1 + n] - geo.angles).max() < 1e-6
    assert np.abs(values[:, 1 + n:1 + 2 * n]).max() < 1e-15     # the centres keep their abscissa
    assert np.abs(values[:, 1 + 2 * n:1 + 3 * n] - geo.centres.imag).max() < 1e-8
    assert not values[:, 1 + 3 * n:].any()          # rigid links: no deflection
    # Rates: d/dt at helix speed omega, against a central difference of the geometry.
    omega, h = 3.0, 1e-6
    for phase in (0.4, 2.0, 5.5):
        rates = table.values_and_rates(phase, omega)[1]
        ahead, behind = link_geometry(robot, phase + h), link_geometry(robot, phase - h)
        expected = (ahead.centres.imag - behind.centres.imag) / (2 * h) * omega
        np.testing.assert_allclose(rates[1 + 2 * n:1 + 3 * n], expected, atol=1e-4 * omega)
    # The flexures' joints carry the core's deflections and their rates as they are, last.
    e, rate = np.linspace(-2e-3, 3e-3, n), np.linspace(0.1, -0.2, n)
    values, rates = table.values_and_rates(0.4, omega, e, rate)
    assert (values[1 + 3 * n:] == e).all() and (rates[1 + 3 * n:] == rate).all()
    assert (values[:1 + 3 * n] == table.values_and_rates(0.4, omega)[0][:1 + 3 * n]).all()


def test_the_links_sit_where_the_core_puts_them_and_turn_within_their_limits():
    robot = RobotParams()
    model = URDF.from_xml_string(urdf.urdf(robot))
    joints = {j.name: j for j in model.joints}
    geo = link_geometry(robot, [0.0, 1.0, 2.0, 4.0])
    assert joints['base_link_joint'].origin.xyz[0] == pytest.approx(geo.hinge.real, abs=1e-6)
    for i in range(robot.wave_links):
        along = joints[f'link_{i:02d}_x']
        assert along.origin.xyz[0] == pytest.approx(geo.centres[0, i].real, abs=1e-9)
        assert along.axis == [1.0, 0.0, 0.0] and joints[f'link_{i:02d}_y'].axis == [0.0, 1.0, 0.0]
        normal = joints[f'link_{i:02d}_y'].limit
        assert normal.lower <= geo.centres[:, i].imag.min() <= geo.centres[:, i].imag.max() \
            <= normal.upper
        joint = joints[f'link_{i:02d}']
        assert joint.origin.xyz == [0.0, 0.0, 0.0]
        assert joint.axis == [0.0, 0.0, 1.0]
        assert joint.limit.lower - 1e-6 <= geo.angles[:, i].min()
        assert geo.angles[:, i].max() <= joint.limit.upper + 1e-6
    assert model.link_map['base_link'].inertial.mass == robot.mass
