"""
The camera reference recording replayed through the tracker gives the recorded run's AR.

The recording is bags/reference_camera, replayed offline (images read from the bag) and live
(player -> vision node through real topics). Ground truth: the recorded /saw/pose
(RunComparator, as the comparison node).
"""
import os

import numpy as np
import pytest

from saw_ros.analysis.compare import RunComparator
from saw_ros.bag import BagReader
from saw_ros.core import Scenario
from saw_ros.graph.process import ManagedProcess, node_command, wait_for
from saw_ros.interface import topics as table
from saw_ros.ros import cdr
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.tracker import Tracker

BAG = os.path.join(os.path.dirname(__file__), '..', '..', 'bags', 'reference_camera')
IMAGE, INFO, POSE = table.IMAGE, table.CAMERA_INFO, table.POSE
PLANE_DISTANCE = 1.0   # m, the camera node's default `distance`: px/m = fx / distance


@pytest.fixture(scope='module')
def reader():
    if not os.path.isdir(BAG):
        pytest.skip('bags/reference_camera not made (scripts/make_reference_bags.sh)')
    return BagReader(BAG)


def comparator() -> RunComparator:
    s = Scenario()   # the recording used the simulator's defaults
    return RunComparator(s.robot, s.frequency)


def truth_from_bag(reader, comp: RunComparator) -> int:
    n = 0
    for m in reader.messages([POSE]):
        t_ns, x, _, _ = cdr.pose_stamped_ns(m.data)
        t = t_ns / 1e9
        comp.add_truth(t, x)
        n += 1
    return n


def image_array(msg) -> np.ndarray:
    assert msg.encoding == 'bgr8'
    rows = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.step)
    return rows[:, :3 * msg.width].reshape(msg.height, msg.width, 3)


@pytest.fixture(scope='module')
def offline(reader):
    """Every recorded image through Tracker, the camera model from the recorded CameraInfo."""
    comp = comparator()
    assert truth_from_bag(reader, comp) == 3000
    tracker, info, frames = None, None, 0
    for m, msg in reader.decoded_messages([INFO, IMAGE]):
        if m.topic == INFO:
            info = msg
            continue
        if tracker is None:
            assert info is not None and info.width == msg.width and info.k[0] == info.k[4]
            cx, cy = (info.width - 1) / 2, (info.height - 1) / 2
            assert (info.k[2], info.k[5]) == pytest.approx((cx, cy))
            tracker = Tracker(CameraModel(width=info.width, height=info.height,
                                          scale=info.k[0] / PLANE_DISTANCE,
                                          distance=PLANE_DISTANCE))
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        res = tracker.update(image_array(msg), t)
        frames += 1
        if res.ok:
            comp.add_tracked(t, res.position.real)
    return comp.result(), tracker.counters, frames


def test_reference_camera_is_complete(reader):
    topics = reader.topics()
    assert reader.complete and reader.metadata['version'] == 9
    # 3 s of simulated time: 3000 steps on every simulator topic, 180 frames (1/60 .. 3 s).
    assert {topics[t].count for t in (table.CLOCK, POSE, table.JOINT_STATES)} == {3000}
    assert topics[IMAGE].count == topics[INFO].count == 180
    stamps = [msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
              for _, msg in reader.decoded_messages([INFO])]
    assert stamps == [round(k * 1e9 / 60) for k in range(1, 181)]


def test_replay_through_the_tracker_gives_the_recorded_ar(offline):
    result, counters, frames = offline
    assert frames == 180 and counters.ok == 180
    assert result.steady and result.window_s >= 1.0      # at least one whole wave cycle
    assert result.ar_tracked == pytest.approx(result.ar_sim, rel=0.005)


@pytest.mark.ros
@pytest.mark.slow
def test_player_into_vision_node_gives_the_same_ar(offline, tmp_path, ros_context):
    """
    Player (images, camera info, /saw/pose) -> vision node -> /saw/tracking/pose.

    Through real topics; the AR from what arrives equals the offline replay's.
    """
    from geometry_msgs.msg import PoseStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from saw_ros.ros.qos import STREAM_QOS
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

    deep = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                      reliability=ReliabilityPolicy.RELIABLE)
    comp, tracked = comparator(), []

    def on_truth(data):
        t_ns, x, _, _ = cdr.pose_stamped_ns(data)
        comp.add_truth(t_ns / 1e9, x)

    def on_tracked(msg):
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        tracked.append(t)
        comp.add_tracked(t, msg.pose.position.x)

    node = Node('bag_camera_listener', context=ros_context)
    node.create_subscription(PoseStamped, POSE, on_truth, deep, raw=True)
    sub = node.create_subscription(PoseStamped, table.TRACKING_POSE, on_tracked, STREAM_QOS)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    spin = lambda t: executor.spin_once(timeout_sec=t)  # noqa: E731
    logs = tmp_path / 'logs'
    vision = ManagedProcess('vision', node_command('vision'), os.environ, logs)
    player = None
    try:
        assert wait_for(lambda: sub.get_publisher_count() >= 1, 30, spin=spin), vision.output()
        # 3 subscriptions: the vision node's image and camera info, ours on /saw/pose.
        player = ManagedProcess('player', node_command('player', params={
            'bag': BAG, 'rate': 0.5, 'topics': [POSE, IMAGE, INFO],
            'wait_for_subscribers': 3}), os.environ, logs)
        assert wait_for(lambda: player.returncode is not None and len(tracked) >= 180
                        and comp.truth.size >= 3000, 45, spin=spin), \
            (player.output(), vision.output(), len(tracked), comp.truth.size)
        assert player.wait(10) == 0, player.output()
    finally:
        for p in (player, vision):
            if p is not None and p.returncode is None:
                p.stop()
        executor.shutdown()
        node.destroy_node()
    live = comp.result()
    ref, _, _ = offline
    assert len(tracked) == 180 and comp.truth.size == 3000
    assert live.steady
    assert live.ar_sim == pytest.approx(ref.ar_sim, rel=1e-9)
    assert live.ar_tracked == pytest.approx(ref.ar_tracked, rel=1e-9)
    assert live.ar_tracked == pytest.approx(live.ar_sim, rel=0.005)
