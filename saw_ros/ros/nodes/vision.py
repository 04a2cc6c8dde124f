"""
The vision node: the two-pink-marker tracker on any image stream.

Subscribes an Image stream (bgr8 or rgb8), or with ``image_transport`` 'compressed' its
``<image_topic>/compressed`` stream (sensor_msgs/CompressedImage, JPEG, as image_transport's
``compressed`` plugin sends it), and, unless ``px_per_m`` is given, its CameraInfo
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
  (ok / front lost / back lost / both lost / ambiguous / partial) and running counts, the slope
  used, how far the camera moved, and the tracker's warnings (level WARN on an ok frame when
  there are any: a slope the markers' motion disagrees with, a zoom...) and notes;
- /saw/tracking/markers         visualization_msgs/MarkerArray: every frame, the measured marker
  centres and the tracked pose, drawn over the simulator's /saw/markers (saw_ros.ros.markers).

Pose and twists are published only for 'ok' frames: nothing is made up. The math lives in
``saw_ros.vision.tracker``.
"""
from __future__ import annotations

from collections import deque
import math
import struct
import sys

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped, PoseStamped, TwistStamped
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from saw_ros.core.params import spec_entries, spec_meta
from saw_ros.interface import frames, scene_markers, topics
from saw_ros.interface import message_checks as checks
from saw_ros.ros import cdr
from saw_ros.ros import conversions as conv
from saw_ros.ros import markers
from saw_ros.ros import tf
from saw_ros.ros.cdr import NS_PER_S
from saw_ros.ros.guard import InputGuard
from saw_ros.ros.params import declare_spec, yaml_text
from saw_ros.ros.qos import IMAGE_PUBLISHER_DEPTH, IMAGE_QOS, publisher_profile, with_depth
from saw_ros.ros.ready import Readiness
from saw_ros.ros.runtime import NodeFailure, run_module, run_node
from saw_ros.ros.stage_cpu import StageCpu
from saw_ros.vision import compressed, images, one_opencv_thread
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.tracker import Tracker, TrackerConfig, TrackStatus
from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from visualization_msgs.msg import MarkerArray

PENDING = 30            # images kept while waiting for the first CameraInfo
REDUCED = 2             # a JPEG is decoded at 1 / REDUCED of its size when downscale allows
JPEG_SOI = b'\xff\xd8'  # a JPEG file's first bytes

# (name, default, spec metadata): the node's own, then the camera pose and the tracker's from
# the CameraModel and TrackerConfig fields (one source: msg_config/vision.yaml is generated
# from this table, --write-yaml).
CAMERA_FIELDS = ('slope', 'center_x', 'center_y', 'mirror')
CONFIG_FIELDS = ('hue_min', 'hue_max', 'sat_min', 'val_min', 'pink_min', 'min_area', 'downscale',
                 'min_contrast', 'merge_distance', 'gate', 'reacquire_after', 'spacing_tolerance',
                 'max_pitch', 'colour_tolerance', 'colour_min', 'com_offset_x', 'com_offset_y',
                 'marker_line_angle', 'smooth_window', 'steady_window', 'steady_fill',
                 'max_step_gap')
