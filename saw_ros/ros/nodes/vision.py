"""The vision node: the two-pink-marker tracker on any image stream.

Subscribes an Image stream (bgr8 or rgb8) and, unless ``px_per_m`` is given, its CameraInfo
(px per metre = K's focal length / ``plane_distance``). Per frame, stamped with the image's stamp,
in frame ``surface`` (docs/vision.md):

- /saw/tracking/front, /saw/tracking/back   geometry_msgs/PointStamped: marker centres (m), only
  when that marker was measured in the frame;
- /saw/tracking/pose            geometry_msgs/PoseStamped: robot (COM) position, pitch about z;
- /saw/tracking/twist           geometry_msgs/TwistStamped: INSTANTANEOUS speed (linear.x along
  the surfaces, linear.y normal, angular.z pitch rate), difference to the previous measured frame;
- /saw/tracking/twist_smoothed  geometry_msgs/TwistStamped: the same, least-squares over the
  trailing ``smooth_window``;
- /saw/tracking/steady_speed    geometry_msgs/TwistStamped: steady-state mean speed (linear.x)
  over the trailing ``steady_window``, once that window is filled;
- /saw/tracking/status          diagnostic_msgs/DiagnosticArray: every frame, the frame's status
  (ok / front lost / back lost / both lost / ambiguous) and running counts.

Pose and twists are published only for 'ok' frames: nothing is made up. The math lives in
``saw_ros.vision.tracker``.
"""
from __future__ import annotations

import struct
from collections import deque

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped, PoseStamped, TwistStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image

from saw_ros.ros import cdr
from saw_ros.ros.cdr import NS_PER_S
from saw_ros.ros import conversions as conv
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.tracker import Tracker, TrackerConfig, TrackStatus
from saw_ros.ros.runtime import (IMAGE_PUBLISHER_DEPTH, IMAGE_QOS, STREAM_QOS, NodeFailure, run_node,
                     with_depth)

PENDING = 30            # images kept while waiting for the first CameraInfo

PARAMETERS = (
    ('image_topic', '/saw/camera/image_raw', 'image input (sensor_msgs/Image, bgr8 or rgb8)'),
    ('camera_info_topic', '/saw/camera/camera_info', 'camera info input (K gives the scale)'),
    ('px_per_m', 0.0, 'pixels per metre in the plane of motion [px/m]; 0 = from CameraInfo'),
    ('plane_distance', 1.0, 'camera to the plane of motion [m] (with CameraInfo: px/m = fx / '
                            'this)'),
    ('slope', 0.0, 'slope of the surfaces as the level camera sees them [rad]'),
    ('center_x', 0.33, 'surface-frame x seen at the principal point [m]'),
    ('center_y', 0.0225, 'surface-frame y seen at the principal point [m]'),
    ('mirror', False, 'true when the robot travels towards the left of the image'),
    ('hue_min', TrackerConfig.hue_min, 'pink hue window, OpenCV hue 0-179 (wraps through 0 if '
                                       'min > max)'),
    ('hue_max', TrackerConfig.hue_max, 'pink hue window upper end'),
    ('sat_min', 70, 'least saturation 0-255'),
    ('val_min', 60, 'least value 0-255'),
    ('pink_min', 60.0, 'least pinkness R + B - 2G of a detected pixel [grey levels]'),
    ('min_area', 20.0, 'smallest marker area [px]'),
    ('downscale', 4, 'detection runs on the image shrunk by this factor'),
    ('gate', 40.0, 'how far a marker may move from its prediction between frames [px]'),
    ('com_offset_x', 0.0, 'COM minus marker midpoint along the back->front line [m]'),
    ('com_offset_y', 0.0, 'COM minus marker midpoint normal to that line [m]'),
    ('marker_line_angle', 0.0, 'angle of the back->front line in the body frame [rad]'),
    ('smooth_window', 0.25, 'smoothed speed: least-squares window [s]'),
    ('steady_window', 4.0, 'steady-state mean speed: least-squares window [s]'),
)
CONFIG_FIELDS = ('hue_min', 'hue_max', 'sat_min', 'val_min', 'pink_min', 'min_area', 'downscale',
                 'gate', 'com_offset_x', 'com_offset_y', 'marker_line_angle', 'smooth_window',
                 'steady_window')


