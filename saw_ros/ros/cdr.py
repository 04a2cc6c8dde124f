"""
Reading the few fields we need straight from CDR bytes (raw subscriptions), without rclpy.

Deserialising a full message costs most of a Python subscriber's time at 1 kHz; a raw
subscription plus struct.unpack_from costs a fraction of it (docs/ros-notes.md).
Layout: XCDR1, a 4-byte encapsulation header, then fields aligned to their size from there.
The other way round: ``CdrWriter`` encodes the constant parts of messages published as bytes
(``ImageCdr`` here, the simulator's encoders in ``conversions``).
"""
from __future__ import annotations

import functools
import math
import struct
from typing import List, Optional

NS_PER_S = 1_000_000_000     # nanoseconds per second: the one name for it in the ROS layer
_LITTLE = (0x00, 0x01)
_HEADER = 4


def _prefix(data: bytes) -> str:
    if len(data) < 8 or data[0] != 0 or data[1] not in _LITTLE:
        raise ValueError('not a CDR message')
    return '<' if data[1] == 0x01 else '>'


_STAMP_LE = struct.Struct('<iI')
_U32_LE = struct.Struct('<I')


def _u32(data, e: str, offset: int) -> int:
    return struct.unpack_from(e + 'I', data, _HEADER + offset)[0]


def _align(offset: int, size: int) -> int:
    return offset + (-offset % size)


def header_stamp_ns(data: bytes) -> int:
    """
    Return header.stamp in ns of serialized bytes that start with a std_msgs/Header (or a Clock).

    (``conversions.stamp_ns`` is the same for a builtin_interfaces/Time message object.)
    """
    e = _prefix(data)
    sec, nanosec = struct.unpack_from(e + 'iI', data, _HEADER)
    return sec * NS_PER_S + nanosec


def array_stamp_ns(data: bytes) -> int:
    """
    Return header.stamp in ns of the first element of a sequence of stamped messages.

    For a visualization_msgs/MarkerArray: its first marker's header, after the sequence's length.
    """
    e = _prefix(data)
    sec, nanosec = struct.unpack_from(e + 'iI', data, _HEADER + 4)
    return sec * NS_PER_S + nanosec


def pose_stamped_ns(data: bytes):
    """(stamp in ns, x, y, pitch about z) of a geometry_msgs/PoseStamped (stamp exact)."""
    e = _prefix(data)
    sec, nanosec, length = struct.unpack_from(e + 'iII', data, _HEADER)
    offset = _align(12 + length, 8)
    x, y, _z, qx, qy, qz, qw = struct.unpack_from(e + '7d', data, _HEADER + offset)
    return sec * NS_PER_S + nanosec, x, y, 2.0 * math.atan2(qz, qw)


def pose_stamped(data: bytes):
    """(stamp in ns, frame_id, x, y, (qx, qy, qz, qw)) of a geometry_msgs/PoseStamped."""
    e = _prefix(data)
    sec, nanosec, length = struct.unpack_from(e + 'iII', data, _HEADER)
    frame_id = bytes(data[_HEADER + 12:_HEADER + 12 + length]).rstrip(b'\0').decode()
    offset = _align(12 + length, 8)
    x, y, _z, qx, qy, qz, qw = struct.unpack_from(e + '7d', data, _HEADER + offset)
    return sec * NS_PER_S + nanosec, frame_id, x, y, (qx, qy, qz, qw)


class JointPositions:
    """
    Reads some joints' positions (by name) from sensor_msgs/JointState CDR bytes.

    ``reader(data)`` -> (stamp in ns, positions), one per name in ``names``' order, None for a
    joint not in the message (or without a position). The offsets are worked out once per
    layout of header and names (a publisher keeps them fixed) and checked by comparing those
    bytes, so a message costs a struct read a joint and a bytes comparison.
    """

    def __init__(self, names):
        self.names = tuple(names)
        self._key = None            # (endianness, bytes of frame_id + names)
        self._at = ()               # body offset of each name's double, or None

    def _layout(self, data, e: str):
        n = _u32(data, e, 8)
        offset = _align(12 + n, 4)           # names: sequence<string>
        count = _u32(data, e, offset)
        offset += 4
        wanted = {name.encode(): k for k, name in enumerate(self.names)}
        index: List[Optional[int]] = [None] * len(self.names)
        for i in range(count):
            offset = _align(offset, 4)
            length = _u32(data, e, offset)
            text = bytes(data[_HEADER + offset + 4:_HEADER + offset + 4 + length]).rstrip(b'\0')
            k = wanted.pop(text, None)
            if k is not None:
                index[k] = i
            offset += 4 + length
        names_end = offset
        offset = _align(offset, 4)           # position: sequence<double>
        positions = _u32(data, e, offset)
        first = _align(offset + 4, 8)
        at = tuple(None if i is None or i >= positions else first + 8 * i for i in index)
        return (e, bytes(data[_HEADER + 8:_HEADER + names_end])), at

    def __call__(self, data):
        e = _prefix(data)
        sec, nanosec, n = struct.unpack_from(e + 'iII', data, _HEADER)
        key = self._key
        if key is None or key[0] != e or \
                data[_HEADER + 8:_HEADER + 8 + len(key[1])] != key[1]:
            self._key, self._at = self._layout(data, e)
        double = e + 'd'
        return sec * NS_PER_S + nanosec, [
            None if at is None else struct.unpack_from(double, data, _HEADER + at)[0]
            for at in self._at]


