"""
Tracking a video file offline: what ``saw-ros track`` and ``saw-ros campaign --videos`` run.

``track_video`` feeds every frame of a file to one ``Tracker``; ``measure_scale`` finds the
scale (px per metre) from the markers' known spacing with a first pass (the pair is picked out by
the robot's line, size, colour and motion, the spacing in pixels not being known yet).

Both take a video file's path or any frame source: an object with ``size`` (width, height) and
``frames()`` yielding (index, t in s, bgr8 frame), such as a recording's camera stream
(saw_ros.analysis.bag_frames.BagFrames: raw or JPEG).
"""
from __future__ import annotations

import dataclasses

from saw_ros.vision.camera import CameraModel
from saw_ros.vision.tracker import scale_from_spacing, Tracker, TrackerConfig
from saw_ros.vision.video import read_frames, video_info

SCALE_FRAMES = 120      # ok frames the first pass measures the marker spacing on


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


def track_video(source, camera_kw: dict, config: TrackerConfig, fps: float = 0.0,
                stop_after_ok: int = 0):
    """
    Return the FrameResults of every frame of a video (or until ``stop_after_ok`` ok frames).

    ``source``: a video file's path, or a frame source (module docstring). The camera's size
    comes from the source.
    """
    if not hasattr(source, 'frames'):
        source = VideoFile(source, fps)
    width, height = source.size
    tracker = Tracker(CameraModel(width=width, height=height, **camera_kw), config)
    results = []
    for _, t, frame in source.frames():
        results.append(tracker.update(frame, t))
        if stop_after_ok and tracker.counters.ok >= stop_after_ok:
            break
    return results, tracker


def measure_scale(source, camera_kw: dict, config: TrackerConfig, spacing: float,
                  fps: float = 0.0):
    """
    (px per metre, frames, spread px) making the markers ``spacing`` m apart.

    From the first SCALE_FRAMES frames with both markers (the spacing in pixels is not known yet:
    the pair is picked out by the robot's line, size, colour and motion), or None.
    """
    blind = dataclasses.replace(config, marker_spacing=None, marker_diameter=None)
    kw = dict(camera_kw, scale=1000.0)          # a placeholder: pixels are what is measured
    results, _ = track_video(source, kw, blind, fps, stop_after_ok=SCALE_FRAMES)
    return scale_from_spacing(results, spacing)