# TrackerConfig's optional fields, as ROS parameters have no 'unset': 0 (all zeros) = not given.
OPTIONAL_FIELDS = ('roi', 'marker_spacing', 'marker_diameter')
PARAMETERS = (
    ('image_topic', topics.IMAGE,
     spec_meta('', 'image input (sensor_msgs/Image, bgr8 or rgb8)')),
    ('image_transport', 'raw',
     spec_meta('', "'raw': Image on image_topic; 'compressed': CompressedImage (JPEG) on "
                   'image_topic/compressed', choices=compressed.TRANSPORTS)),
    ('camera_info_topic', topics.CAMERA_INFO,
     spec_meta('', 'camera info input (K gives the scale)')),
    ('px_per_m', 0.0, spec_meta('px/m', 'pixels per metre in the plane of motion; 0 = from '
                                        'CameraInfo', 0.0, None)),
    ('plane_distance', 1.0, spec_meta('m', 'camera to the plane of motion (with CameraInfo: '
                                           'px/m = fx / this)', 0.0, None, low_open=True)),
    ('plane_homography', [0.0] * 9,
     spec_meta('', 'the plane of motion of a camera not square to it: 3x3 homography, row-major, '
                   'from undistorted pixels to metres on the plane (saw-ros calibrate-camera '
                   "--plane-output); all 0 = none (the scale is px_per_m's or CameraInfo's)")),
    ('max_image_pixels', 4096 * 4096,
     spec_meta('', 'largest image taken, width x height (a CompressedImage: as its JPEG or PNG '
                   'header declares it, and at most 3 bytes a pixel); larger ones are refused '
                   'from the header, before decoding', 1, None)),
    *spec_entries(CameraModel, CAMERA_FIELDS),
    ('slope_from_motion', False,
     spec_meta('', "true: the track's direction is the markers' own motion (footage whose slope "
                   'is not known; slope is then only a first guess); false: slope is the '
                   "track's, and a motion that disagrees is warned about on the status")),
    *spec_entries(TrackerConfig, CONFIG_FIELDS),
    ('roi', [0, 0, 0, 0], spec_meta('px', 'region of interest x0, y0, x1, y1 (x1, y1 excluded): '
                                          'markers are looked for only there; all 0 = the '
                                          'whole picture')),
    ('marker_spacing', 0.0, spec_meta('m', "distance between the markers' centres on the "
                                           'robot: picks the pair among pink things; 0 = not '
                                           'known', 0.0, None)),
    ('marker_diameter', 0.0, spec_meta('m', 'diameter of a marker: blobs of another size are '
                                            'not markers; 0 = not known', 0.0, None)),
)
YAML_HEADER = """\
Parameters of the saw_ros vision node (two-pink-marker tracker):
  python -m saw_ros.ros.nodes.vision --ros-args --params-file msg_config/vision.yaml
SI units (m, s, rad); each comment gives the allowed range and unit. Read at start-up only.
Integers are taken for doubles. slope / center_x / center_y must describe the same camera pose as
the camera node's (or, for a real camera, as measured). Outputs: /saw/tracking/*; see
docs/vision.md.
Generated by: python -m saw_ros.ros.nodes.vision --write-yaml msg_config/vision.yaml"""


def lens_of(info) -> dict:
    """Return the CameraModel lens arguments of a CameraInfo (none without a distortion)."""
    d = [float(v) for v in info.d]
    if info.distortion_model not in ('plumb_bob', 'rational_polynomial') or \
            len(d) not in (4, 5, 8) or not any(d):
        return {}
    k = [float(v) for v in info.k]
    return {'dist_coeffs': tuple(d), 'dist_matrix': (k[0], k[4], k[2], k[5])}


def yaml_file() -> str:
    """msg_config/vision.yaml, from PARAMETERS."""
    return yaml_text('vision', YAML_HEADER, PARAMETERS, with_scenario=False)


