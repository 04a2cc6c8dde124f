"""
TF and the robot description through real topics, and the tf2_msgs the set-up builds.

The simulator runs as a subprocess in the run's isolated DDS domain (tests/conftest.py); a private
rclpy context watches /tf, /saw/pose, /saw/joint_states and the latched /robot_description.
"""
import json
import math

import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from saw_ros.bag import schema
from saw_ros.core.dynamics import Simulator
from saw_ros.core.kinematics import link_geometry
from saw_ros.core.params import RobotParams, Scenario
from saw_ros.graph.process import ManagedProcess, node_command, wait_for
from saw_ros.interface import frames, share, topics, urdf
from saw_ros.ros import conversions as conv
from saw_ros.ros import tf
from saw_ros.vision.camera import CameraModel

pytestmark = pytest.mark.ros

from saw_ros.ros.nodes.simulator import TOPICS as STEP_TOPICS  # noqa: E402, I100

# tf2_msgs/msg/TFMessage's RIHS01 type hash in ROS 2 Jazzy (`ros2 topic info -v /tf` on a ROS
# install): the message scripts/bootstrap.sh builds must be the same type on the wire and in bags.
JAZZY_TFMESSAGE_HASH = 'RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087'


def test_tf2_msgs_is_jazzys_type_and_the_bag_writer_finds_its_definition():
    from tf2_msgs.msg import TFMessage
    assert tf.TFMessage is TFMessage
    path = share.share_file('tf2_msgs', 'msg', 'TFMessage.json')
    with open(path, encoding='utf-8') as f:
        assert json.load(f)['type_hashes'][0]['hash_string'] == JAZZY_TFMESSAGE_HASH
    definition = schema.message_definition(topics.topic(topics.TF).type)
    assert definition.startswith('geometry_msgs/TransformStamped[] transforms')
    assert 'MSG: geometry_msgs/TransformStamped' in definition


@pytest.mark.parametrize('mirror', [False, True])
@pytest.mark.parametrize('slope', [0.0, math.radians(30.0)])
def test_the_camera_frame_projects_surface_points_where_the_camera_model_draws_them(
        slope, mirror):
    """A pinhole at saw_camera with the model's K puts points of the plane on its pixels."""
    cam = CameraModel(slope=slope, mirror=mirror, center_x=0.4, center_y=0.02, distance=0.8)
    t = tf.camera_transform(cam)
    assert (t.header.frame_id, t.child_frame_id) == (frames.SURFACE, frames.CAMERA)
    v, q = t.transform.translation, t.transform.rotation
    x, y, z, w = q.x, q.y, q.z, q.w
    assert x * x + y * y + z * z + w * w == pytest.approx(1.0)
    rotation = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    points = np.array([[0.35, 0.0, 0.0], [0.52, 0.045, 0.0], [0.3, 0.03, 0.0]])
    in_camera = (points - [v.x, v.y, v.z]) @ rotation          # rows: R^T (p - t)
    assert np.all(in_camera[:, 2] > 0)                         # in front of the lens
    pixels = (cam.K @ (in_camera / in_camera[:, 2:]).T).T[:, :2]
    expected = cam.to_pixels(points[:, 0] + 1j * points[:, 1])
    expected = np.column_stack([np.real(expected), np.imag(expected)]) \
        if np.iscomplexobj(expected) else np.asarray(expected)
    np.testing.assert_allclose(pixels, expected, atol=1e-6)


def test_the_tf_encoder_gives_rclpys_message():
    """tf.message_cdr, the simulator's TF bytes, decodes to the message rclpy would send."""
    from rclpy.serialization import deserialize_message
    transforms = [('surface', 'base_link', (0.1, 0.02, 0.0), frames.yaw_quaternion(0.3))]
    transforms += urdf.link_frames(RobotParams(), 2.0)
    for some in (transforms, transforms[:1], transforms[:2], transforms[3:4], []):
        decoded = deserialize_message(tf.message_cdr(some, 1_234_567_891_234), tf.TFMessage)
        assert decoded == tf.message([tf.transform(parent, child, 1_234_567_891_234, t, q)
                                      for parent, child, t, q in some])


