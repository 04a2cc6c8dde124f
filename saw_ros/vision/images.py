"""
Image messages as arrays: the one decoder of sensor_msgs/Image and CompressedImage.

Duck-typed, so that it needs no message package: an Image is anything with ``encoding``,
``height``, ``width``, ``step`` and ``data`` (rclpy's message, mcap_ros2's decoded one, or the
vision node's ``cdr.ImageView``); a CompressedImage anything with ``format`` and ``data``. The
vision node and a recording's frames (``saw_ros.analysis.bag_frames``) decode through here, so a
row padded past ``3 * width`` (``step``) and an rgb8 stream read the same everywhere.
"""
from __future__ import annotations

from typing import Any, Tuple

import numpy as np
from saw_ros.vision import compressed

ENCODINGS = ('bgr8', 'rgb8')


def image_to_array(msg: Any) -> Tuple[np.ndarray, str]:
    """
    Return (H x W x 3 uint8 view, encoding) of a bgr8 or rgb8 Image; ValueError otherwise.

    The array is a view of the message's bytes (no copy), its rows cut to ``3 * width`` out of
    ``step``.
    """
    if msg.encoding not in ENCODINGS:
        raise ValueError(f'unsupported image encoding {msg.encoding!r}: bgr8 or rgb8 only')
    h, w, step = msg.height, msg.width, msg.step
    buf = np.frombuffer(msg.data, np.uint8)
    if step < 3 * w or buf.size < h * step:
        raise ValueError(f'image data too short: {buf.size} bytes for {w}x{h}, step {step}')
    return buf[:h * step].reshape(h, step)[:, :3 * w].reshape(h, w, 3), msg.encoding


def decode(msg: Any, reduced: int = 1) -> Tuple[np.ndarray, str]:
    """
    Return (H x W x 3 uint8 image, encoding) of an Image or a CompressedImage.

    ``reduced``: a CompressedImage's picture at 1 / ``reduced`` of its size
    (``compressed.decode``); an Image is always whole.
    """
    if hasattr(msg, 'format'):
        return compressed.decode(msg.format, msg.data, reduced)
    return image_to_array(msg)


def to_bgr(image: np.ndarray, encoding: str) -> np.ndarray:
    """Return a contiguous bgr8 copy of an image in ``encoding`` (the image itself if it is)."""
    if encoding == 'rgb8':
        image = image[:, :, ::-1]
    return np.ascontiguousarray(image)
