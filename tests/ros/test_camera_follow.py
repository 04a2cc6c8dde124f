"""
The camera follows the robot (issue 12).

With a fixed camera the robot walks out of the picture after about 13 s of simulated time and
/saw/tracking/* go silent; the camera node's ``follow`` moves it along the track in steps, the
CameraInfo's principal point carries the offset, and the vision node keeps metric positions
continuous. An 8 s run (a small picture: a move every second or two) is tracked to its end,
every frame but at most one per move ok.
"""
import math

import pytest

from saw_ros.core import Scenario, Simulator
from saw_ros.graph.process import wait_for
from saw_ros.ros import conversions as conv

pytestmark = pytest.mark.ros

DURATION = 8.0
STEADY = 2.0


def test_following_camera_keeps_tracking(ros_context, drive_camera):
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseStamped, TwistStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import CameraInfo, JointState

    from saw_ros.ros.nodes.camera import CameraNode
    from saw_ros.ros.nodes.vision import VisionNode
    from saw_ros.ros.qos import STREAM_QOS as qos

    camera = CameraNode(context=ros_context, parameter_overrides=[
        Parameter('width', value=640), Parameter('height', value=360),
        Parameter('texture', value=False)])
    vision = VisionNode(context=ros_context, parameter_overrides=[
        Parameter('steady_window', value=STEADY)])
    source = Node('test_source', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    for n in (camera, vision, source):
        executor.add_node(n)
    spin = lambda t: executor.spin_once(timeout_sec=t)   # noqa: E731
    got = {k: [] for k in ('pose', 'steady', 'status', 'info')}
    source.create_subscription(PoseStamped, '/saw/tracking/pose', got['pose'].append, qos)
    source.create_subscription(TwistStamped, '/saw/tracking/steady_speed', got['steady'].append,
                               qos)
    source.create_subscription(DiagnosticArray, '/saw/tracking/status', got['status'].append,
                               qos)
    source.create_subscription(CameraInfo, '/saw/camera/camera_info',
                               lambda m: got['info'].append(m.k[2]), qos)
    pub_pose = source.create_publisher(PoseStamped, '/saw/pose', qos)
    pub_joints = source.create_publisher(JointState, '/saw/joint_states', qos)
    try:
        assert wait_for(lambda: pub_pose.get_subscription_count() >= 1
                        and pub_joints.get_subscription_count() >= 1
                        and vision.count_publishers('/saw/camera/image_raw') >= 1, 10.0,
                        spin=spin)
        sim = Simulator(Scenario())
        truth = drive_camera(sim, pub_pose, pub_joints, DURATION, vision, camera, spin)
        assert wait_for(lambda: len(got['status']) >= vision.results and got['steady'], 5.0,
                        spin=spin)
    finally:
        executor.shutdown()
        camera.close()
        for n in (camera, vision, source):
            n.destroy_node()

    moves = len(set(got['info'])) - 1
    assert moves >= 3 and camera.offset > 0.04, (moves, camera.offset)   # ~6 cm by 8 s
    statuses = [s.status[0].message for s in got['status']]
    assert len(statuses) == int(math.floor(DURATION * 60 + 1e-9)) + 1
    assert statuses.count('ok') >= len(statuses) - moves, \
        [(k, s) for k, s in enumerate(statuses) if s != 'ok']
    assert statuses[-1] == 'ok'
    # Metric positions continuous across the moves and on the truth to the end.
    xs = [(conv.stamp_ns(p.header.stamp), p.pose.position.x) for p in got['pose']]
    assert xs[-1][0] / 1e9 > DURATION - 0.05
    for t_ns, x in xs:
        assert x == pytest.approx(truth[round(t_ns / 1e6)], abs=1e-3)
    live = got['steady'][-1].twist.linear.x
    end = max(truth)
    assert live == pytest.approx((truth[end] - truth[end - 2000]) / 2.0, rel=0.01)
