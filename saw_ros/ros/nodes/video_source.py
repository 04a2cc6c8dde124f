"""
The video source node: recorded footage as a camera stream.

Publishes a video file (anything OpenCV reads), or a folder of frame images (sorted by name), as
sensor_msgs/Image (bgr8) plus sensor_msgs/CameraInfo on the camera node's topics
(/saw/camera/image_raw, /saw/camera/camera_info, frame ``saw_camera``, the camera's publisher
QoS), so the vision node takes them unchanged. Frame k is stamped k / fps s from t = 0 (fps from
the file unless ``fps`` is given; a folder needs it) and sent at ``rate`` times real time;
``publish_clock`` also publishes /clock with each frame's stamp, for nodes with use_sim_time.
``loop`` starts the file again with stamps going on. CameraInfo carries K from ``camera_matrix``
(FX, FY, CX, CY) or from ``px_per_m`` x ``distance`` (the vision node's ``plane_distance``);
with neither, K is zero (uncalibrated: give the vision node ``px_per_m``).

A missing, unreadable or damaged video is refused at start (one line, exit 1). At the end of the
file the node stops (exit 0) after its subscribers acknowledged the last frames (run_node's
flush), as on Ctrl-C. Parameters are read-only (read at start).
"""
from __future__ import annotations

import math
import os
import sys
import time
from typing import Iterator, Optional

# FFmpeg's own messages about a damaged file ("moov atom not found") would come before our
# one-line refusal: quiet (the refusal says it); set before OpenCV loads FFmpeg.
os.environ.setdefault('OPENCV_FFMPEG_LOGLEVEL', '-8')

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from rclpy.clock import Clock, ClockType  # noqa: E402
from rclpy.exceptions import ParameterException  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rosgraph_msgs.msg import Clock as ClockMsg  # noqa: E402
from saw_ros.core.params import spec_meta  # noqa: E402
from saw_ros.interface import topics  # noqa: E402
from saw_ros.ros import cdr  # noqa: E402
from saw_ros.ros import conversions as conv  # noqa: E402
from saw_ros.ros.cdr import NS_PER_S  # noqa: E402
from saw_ros.ros.params import declare_spec  # noqa: E402
from saw_ros.ros.qos import CLOCK_QOS, image_publisher_qos  # noqa: E402
from saw_ros.ros.runtime import NodeFailure, run_node, spin_node  # noqa: E402
from saw_ros.vision import one_opencv_thread  # noqa: E402
from saw_ros.vision.video import frame_files, VideoError  # noqa: E402
from sensor_msgs.msg import CameraInfo, Image  # noqa: E402

TICK = 0.002            # s, wall-clock timer period of the publishing loop
INFO_GRACE = 2.0        # s to wait for camera-info subscribers once the image ones matched

# (name, default, spec metadata); every one read once at start, so read-only. declare_spec checks
# the values against these ranges.
PARAMETERS = (
    ('path', '', spec_meta('', 'video file, or folder of frame images (sorted by name); '
                               'required')),
    ('fps', 0.0, spec_meta('Hz', "frame rate; 0 = the file's (a folder needs it)", 0.0, None)),
    ('loop', False, spec_meta('', 'start the file again at its end (stamps go on)')),
    ('rate', 1.0, spec_meta('', 'real-time factor: video seconds per wall-clock second', 0.0,
                            None, low_open=True)),
    ('publish_clock', False, spec_meta('', "publish /clock with each frame's stamp (for "
                                           'use_sim_time nodes)')),
    ('frame_id', 'saw_camera', spec_meta('', 'frame_id of the images and camera info')),
    ('px_per_m', 0.0, spec_meta('px/m', 'pixels per metre in the plane of motion; with distance '
                                        'gives K', 0.0, None)),
    ('distance', 1.0, spec_meta('m', 'camera to the plane of motion: fx = px_per_m * distance',
                                0.0, None, low_open=True)),
    ('camera_matrix', [0.0], spec_meta('px', 'FX, FY, CX, CY of a calibration; overrides '
                                             'px_per_m')),
    ('wait_for_subscribers', 0, spec_meta('', 'image (and camera info) subscribers to wait for '
                                              'before the first frame', 0, None)),
    ('image_topic', topics.IMAGE, spec_meta('', 'image output (sensor_msgs/Image, bgr8)')),
    ('camera_info_topic', topics.CAMERA_INFO, spec_meta('', 'camera info output')),
)