def _planar(t):
    """Return a transform in the side view as (x + i y, angle about z); it must stay there."""
    v, q = t.transform.translation, t.transform.rotation
    assert v.z == 0.0 and q.x == 0.0 and q.y == 0.0
    return complex(v.x, v.y), 2.0 * math.atan2(q.z, q.w)


def _chain(transforms, child):
    """Return ``child``'s pose in base_link, composing the planar transforms up to base_link."""
    by_child = {t.child_frame_id: t for t in transforms}
    position, angle = 0j, 0.0
    while child != frames.BASE_LINK:
        t = by_child[child]
        p, a = _planar(t)
        position, angle = p + np.exp(1j * a) * position, a + angle
        child = t.header.frame_id
    return position, angle


def _urdf_pose(model, joints, child):
    """Return ``child``'s pose in base_link from the URDF and joint values, as RSP computes it."""
    by_child = {j.child: j for j in model.joints}
    position, angle = 0j, 0.0
    while child != frames.BASE_LINK:
        j = by_child[child]
        assert j.origin.rpy == [0.0, 0.0, 0.0]
        offset, turn = complex(*j.origin.xyz[:2]), 0.0
        if j.type == 'prismatic':
            offset += joints[j.name] * complex(*j.axis[:2])
        else:
            turn = joints[j.name] * j.axis[2]
        position, angle = offset + np.exp(1j * turn) * position, turn + angle
        child = j.parent
    return position, angle


def _wrapped(angle):
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


# A compliant robot (issue 31, docs/compliant_robot.md): the best flexure of the level, its links
# deflecting by millimetres; the TF carries each link where the core deflected it.
COMPLIANT = {'flexure.stiffness': 1463.0, 'flexure.damping': 3.4}


def _core_run(values, steps):
    """Return {stamp ns: (phase, deflections)} of the core's own run of the node's scenario."""
    sim = Simulator(Scenario().with_values(values))
    out = {}
    for _ in range(steps):
        sim.step()
        out[sim.steps * conv.dt_nanoseconds(sim.dt)] = (float(sim.phase[0]),
                                                        sim.deflection[0].copy())
    return out


