"""
Shapes of saw_ros.interface.scene_markers as visualization_msgs/MarkerArray, for RViz and Foxglove.

The simulator publishes the ground truth on /saw/markers (surfaces, robot, contact forces) and
the vision node the tracker's estimate on /saw/tracking/markers, each from its own state: no node
subscribes to the 1 kHz streams only to draw them (every 1 kHz subscription costs the graph real
time on two cores). A viewer shows both topics in frame ``surface``.

Each array starts with a DELETEALL (contact arrows come and go; a lost marker must disappear);
it clears only the markers of its own topic in RViz and Foxglove.
"""
from __future__ import annotations

import math
import struct
from typing import Iterable, Optional

from geometry_msgs.msg import Point
import numpy as np
from saw_ros.interface import scene_markers
from saw_ros.ros import conversions as conv
from saw_ros.ros.cdr import CdrWriter, ENCAPSULATION, NS_PER_S, stamp_bytes, string_bytes
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

FRAME = 'surface'
RATE = 60.0          # Hz of simulated time: a viewer's frame rate, not the physics' 1 kHz

_KINDS = {'cube': Marker.CUBE, 'sphere': Marker.SPHERE, 'arrow': Marker.ARROW,
          'sphere_list': Marker.SPHERE_LIST, 'triangle_list': Marker.TRIANGLE_LIST}


def marker_of(shape: scene_markers.Shape, stamp, frame: str = FRAME) -> Marker:
    """Return a scene_markers.Shape as a visualization_msgs/Marker."""
    m = Marker()
    m.header.stamp = stamp
    m.header.frame_id = frame
    m.ns = shape.namespace
    m.id = shape.id
    m.type = _KINDS[shape.kind]
    m.action = Marker.ADD
    m.pose.position.x, m.pose.position.y, m.pose.position.z = shape.position
    m.pose.orientation.z = math.sin(0.5 * shape.yaw)
    m.pose.orientation.w = math.cos(0.5 * shape.yaw)
    m.scale.x, m.scale.y, m.scale.z = shape.scale
    m.color = ColorRGBA(r=shape.colour[0], g=shape.colour[1], b=shape.colour[2],
                        a=shape.colour[3])
    m.points = [Point(x=p[0], y=p[1], z=p[2]) for p in shape.points]
    return m


def marker_array(shapes: Iterable[scene_markers.Shape], stamp_ns: int,
                 frame: str = FRAME) -> MarkerArray:
    """Return a DELETEALL, then every shape, stamped ``stamp_ns``."""
    stamp = conv.time_msg(stamp_ns)
    clear = Marker()
    clear.header.stamp = stamp
    clear.header.frame_id = frame
    clear.action = Marker.DELETEALL
    return MarkerArray(markers=[clear] + [marker_of(s, stamp, frame) for s in shapes])


def _tail() -> bytes:
    """
    Return what follows a Marker's points, all empty.

    That is colors, texture_resource, texture, uv_coordinates, text, mesh_resource, mesh_file and
    mesh_use_embedded_materials. Nothing in it needs more than 4-byte alignment, and it always
    starts 4-aligned (after the points' u32 length or float64s), so its bytes never change.
    """
    w = CdrWriter()
    w.u32(0).string('')                                 # colors, texture_resource
    w.u32(0).u32(0).string('').string('').u32(0)        # texture: stamp, frame, format, data
    w.u32(0).string('').string('')                      # uv_coordinates, text, mesh_resource
    w.string('').u32(0).u8(0)                           # mesh_file, mesh_use_embedded_materials
    return bytes(w.buf)


_TAIL = _tail()
_IDS = struct.Struct('<iii')           # id, type, action
_POSE_SCALE = struct.Struct('<10d')    # position, orientation (x y z w), scale
_COLOUR_LIFETIME = struct.Struct('<4fiIB')   # colour, lifetime 0 s 0 ns (forever), unlocked
_PAD = (b'', b'\0', b'\0' * 2, b'\0' * 3, b'\0' * 4, b'\0' * 5, b'\0' * 6, b'\0' * 7)


def marker_array_cdr(shapes: Iterable[scene_markers.Shape], stamp_ns: int,
                     frame: str = FRAME) -> bytes:
    """
    Return ``marker_array(shapes, stamp_ns, frame)`` serialized (XCDR1 little-endian).

    rclpy's own conversion takes about 7 ms for the robot's array (hundreds of Point objects);
    this joins a few packed pieces per marker, the points as one numpy block: about 0.1 ms, at
    60 Hz in the simulator and per frame in the vision node. tests/ros/test_markers.py checks it
    byte for byte against rclpy's serialization.
    """
    shapes = list(shapes)
    header = stamp_bytes(stamp_ns) + string_bytes(frame)
    parts = [struct.pack('<I', len(shapes) + 1)]
    size = 4                              # bytes so far, after the encapsulation

    def add(piece: bytes) -> None:
        nonlocal size
        parts.append(piece)
        size += len(piece)

    def align(n: int) -> None:
        add(_PAD[-size % n])

    empty = np.zeros((0, 3))
    for namespace, id_, kind, action, position, yaw, scale, colour, points in (
            [('', 0, 0, Marker.DELETEALL, (0.0,) * 3, 0.0, (0.0,) * 3, (0.0,) * 4, empty)]
            + [(s.namespace, s.id, _KINDS[s.kind], Marker.ADD, s.position, s.yaw, s.scale,
                s.colour, s.points) for s in shapes]):
        align(4)
        add(header)
        add(string_bytes(namespace))
        align(4)
        add(_IDS.pack(id_, kind, action))
        align(8)
        add(_POSE_SCALE.pack(*position, 0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw),
                             *scale))
        add(_COLOUR_LIFETIME.pack(*colour, 0, 0, 0))
        points = np.asarray(points, '<f8').reshape(-1, 3)
        align(4)
        add(struct.pack('<I', len(points)))
        if len(points):
            align(8)
            add(points.tobytes())
        add(_TAIL)
    return ENCAPSULATION + b''.join(parts)


class Decimator:
    """
    Says which stamps start a new 1/rate slot of simulated time (slots start at 0).

    Decimated by stamps, not by a wall timer, so that a simulation at any real-time factor gives
    the same pictures; ``rate`` 0 turns it off.
    """

    def __init__(self, rate: float = RATE):
        self.period = NS_PER_S / rate if rate > 0 else None
        self._slot: Optional[int] = None

    def due(self, stamp_ns: int) -> bool:
        if self.period is None:
            return False
        slot = math.floor(stamp_ns / self.period + 1e-9)
        if self._slot is not None and slot == self._slot:
            return False
        self._slot = slot
        return True
