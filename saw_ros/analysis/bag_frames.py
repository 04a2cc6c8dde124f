"""
A recording's camera frames: as a frame source for tracking, and as a video.

``BagFrames`` is what ``saw-ros track`` reads from a bag (a frame source of
``saw_ros.vision.offline``), ``bag_video`` what ``saw-ros bag video`` and the demo's ``camera.mp4``
write. Frames are decoded by ``saw_ros.vision.images``, the vision node's decoder,
and handed on as bgr8.
"""
from __future__ import annotations

from typing import Callable, Iterator, Optional, Tuple

import numpy as np
from saw_ros.bag.reader import BagReader, BagReadError
from saw_ros.interface import topics
from saw_ros.vision import images
from saw_ros.vision.camera import FPS
from saw_ros.vision.video import VideoWriter

FPS_SAMPLE = 61         # stamps the frame rate is measured on (60 intervals)


class BagFrames:
    """
    The camera frames of a recording as a frame source (saw_ros.vision.offline).

    ``topic``: an image topic (CompressedImage or Image); default the camera's compressed
    stream if recorded, else its raw one. A recording without frames is a BagReadError that names
    the image topics it has. Times are the frames' stamps, s.
    """

    def __init__(self, bag, topic: Optional[str] = None):
        self.bag = bag
        self.reader = BagReader(bag)
        recorded = self.reader.info()['topics']
        candidates = [topic] if topic else [topics.IMAGE_COMPRESSED, topics.IMAGE]
        chosen = next((t for t in candidates if t in recorded and recorded[t].count), None)
        if chosen is None:
            found = [t.name for t in recorded.values()
                     if t.type.startswith('sensor_msgs/msg/') and 'Image' in t.type]
            raise BagReadError(f'{bag} holds no frames on {" or ".join(candidates)}; image '
                               f'topics recorded: {", ".join(found) or "none"}')
        self.topic: str = chosen
        self.count = recorded[chosen].count

    def frames(self) -> Iterator[Tuple[int, float, np.ndarray]]:
        """Yield (index, stamp in s, bgr8 frame) of every frame, in the order recorded."""
        for k, (_, msg) in enumerate(self.reader.decoded_messages([self.topic])):
            try:
                image, encoding = images.decode(msg)
            except ValueError as exc:
                raise BagReadError(f'{self.bag}: {self.topic} frame {k + 1}: {exc}') from None
            stamp = msg.header.stamp
            yield k, stamp.sec + stamp.nanosec * 1e-9, images.to_bgr(image, encoding)

    @property
    def size(self) -> Tuple[int, int]:
        _, _, frame = next(iter(self.frames()))
        return frame.shape[1], frame.shape[0]

    @property
    def fps(self) -> float:
        return fps_of(self.reader, self.topic)

    def __str__(self):
        return f'{self.bag} ({self.topic})'


def bag_video(bag, output, topic: Optional[str] = None,
              progress: Optional[Callable[[int, int], None]] = None) -> Tuple[int, float]:
    """
    Write the camera frames of ``bag`` to the video ``output``; return (frames, fps).

    The frames' rate comes from their stamps (the median interval), in the order recorded.
    ``progress(frames written, frames recorded)`` is called after every frame.
    """
    source = BagFrames(bag, topic)
    fps = source.fps
    frames = 0
    writer = None
    try:
        for _, _, frame in source.frames():
            if writer is None:
                writer = VideoWriter(output, fps, frame.shape[1::-1])
            writer.write(frame)
            frames += 1
            if progress is not None:
                progress(frames, source.count)
    finally:
        if writer is not None:
            writer.close()
    return frames, fps


def fps_of(reader: BagReader, topic: str) -> float:
    """Return the frame rate of ``topic`` from the median interval of its first stamps."""
    stamps = []
    for _, msg in reader.decoded_messages([topic]):
        stamps.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
        if len(stamps) >= FPS_SAMPLE:
            break
    gaps = np.diff(stamps)
    gaps = gaps[gaps > 0]
    return round(1e9 / float(np.median(gaps)), 3) if len(gaps) else FPS
