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
from saw_ros.graph.process import ManagedProcess, node_command, wait_for
from saw_ros.interface import frames, share, topics
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


def test_the_simulator_publishes_base_link_on_tf_at_its_pose_and_a_latched_urdf(ros_context,
                                                                                tmp_path):
    from geometry_msgs.msg import PoseStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String
    from urdf_parser_py.urdf import URDF
    node = Node('tf_watcher', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    got = {'tf': [], 'pose': {}, 'names': [], 'urdf': []}
    reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_subscription(tf.TFMessage, topics.TF, got['tf'].append, reliable)
    node.create_subscription(
        PoseStamped, topics.POSE,
        lambda m: got['pose'].__setitem__(conv.stamp_ns(m.header.stamp), m), reliable)
    node.create_subscription(JointState, topics.JOINT_STATES,
                             lambda m: got['names'].append(list(m.name)), reliable)
    node.create_subscription(String, topics.ROBOT_DESCRIPTION, got['urdf'].append, latched)
    # The simulator waits for a subscriber on each of its step topics (wait_for_subscribers).
    for name, cls in STEP_TOPICS.items():
        if name not in (topics.POSE, topics.JOINT_STATES):
            node.create_subscription(cls, name, lambda data: None, reliable, raw=True)
    proc = ManagedProcess('simulator', node_command('simulator', params={
        'duration': 0.5, 'real_time_factor': 1.0, 'wait_for_subscribers': 1}), env=None,
        log_dir=tmp_path)
    try:
        def spin(timeout):
            executor.spin_once(timeout_sec=timeout)
        assert wait_for(lambda: proc.returncode is not None, 30.0, spin=spin), 'no exit'
        assert proc.returncode == 0, proc.log_path.read_text()[-2000:]
    finally:
        proc.stop(timeout=5)
    # 60 Hz of simulated time over 0.5 s, each one transform surface -> base_link at the pose.
    assert len(got['tf']) == 31, len(got['tf'])
    for msg in got['tf']:
        (t,) = msg.transforms
        assert (t.header.frame_id, t.child_frame_id) == (frames.SURFACE, frames.BASE_LINK)
        pose = got['pose'][conv.stamp_ns(t.header.stamp)].pose
        assert (t.transform.translation.x, t.transform.translation.y) == \
            (pose.position.x, pose.position.y)
        assert t.transform.rotation.z == pytest.approx(pose.orientation.z, abs=1e-12)
        assert t.transform.rotation.w == pytest.approx(pose.orientation.w, abs=1e-12)
    assert len(got['urdf']) == 1, len(got['urdf'])
    robot = URDF.from_xml_string(got['urdf'][0].data)
    assert [j.name for j in robot.joints] == got['names'][0]
    assert robot.get_root() == frames.BASE_LINK
