"""
Video files: write rendered frames to .mp4, read any video frame by frame.

Writing uses OpenCV's FFmpeg back end with the MPEG-4 Part 2 codec (fourcc 'mp4v'): the one .mp4
encoder that opencv-python-headless carries (H.264 'avc1' is not built in). Frames are BGR.
A folder of frame images (``FrameFolder``, sorted by name, at a frame rate given) is a video too:
for ``saw-ros track``, the campaign's footage and the video_source node.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterator, List, Optional, Tuple

import cv2
import numpy as np


IMAGE_EXTENSIONS = ('.png', '.jpg', '.jpeg', '.bmp', '.tif', '.tiff', '.ppm', '.pgm')


class VideoError(RuntimeError):
    """A video file cannot be written or read."""


def frame_files(path) -> List[Path]:
    """Return the frame images of a folder, sorted by name (VideoError when there is none)."""
    files = sorted(p for p in Path(path).iterdir() if p.suffix.lower() in IMAGE_EXTENSIONS)
    if not files:
        raise VideoError(f'no frame images ({", ".join(IMAGE_EXTENSIONS)}) in folder {path}')
    return files


class FrameFolder:
    """
    A folder of frame images as a frame source: ``size``, ``count``, ``frames()``.

    Frames sorted by name, frame k at k / ``fps`` s (a folder says no frame rate: it must be
    given). Every image must decode and have the first one's size.
    """

    def __init__(self, path, fps: float):
        self.path = Path(path)
        self.files = frame_files(self.path)
        if not (fps and fps > 0):
            raise VideoError(f'a folder of frames has no frame rate: give it (--fps) '
                             f'({self.path})')
        self.fps = float(fps)
        first = self._read(0)
        self.size = (first.shape[1], first.shape[0])

    @property
    def count(self) -> int:
        return len(self.files)

    def _read(self, k: int) -> np.ndarray:
        frame = cv2.imread(str(self.files[k]), cv2.IMREAD_COLOR)
        if frame is None:
            raise VideoError(f'cannot read frame image {self.files[k]}')
        return frame

    def frames(self) -> Iterator[Tuple[int, float, np.ndarray]]:
        for k in range(len(self.files)):
            frame = self._read(k)
            if (frame.shape[1], frame.shape[0]) != self.size:
                raise VideoError(f'frame image {self.files[k]} is {frame.shape[1]}x'
                                 f'{frame.shape[0]}, the first was {self.size[0]}x'
                                 f'{self.size[1]}')
            yield k, k / self.fps, frame

    def __str__(self):
        return str(self.path)


class VideoWriter:
    """``with VideoWriter(path, fps, (width, height)) as w: w.write(frame_bgr)``."""

    def __init__(self, path, fps: float, size: Tuple[int, int], fourcc: str = 'mp4v'):
        self.path = Path(path)
        if self.path.parent and not self.path.parent.exists():
            self.path.parent.mkdir(parents=True, exist_ok=True)
        self.size = (int(size[0]), int(size[1]))
        self._writer = cv2.VideoWriter(str(self.path), cv2.VideoWriter.fourcc(*fourcc),
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
