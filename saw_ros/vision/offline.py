"""
Tracking a video file offline: what ``saw-ros track`` and ``saw-ros campaign --videos`` run.

``track_video`` feeds every frame of a file to one ``Tracker``; ``measure_scale`` finds the
scale (px per metre) from the markers' known spacing with a first pass (the pair is picked out by
the robot's line, size, colour and motion, the spacing in pixels not being known yet).
"""
from __future__ import annotations

import dataclasses

from saw_ros.vision.camera import CameraModel
from saw_ros.vision.tracker import scale_from_spacing, Tracker, TrackerConfig
from saw_ros.vision.video import read_frames, video_info

SCALE_FRAMES = 120      # ok frames the first pass measures the marker spacing on


def track_video(path, camera_kw: dict, config: TrackerConfig, fps: float = 0.0,
                stop_after_ok: int = 0):
    """
    Return the FrameResults of every frame of a video (or until ``stop_after_ok`` ok frames).

    The camera's size comes from the file.
    """
    _, _, width, height = video_info(path)
    tracker = Tracker(CameraModel(width=width, height=height, **camera_kw), config)
    results = []
    for _, t, frame in read_frames(path, fps or None):
        results.append(tracker.update(frame, t))
        if stop_after_ok and tracker.counters.ok >= stop_after_ok:
            break
    return results, tracker


def measure_scale(path, camera_kw: dict, config: TrackerConfig, spacing: float,
                  fps: float = 0.0):
    """
    (px per metre, frames, spread px) making the markers ``spacing`` m apart.

    From the first SCALE_FRAMES frames with both markers (the spacing in pixels is not known yet:
    the pair is picked out by the robot's line, size, colour and motion), or None.
    """
    blind = dataclasses.replace(config, marker_spacing=None, marker_diameter=None)
    kw = dict(camera_kw, scale=1000.0)          # a placeholder: pixels are what is measured
    results, _ = track_video(path, kw, blind, fps, stop_after_ok=SCALE_FRAMES)
    return scale_from_spacing(results, spacing)
