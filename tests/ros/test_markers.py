"""
The markers node through real topics.

A feeder publishes hand-made ground truth (pose, contacts, helix phase) every simulated
millisecond and a tracker's estimate; the node, in the same executor, draws them on /saw/markers.
"""
import math
import time

from geometry_msgs.msg import PointStamped, PoseStamped
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from saw_ros.core.params import Scenario
from saw_ros.interface import topics as table
from saw_ros.ros import conversions as conv
from saw_ros.ros.nodes.markers import MarkersNode, next_due
from saw_ros.ros.qos import profile, STREAM_QOS, with_depth
from sensor_msgs.msg import JointState, PointCloud2
from visualization_msgs.msg import Marker, MarkerArray

pytestmark = pytest.mark.ros

STEPS = 101                      # 0 .. 100 ms of stamps
X, Y, THETA = 0.12, 0.0225, 0.05
NORMAL = np.array([2.0, 3.0])
TANGENTIAL = np.array([0.5, -1.0])


def contacts():
    points = np.zeros(2, conv.CONTACT_DTYPE)
    points['x'] = [0.01, 0.05]
    points['y'] = [0.0, 0.045]
    points['normal_force'] = NORMAL
    points['tangential_force'] = TANGENTIAL
    points['link'] = [3, 7]
    points['surface'] = [conv.BOTTOM, conv.TOP]
    points['slipping'] = [0, 1]
    return points


class Feeder(Node):
    def __init__(self, context):
        super().__init__('feeder', context=context)
        stream = with_depth(STREAM_QOS, 1000)
        self.pose = self.create_publisher(PoseStamped, table.POSE, stream)
        self.contacts = self.create_publisher(PointCloud2, table.CONTACTS, stream)
        self.joints = self.create_publisher(JointState, table.JOINT_STATES, stream)
        self.front = self.create_publisher(PointStamped, table.TRACKING_FRONT, profile('tracking'))
        self.tracked = self.create_publisher(PoseStamped, table.TRACKING_POSE,
                                             profile('tracking'))
        self.arrays = []
        self.create_subscription(MarkerArray, table.MARKERS, self.arrays.append,
                                 profile('tracking'))


def spin_until(executor, condition, timeout=10.0):
    end = time.monotonic() + timeout
    while not condition() and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)
    assert condition()


def by_namespace(array, namespace):
    return [m for m in array.markers if m.ns == namespace]


def test_markers_draw_truth_forces_and_tracking_at_60_hz_of_stamps(ros_context):
    executor = SingleThreadedExecutor(context=ros_context)
    feeder = Feeder(ros_context)
    node = MarkersNode(context=ros_context)
    executor.add_node(feeder)
    executor.add_node(node)
    try:
        spin_until(executor, lambda: all(p.get_subscription_count() > 0 for p in (
            feeder.pose, feeder.contacts, feeder.joints, feeder.front, feeder.tracked)))
        spin_until(executor, lambda: feeder.count_publishers(table.MARKERS) > 0)
        front = PointStamped()
        front.point.x, front.point.y = 0.28, 0.0225
        feeder.front.publish(front)
        feeder.tracked.publish(conv.pose_msg(0.11, 0.02, 0.1, 0))
        spin_until(executor, lambda: node.front is not None and node.tracked is not None)
        cloud = conv.ContactsCdr()
        for step in range(STEPS):
            ns = step * 1_000_000
            feeder.pose.publish(conv.pose_cdr(X, Y, THETA, ns))
            joints = JointState(name=['helix'], position=[0.3])
            joints.header.stamp = conv.time_msg(ns)
            feeder.joints.publish(joints)
            feeder.contacts.publish(cloud(contacts(), ns))
            executor.spin_once(timeout_sec=0)
        spin_until(executor, lambda: len(feeder.arrays) >= 7)
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
    finally:
        executor.shutdown()
        node.destroy_node()
        feeder.destroy_node()

    # Decimated by stamps: one array per 1/60 s slot, at the first stamp in it.
    stamps = [conv.stamp_ns(a.markers[0].header.stamp) // 1_000_000 for a in feeder.arrays]
    assert stamps == [0, 17, 34, 50, 67, 84, 100]
    assert next_due(0, 60.0) == 16_666_667 and next_due(49_000_000, 60.0) == 50_000_000

    gap = Scenario().conditions.gap
    for array in feeder.arrays:
        assert array.markers[0].action == Marker.DELETEALL
        assert all(m.header.frame_id == 'surface' for m in array.markers)
        surfaces = by_namespace(array, 'surfaces')
        assert sorted(m.pose.position.y for m in surfaces) == pytest.approx([0.0, gap])
        assert all(m.type == Marker.CUBE for m in surfaces)
        body, = by_namespace(array, 'body')
        assert body.type == Marker.CUBE
        assert (body.pose.position.x, body.pose.position.y) == pytest.approx((X, Y))
        assert 2 * math.atan2(body.pose.orientation.z, body.pose.orientation.w) == \
            pytest.approx(THETA)
        assert len(by_namespace(array, 'base_link')) == 1
        links, = by_namespace(array, 'wave_links')
        tips, = by_namespace(array, 'tips')
        n = Scenario().robot.wave_links
        assert len(links.points) == 6 * n and len(tips.points) == 2 * n
        # One arrow per touching tip, 1 cm per N, away from its surface, green stick / red slip.
        arrows = by_namespace(array, 'contact_forces')
        assert [m.type for m in arrows] == [Marker.ARROW] * 2
        for m, fn, ft, up in zip(arrows, NORMAL, TANGENTIAL, (1, -1)):
            start, end = m.points
            assert end.x - start.x == pytest.approx(0.01 * ft, abs=1e-6)
            assert end.y - start.y == pytest.approx(0.01 * fn * up, abs=1e-6)
            assert math.hypot(end.x - start.x, end.y - start.y) == \
                pytest.approx(0.01 * math.hypot(fn, ft), abs=1e-6)
        assert (arrows[0].color.g, arrows[0].color.r) == (pytest.approx(0.8), 0.0)
        assert (arrows[1].color.r, arrows[1].color.g) == (pytest.approx(0.9), 0.0)
        # The tracker's estimate: the front marker centre and the tracked pose's arrow.
        sphere, = by_namespace(array, 'tracking_markers')
        assert (sphere.type, sphere.pose.position.x) == (Marker.SPHERE, pytest.approx(0.28))
        pose_arrow, = by_namespace(array, 'tracking_pose')
        start, end = pose_arrow.points
        assert (start.x, start.y) == pytest.approx((0.11, 0.02))
        assert math.atan2(end.y - start.y, end.x - start.x) == pytest.approx(0.1)


def test_viewer_configs_name_our_topics():
    import json
    from pathlib import Path
    docs = Path(__file__).resolve().parents[2] / 'docs'
    layout = json.dumps(json.loads((docs / 'foxglove_layout.json').read_text()))
    for name in (table.MARKERS, table.IMAGE, table.COMPARISON, table.TWIST,
                 table.TRACKING_TWIST_SMOOTHED):
        assert name in layout and name in table.BY_NAME
    assert '"followTf": "surface"' in layout
    rviz = (docs / 'saw_ros.rviz').read_text()
    assert 'Fixed Frame: surface' in rviz and 'Value: /saw/markers' in rviz
