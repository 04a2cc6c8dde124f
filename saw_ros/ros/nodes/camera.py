"""
The camera node: a virtual 60 fps side-view camera of the simulated robot.

Subscribes /saw/pose (PoseStamped) and /saw/joint_states (JointState, ``helix`` = wave phase,
``link_NN_flex`` = each wave link's deflection on its flexure, drawn along body y; a link whose
joint is missing is rigid, at its target) and renders one frame for every 1/fps s of SIMULATED
time, stamped with that time: frame k is drawn once both streams have reached t_k + exposure / 2
(poses are interpolated between samples), and no frame is ever skipped, however late. With bending
walls the simulator also publishes their shape on /saw/walls (PointCloud2): each frame draws the
surfaces bent as the last shape received stamped at or before its time says (flat while none has
come, as with rigid walls, which publish none). Publishes /saw/camera/image_raw (sensor_msgs/Image,
bgr8), /saw/camera/image_raw/compressed (sensor_msgs/CompressedImage, JPEG as image_transport's
``compressed`` plugin: ``image_transport`` chooses raw, compressed or both) and
/saw/camera/camera_info (sensor_msgs/CameraInfo: K, P of the rendering, no distortion), all with
the frame's stamp. Optionally writes the frames to an .mp4 (``video_path``).

Like image_transport's publishers, a stream goes out only while someone subscribes to it: a
1280x720 frame costs about 0.8 ms of CPU to publish raw and 0.4 to encode as JPEG (only the rows
the robot was drawn on: ``compressed.BandJpeg``; 1.7 for a whole frame) on this 2-core machine,
which the camera spends only for a reader. (Frames are still rendered, counted and put in the
video; CameraInfo always goes out.)

The drawing lives in ``saw_ros.vision.frames``; docs/vision.md lists topics and parameters.
"""
from __future__ import annotations

import math
import queue
import sys
import threading
import time
from typing import Optional, Tuple

from geometry_msgs.msg import PoseStamped
import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.serialization import serialize_message
from saw_ros.core.params import ParameterError, Scenario, spec_entries, spec_meta
from saw_ros.interface import message_checks as checks
from saw_ros.interface import topics, urdf
from saw_ros.ros import cdr
from saw_ros.ros import conversions as conv
from saw_ros.ros import tf
from saw_ros.ros.cdr import NS_PER_S
from saw_ros.ros.guard import InputGuard
from saw_ros.ros.params import declare_spec, ScenarioParameters, yaml_text
from saw_ros.ros.qos import (image_publisher_qos, INPUT_DEPTH, message_class, profile,
                             STREAM_QOS, with_depth)
from saw_ros.ros.ready import Readiness
from saw_ros.ros.runtime import NodeFailure, run_module, run_node
from saw_ros.ros.simulator_parameters import SimulatorParameters
from saw_ros.ros.stage_cpu import StageCpu
from saw_ros.vision import compressed, one_opencv_thread
from saw_ros.vision.camera import CameraModel, FPS
from saw_ros.vision.frames import (pose_between, Renderer, RenderOptions, RobotPose,
                                   StampedSeries, StampedShapes, wall_shape)
from saw_ros.vision.video import VideoError, VideoWriter
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, JointState

TRANSPORTS = ('raw', 'compressed', 'both')
KEEP = 2.0          # s of simulated time kept in the pose and wall-shape buffers
WALLS_STALE = 0.25  # s after which a wall shape no longer counts (at least 3 publishing periods)
SIMULATOR_WAIT = 1.0  # s after the inputs matched that readiness waits for the simulator's values
# frame_id a pose input may carry: the frames the topic table gives the poses in.
POSE_FRAMES = tuple({topics.topic(topics.POSE).frame, topics.topic(topics.TRACKING_POSE).frame})
OUTPUT_QUEUE = 120  # rendered frames waiting for the output thread (2 s at 60 fps, 330 MB max)


def _described(entry, more: str):
    """Return a spec entry with ``more`` added to its description."""
    name, default, meta = entry
    return name, default, dict(meta, description=meta['description'] + more)