class VisionNode(Node):
    def __init__(self, **kwargs):
        super().__init__('vision', **kwargs)
        try:
            p = declare_spec(self, PARAMETERS)
            optional = {k: (None if not any(p[k] if k == 'roi' else [p[k]]) else
                            tuple(p[k]) if k == 'roi' else p[k]) for k in OPTIONAL_FIELDS}
            self.config = TrackerConfig(**{k: p[k] for k in CONFIG_FIELDS}, **optional)
        except (ParameterException, ValueError, TypeError) as exc:
            raise NodeFailure(f'invalid parameters: {exc}') from exc
        self.p = p
        self.max_pixels = int(p['max_image_pixels'])
        self.pose_kw = {'slope': float(p['slope']), 'center_x': float(p['center_x']),
                        'center_y': float(p['center_y']), 'mirror': bool(p['mirror'])}
        plane = [float(v) for v in p['plane_homography']]
        self.plane = tuple(plane) if any(plane) else None
        if self.plane is not None:
            try:
                CameraModel(plane=self.plane)
            except ValueError as exc:
                raise NodeFailure(f'invalid parameters: plane_homography: {exc}') from exc
        self.tracker = None
        self.info = None
        self.reduced = REDUCED if self.config.downscale % REDUCED == 0 else 1
        self._pending = deque(maxlen=PENDING)
        self.results = 0
        self.gaps = checks.FrameGaps()    # frames missing from the image stream, by stamp
        self.stage_cpu = StageCpu('decode', 'track', 'publish')
        self._jpegs = compressed.JpegStream()
        pub = self.create_publisher
        out_qos = publisher_profile('tracking')
        self._pub_front = pub(PointStamped, topics.TRACKING_FRONT, out_qos)
        self._pub_back = pub(PointStamped, topics.TRACKING_BACK, out_qos)
        self._pub_pose = pub(PoseStamped, topics.TRACKING_POSE, out_qos)
        self._pub_twist = pub(TwistStamped, topics.TRACKING_TWIST, out_qos)
        self._pub_smooth = pub(TwistStamped, topics.TRACKING_TWIST_SMOOTHED, out_qos)
        self._pub_steady = pub(TwistStamped, topics.TRACKING_STEADY_SPEED, out_qos)
        self._pub_status = pub(DiagnosticArray, topics.TRACKING_STATUS, out_qos)
        self._pub_markers = pub(MarkerArray, topics.TRACKING_MARKERS,
                                publisher_profile(topics.topic(topics.TRACKING_MARKERS).qos))
        self._pub_tf = tf.publisher(self)       # surface -> base_link_tracked, the estimate
        # Raw: the 2.7 MB pixels are read in place (cdr.ImageView) instead of being converted
        # to a Python array and copied again.
        image_qos = with_depth(IMAGE_QOS, IMAGE_PUBLISHER_DEPTH)
        # Every input through the guard: an image or camera info the tracker cannot take is
        # refused, counted on /diagnostics and warned about, and the node runs on.
        self.guard = InputGuard(self)
        self._image_order = checks.StampOrder()
        if p['image_transport'] == 'compressed':
            self.image_topic = compressed.compressed_topic(p['image_topic'])
            self.guard.subscribe(CompressedImage, self.image_topic, self._on_compressed,
                                 image_qos)
        else:
            self.image_topic = p['image_topic']
            self.guard.subscribe(Image, self.image_topic, self._on_image_raw, image_qos,
                                 raw=True)
        if not p['px_per_m'] > 0:
            self.guard.subscribe(CameraInfo, p['camera_info_topic'], self._on_info_raw,
                                 IMAGE_QOS, raw=True)
        self._info_unchanged = None     # the last CameraInfo's bytes after its stamp
        self.get_logger().info(f'tracking the markers in {self.image_topic}')
        self._readiness = Readiness(self)
        self._readiness.announce()

    def _camera(self, width: int, height: int) -> CameraModel:
        # The lens as ROS cameras publish it: CameraInfo's D (plumb_bob or rational_polynomial,
        # OpenCV's order) with its K; marker centres are undistorted with it.
        lens = {} if self.info is None else lens_of(self.info)
        if self.plane is not None:
            return CameraModel(width=width, height=height, plane=self.plane, **lens,
                               **self.pose_kw)
        if self.p['px_per_m'] > 0:
            return CameraModel(width=width, height=height, scale=float(self.p['px_per_m']),
                               **self.pose_kw)
        return CameraModel.from_intrinsics(self.info.k, width, height,
                                           float(self.p['plane_distance']), **lens,
                                           **self.pose_kw)

    def _on_info_raw(self, data: bytes) -> None:
        """
        Take a CameraInfo as bytes; deserialize it only when more than its stamp changed.

        One comes with every frame, and rclpy's conversion of its arrays cost ~0.2 ms.
        """
        after_stamp = cdr.after_stamp(data)
        if after_stamp == self._info_unchanged:
            return
        try:
            msg = deserialize_message(data, CameraInfo)
        except Exception as exc:  # noqa: BLE001  (rclpy raises several types for bad CDR)
            raise checks.Refused('unreadable', f'malformed camera info: {exc}') from None
        self._on_info(msg)
        self._info_unchanged = after_stamp

    def _on_info(self, msg: CameraInfo) -> None:
        first = self.info is None
        if not first and list(msg.k) == list(self.info.k):
            return
        checks.camera_matrix(list(msg.k), msg.width, msg.height, self.max_pixels)
        moved = not first and list(msg.k[:2]) + list(msg.k[3:5]) == \
            list(self.info.k[:2]) + list(self.info.k[3:5]) and self.tracker is not None
        self.info = msg
        if moved and not self.p['px_per_m'] > 0:
            # Only the principal point: the camera moved along the track (camera node's
            # follow): positions stay continuous.
            cam = self.tracker.camera
            self.tracker.move_camera(self._camera(cam.width, cam.height))
        elif not first:
            self.get_logger().info('camera intrinsics changed: tracker restarted')
            self.tracker = None
        on_image = self.guard.guarded(self.image_topic, lambda item: self._on_image(*item))
        while self._pending:
            on_image(self._pending.popleft())

    def _on_image_raw(self, data: bytes) -> None:
        try:
            view = cdr.ImageView(data)
        except (ValueError, struct.error, UnicodeDecodeError) as exc:
            raise checks.Refused('unreadable', f'malformed image message: {exc}') from None
        checks.image_header(view.width, view.height, view.encoding, view.step, len(view.data),
                            images.ENCODINGS, self.max_pixels)
        self._on_image(view)

    def _on_compressed(self, msg: CompressedImage) -> None:
        # A compressed image is no bigger than its pixels (3 bytes each, bgr8).
        size = checks.compressed_image(msg.format, msg.data, self.max_pixels,
                                       3 * self.max_pixels)
        self._on_image(msg, size)

    def _on_image(self, msg, size=None) -> None:
        """
        One image: a sensor_msgs/Image, a cdr.ImageView or a sensor_msgs/CompressedImage.

        ``size``: the (width, height) a CompressedImage's header declares.
        """
        if self.info is None and not self.p['px_per_m'] > 0:
            self._pending.append((msg, size))
            return
        t_ns = msg.stamp_ns if isinstance(msg, cdr.ImageView) else conv.stamp_ns(
            msg.header.stamp)
        self._image_order.check(t_ns)
        self.gaps.add(t_ns)
        # A JPEG decoded at half size (its chroma's own resolution, all that the markers'
        # pinkness is made of): 1.1 ms against 1.7 at 1280x720, the tracker's accuracy kept
        # (docs/vision.md). PNG and raw images whole.
        reduced = self.reduced if size is not None and bytes(msg.data[:2]) == JPEG_SOI else 1
        t0 = self.stage_cpu.now()
        try:
            # A JPEG stream: only its block rows that changed are decoded again (JpegStream).
            image, encoding = self._jpegs.decode(msg.format, msg.data, reduced) \
                if size is not None else images.decode(msg)
        except ValueError as exc:
            raise checks.Refused('undecodable', str(exc)) from None
        h, w = image.shape[:2]
        if reduced > 1:
            if (h, w) != tuple(-(-v // reduced) for v in size[::-1]):
                raise checks.Refused('undecodable', f'declares {size[0]}x{size[1]}, decodes to '
                                                    f'{w * reduced}x{h * reduced}')
            w, h = size
        if self.tracker is None or (self.tracker.camera.width, self.tracker.camera.height) != (
                w, h) or self.tracker.encoding != encoding:
            self.tracker = Tracker(self._camera(w, h), self.config, encoding,
                                   not self.p['slope_from_motion'])
        elif self.tracker.last_time is not None and t_ns / NS_PER_S <= self.tracker.last_time:
            self.get_logger().warning('image stamps went backwards: tracker restarted')
            self.tracker = Tracker(self.tracker.camera, self.config, encoding,
                                   not self.p['slope_from_motion'])
        t1 = self.stage_cpu.add('decode', t0)
        res = self.tracker.update(image, t_ns / NS_PER_S, reduced)
        self.results += 1
        t2 = self.stage_cpu.add('track', t1)
        self._publish(res, t_ns)
        self.stage_cpu.add('publish', t2)
        self.stage_cpu.frame()

    def close(self) -> None:
        """Say what a frame cost (run_node calls this before the node is destroyed)."""
        # After Ctrl-C the context (and /rosout) may be gone: plain stderr.
        print(f'[vision] frames tracked {self.results}, {self.stage_cpu.summary()}',
              file=sys.stderr, flush=True)

    def _publish(self, res, t_ns: int) -> None:
        # Points, pose and twists as CDR bytes (conversions' encoders, checked against rclpy):
        # right after a frame's decode the Python message conversion ran cold, 0.1-0.3 ms each.
        for name, pub in (('front', self._pub_front), ('back', self._pub_back)):
            p = getattr(res, name)
            if p is not None:
                pub.publish(conv.point_cdr(float(p.real), float(p.imag), t_ns))
        if res.status is TrackStatus.OK:
            self._pub_pose.publish(conv.pose_cdr(float(res.position.real),
                                                 float(res.position.imag), float(res.pitch),
                                                 t_ns))
            self._pub_tf.publish(tf.message_cdr([(
                frames.SURFACE, frames.TRACKED, (float(res.position.real),
                                                 float(res.position.imag), 0.0),
                frames.yaw_quaternion(float(res.pitch)))], t_ns))
            if res.velocity is not None:
                self._pub_twist.publish(conv.twist_cdr(
                    float(res.velocity.real), float(res.velocity.imag), float(res.pitch_rate),
                    t_ns))
            if res.velocity_smoothed is not None:
                self._pub_smooth.publish(conv.twist_cdr(
                    float(res.velocity_smoothed.real), float(res.velocity_smoothed.imag),
                    float(res.pitch_rate_smoothed), t_ns))
            if res.steady_speed is not None:
                self._pub_steady.publish(conv.twist_cdr(float(res.steady_speed), 0.0, 0.0,
                                                        t_ns))
        self._pub_status.publish(self._status(res, t_ns))
        front, back = ((None if p is None else (p.real, p.imag, 0.0))
                       for p in (res.front, res.back))
        self._pub_markers.publish(markers.marker_array_cdr(scene_markers.tracking(
            front, back, (res.position.real, res.position.imag, res.pitch)
            if res.status is TrackStatus.OK else None), t_ns))

    def _status(self, res, t_ns: int) -> DiagnosticArray:
        c = self.tracker.counters
        st = DiagnosticStatus()
        st.name = 'saw_ros vision: marker tracker'
        st.hardware_id = 'pink markers'
        st.level = (DiagnosticStatus.OK if res.status is TrackStatus.OK else
                    DiagnosticStatus.ERROR if res.status is TrackStatus.BOTH_LOST else
                    DiagnosticStatus.WARN)
        st.message = res.status.value
        # What makes the numbers doubtful (a slope the motion disagrees with, a zoom, ...):
        # an ok frame with a warning is WARN, so that no wrong speed looks trusted.
        warnings = self.tracker.warnings
        if warnings and st.level == DiagnosticStatus.OK:
            st.level = DiagnosticStatus.WARN
        slope = self.tracker.slope_used
        values = {'status': res.status, 'candidates': res.candidates, 'frames': c.frames,
                  'frames_missed': self.gaps.missed,
                  'ok_frames': c.ok, 'front_lost_frames': c.front_lost,
                  'back_lost_frames': c.back_lost, 'ambiguous_frames': c.ambiguous,
                  'partial_frames': c.partial,
                  'consecutive_not_ok': c.consecutive_not_ok,
                  'longest_not_ok': c.longest_not_ok,
                  'steady_speed': '' if res.steady_speed is None else f'{res.steady_speed:.6f}',
                  'slope_deg': '' if slope is None else f'{math.degrees(slope):.3f}',
                  'camera_shift_px': f'{self.tracker.motion.largest_shift:.1f}',
                  'warnings': ' | '.join(warnings), 'notes': ' | '.join(self.tracker.notes)}
        st.values = [KeyValue(key=k, value=str(v)) for k, v in values.items()]
        msg = DiagnosticArray()
        conv.time_msg(t_ns, msg.header.stamp)
        msg.header.frame_id = conv.SURFACE_FRAME
        msg.status = [st]
        return msg


def main(args=None) -> int:
    one_opencv_thread()
    return run_node(VisionNode, args=args, events=True, name='vision',
                    parameters=lambda: PARAMETERS)


if __name__ == '__main__':
    run_module(main, yaml_file)
