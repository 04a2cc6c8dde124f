"""
What a node checks in a message before it uses it (pure: no rclpy, tested without ROS).

Every topic of the graph is open to any participant of the DDS domain (docs/security.md), so a
node takes nothing on trust: a message whose values are not finite, whose arrays do not match,
whose image declares more pixels than the node takes, whose encoding or frame the node does not
know, or whose stamp goes back, is refused with a ``Refused`` naming the reason (a short kind,
counted per topic on the node's /diagnostics, and the detail for the warning). The ROS side,
which subscribes, counts and warns, is ``saw_ros.ros.guard``.
"""
from __future__ import annotations

import math
import struct
from typing import Iterable, List, Optional, Sequence, Tuple

# m: no pose of the robot is this far from the origin (it crawls mm/s for minutes); a value past
# it would only move the camera's rail or the comparison's fit somewhere no picture can show.
POSITION_LIMIT = 1.0e3
# Stamps going back: the messages that must follow one another, each later than the one before
# and all behind the last accepted, before a node takes them for a restarted replay (one stray
# stamp is refused; a replay's restart is a stream of them).
RESTART_AFTER = 5


class Refused(ValueError):
    """A message a node will not use: ``kind`` (counted) and the detail (said in the warning)."""

    def __init__(self, kind: str, detail: str):
        super().__init__(f'{kind}: {detail}')
        self.kind = kind
        self.detail = detail


def finite(what: str, values: Iterable[float]) -> None:
    """Refuse ``values`` unless every one is a finite number."""
    for v in values:
        if not math.isfinite(v):
            raise Refused('not finite', f'{what} has {v!r}')


def position(x: float, y: float, limit: float = POSITION_LIMIT) -> None:
    """Refuse a position that is not finite or lies more than ``limit`` m from the origin."""
    finite('position', (x, y))
    if abs(x) > limit or abs(y) > limit:
        raise Refused('out of range', f'position ({x:g}, {y:g}) m is more than {limit:g} m '
                                      'from the origin')


def pose(x: float, y: float, quaternion: Sequence[float]) -> None:
    """Refuse a planar pose whose position or orientation is not usable."""
    position(x, y)
    finite('orientation', quaternion)
    if sum(q * q for q in quaternion) < 1e-12:
        raise Refused('not a rotation', 'orientation quaternion is zero')


def frame(frame_id: str, known: Sequence[str]) -> None:
    """Refuse a frame_id outside ``known``."""
    if frame_id not in known:
        raise Refused('unknown frame', f'frame_id {frame_id!r}, expected '
                                       + ' or '.join(repr(k) for k in known))


def joint_arrays(names: int, position: int, velocity: int, effort: int) -> None:
    """Refuse a JointState whose position, velocity or effort is neither empty nor one a name."""
    for field, n in (('position', position), ('velocity', velocity), ('effort', effort)):
        if n not in (0, names):
            raise Refused('mis-sized arrays', f'{n} {field} values for {names} names')


def image_header(width: int, height: int, encoding: str, step: int, size: int,
                 encodings: Sequence[str], max_pixels: int, channels: int = 3) -> None:
    """
    Refuse a sensor_msgs/Image by its header alone (before its pixels are touched).

    The size must be > 0 and at most ``max_pixels``, the encoding one of ``encodings``
    (``channels`` bytes a pixel), ``step`` at least a row's bytes and the data at least
    ``height * step``.
    """
    if width <= 0 or height <= 0:
        raise Refused('empty image', f'{width}x{height}')
    if width * height > max_pixels:
        raise Refused('image too large', f'{width}x{height} is over the limit of {max_pixels} '
                                         'pixels')
    if encoding not in encodings:
        raise Refused('wrong encoding', f'{encoding!r}, expected ' + ' or '.join(encodings))
    if step < channels * width:
        raise Refused('step mismatch', f'step {step} < {channels} x width {width}')
    if size < height * step:
        raise Refused('data too short', f'{size} bytes for {height} rows of {step}')


_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}   # JPEG start-of-frame markers


def compressed_size(data: bytes) -> Optional[Tuple[int, int]]:
    """
    Return (width, height) a JPEG or PNG declares in its header, None when it declares none.

    JPEG: the first start-of-frame segment; PNG: its IHDR chunk. Read before decoding, so that an
    image declaring a huge size is refused before a decoder allocates it.
    """
    if data[:8] == b'\x89PNG\r\n\x1a\n' and len(data) >= 24 and data[12:16] == b'IHDR':
        w, h = struct.unpack_from('>II', data, 16)
        return w, h
    if data[:2] != b'\xff\xd8':
        return None
    i = 2
    while i + 4 <= len(data):
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker == 0xFF:              # fill byte
            i += 1
            continue
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
            i += 2
            continue
        length = struct.unpack_from('>H', data, i + 2)[0]
        if marker in _SOF:
            if i + 9 > len(data):
                return None
            h, w = struct.unpack_from('>HH', data, i + 5)
            return w, h
        i += 2 + length
    return None