# (name, default, spec metadata): the camera model's and the render options' from their
# dataclasses, the node's own beside them; declared from here and written to
# msg_config/camera.yaml (--write-yaml).
_CAMERA = {n: (n, d, m) for n, d, m in spec_entries(CameraModel)}
_RENDER = {n: (n, d, m) for n, d, m in spec_entries(RenderOptions)}
PARAMETERS = (
    _CAMERA['width'],
    _CAMERA['height'],
    ('fps', FPS, spec_meta('Hz', 'frames per second of simulated time', 0.0, None,
                           low_open=True)),
    _described(_CAMERA['scale'], '; used when fov is 0'),
    ('fov', 0.0, spec_meta('rad', 'horizontal field of view; > 0 overrides scale', 0.0, None)),
    _CAMERA['distance'],
    _described(_CAMERA['slope'], "; set it to the simulator's conditions.slope"),
    _CAMERA['center_x'],
    _CAMERA['center_y'],
    ('follow', True, spec_meta('', 'camera on a rail: when a marker nears the edge of the '
                                   "picture it re-centres on the robot; CameraInfo's principal "
                                   'point carries the offset')),
    ('follow_step', 0.0, spec_meta('m', 'fixed re-centring step along the track; 0 = onto the '
                                        'robot', 0.0, None)),
    ('follow_margin', 0.03, spec_meta('', 're-centre when a marker is within this fraction of '
                                          'the picture size of an edge', 0.0, 0.5, low_open=True,
                                      high_open=True)),
    *(_RENDER[n] for n in ('noise', 'exposure', 'blur_samples', 'brightness', 'texture', 'seed')),
    ('image_transport', 'both',
     spec_meta('', "images published: 'raw' (Image on image_raw), 'compressed' (JPEG "
                   'CompressedImage on image_raw/compressed, what the recorder takes) or '
                   "'both'", choices=TRANSPORTS)),
    ('jpeg_quality', compressed.DEFAULT_QUALITY,
     spec_meta('', 'JPEG quality of the compressed images', 1, 100)),
    ('video_path', '', spec_meta('', '.mp4 file to write the frames to; empty = none')),
    ('frame_id', 'saw_camera', spec_meta('', 'frame_id of the images and camera info')),
    ('pose_topic', topics.POSE, spec_meta('', 'robot pose input (PoseStamped)')),
    ('joint_states_topic', topics.JOINT_STATES,
     spec_meta('', "joint states input (JointState with 'helix' and the links' "
                   "'link_NN_flex')")),
    ('simulator_node', 'simulator', spec_meta(
        '', 'simulator node whose robot.* and conditions.gap the camera draws (its own are used '
            'while none answers, as in a replay)', read_only=True)),
)
# Scenario parameters the camera does not declare: it needs only what the drawing needs, the
# robot geometry and the gap.
SCENARIO_EXCLUDED = tuple(n for n, _, _ in Scenario().describe()
                          if not (n.startswith('robot.') or n == 'conditions.gap'))
YAML_HEADER = """\
Parameters of the saw_ros camera node (virtual 60 fps side-view camera):
  python -m saw_ros.ros.nodes.camera --ros-args --params-file msg_config/camera.yaml
SI units (m, s, rad); each comment gives the allowed range and unit. Read at start-up only.
Integers are taken for doubles. The robot geometry (robot.*) and conditions.gap are the
simulator's (simulator_node): the camera asks it for them. Its own, with the simulator's names
and defaults, are used only where no simulator answers (a replay).
Images: /saw/camera/image_raw (bgr8), /saw/camera/camera_info; see docs/vision.md.
Generated by: python -m saw_ros.ros.nodes.camera --write-yaml msg_config/camera.yaml"""


def yaml_file() -> str:
    """msg_config/camera.yaml, from PARAMETERS."""
    return yaml_text('camera', YAML_HEADER, PARAMETERS, with_scenario=False)


