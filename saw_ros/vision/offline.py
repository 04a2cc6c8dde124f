"""
Tracking a video file offline: what ``saw-ros track`` and ``saw-ros campaign --videos`` run.

``track_video`` feeds every frame of a file to one ``Tracker``; ``measure_scale`` finds the
scale (px per metre) from the markers' known spacing with a first pass (the same acquisition: the
pair is picked out by its colour, roundness, size and motion, the spacing in pixels not being
known yet), from at least MIN_SCALE_FRAMES frames.

Both take a video file's path, a folder of frame images (with ``fps``), or any frame source: an
object with ``size`` (width, height) and ``frames()`` yielding (index, t in s, bgr8 frame), such
as a recording's camera stream (saw_ros.analysis.bag_frames.BagFrames: raw or JPEG) or
``footage.Shot``.
"""
from __future__ import annotations

import dataclasses
import math
import os
from typing import Optional

import numpy as np

from saw_ros.vision import perspective
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.tracker import scale_from_spacing, Tracker, TrackerConfig
from saw_ros.vision.video import FrameFolder, read_frames, video_info

SCALE_FRAMES = 120      # ok frames the first pass measures the marker spacing on
MIN_SCALE_FRAMES = 30   # fewer: no scale (one frame of a wrong pair gave a scale 4.4x too large)
PLANE_FRAMES = 900      # ok frames the first pass looks for a perspective on (15 s at 60 fps)
PLACEHOLDER = 1000.0    # px/m of the first pass: pixels are what it measures


class VideoFile:
    """A video file as a frame source: its size and its frames, at ``fps`` (0: the file's)."""

    def __init__(self, path, fps: float = 0.0):
        self.path, self.fps = path, fps

    @property
    def size(self):
        return video_info(self.path)[2:]

    def frames(self):
        return read_frames(self.path, self.fps or None)

    def __str__(self):
        return str(self.path)


def open_source(path, fps: float = 0.0):
    """Return a frame source for a video file or a folder of frame images (``fps`` needed)."""
    return FrameFolder(path, fps) if os.path.isdir(path) else VideoFile(path, fps)


def track_video(source, camera_kw: dict, config: TrackerConfig, fps: float = 0.0,
                stop_after_ok: int = 0, slope_known: bool = True):
    """
    Return the FrameResults of every frame of a video (or until ``stop_after_ok`` ok frames).

    ``source``: a video file's path, a folder of frames, or a frame source (module docstring).
    The camera's size comes from the source. ``slope_known``: ``camera_kw``'s slope is the
    track's; False: the track's direction comes from the markers' motion.
    """
    if not hasattr(source, 'frames'):
        source = open_source(source, fps)
    width, height = source.size
    tracker = Tracker(CameraModel(width=width, height=height, **camera_kw), config,
                      slope_known=slope_known)
    results = []
    for _, t, frame in source.frames():
        results.append(tracker.update(frame, t))
        if stop_after_ok and tracker.counters.ok >= stop_after_ok:
            break
    return results, tracker


def measure_scale(source, camera_kw: dict, config: TrackerConfig, spacing: float,
                  fps: float = 0.0, slope_known: bool = True):
    """
    (px per metre, frames, spread px) making the markers ``spacing`` m apart.

    From the first SCALE_FRAMES frames with both markers (the spacing in pixels is not known yet:
    the pair is picked out by its colour, shape, size and motion, as when tracking), or None
    without any. ValueError when fewer than MIN_SCALE_FRAMES frames had both markers: a scale
    from a handful of frames may be a wrong pair's.
    """
    measured = _first_pass(source, camera_kw, config, spacing, fps, slope_known, SCALE_FRAMES)
    if measured is None:
        return None
    return measured.median, measured.frames, measured.spread


@dataclasses.dataclass
class SpacingScale:
    """The scale from the markers' spacing, and the perspective along the track it shows."""

    scale: float                # px/m: the median over the frames (at the principal point with
    frames: int                 # ... a perspective)
    spread: float               # px, half the 16-84 % range of the spacing
    median: float               # px/m: the median over the frames
    along: Optional[perspective.AlongTrack]     # the fit (None: too few frames or no travel)
    plane: Optional[np.ndarray]                 # its homography, when it is significant

    def camera_kw(self, camera_kw: dict) -> dict:
        """Return the camera arguments that measure with this scale (and its perspective)."""
        if self.plane is None:
            return dict(camera_kw, scale=self.scale)
        return dict(camera_kw, plane=tuple(self.plane.ravel()))


def _first_pass(source, camera_kw: dict, config: TrackerConfig, spacing: float, fps: float,
                slope_known: bool, frames: int) -> Optional[SpacingScale]:
    blind = dataclasses.replace(config, marker_spacing=None, marker_diameter=None)
    kw = dict(camera_kw, scale=PLACEHOLDER)
    results, tracker = track_video(source, kw, blind, fps, stop_after_ok=frames,
                                   slope_known=slope_known)
    if tracker.switched_at is not None:         # frames of a static pair dropped: not these
        results = [r for r in results if r.t > tracker.switched_at]
    measured = scale_from_spacing(results, spacing)
    if measured is None:
        return None
    if measured[1] < MIN_SCALE_FRAMES:
        raise ValueError(f'the marker spacing was measured on {measured[1]} frames only (at '
                         f'least {MIN_SCALE_FRAMES} needed for a scale): give --px-per-m, or '
                         'a clip in which both markers are in view for longer')
    camera = tracker.camera
    slope = tracker.slope_used
    along = None if slope is None else \
        perspective.fit(*perspective.along_track(results, camera, slope), spacing)
    plane = None
    if along is not None and along.significant and slope is not None:
        direction = complex(math.cos(slope), math.sin(slope))
        if camera.mirror:
            direction = -direction.conjugate()
        plane = along.homography(PLACEHOLDER, camera.principal_point, direction)
        scale = along.g * PLACEHOLDER
    else:
        scale = measured[0]
    return SpacingScale(scale, measured[1], measured[2], measured[0], along, plane)


def measure_plane(source, camera_kw: dict, config: TrackerConfig, spacing: float,
                  fps: float = 0.0, slope_known: bool = True) -> Optional[SpacingScale]:
    """
    Return the scale from the markers' spacing, with the perspective along the track.

    A first pass over up to PLANE_FRAMES frames with both markers (as ``measure_scale``); when
    the spacing changes with the markers' place along the track (``perspective``), the plane's
    homography that makes them ``spacing`` apart wherever they are. None without any frame.
    """
    return _first_pass(source, camera_kw, config, spacing, fps, slope_known, PLANE_FRAMES)
