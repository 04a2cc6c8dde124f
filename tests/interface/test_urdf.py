"""The robot's URDF: generated from the core's parameters, parsed by ROS's URDF reader."""
from pathlib import Path

import pytest
from saw_ros.core.kinematics import JointTable, link_geometry
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
    names = ['helix', 'base_link_joint'] + [f'link_{i:02d}' for i in range(robot.wave_links)]
    assert [j.name for j in model.joints] == names == urdf.joint_names(robot)
    # One value per joint of the simulator's JointState: phase, base-link angle, link angles.
    assert len(JointTable(robot).angles_and_rates(0.3)[0]) + 1 == len(names)
    assert model.get_root() == 'base_link'
    for joint in model.joints:
        assert joint.parent == 'base_link' and joint.child == joint.name
        assert model.get_chain('base_link', joint.child) == ['base_link', joint.name,
                                                             joint.child]


def test_the_links_sit_where_the_core_puts_them_and_turn_within_their_limits():
    robot = RobotParams()
    model = URDF.from_xml_string(urdf.urdf(robot))
    joints = {j.name: j for j in model.joints}
    geo = link_geometry(robot, [0.0, 1.0, 2.0, 4.0])
    assert joints['base_link_joint'].origin.xyz[0] == pytest.approx(geo.hinge.real, abs=1e-6)
    for i in range(robot.wave_links):
        joint = joints[f'link_{i:02d}']
        assert joint.origin.xyz[0] == pytest.approx(geo.centres[0, i].real, abs=1e-6)
        assert joint.axis == [0.0, 0.0, 1.0]
        assert joint.limit.lower - 1e-6 <= geo.angles[:, i].min()
        assert geo.angles[:, i].max() <= joint.limit.upper + 1e-6
    assert model.link_map['base_link'].inertial.mass == robot.mass