def camera_and_options(p: dict) -> Tuple[CameraModel, RenderOptions]:
    """Return the camera model and the render options of the node's parameter values."""
    camera = CameraModel(width=int(p['width']), height=int(p['height']),
                         scale=float(p['scale']), slope=float(p['slope']),
                         center_x=float(p['center_x']), center_y=float(p['center_y']),
                         distance=float(p['distance']))
    if p['fov'] > 0:
        camera = camera.with_fov(float(p['fov']))
    options = RenderOptions(noise=float(p['noise']), exposure=float(p['exposure']),
                            blur_samples=int(p['blur_samples']),
                            brightness=float(p['brightness']), texture=bool(p['texture']),
                            seed=int(p['seed']))
    return camera, options


class CameraNode(Node):
    """Declare, then build: parameters, the renderer and video, the frame state, the topics."""

    def __init__(self, **kwargs):
        super().__init__('camera', **kwargs)
        try:
            p = self._declare()
            camera, options = camera_and_options(p)
            scenario = self.params.scenario
            self.renderer = Renderer(scenario.robot, scenario.conditions.gap, camera, options)
            self.writer = VideoWriter(p['video_path'], p['fps'], (camera.width, camera.height)) \
                if p['video_path'] else None
        except (ParameterError, ParameterException, ValueError, VideoError) as exc:
            raise NodeFailure(f'invalid parameters: {exc}') from exc
        self._build_state(p, camera, options)
        self._build_topics(p, camera)
        self.get_logger().info(
            f'camera {camera.width}x{camera.height} at {self.fps:g} fps of simulated time, '
            f'{camera.scale:g} px/m (f = {camera.focal:g} px), slope '
            f'{math.degrees(camera.slope):g} deg'
            + (f', writing {p["video_path"]}' if self.writer else ''))

    def _declare(self) -> dict:
        """Declare the scenario's parameters the drawing needs, then the node's; return its own."""
        self.params = ScenarioParameters(self, exclude=SCENARIO_EXCLUDED,
                                         frozen={'robot': 'restart the camera',
                                                 'conditions.gap': 'restart the camera'})
        return declare_spec(self, PARAMETERS)

    def _build_state(self, p: dict, camera: CameraModel, options: RenderOptions) -> None:
        """Set the frame clock, the follow rail, the counters and the output thread's queue."""
        self.camera = camera
        self.fps = float(p['fps'])
        self.frame_id = p['frame_id']
        self.half_exposure_ns = options.exposure / 2.0 * NS_PER_S
        self.info = self._camera_info()
        self.follow, self.follow_step = bool(p['follow']), float(p['follow_step'])
        self.follow_margin = float(p['follow_margin'])
        self._camera0 = camera
        self.offset = 0.0          # m the camera moved along the track (follow)
        self._poses = StampedSeries(int(KEEP * NS_PER_S))       # (x, y, theta)
        self._phases = StampedSeries(int(KEEP * NS_PER_S))      # (helix phase,)
        # Each wave link's deflection on its flexure, at the phases' stamps (rigid: none kept).
        self._deflections = StampedSeries(int(KEEP * NS_PER_S))
        self._walls = StampedShapes(int(KEEP * NS_PER_S), int(WALLS_STALE * NS_PER_S))
        # Stamps going back: refused, unless a stream of them follows (a replay restarted).
        # (A leap of more than the buffers hold is refused the same way: it would have the
        # camera render every frame up to it.)
        self._pose_order, self._phase_order = (checks.StampOrder(max_leap=int(KEEP * NS_PER_S))
                                               for _ in range(2))
        self._next: Optional[int] = None          # index of the next frame
        self.frames = 0
        self.received = {'poses': 0, 'joint_states': 0, 'walls': 0}
        self.busy = {'render': 0.0, 'publish': 0.0, 'jpeg': 0.0, 'video': 0.0}  # wall s/stage
        # CPU a frame of each thread's stages (the executor's thread renders, the output
        # thread encodes and publishes): the final log line.
        self.render_cpu = StageCpu('render')
        self.output_cpu = StageCpu('jpeg', 'publish', 'video')
        self.raw = p['image_transport'] in ('raw', 'both')
        self.jpeg_quality = int(p['jpeg_quality']) \
            if p['image_transport'] in ('compressed', 'both') else None
        # Publishing a 2.7 MB image and encoding it into the video take longer than rendering
        # it (measured in the full graph: publish 7 ms, video 7 ms, render 4 ms a frame): an
        # output thread does both, in frame order, so that the executor thread keeps taking
        # the 1 kHz inputs (its queues hold 200 ms) and rendering. OpenCV releases the GIL.
        self._frames_out: 'queue.Queue' = queue.Queue(maxsize=OUTPUT_QUEUE)
        self._band_jpeg: Optional[compressed.BandJpeg] = None     # the output thread's
        self._thread: Optional[threading.Thread] = None
        self._output_error: Optional[Exception] = None
        # Images go out pre-encoded (one copy of the pixels instead of three); the 1 kHz inputs
        # come in raw and only the fields used are read (a camera uses 60 of 2000 messages/s).
        self._image_cdr = cdr.ImageCdr(camera.width, camera.height, 'bgr8', camera.width * 3,
                                       self.frame_id)
        self._joints = self._joint_reader()

    def _build_topics(self, p: dict, camera: CameraModel) -> None:
        """Create the publishers, the inputs' subscriptions and the readiness report."""
        out_qos = image_publisher_qos()
        in_qos = with_depth(STREAM_QOS, INPUT_DEPTH)
        self._pub_image = self.create_publisher(Image, topics.IMAGE, out_qos) \
            if self.raw else None
        self._compressed_cdr = cdr.CompressedImageCdr(compressed.JPEG_FORMAT, self.frame_id)
        self._pub_compressed = self.create_publisher(
            CompressedImage, topics.IMAGE_COMPRESSED, out_qos) \
            if self.jpeg_quality is not None else None
        self._pub_info = self.create_publisher(CameraInfo, topics.CAMERA_INFO, out_qos)
        # surface -> frame_id on /tf_static, latched. The fixed camera's pose: when the camera
        # follows the robot, CameraInfo shifts the principal point instead, which for points of
        # the plane of motion is the same as moving the camera (see _follow).
        self._pub_tf_static = tf.publisher(self, static=True)
        self._pub_tf_static.publish(tf.message([tf.camera_transform(camera, self.frame_id)]))
        self._info_source: Optional[CameraInfo] = None
        self._info_serialized = b''
        # Every input through the guard: a message the camera cannot draw is refused, counted on
        # /diagnostics and warned about, and the camera runs on (saw_ros.ros.guard).
        self.guard = InputGuard(self)
        self._inputs = (
            self.guard.subscribe(PoseStamped, p['pose_topic'], self._on_pose_raw, in_qos,
                                 raw=True),
            self.guard.subscribe(JointState, p['joint_states_topic'], self._on_joints_raw,
                                 in_qos, raw=True))
        # The bending walls' shape: optional (rigid walls publish none), so not an input the
        # readiness waits for.
        walls = topics.topic(topics.WALLS)
        self._walls_sub = self.guard.subscribe(message_class(walls.type), walls.name,
                                               self._on_walls, profile(walls.qos))
        # 'inputs matched' once both inputs have a publisher: from then on no input is missed
        # (said ready on /saw/ready: run_pipeline waits for it before letting the simulator start).
        self._readiness = Readiness(self)
        # The robot and gap to draw are the simulator's (saw_ros.ros.simulator_parameters).
        self.simulator_parameters = SimulatorParameters(self, p['simulator_node'],
                                                        self.params.names, self._draw_simulators,
                                                        self.guard)
        self._matched_at: Optional[float] = None
        # (A steady clock: with use_sim_time the node's clock stands still until /clock runs.)
        self._match_timer = self.create_timer(0.05, self._report_matched,
                                              clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _camera_info(self, cam: Optional[CameraModel] = None) -> CameraInfo:
        cam = cam or self.camera
        info = CameraInfo()
        info.header.frame_id = self.frame_id
        info.width, info.height = cam.width, cam.height
        info.distortion_model = 'plumb_bob'
        info.d = [0.0] * 5
        info.k = [float(v) for v in cam.K.ravel()]
        info.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        info.p = [float(v) for v in cam.P.ravel()]
        return info

    # -- inputs --------------------------------------------------------------------------------
    def _report_matched(self) -> None:
        self.simulator_parameters.request()
        if not self._readiness.announced:
            if not all(sub.get_publisher_count() > 0 for sub in self._inputs):
                return
            if self._matched_at is None:
                self._matched_at = time.monotonic()
                self.get_logger().info('inputs matched')
            # Ready once the simulator's robot is known, so that the first frame draws it;
            # without a simulator (a replay) after SIMULATOR_WAIT, with the camera's own
            # parameters.
            if not self.simulator_parameters.known and \
                    time.monotonic() - self._matched_at < SIMULATOR_WAIT:
                return
            self._readiness.announce()
        # Asked on until the simulator's values come: on a busy machine its parameter service
        # was found after SIMULATOR_WAIT, the camera never asked again, drew its own robot and
        # ignored every /parameter_events naming the simulator (they apply to values it has).
        if self.simulator_parameters.known:
            self._match_timer.cancel()
            self.destroy_timer(self._match_timer)

    def _draw_simulators(self, values: dict) -> bool:
        """Draw the robot and the gap the simulator runs (SimulatorParameters' callback)."""
        try:
            scenario = Scenario().with_values(values)
        except ParameterError as exc:
            self.get_logger().warning(f'ignoring the simulator parameters: {exc}')
            return False
        r = self.renderer
        if (scenario.robot, scenario.conditions.gap) != (r.robot, r.gap):
            self.renderer = Renderer(scenario.robot, scenario.conditions.gap, r.camera, r.options,
                                     r.scene)
            if scenario.robot.wave_links != r.robot.wave_links:
                # Other links, other flexure joints: the deflections kept were another robot's.
                self._joints = self._joint_reader()
                self._deflections.t.clear()
                self._deflections.v.clear()
            self.get_logger().info(f"drawing the simulator's robot and gap "
                                   f'({1000 * scenario.conditions.gap:g} mm)')
        return True

    def _on_pose_raw(self, data: bytes) -> None:
        t, frame_id, x, y, q = cdr.pose_stamped(data)
        checks.frame(frame_id, POSE_FRAMES)
        checks.pose(x, y, q)
        self._pose_order.check(t)
        self._add_pose(t, x, y, 2.0 * math.atan2(q[2], q[3]))

    def _add_pose(self, t: int, x: float, y: float, theta: float) -> None:
        self.received['poses'] += 1
        if not self._poses.add(t, (x, y, theta)):
            self._restart()
        self._render_due()

    def _joint_reader(self) -> cdr.JointPositions:
        """Return a reader of the helix and the drawn robot's link_NN_flex joints, in order."""
        return cdr.JointPositions(['helix'] + [f'{name}_flex' for name in
                                               urdf.link_names(self.renderer.robot)])

    def _on_joints_raw(self, data: bytes) -> None:
        t, (phase, *flex) = self._joints(data)
        if phase is None:
            raise checks.Refused('no helix position', "no position for the joint 'helix'")
        checks.finite('helix position', (phase,))
        # A link without its flexure joint is rigid (an older simulator, a rigid robot's bag).
        deflection = tuple(0.0 if e is None else e for e in flex)
        checks.finite('link deflection', deflection)
        limit = urdf.flex_limit(self.renderer.robot)
        if max(map(abs, deflection), default=0.0) > limit:
            raise checks.Refused('out of range', f'a link deflection of '
                                 f'{max(map(abs, deflection)):g} m is more than the '
                                 f'link_NN_flex limit, {limit:g} m')
        self._phase_order.check(t)
        self._add_phase(t, phase, deflection if any(deflection) else None)

    def _add_phase(self, t: int, phase, deflection=None) -> None:
        self.received['joint_states'] += 1
        if phase is None:
            return
        if not self._phases.add(t, (phase,)):
            self._restart()
            self._deflections.t.clear()
            self._deflections.v.clear()
        if deflection is not None and not self._deflections.t and len(self._phases.t) > 1:
            # The links were at their targets until the sample before.
            self._deflections.add(self._phases.t[-2], (0.0,) * len(deflection))
        if deflection is not None or self._deflections.t:
            # Once a link has flexed, zeros too: it goes back to its target in the frames.
            self._deflections.add(t, deflection or (0.0,) * len(self._joints.names[1:]))
        self._render_due()

    def _on_walls(self, msg) -> None:
        """Keep a /saw/walls shape by its stamp; refuse what is not one (the guard warns)."""
        try:
            shape = wall_shape(*conv.walls_of(msg))
        except ValueError as exc:
            raise checks.Refused('not a wall shape', str(exc)) from None
        self.received['walls'] += 1
        self._walls.add(conv.stamp_ns(msg.header.stamp), shape)

    def _restart(self) -> None:
        self.get_logger().warning('input time went backwards: restarting the frame clock')
        self._next = None

    # -- frames --------------------------------------------------------------------------------
    def frame_ns(self, k: int) -> int:
        return int(round(k * NS_PER_S / self.fps))

    def pose_at(self, t_ns: float) -> RobotPose:
        return pose_between(self._poses, self._phases, t_ns, self._deflections)

    def _render_due(self) -> None:
        if not self._poses.t or not self._phases.t:
            return
        if self._next is None:
            start = max(self._poses.t[0], self._phases.t[0])
            self._next = int(math.ceil(start * self.fps / NS_PER_S - 1e-9))
        ready = min(self._poses.last, self._phases.last)
        while self.frame_ns(self._next) + self.half_exposure_ns <= ready:
            t_ns = self.frame_ns(self._next)
            if self.follow:
                self._follow(t_ns)
            t0, c0 = time.perf_counter(), self.render_cpu.now()
            frame = self.renderer.render(self.pose_at(t_ns), (),
                                         lambda t: self.pose_at(t * NS_PER_S), t_ns / NS_PER_S,
                                         self._walls.before(t_ns))
            self.busy['render'] += time.perf_counter() - t0
            self.render_cpu.add('render', c0)
            self.render_cpu.frame()
            self._output(frame, t_ns)
            self._next += 1

    def _output(self, frame, t_ns: int) -> None:
        """Hand a rendered frame to the output thread (in order; waits when it is far behind)."""
        if self._output_error is not None:
            raise NodeFailure(f'camera output failed: {self._output_error}')
        if self._thread is None:
            self._thread = threading.Thread(target=self._output_loop, name='camera-output',
                                            daemon=True)
            self._thread.start()
        self._frames_out.put((frame, t_ns, self.info))

    def _output_loop(self) -> None:
        while True:
            item = self._frames_out.get()
            if item is None:
                return
            try:
                self._publish(*item)
            except Exception as exc:  # noqa: BLE001  (reported by the executor thread)
                # run_node closes the node (and this thread) before it shuts the context down;
                # a context shut down by someone else is a stop, not a failure.
                if self._output_error is None and self.context.ok():
                    self._output_error = exc

    def _follow(self, t_ns: int) -> None:
        """
        Return a camera on a rail along the track.

        When a marker comes within ``follow_margin`` of the picture's edge, move by ``follow_step``
        (or onto the robot's COM, to the mm) along the surfaces. The images from then on are the
        moved camera's; their CameraInfo is the fixed camera's with the principal point shifted by
        the move (cx - scale d cos(slope), cy + scale d sin(slope)): with the same ``center_x`` a
        reader keeps metric positions continuous.
        """
        cam = self.camera
        pose = self.pose_at(t_ns)
        m = self.follow_margin * min(cam.width, cam.height)
        if all(m <= p.real <= cam.width - 1 - m and m <= p.imag <= cam.height - 1 - m
               for p in map(complex, self.renderer.marker_pixels(pose))):
            return
        step = round(pose.x - cam.center_x, 3)
        if self.follow_step:
            step = math.copysign(self.follow_step, step)
        if step == 0:
            return
        self.offset += step
        self.camera = cam.replace(center_x=cam.center_x + step)
        r = self.renderer
        self.renderer = Renderer(r.robot, r.gap, self.camera, r.options, r.scene)
        c0 = self._camera0
        cx, cy = c0.principal_point
        d = self.offset * c0.scale
        self.info = self._camera_info(c0.replace(cx=cx - d * math.cos(c0.slope),
                                                 cy=cy + d * math.sin(c0.slope)))
        self.get_logger().info(f'camera moved {step:+.3f} m along the track at '
                               f't = {t_ns / NS_PER_S:.3f} s (offset {self.offset:.3f} m)')

    def _info_cdr(self, info: CameraInfo, t_ns: int) -> bytes:
        """
        Return ``info`` serialized with the stamp ``t_ns``.

        Serialized once per CameraInfo (it changes only when the camera moves), then only the
        stamp is replaced: rclpy's conversion of its arrays cost ~0.2 ms a frame.
        """
        if info is not self._info_source:
            self._info_source, self._info_serialized = info, serialize_message(info)
        return cdr.restamp(self._info_serialized, t_ns)

    def _publish(self, frame, t_ns: int, info: CameraInfo = None) -> None:
        """
        Publish image and camera info, then add the frame to the video.

        The video gets the frame even when publishing failed: after Ctrl-C the context is gone,
        but the video still gets every frame.
        """
        t0, c0 = time.perf_counter(), self.output_cpu.now()
        try:
            # First: a reader has the new K for the image.
            self._pub_info.publish(self._info_cdr(info or self.info, t_ns))
            frame = np.ascontiguousarray(frame)
            if self._pub_image is not None and self._pub_image.get_subscription_count():
                self._pub_image.publish(self._image_cdr(frame, t_ns))
            if self._pub_compressed is not None and self.jpeg_quality is not None and \
                    self._pub_compressed.get_subscription_count():
                # Here, in the output thread: OpenCV encodes without the GIL.
                t = time.perf_counter()
                c0 = self.output_cpu.add('publish', c0)
                data = self._jpeg(frame, self.jpeg_quality)
                self.busy['jpeg'] += time.perf_counter() - t
                c0 = self.output_cpu.add('jpeg', c0)
                self._pub_compressed.publish(self._compressed_cdr(data, t_ns))
            self.frames += 1
        finally:
            t1 = time.perf_counter()
            c0 = self.output_cpu.add('publish', c0)
            self.busy['publish'] += t1 - t0
            if self.writer is not None:
                self.writer.write(frame)
                self.busy['video'] += time.perf_counter() - t1
                self.output_cpu.add('video', c0)
            # Read by no one any more: the renderer draws a later frame into it.
            self.renderer.recycle(frame)
            self.output_cpu.frame()

    def _jpeg(self, frame: np.ndarray, quality: int) -> bytes:
        """
        Return the JPEG of a frame: only its rows the renderer drew on encoded (BandJpeg).

        The rest is the background's, encoded once per renderer (the camera moved: another).
        A frame the renderer does not know (the camera moved since) is encoded whole.
        """
        renderer = self.renderer
        rows = renderer.rows_drawn(frame)
        if rows is None:
            return compressed.encode_jpeg(frame, quality)
        if self._band_jpeg is None or self._band_jpeg.background is not renderer.background:
            self._band_jpeg = compressed.BandJpeg(renderer.background, quality)
        return self._band_jpeg.encode(frame, *rows)

    def close(self) -> None:
        if self._thread is not None:
            self._frames_out.put(None)
            self._thread.join()
            self._thread = None
        if self.writer is not None:
            self.writer.close()
        # After Ctrl-C the context (and /rosout) may be gone: plain stderr. The pipeline
        # benchmark reads this line to check that no input was lost.
        print('[camera] inputs received: ' + ' '.join(f'{k}={v}' for k, v in
              self.received.items()) + f' frames={self.frames}; wall s spent: '
              + ' '.join(f'{k}={v:.2f}' for k, v in self.busy.items())
              + f'; executor thread {self.render_cpu.summary()}; output thread '
              + self.output_cpu.summary(), file=sys.stderr, flush=True)


def parameters():
    """Every parameter the node declares: the Scenario's it draws with, then its own."""
    return [e for e in Scenario().describe() if e[0] not in SCENARIO_EXCLUDED] + list(PARAMETERS)


def main(args=None) -> int:
    one_opencv_thread()
    return run_node(CameraNode, args=args, events=True, name='camera', parameters=parameters)


if __name__ == '__main__':
    run_module(main, yaml_file)