class FrameSource:
    """
    Frames (BGR uint8) of a video file or of a folder of images, in order.

    Checked at open: the first frame must decode.
    """

    def __init__(self, path: str, fps: float = 0.0):
        self.path = os.fspath(path)
        self._cap = None
        self._files = None
        if os.path.isdir(self.path):
            self._files = frame_files(self.path)     # (the same as saw-ros track's)
            if not fps > 0:
                raise VideoError(f'a folder of frames has no frame rate: give fps ({self.path})')
            self.fps = float(fps)
        elif os.path.isfile(self.path):
            cap = cv2.VideoCapture(self.path)
            if not cap.isOpened():
                cap.release()
                raise VideoError(f'cannot read video {self.path}: not a video OpenCV can decode')
            self._cap = cap
            self.fps = float(fps) if fps > 0 else float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
            if not (self.fps > 0 and math.isfinite(self.fps)):
                self.close()
                raise VideoError(f'video {self.path} does not say its frame rate: give fps')
        else:
            raise VideoError(f'no such video file or folder: {self.path}')
        self._index = 0
        self._first = self._read()
        if self._first is None:
            self.close()
            raise VideoError(f'cannot read video {self.path}: no frame could be decoded '
                             f'(damaged?)')
        self.height, self.width = self._first.shape[:2]

    def _read(self) -> Optional[np.ndarray]:
        if self._files is not None:
            if self._index >= len(self._files):
                return None
            frame = cv2.imread(str(self._files[self._index]), cv2.IMREAD_COLOR)
            if frame is None:
                raise VideoError(f'cannot read frame image {self._files[self._index]}')
            self._index += 1
            return frame
        if self._cap is None:          # closed: nothing more to read
            return None
        ok, frame = self._cap.read()
        return frame if ok else None

    def frames(self) -> Iterator[np.ndarray]:
        """Every frame once, from the first."""
        if self._first is not None:
            first, self._first = self._first, None
            yield first
        while True:
            frame = self._read()
            if frame is None:
                return
            if frame.shape[:2] != (self.height, self.width):
                raise VideoError(f'frame size changed in {self.path}')
            yield frame

    def rewind(self) -> None:
        if self._files is not None:
            self._index = 0
        elif self._cap is not None:
            self._cap.set(cv2.CAP_PROP_POS_FRAMES, 0)

    def close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None