@pytest.mark.parametrize('flexure', [{}, COMPLIANT], ids=['rigid', 'compliant'])
def test_the_simulator_publishes_base_link_on_tf_at_its_pose_and_a_latched_urdf(ros_context,
                                                                                tmp_path,
                                                                                flexure):
    from geometry_msgs.msg import PoseStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String
    from urdf_parser_py.urdf import URDF
    node = Node('tf_watcher', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    got = {'tf': [], 'pose': {}, 'names': [], 'urdf': [], 'joints': {}}
    reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_subscription(tf.TFMessage, topics.TF, got['tf'].append, reliable)
    node.create_subscription(
        PoseStamped, topics.POSE,
        lambda m: got['pose'].__setitem__(conv.stamp_ns(m.header.stamp), m), reliable)

    def joints(m):
        got['names'].append(list(m.name))
        got['joints'][conv.stamp_ns(m.header.stamp)] = dict(zip(m.name, m.position))
    node.create_subscription(JointState, topics.JOINT_STATES, joints, reliable)
    node.create_subscription(String, topics.ROBOT_DESCRIPTION, got['urdf'].append, latched)
    # The simulator waits for a subscriber on each of its step topics (wait_for_subscribers).
    for name, cls in STEP_TOPICS.items():
        if name not in (topics.POSE, topics.JOINT_STATES):
            node.create_subscription(cls, name, lambda data: None, reliable, raw=True)
    proc = ManagedProcess('simulator', node_command('simulator', params={
        'duration': 0.5, 'real_time_factor': 1.0, 'wait_for_subscribers': 1, **flexure}),
        env=None, log_dir=tmp_path)
    try:
        def spin(timeout):
            executor.spin_once(timeout_sec=timeout)
        # 90 s: the simulator's start (imports, compiled kernels) on a busy machine; the run
        # itself is 0.5 s of simulated time.
        assert wait_for(lambda: proc.returncode is not None, 90.0, spin=spin), 'no exit'
        assert proc.returncode == 0, proc.log_path.read_text()[-2000:]
    finally:
        proc.stop(timeout=5)
    # 60 Hz of simulated time over 0.5 s, each surface -> base_link at the pose, then every
    # frame of the URDF (link_tf, on by default) where the core puts it (issue 34: 1e-6 m and
    # rad), and where robot_state_publisher puts it from /saw/joint_states of the same stamp.
    # The core's pose: its own run of the same scenario, each link at its kinematic target
    # moved by its deflection on its flexure normal to the backbone (0 for rigid links).
    assert len(got['tf']) == 31, len(got['tf'])
    robot = RobotParams()
    core_run = _core_run(flexure, 500)
    model = URDF.from_xml_string(got['urdf'][0].data)
    worst = {'core_m': 0.0, 'core_rad': 0.0, 'urdf_m': 0.0, 'urdf_rad': 0.0, 'joint_m': 0.0}
    # /saw/joint_states at 100 Hz: every 50 ms its stamps meet the 60 Hz TF's (10 in 0.5 s).
    same_stamp = [m for m in got['tf'] if conv.stamp_ns(m.transforms[0].header.stamp) in
                  got['joints']]
    assert len(same_stamp) == 10, sorted(got['joints'])
    names = urdf.link_names(robot)
    deflections = []
    for msg in got['tf']:
        t, *links = msg.transforms
        assert {x.child_frame_id for x in links} == {link.name for link in model.links} - {
            frames.BASE_LINK}
        stamp = conv.stamp_ns(t.header.stamp)
        phase, deflection = core_run[stamp]
        deflections.append(np.abs(deflection).max())
        geo = link_geometry(robot, phase)
        helix = next(x for x in links if x.child_frame_id == 'helix').transform.rotation
        assert _wrapped(2.0 * math.atan2(helix.x, helix.w) - phase) == \
            pytest.approx(0.0, abs=1e-9)
        core = {'base_link_joint': (geo.hinge, -float(geo.base_angle))}
        core.update({name: (complex(c) + 1j * e, float(a)) for name, c, a, e in zip(
            names, geo.centres, geo.angles, deflection)})
        joints = got['joints'].get(stamp)
        if joints is not None:
            assert joints['helix'] == phase
            worst['joint_m'] = max(worst['joint_m'], np.abs(
                [joints[f'{n}_flex'] for n in names] - deflection).max())
        for name, (position, angle) in core.items():
            p, a = _chain(links, name)
            worst['core_m'] = max(worst['core_m'], abs(p - position))
            worst['core_rad'] = max(worst['core_rad'], abs(_wrapped(a - angle)))
            if joints is not None:
                p, a = _urdf_pose(model, joints, name)
                worst['urdf_m'] = max(worst['urdf_m'], abs(p - position))
                worst['urdf_rad'] = max(worst['urdf_rad'], abs(_wrapped(a - angle)))
    # Rigid links stay on their targets; the compliant ones deflect by millimetres.
    assert (max(deflections) > 1e-3) if flexure else (max(deflections) == 0.0), deflections
    assert worst['joint_m'] == 0.0, worst           # the core's deflections as they are
    assert worst['core_m'] < 1e-6 and worst['core_rad'] < 1e-6, worst
    # /saw/joint_states come from a table of the same geometry (JointStateTable: 1e-5 rad).
    assert worst['urdf_m'] < 1e-7 and worst['urdf_rad'] < 1e-5, worst
    for msg in got['tf']:
        t = msg.transforms[0]
        assert (t.header.frame_id, t.child_frame_id) == (frames.SURFACE, frames.BASE_LINK)
        pose = got['pose'][conv.stamp_ns(t.header.stamp)].pose
        assert (t.transform.translation.x, t.transform.translation.y) == \
            (pose.position.x, pose.position.y)
        assert t.transform.rotation.z == pytest.approx(pose.orientation.z, abs=1e-12)
        assert t.transform.rotation.w == pytest.approx(pose.orientation.w, abs=1e-12)
    assert len(got['urdf']) == 1, len(got['urdf'])
    robot = URDF.from_xml_string(got['urdf'][0].data)
    assert sorted(j.name for j in robot.joints) == sorted(got['names'][0])
    assert robot.get_root() == frames.BASE_LINK