def image_to_array(msg):
    """(H x W x 3 uint8 view, encoding) of a bgr8/rgb8 Image (or a ``cdr.ImageView`` of its
    bytes: then a view of the message buffer, no copy); ValueError otherwise."""
    if msg.encoding not in ('bgr8', 'rgb8'):
        raise ValueError(f'unsupported image encoding {msg.encoding!r}: bgr8 or rgb8 only')
    h, w, step = msg.height, msg.width, msg.step
    buf = np.frombuffer(msg.data, np.uint8)
    if step < 3 * w or buf.size < h * step:
        raise ValueError(f'image data too short: {buf.size} bytes for {w}x{h}, step {step}')
    return buf[:h * step].reshape(h, step)[:, :3 * w].reshape(h, w, 3), msg.encoding


class VisionNode(Node):
    def __init__(self, **kwargs):
        super().__init__('vision', **kwargs)
        try:
            for name, default, text in PARAMETERS:
                self.declare_parameter(name, default, ParameterDescriptor(
                    description=text, read_only=True))
            p = {name: self.get_parameter(name).value for name, _, _ in PARAMETERS}
            self.config = TrackerConfig(**{k: p[k] for k in CONFIG_FIELDS})
            if p['px_per_m'] < 0 or not p['plane_distance'] > 0:
                raise ValueError('px_per_m must be >= 0 and plane_distance > 0')
        except (ParameterException, ValueError, TypeError) as exc:
            raise NodeFailure(f'invalid parameters: {exc}') from exc
        self.p = p
        self.pose_kw = dict(slope=float(p['slope']), center_x=float(p['center_x']),
                            center_y=float(p['center_y']), mirror=bool(p['mirror']))
        self.tracker = None
        self.info = None
        self._pending = deque(maxlen=PENDING)
        self.results = 0
        pub = self.create_publisher
        self._pub_front = pub(PointStamped, '/saw/tracking/front', STREAM_QOS)
        self._pub_back = pub(PointStamped, '/saw/tracking/back', STREAM_QOS)
        self._pub_pose = pub(PoseStamped, '/saw/tracking/pose', STREAM_QOS)
        self._pub_twist = pub(TwistStamped, '/saw/tracking/twist', STREAM_QOS)
        self._pub_smooth = pub(TwistStamped, '/saw/tracking/twist_smoothed', STREAM_QOS)
        self._pub_steady = pub(TwistStamped, '/saw/tracking/steady_speed', STREAM_QOS)
        self._pub_status = pub(DiagnosticArray, '/saw/tracking/status', STREAM_QOS)
        # Raw: the 2.7 MB pixels are read in place (cdr.ImageView) instead of being converted
        # to a Python array and copied again.
        self.create_subscription(Image, p['image_topic'], self._on_image_raw,
                                 with_depth(IMAGE_QOS, IMAGE_PUBLISHER_DEPTH),
                                 raw=True)
        if not p['px_per_m'] > 0:
            self.create_subscription(CameraInfo, p['camera_info_topic'], self._on_info,
                                     IMAGE_QOS)
        self.get_logger().info(f"tracking the markers in {p['image_topic']}")

    def _camera(self, width: int, height: int) -> CameraModel:
        if self.p['px_per_m'] > 0:
            return CameraModel(width=width, height=height, scale=float(self.p['px_per_m']),
                               **self.pose_kw)
        return CameraModel.from_intrinsics(self.info.k, width, height,
                                           float(self.p['plane_distance']), **self.pose_kw)

    def _on_info(self, msg: CameraInfo) -> None:
        first = self.info is None
        if not first and list(msg.k) == list(self.info.k):
            return
        if not msg.k[0] > 0:
            self.get_logger().warning('camera info without a focal length ignored')
            return
        self.info = msg
        if not first:
            self.get_logger().info('camera intrinsics changed: tracker restarted')
            self.tracker = None
        while self._pending:
            self._on_image(self._pending.popleft())

    def _on_image_raw(self, data: bytes) -> None:
        try:
            view = cdr.ImageView(data)
        except (ValueError, struct.error, UnicodeDecodeError) as exc:
            self.get_logger().error(f'malformed image message: {exc}', throttle_duration_sec=5.0)
            return
        self._on_image(view)

    def _on_image(self, msg) -> None:
        """One image: a sensor_msgs/Image or a cdr.ImageView."""
        if self.info is None and not self.p['px_per_m'] > 0:
            self._pending.append(msg)
            return
        try:
            image, encoding = image_to_array(msg)
        except ValueError as exc:
            self.get_logger().error(str(exc), throttle_duration_sec=5.0)
            return
        t_ns = msg.stamp_ns if isinstance(msg, cdr.ImageView) else conv.stamp_ns(
            msg.header.stamp)
        h, w = image.shape[:2]
        if self.tracker is None or (self.tracker.camera.width, self.tracker.camera.height) != (
                w, h) or self.tracker.encoding != encoding:
            self.tracker = Tracker(self._camera(w, h), self.config, encoding)
        elif self.tracker.last_time is not None and t_ns / NS_PER_S <= self.tracker.last_time:
            self.get_logger().warning('image stamps went backwards: tracker restarted')
            self.tracker = Tracker(self.tracker.camera, self.config, encoding)
        res = self.tracker.update(image, t_ns / NS_PER_S)
        self.results += 1
        self._publish(res, t_ns)

    def _publish(self, res, t_ns: int) -> None:
        for name, pub in (('front', self._pub_front), ('back', self._pub_back)):
            p = getattr(res, name)
            if p is not None:
                msg = PointStamped()
                conv.time_msg(t_ns, msg.header.stamp)
                msg.header.frame_id = conv.SURFACE_FRAME
                msg.point.x, msg.point.y = float(p.real), float(p.imag)
                pub.publish(msg)
        if res.status is TrackStatus.OK:
            self._pub_pose.publish(conv.pose_msg(res.position.real, res.position.imag,
                                                 res.pitch, t_ns))
            if res.velocity is not None:
                self._pub_twist.publish(conv.twist_msg(res.velocity.real, res.velocity.imag,
                                                       res.pitch_rate, t_ns))
            if res.velocity_smoothed is not None:
                self._pub_smooth.publish(conv.twist_msg(
                    res.velocity_smoothed.real, res.velocity_smoothed.imag,
                    res.pitch_rate_smoothed, t_ns))
            if res.steady_speed is not None:
                self._pub_steady.publish(conv.twist_msg(res.steady_speed, 0.0, 0.0, t_ns))
        self._pub_status.publish(self._status(res, t_ns))

    def _status(self, res, t_ns: int) -> DiagnosticArray:
        c = self.tracker.counters
        st = DiagnosticStatus()
        st.name = 'saw_ros vision: marker tracker'
        st.hardware_id = 'pink markers'
        st.level = (DiagnosticStatus.OK if res.status is TrackStatus.OK else
                    DiagnosticStatus.ERROR if res.status is TrackStatus.BOTH_LOST else
                    DiagnosticStatus.WARN)
        st.message = res.status.value
        values = {'status': res.status, 'candidates': res.candidates, 'frames': c.frames,
                  'ok_frames': c.ok, 'front_lost_frames': c.front_lost,
                  'back_lost_frames': c.back_lost, 'ambiguous_frames': c.ambiguous,
                  'consecutive_not_ok': c.consecutive_not_ok,
                  'longest_not_ok': c.longest_not_ok,
                  'steady_speed': '' if res.steady_speed is None else f'{res.steady_speed:.6f}'}
        st.values = [KeyValue(key=k, value=str(v)) for k, v in values.items()]
        msg = DiagnosticArray()
        conv.time_msg(t_ns, msg.header.stamp)
        msg.header.frame_id = conv.SURFACE_FRAME
        msg.status = [st]
        return msg


def main(args=None) -> int:
    return run_node(VisionNode, args=args, events=True)


if __name__ == '__main__':
    import sys
    sys.exit(main())
