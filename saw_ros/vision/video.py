"""
Video files: write rendered frames to .mp4, read any video frame by frame.

Writing uses OpenCV's FFmpeg back end with the MPEG-4 Part 2 codec (fourcc 'mp4v'): the one .mp4
encoder that opencv-python-headless carries (H.264 'avc1' is not built in). Frames are BGR.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterator, Optional, Tuple

import cv2
import numpy as np


class VideoError(RuntimeError):
    """A video file cannot be written or read."""


class VideoWriter:
    """``with VideoWriter(path, fps, (width, height)) as w: w.write(frame_bgr)``."""

    def __init__(self, path, fps: float, size: Tuple[int, int], fourcc: str = 'mp4v'):
        self.path = Path(path)
        if self.path.parent and not self.path.parent.exists():
            self.path.parent.mkdir(parents=True, exist_ok=True)
        self.size = (int(size[0]), int(size[1]))
        self._writer = cv2.VideoWriter(str(self.path), cv2.VideoWriter_fourcc(*fourcc),
                                       float(fps), self.size)
        if not self._writer.isOpened():
            raise VideoError(f'cannot write video {self.path} (codec {fourcc!r}, {fps} fps, '
                             f'{self.size[0]}x{self.size[1]})')
        self.frames = 0
        self._closed = False

    def write(self, frame_bgr: np.ndarray) -> None:
        h, w = frame_bgr.shape[:2]
        if (w, h) != self.size:
            raise VideoError(f'frame {w}x{h} does not match the video {self.size[0]}x'
                             f'{self.size[1]}')
        self._writer.write(frame_bgr)
        self.frames += 1

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._writer.release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def video_info(path) -> Tuple[float, int, int, int]:
    """(fps, frame count (may be an estimate), width, height) of a readable video."""
    cap = _open(path)
    try:
        return (cap.get(cv2.CAP_PROP_FPS), int(cap.get(cv2.CAP_PROP_FRAME_COUNT)),
                int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
    finally:
        cap.release()


def _open(path) -> cv2.VideoCapture:
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise VideoError(f'no such video file: {path}')
    cap = cv2.VideoCapture(path)
    if not cap.isOpened():
        cap.release()
        raise VideoError(f'cannot read video {path}: not a video OpenCV can decode')
    return cap


def read_frames(path, fps: Optional[float] = None) -> Iterator[Tuple[int, float, np.ndarray]]:
    """
    Yield (index, time in s, BGR frame) for every frame.

    Time = index / fps, fps from the file unless given. Raises VideoError when the file is missing,
    unreadable or has no frames.
    """
    cap = _open(path)
    try:
        rate = fps if fps else cap.get(cv2.CAP_PROP_FPS)
        if not rate or not rate > 0:
            raise VideoError(f'video {path} does not say its frame rate: give it (--fps)')
        index = 0
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            yield index, index / rate, frame
            index += 1
        if index == 0:
            raise VideoError(f'cannot read video {path}: no frame could be decoded')
    finally:
        cap.release()
