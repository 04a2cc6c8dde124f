"""
Camera + vision nodes through real topics, and the camera's video read by the offline tracker.

The topics are in the isolated domain from conftest.
"""
import math

import pytest

from saw_ros.core import Scenario, Simulator
from saw_ros.graph.process import wait_for
from saw_ros.interface import topics as table
from saw_ros.ros import conversions as conv
from saw_ros.vision.tracker import TrackerConfig

STEADY = 2.0          # s, steady window for this short run
DURATION = 4.6        # s of simulated time


@pytest.fixture
def nodes(ros_context, tmp_path, request):
    """Camera (raw and compressed images) and vision on ``request.param``'s transport."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    from saw_ros.ros.nodes.camera import CameraNode
    from saw_ros.ros.qos import STREAM_QOS
    from saw_ros.ros.nodes.vision import VisionNode

    transport = getattr(request, 'param', 'raw')
    # (the camera's video once, with raw images: what it holds does not depend on the transport)
    video = tmp_path / 'camera.mp4' if transport == 'raw' else None
    camera = CameraNode(context=ros_context, parameter_overrides=[
        Parameter('video_path', value=str(video or ''))])
    vision = VisionNode(context=ros_context, parameter_overrides=[
        Parameter('steady_window', value=STEADY),
        Parameter('image_transport', value=transport)])
    source = Node('test_source', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    for n in (camera, vision, source):
        executor.add_node(n)
    try:
        yield camera, vision, source, executor, video, STREAM_QOS
    finally:
        executor.shutdown()
        camera.close()
        for n in (camera, vision, source):
            n.destroy_node()


@pytest.mark.parametrize('nodes', ['raw', 'compressed'], indirect=True)
def test_camera_and_vision_nodes_track_the_simulation(nodes, drive_camera):
    """The same tolerances through raw images and through JPEG (quality 90)."""
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PointStamped, PoseStamped, TwistStamped
    from sensor_msgs.msg import CameraInfo, CompressedImage, Image, JointState

    from saw_ros.cli.commands.track import track_video

    camera, vision, source, executor, video, qos = nodes
    from visualization_msgs.msg import MarkerArray
    from saw_ros.ros import tf
    got = {k: [] for k in ('pose', 'steady', 'status', 'front', 'info', 'image', 'jpeg',
                           'markers', 'tf')}
    source.create_subscription(tf.TFMessage, table.TF, got['tf'].append, qos)
    source.create_subscription(MarkerArray, table.TRACKING_MARKERS, got['markers'].append, qos)
    source.create_subscription(PoseStamped, table.TRACKING_POSE, got['pose'].append, qos)
    source.create_subscription(TwistStamped, table.TRACKING_STEADY_SPEED, got['steady'].append,
                               qos)
    source.create_subscription(DiagnosticArray, table.TRACKING_STATUS, got['status'].append,
                               qos)
    source.create_subscription(PointStamped, table.TRACKING_FRONT, got['front'].append, qos)
    source.create_subscription(CameraInfo, table.CAMERA_INFO, got['info'].append, qos)
    source.create_subscription(Image, table.IMAGE,
                               lambda m: got['image'].append(conv.stamp_ns(m.header.stamp)), qos)
    source.create_subscription(CompressedImage, table.IMAGE_COMPRESSED,
                               lambda m: got['jpeg'].append((conv.stamp_ns(m.header.stamp),
                                                             m.header.frame_id, m.format)), qos)
    pub_pose = source.create_publisher(PoseStamped, table.POSE, qos)
    pub_joints = source.create_publisher(JointState, table.JOINT_STATES, qos)
    assert wait_for(lambda: pub_pose.get_subscription_count() >= 1
                    and pub_joints.get_subscription_count() >= 1
                    and vision.count_publishers(vision.image_topic) >= 1, 10.0,
                    spin=lambda t: executor.spin_once(timeout_sec=t))

    sim = Simulator(Scenario())
    truth = drive_camera(sim, pub_pose, pub_joints, DURATION, vision, camera,
                         lambda t: executor.spin_once(timeout_sec=t))
    wait_for(lambda: min(len(got[k]) for k in ('status', 'pose', 'front', 'image', 'jpeg',
                                               'markers'))
             >= vision.results and got['steady'], 5.0,
             spin=lambda t: executor.spin_once(timeout_sec=t))

    # 60 frames per simulated second, stamped k / 60 s, none skipped.
    frames = camera.frames
    assert frames == int(math.floor(DURATION * 60 + 1e-9)) + 1
    stamps = sorted(got['image'])
    assert stamps == [int(round(k * 1e9 / 60)) for k in range(len(stamps))]
    assert sorted(got['jpeg']) == [(t, 'saw_camera', 'bgr8; jpeg compressed bgr8')
                                   for t in stamps]
    assert got['info'][-1].k[0] == pytest.approx(1200.0)
    assert all(s.status[0].message == 'ok' for s in got['status'])
    assert len(got['pose']) == frames and len(got['front']) == frames
    # The estimate for a viewer, every frame: the front marker's sphere where it was measured.
    assert len(got['markers']) == frames
    for array, front in zip(got['markers'][-5:], got['front'][-5:]):
        sphere = next(m for m in array.markers if m.ns == 'tracking_markers' and m.id == 0)
        assert (sphere.pose.position.x, sphere.pose.position.y) == pytest.approx(
            (front.point.x, front.point.y))
        assert array.markers[0].header.stamp == front.header.stamp
    # The estimate on /tf, surface -> base_link_tracked: the tracked pose, stamp and all.
    wait_for(lambda: len(got['tf']) >= frames, 5.0,
             spin=lambda t: executor.spin_once(timeout_sec=t))
    for message, pose in zip(got['tf'][-5:], got['pose'][-5:]):
        (moved,) = message.transforms
        assert (moved.header.frame_id, moved.child_frame_id) == ('surface', 'base_link_tracked')
        assert moved.header.stamp == pose.header.stamp
        v, q, p = moved.transform.translation, moved.transform.rotation, pose.pose
        assert (v.x, v.y, v.z) == (p.position.x, p.position.y, p.position.z)
        assert (q.x, q.y, q.z, q.w) == pytest.approx(
            (p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w), abs=1e-12)
    last = got['pose'][-1]
    t_last = conv.stamp_ns(last.header.stamp) / 1e9
    assert last.header.frame_id == 'surface'
    assert last.pose.position.x == pytest.approx(truth[round(t_last * 1000)], abs=3e-4)
    live = got['steady'][-1].twist.linear.x
    true_speed = (truth[sim.steps] - truth[sim.steps - 2000]) / 2.0
    assert live == pytest.approx(true_speed, rel=0.01)

    # The camera's video, read back offline, gives the same speed within 0.5 %.
    camera.close()
    if video is None:
        return
    results, tracker = track_video(video, {'scale': 1200.0}, TrackerConfig(steady_window=STEADY))
    assert len(results) == frames and tracker.counters.ok == frames
    offline = results[-1].steady_speed
    assert offline == pytest.approx(live, rel=0.005)


def test_vision_node_rejects_bad_parameters(ros_context):
    from rclpy.parameter import Parameter

    from saw_ros.ros.runtime import NodeFailure
    from saw_ros.ros.nodes.vision import VisionNode
    with pytest.raises(NodeFailure):
        VisionNode(context=ros_context, parameter_overrides=[Parameter('gate', value=-1.0)])


def test_vision_node_takes_the_region_and_the_markers_known_size(ros_context):
    """roi, marker_spacing and marker_diameter reach the tracker (all 0 = not given)."""
    from rclpy.parameter import Parameter

    from saw_ros.ros.nodes.vision import VisionNode
    from saw_ros.ros.runtime import NodeFailure
    default = VisionNode(context=ros_context)
    try:
        assert default.config.roi is None and default.config.marker_spacing is None
        assert default.config.marker_diameter is None
    finally:
        default.destroy_node()
    given = VisionNode(context=ros_context, parameter_overrides=[
        Parameter('roi', value=[10, 20, 1200, 700]), Parameter('marker_spacing', value=0.32),
        Parameter('marker_diameter', value=0.012)])
    try:
        assert given.config.roi == (10, 20, 1200, 700)
        assert (given.config.marker_spacing, given.config.marker_diameter) == (0.32, 0.012)
    finally:
        given.destroy_node()
    with pytest.raises(NodeFailure, match='roi'):
        VisionNode(context=ros_context, parameter_overrides=[Parameter('roi', value=[5, 5, 1])])


def test_vision_node_measures_on_the_calibrated_plane(ros_context):
    """plane_homography and CameraInfo's D (as ROS cameras publish them) make the node's camera."""
    import numpy as np
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import CameraInfo

    from saw_ros.ros.nodes.vision import VisionNode
    from saw_ros.ros.runtime import NodeFailure
    from saw_ros.vision.footage import Shot
    shot = Shot(width=960, height=540, scale=900.0, yaw_deg=18.0, pitch_deg=10.0,
                dist_coeffs=(-0.12, 0.0, 0.0, 0.0))
    node = VisionNode(context=ros_context, parameter_overrides=[
        Parameter('plane_homography', value=[float(v) for v in shot.plane().ravel()]),
        Parameter('center_x', value=0.0), Parameter('center_y', value=shot.track_y)])
    try:
        info = CameraInfo(width=960, height=540, distortion_model='plumb_bob')
        info.k = [float(v) for v in shot.lens().K.ravel()]
        info.d = [-0.12, 0.0, 0.0, 0.0, 0.0]
        node._on_info(info)
        camera = node._camera(960, 540)
        truth = shot.calibrated_camera()
        points = np.array([0.1 + 0.03j, -0.25 + 0.02j])
        # a surface point -> where the lens puts it in the picture, and back
        image = truth.distort(truth.to_pixels(points))
        np.testing.assert_allclose(camera.to_surface(camera.undistort(image)), points,
                                   atol=1e-6)
    finally:
        node.destroy_node()
    with pytest.raises(NodeFailure, match='plane_homography'):
        VisionNode(context=ros_context, parameter_overrides=[
            Parameter('plane_homography', value=[1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 0.0, 0.0, 0.0])])
