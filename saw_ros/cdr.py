"""Reading the few fields we need straight from CDR bytes (raw subscriptions), without rclpy.

Deserialising a full message costs most of a Python subscriber's time at 1 kHz; a raw
subscription plus struct.unpack_from costs a fraction of it (shared/docs/ros-notes.md).
Layout: XCDR1, a 4-byte encapsulation header, then fields aligned to their size from there.
"""
from __future__ import annotations

import math
import struct

_LITTLE = (0x00, 0x01)
_HEADER = 4


def _prefix(data: bytes) -> str:
    if len(data) < 8 or data[0] != 0 or data[1] not in _LITTLE:
        raise ValueError('not a CDR message')
    return '<' if data[1] == 0x01 else '>'


def pose_stamped(data: bytes):
    """(stamp in s, x, y, pitch about z) of a geometry_msgs/PoseStamped."""
    e = _prefix(data)
    sec, nanosec, length = struct.unpack_from(e + 'iII', data, _HEADER)
    offset = 12 + length
    offset += -offset % 8                        # doubles align to 8 (from the body start)
    x, y, _z, qx, qy, qz, qw = struct.unpack_from(e + '7d', data, _HEADER + offset)
    return sec + nanosec * 1e-9, x, y, 2.0 * math.atan2(qz, qw)