def compressed_image(format_: str, data: bytes, max_pixels: int,
                     max_bytes: int) -> Tuple[int, int]:
    """
    Refuse a CompressedImage that cannot be a frame we decode, from its bytes' header alone.

    Empty, more than ``max_bytes``, not a JPEG or PNG by its header, a declared size of 0 or more
    than ``max_pixels``. Return the size it declares, (width, height).
    """
    if not data:
        raise Refused('empty image', f'no data (format {format_!r})')
    if len(data) > max_bytes:
        raise Refused('image too large', f'{len(data)} bytes is over the limit of {max_bytes}')
    size = compressed_size(bytes(data[:65536]))
    if size is None:
        raise Refused('not an image', f'{len(data)} bytes with no JPEG or PNG header (format '
                                      f'{format_!r})')
    w, h = size
    if w <= 0 or h <= 0:
        raise Refused('empty image', f'declares {w}x{h}')
    if w * h > max_pixels:
        raise Refused('image too large', f'declares {w}x{h}, over the limit of {max_pixels} '
                                         'pixels')
    return w, h


def camera_matrix(k: Sequence[float], width: int, height: int, max_pixels: int) -> None:
    """Refuse CameraInfo intrinsics that are not finite, have no focal length or a bad size."""
    if len(k) != 9:
        raise Refused('mis-sized arrays', f'K has {len(k)} values, not 9')
    finite('K', k)
    if not (k[0] > 0 and k[4] > 0):
        raise Refused('no focal length', f'fx {k[0]:g}, fy {k[4]:g}')
    if width < 0 or height < 0 or width * height > max_pixels:
        raise Refused('image too large', f'{width}x{height}, over the limit of {max_pixels} '
                                         'pixels')


class FrameGaps:
    """
    Counts the frames missing from a stream of images by their stamps (ns), in order.

    A camera publishes at a fixed rate; its period is taken as the shortest interval seen so
    far, and an interval of k periods (k >= 1.5, rounded) means k - 1 frames that never came:
    dropped on the way (a reader slower than the stream loses the oldest of its queue without
    a word from DDS) or by the source. A stream whose rate varies is over-counted; the count is
    a report, never a reason to refuse a frame. A stamp not after the last restarts the count's
    reference (a replay).
    """

    def __init__(self) -> None:
        self.period: Optional[int] = None
        self.last: Optional[int] = None
        self.missed = 0

    def add(self, t: int) -> int:
        """Take the stamp of a frame that arrived; return the frames missed just before it."""
        last, self.last = self.last, t
        if last is None or t <= last:
            return 0
        dt = t - last
        self.period = dt if self.period is None else min(self.period, dt)
        gap = int(round(dt / self.period)) - 1 if dt >= 1.5 * self.period else 0
        self.missed += gap
        return gap


class StampOrder:
    """
    Refuses stamps that go back (or leap ahead), unless ``restart_after`` in a row go on from them.

    ``check(t)`` raises Refused for a stamp before the last accepted one or, with ``max_leap``
    (ns), more than that after it; when ``restart_after`` such stamps came in a row, each later
    than the one before, the last is accepted (the source restarted: a replay) and ``restarted``
    is set until the next check. One stray stamp (0, or a year ahead) is refused; a stream that
    really restarted is taken after ``restart_after`` messages.
    """

    def __init__(self, restart_after: int = RESTART_AFTER, max_leap: Optional[int] = None):
        self.restart_after = restart_after
        self.max_leap = max_leap
        self.last: Optional[int] = None
        self._streak: List[int] = []
        self.restarted = False

    def check(self, t: int) -> None:
        self.restarted = False
        last = self.last
        if last is None or last <= t and (self.max_leap is None or t - last <= self.max_leap):
            self.last = t
            self._streak.clear()
            return
        if self._streak and t <= self._streak[-1]:
            self._streak.clear()
        self._streak.append(t)
        if len(self._streak) >= self.restart_after:
            self.last = t
            self._streak.clear()
            self.restarted = True
            return
        what = 'stamp went back' if t < last else 'stamp leapt ahead'
        raise Refused(what, f'{t * 1e-9:.9f} s after {last * 1e-9:.9f} s')