class JointPosition(JointPositions):
    """``JointPositions`` of one joint: ``reader(data)`` -> (stamp in ns, position or None)."""

    def __init__(self, name: str):
        super().__init__((name,))
        self.name = name

    def __call__(self, data):
        t, (value,) = super().__call__(data)
        return t, value


class ImageView:
    """
    The fields of a sensor_msgs/Image read from its CDR bytes.

    ``data`` is a zero-copy memoryview of the pixel bytes (valid as long as the message buffer is).
    """

    __slots__ = ('stamp_ns', 'frame_id', 'height', 'width', 'encoding', 'is_bigendian', 'step',
                 'data')

    def __init__(self, raw):
        e = _prefix(raw)
        view = memoryview(raw)
        sec, nanosec, n = struct.unpack_from(e + 'iII', raw, _HEADER)
        self.stamp_ns = sec * NS_PER_S + nanosec
        self.frame_id = bytes(view[_HEADER + 12:_HEADER + 12 + n]).rstrip(b'\0').decode()
        offset = _align(12 + n, 4)
        self.height, self.width, n = struct.unpack_from(e + 'III', raw, _HEADER + offset)
        offset += 12
        self.encoding = bytes(view[_HEADER + offset:_HEADER + offset + n]).rstrip(
            b'\0').decode()
        offset += n
        self.is_bigendian = raw[_HEADER + offset]
        offset = _align(offset + 1, 4)
        self.step, size = struct.unpack_from(e + 'II', raw, _HEADER + offset)
        offset += 8
        if _HEADER + offset + size > len(raw):
            raise ValueError('image data runs past the end of the message')
        self.data = view[_HEADER + offset:_HEADER + offset + size]


ENCAPSULATION = b'\x00\x01\x00\x00'   # CDR, little endian


def stamp_bytes(nanoseconds: int) -> bytes:
    """Return a builtin_interfaces/Time (sec, nanosec) as little-endian CDR."""
    return _STAMP_LE.pack(*divmod(int(nanoseconds), NS_PER_S))


@functools.lru_cache(maxsize=1024)
def string_bytes(text: str) -> bytes:
    """
    Return a CDR string without its alignment: u32 length (with the NUL), characters, NUL.

    Cached: the simulator's markers and TF name the same frames and namespaces 86 times a tick
    (60 Hz), which cost 2 us each to encode.
    """
    data = text.encode() + b'\0'
    return _U32_LE.pack(len(data)) + data


def after_stamp(data: bytes) -> bytes:
    """Return the bytes of a serialized message that starts with a Header, after its stamp."""
    return data[_HEADER + 8:]


def restamp(data: bytes, nanoseconds: int) -> bytes:
    """Return a little-endian serialized message that starts with a Header, stamped anew."""
    return data[:_HEADER] + stamp_bytes(nanoseconds) + after_stamp(data)


class CdrWriter:
    """
    Minimal XCDR1 little-endian writer for the constant parts of encoded messages.

    Alignment is relative to the end of the 4-byte encapsulation header.
    """

    def __init__(self, offset: int = 0):
        self.buf = bytearray()
        self.offset = offset        # position of buf[0] in the message body

    def align(self, size: int) -> 'CdrWriter':
        self.buf += b'\0' * (-(self.offset + len(self.buf)) % size)
        return self

    def u8(self, value: int) -> 'CdrWriter':
        self.buf += struct.pack('<B', value)
        return self

    def u32(self, value: int) -> 'CdrWriter':
        self.align(4).buf += struct.pack('<I', value)
        return self

    def string(self, text: str) -> 'CdrWriter':
        """u32 length (with the NUL), the characters, the NUL."""
        self.align(4).buf += string_bytes(text)
        return self

    @property
    def end(self) -> int:
        return self.offset + len(self.buf)


class ImageCdr:
    """
    Encodes sensor_msgs/Image as little-endian XCDR1 around a frame's pixel bytes.

    One copy of the pixels: ``encoder(pixels, stamp_ns)`` -> bytes ready for ``publish``.
    """

    def __init__(self, width: int, height: int, encoding: str, step: int, frame_id: str):
        w = CdrWriter(8).string(frame_id)               # after the stamp (8 bytes)
        w.u32(height).u32(width).string(encoding).u8(0)  # u8: is_bigendian
        w.u32(step)
        self._head = bytes(w.buf)
        self._size = step * height

    def __call__(self, pixels, nanoseconds: int) -> bytes:
        view = memoryview(pixels).cast('B')
        if view.nbytes != self._size:
            raise ValueError(f'{view.nbytes} pixel bytes, expected {self._size}')
        return b''.join((ENCAPSULATION, stamp_bytes(nanoseconds), self._head,
                         _U32_LE.pack(self._size), view))


class CompressedImageCdr:
    """
    Encodes sensor_msgs/CompressedImage as little-endian XCDR1 around the compressed bytes.

    ``encoder(data, stamp_ns)`` -> bytes ready for ``publish``.
    """

    def __init__(self, format_: str, frame_id: str):
        w = CdrWriter(8).string(frame_id)               # after the stamp (8 bytes)
        w.string(format_).align(4)                      # then the data's u32 length
        self._head = bytes(w.buf)

    def __call__(self, data: bytes, nanoseconds: int) -> bytes:
        return b''.join((ENCAPSULATION, stamp_bytes(nanoseconds), self._head,
                         _U32_LE.pack(len(data)), data))