def camera_info(width: int, height: int, frame_id: str, px_per_m: float = 0.0,
                distance: float = 1.0, camera_matrix=None) -> CameraInfo:
    """
    Return the CameraInfo of the footage.

    K from the calibration, or f = px_per_m * distance with the principal point at the image centre
    (the camera node's convention), or zero.
    """
    if camera_matrix:
        fx, fy, cx, cy = (float(v) for v in camera_matrix)
    elif px_per_m > 0:
        fx = fy = float(px_per_m) * float(distance)
        cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    else:
        fx = fy = cx = cy = 0.0
    info = CameraInfo()
    info.header.frame_id = frame_id
    info.width, info.height = int(width), int(height)
    info.distortion_model = 'plumb_bob'
    info.d = [0.0] * 5
    info.k = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
    info.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    info.p = [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return info


class VideoSourceNode(Node):
    def __init__(self, **kwargs):
        super().__init__('video_source', **kwargs)
        try:
            p = declare_spec(self, PARAMETERS)
            if not p['path']:
                raise ValueError('give the video: -p path:=<file or folder>')
            matrix = [float(v) for v in p['camera_matrix']]
            if matrix == [0.0]:
                matrix = []
            if matrix and (len(matrix) != 4 or not matrix[0] > 0 or not matrix[1] > 0):
                raise ValueError(f'camera_matrix = {matrix}: give FX, FY, CX, CY (px, FX, FY > 0)')
            self.source = FrameSource(p['path'], float(p['fps']))
        except (ParameterException, ValueError, TypeError) as exc:
            raise NodeFailure(f'invalid parameters: {exc}') from exc
        except VideoError as exc:
            raise NodeFailure(str(exc)) from exc
        self.p = p
        src = self.source
        self.fps = src.fps
        self.rate = float(p['rate'])
        self.loop = bool(p['loop'])
        self.info = camera_info(src.width, src.height, p['frame_id'], float(p['px_per_m']),
                                float(p['distance']), matrix)
        self._image_cdr = cdr.ImageCdr(src.width, src.height, 'bgr8', src.width * 3,
                                       p['frame_id'])
        qos = image_publisher_qos()
        self._pub_image = self.create_publisher(Image, p['image_topic'], qos)
        self._pub_info = self.create_publisher(CameraInfo, p['camera_info_topic'], qos)
        self._pub_clock = self.create_publisher(ClockMsg, topics.CLOCK, CLOCK_QOS) \
            if p['publish_clock'] else None
        self._frames = src.frames()
        self.sent = 0               # frames published (all passes)
        self.passes = 1
        self.done = False
        self._start = None          # wall time of frame 0
        self._images_matched = None
        self._timer = self.create_timer(TICK, self._tick,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f'{p["path"]}: {src.width}x{src.height} at {self.fps:g} fps, rate {self.rate:g}'
            + (', publishing /clock' if self._pub_clock else '')
            + ('' if self.info.k[0] > 0 else '; no scale given: CameraInfo K is zero'))

    def _tick(self) -> None:
        if self.done:
            return
        if self._start is None:
            if not self._subscribers_ready():
                return
            self._start = time.monotonic()
        due = int(math.floor((time.monotonic() - self._start) * self.fps * self.rate)) + 1
        while self.sent < due and not self.done:
            frame = self._next_frame()
            if frame is None:
                self.done = True
                break
            self._publish(frame, int(round(self.sent * NS_PER_S / self.fps)))
            self.sent += 1

    def _subscribers_ready(self) -> bool:
        """
        Return whether ``wait_for_subscribers`` image and camera-info subscribers matched.

        The camera-info ones count as matched once INFO_GRACE s passed since the images matched:
        a reader with px_per_m takes none.
        """
        n = int(self.p['wait_for_subscribers'])
        if self._pub_image.get_subscription_count() < n:
            return False
        if self._pub_info.get_subscription_count() >= n:
            return True
        now = time.monotonic()
        if self._images_matched is None:
            self._images_matched = now
        return now - self._images_matched >= INFO_GRACE

    def _next_frame(self) -> Optional[np.ndarray]:
        try:
            frame = next(self._frames, None)
            if frame is None and self.loop:
                self.source.rewind()
                self.passes += 1
                self._frames = self.source.frames()
                frame = next(self._frames, None)
        except VideoError as exc:
            self.get_logger().error(f'{exc}: stopping at frame {self.sent}')
            return None
        return frame

    def _publish(self, frame: np.ndarray, t_ns: int) -> None:
        if self._pub_clock is not None:
            clock = ClockMsg()
            conv.time_msg(t_ns, clock.clock)
            self._pub_clock.publish(clock)
        conv.time_msg(t_ns, self.info.header.stamp)
        self._pub_image.publish(self._image_cdr(np.ascontiguousarray(frame), t_ns))
        self._pub_info.publish(self.info)

    def close(self) -> None:
        self.source.close()
        print(f'[video_source] published {self.sent} frames '
              f'({self.sent / self.fps:.3f} s of video, {self.passes} pass(es))',
              file=sys.stderr, flush=True)


def main(args=None) -> int:
    one_opencv_thread()
    return run_node(VideoSourceNode, args=args, name='video_source',
                    parameters=lambda: PARAMETERS,
                    spin=lambda node: spin_node(node, until=lambda: node.done))


if __name__ == '__main__':
    sys.exit(main())
