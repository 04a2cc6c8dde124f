"""
Numpy state of the simulator -> standard ROS 2 messages (and back, for readers and tests).

Pure functions, no node: every function takes arrays/floats and returns a message. The builders
accept ``out=`` (a message to fill in place) because the simulator publishes six messages per
step at 1 kHz and reusing them saves the construction of nested Python objects.

Frames (REP 103): ``surface`` is fixed, x along the surfaces in the direction of travel, y normal
from the bottom surface, z out of the side-view plane; ``base_link`` is the robot body at its
centre of mass. Stamps are simulated time, kept as integer nanoseconds (``steps * dt_ns``) so
that 1 ms steps give stamps exactly 1 000 000 ns apart, with no floating-point drift.
"""
from __future__ import annotations

import math
import struct
from typing import Any, Mapping, Optional, Sequence, Tuple

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped, TwistStamped
import numpy as np
from saw_ros.ros.cdr import CdrWriter, ENCAPSULATION, NS_PER_S
from sensor_msgs.msg import BatteryState, PointCloud2, PointField

SURFACE_FRAME = 'surface'
BODY_FRAME = 'base_link'

# /saw/contacts point layout: 24 bytes a point, every field naturally aligned.
CONTACT_DTYPE = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('normal_force', '<f4'),
                          ('tangential_force', '<f4'), ('link', '<u2'), ('surface', 'u1'),
                          ('slipping', 'u1')])
_ROS_TYPE = {'<f4': PointField.FLOAT32, '<u2': PointField.UINT16, 'u1': PointField.UINT8,
             '|u1': PointField.UINT8}
_NUMPY_TYPE = {PointField.INT8: 'i1', PointField.UINT8: 'u1', PointField.INT16: '<i2',
               PointField.UINT16: '<u2', PointField.INT32: '<i4', PointField.UINT32: '<u4',
               PointField.FLOAT32: '<f4', PointField.FLOAT64: '<f8'}
_CONTACT_LAYOUT: Mapping[str, Any] = CONTACT_DTYPE.fields or {}     # (structured: never None)
CONTACT_FIELDS = [PointField(name=name, offset=_CONTACT_LAYOUT[name][1],
                             datatype=_ROS_TYPE[_CONTACT_LAYOUT[name][0].str], count=1)
                  for name in CONTACT_DTYPE.names or ()]
BOTTOM, TOP = 0, 1


def dt_nanoseconds(dt: float) -> int:
    """Return the step as an integer number of nanoseconds (stamps are steps * this)."""
    ns = int(round(dt * NS_PER_S))
    if ns <= 0 or abs(ns - dt * NS_PER_S) > 1e-3:
        raise ValueError(f'time step {dt!r} s is not a whole number of nanoseconds')
    return ns


def time_msg(nanoseconds: int, out: Optional[Time] = None) -> Time:
    msg = Time() if out is None else out
    msg.sec, msg.nanosec = divmod(int(nanoseconds), NS_PER_S)
    return msg


def stamp_ns(stamp: Time) -> int:
    """Return a builtin_interfaces/Time message in ns (``cdr.header_stamp_ns``: from bytes)."""
    return stamp.sec * NS_PER_S + stamp.nanosec


def _header(msg, nanoseconds: int, frame: str):
    time_msg(nanoseconds, msg.header.stamp)
    msg.header.frame_id = frame
    return msg


def pose_msg(x: float, y: float, theta: float, nanoseconds: int,
             out: Optional[PoseStamped] = None) -> PoseStamped:
    """COM at (x, y, 0) in ``surface``, pitch theta as a rotation about z."""
    msg = _header(PoseStamped() if out is None else out, nanoseconds, SURFACE_FRAME)
    p, o = msg.pose.position, msg.pose.orientation
    p.x, p.y, p.z = float(x), float(y), 0.0
    half = 0.5 * float(theta)
    o.x, o.y, o.z, o.w = 0.0, 0.0, math.sin(half), math.cos(half)
    return msg


def pitch_of(quaternion) -> float:
    """Rotation about z of a quaternion that only rotates about z (the inverse of pose_msg)."""
    return 2.0 * math.atan2(quaternion.z, quaternion.w)


def twist_msg(vx: float, vy: float, w: float, nanoseconds: int,
              out: Optional[TwistStamped] = None) -> TwistStamped:
    """COM velocity (vx, vy, 0) and pitch rate (0, 0, w), in ``surface`` axes."""
    msg = _header(TwistStamped() if out is None else out, nanoseconds, SURFACE_FRAME)
    lin, ang = msg.twist.linear, msg.twist.angular
    lin.x, lin.y, lin.z = float(vx), float(vy), 0.0
    ang.x, ang.y, ang.z = 0.0, 0.0, float(w)
    return msg


def contact_points(tips: np.ndarray, normal: np.ndarray, tangential: np.ndarray,
                   touching: np.ndarray, slipping: np.ndarray) -> np.ndarray:
    """
    Structured (CONTACT_DTYPE) array of the tips in contact.

    Arrays are one scenario's (P,) columns in the Simulator's order: the n down tips (bottom
    surface, link 0 = frontmost) then the n up tips (top surface). ``tips`` is complex x + i y in
    the surface frame (the tip itself, pressed into the surface by its penetration).
    """
    index = np.flatnonzero(touching)
    n = len(tips) // 2
    points = np.zeros(len(index), CONTACT_DTYPE)
    where = tips[index]
    points['x'] = where.real
    points['y'] = where.imag
    points['normal_force'] = normal[index]
    points['tangential_force'] = tangential[index]
    points['link'] = index % n
    points['surface'] = index // n
    points['slipping'] = slipping[index]
    return points


def points_of(msg: PointCloud2) -> np.ndarray:
    """Read any little-endian PointCloud2 by its field names into a structured array."""
    if msg.is_bigendian:
        raise ValueError('big-endian point clouds are not supported')
    dtype = np.dtype({'names': [f.name for f in msg.fields],
                      'formats': [_NUMPY_TYPE[f.datatype] for f in msg.fields],
                      'offsets': [f.offset for f in msg.fields],
                      'itemsize': msg.point_step})
    count = msg.width * msg.height
    return np.frombuffer(bytes(msg.data), dtype=dtype, count=count)


def body_axes(fx: float, fy: float, theta: float):
    """
    Return a surface-frame force (fx, fy) in ``base_link`` axes.

    Turned by -theta (a moment about z does not change when the axes turn about z).
    """
    c, s = math.cos(theta), math.sin(theta)
    return c * fx + s * fy, -s * fx + c * fy


# -- the same messages as CDR bytes ---------------------------------------------------------------
# rclpy converts a Python message to C field by field: 15-40 us per message here, against 2-4 us
# to publish bytes. At six messages per step the simulator therefore publishes serialized
# messages, encoded below (XCDR1 little-endian, the encoding rmw_fastrtps uses and rosbag2
# records). Only the numbers change from step to step; the constant parts (frame ids, joint
# names, PointField list) are encoded once. tests/ros/test_conversions.py checks every encoder
# against rclpy's own serialization.


def _frame_block(frame: str, then_align: int) -> bytes:
    """frame_id string after the 8-byte stamp, padded for the next field's alignment."""
    return bytes(CdrWriter(8).string(frame).align(then_align).buf)


_CLOCK = struct.Struct('<4siI')
_POSE = struct.Struct(f'<4siI{len(_frame_block(SURFACE_FRAME, 8))}s7d')
_TWIST = struct.Struct(f'<4siI{len(_frame_block(SURFACE_FRAME, 8))}s6d')
_POINT = struct.Struct(f'<4siI{len(_frame_block(SURFACE_FRAME, 8))}s3d')
_WRENCH = struct.Struct(f'<4siI{len(_frame_block(BODY_FRAME, 8))}s6d')
_SURFACE_BLOCK = _frame_block(SURFACE_FRAME, 8)
_BODY_BLOCK = _frame_block(BODY_FRAME, 8)


def _split_ns(nanoseconds: int):
    return divmod(int(nanoseconds), NS_PER_S)


def clock_cdr(nanoseconds: int) -> bytes:
    return _CLOCK.pack(ENCAPSULATION, *_split_ns(nanoseconds))


def pose_cdr(x: float, y: float, theta: float, nanoseconds: int) -> bytes:
    half = 0.5 * theta
    return _POSE.pack(ENCAPSULATION, *_split_ns(nanoseconds), _SURFACE_BLOCK, x, y, 0.0,
                      0.0, 0.0, math.sin(half), math.cos(half))


def twist_cdr(vx: float, vy: float, w: float, nanoseconds: int) -> bytes:
    return _TWIST.pack(ENCAPSULATION, *_split_ns(nanoseconds), _SURFACE_BLOCK, vx, vy, 0.0,
                       0.0, 0.0, w)


def point_cdr(x: float, y: float, nanoseconds: int) -> bytes:
    """geometry_msgs/PointStamped (x, y, 0) in ``surface``."""
    return _POINT.pack(ENCAPSULATION, *_split_ns(nanoseconds), _SURFACE_BLOCK, x, y, 0.0)


def wrench_cdr(fx: float, fy: float, mz: float, nanoseconds: int) -> bytes:
    return _WRENCH.pack(ENCAPSULATION, *_split_ns(nanoseconds), _BODY_BLOCK, fx, fy, 0.0,
                        0.0, 0.0, mz)


class ContactsCdr:
    """
    PointCloud2 of CONTACT_DTYPE points as CDR.

    Header, height 1, width, the constant field list and point step, row_step, data, is_dense.
    """

    def __init__(self):
        w = CdrWriter(8).string(SURFACE_FRAME)
        w.u32(1)                                   # height
        self._head = bytes(w.buf)
        w = CdrWriter(w.end + 4)                  # after width
        w.u32(len(CONTACT_FIELDS))
        for f in CONTACT_FIELDS:
            w.string(f.name).u32(f.offset).u8(f.datatype).u32(f.count)
        w.u8(0)                                    # is_bigendian
        w.u32(CONTACT_DTYPE.itemsize)              # point_step
        w.align(4)
        self._fields = bytes(w.buf)
        self._step = CONTACT_DTYPE.itemsize

    def __call__(self, points: np.ndarray, nanoseconds: int) -> bytes:
        data = np.ascontiguousarray(points, CONTACT_DTYPE).tobytes()
        n = len(points)
        return b''.join((_CLOCK.pack(ENCAPSULATION, *_split_ns(nanoseconds)), self._head,
                         struct.pack('<I', n), self._fields,
                         struct.pack('<II', n * self._step, len(data)), data, b'\x01'))


class JointStateCdr:
    """
    JointState with fixed names as CDR.

    Position and velocity float64[len(names)]; effort empty, or with the helix's ``effort``
    (the motor torque, N m) first and NaN for the links, whose efforts the model does not
    resolve.
    """

    def __init__(self, names: Sequence[str]):
        self.count = len(names)
        w = CdrWriter(8).string(BODY_FRAME)
        w.u32(len(names))
        for name in names:
            w.string(name)
        w.u32(len(names)).align(8)
        self._head = bytes(w.buf)
        after_position = w.end + 8 * len(names)
        w = CdrWriter(after_position).u32(len(names)).align(8)
        self._middle = bytes(w.buf)
        after_velocity = after_position + len(self._middle) + 8 * len(names)
        self._tail = bytes(CdrWriter(after_velocity).u32(0).buf)
        w = CdrWriter(after_velocity).u32(len(names)).align(8)
        self._effort_head = bytes(w.buf)
        self._link_efforts = np.full(len(names) - 1, np.nan, '<f8').tobytes()

    def __call__(self, phase: float, omega: float, angles: np.ndarray, rates: np.ndarray,
                 nanoseconds: int, effort: Optional[float] = None) -> bytes:
        position = struct.pack('<d', phase) + np.ascontiguousarray(angles, '<f8').tobytes()
        velocity = struct.pack('<d', omega) + np.ascontiguousarray(rates, '<f8').tobytes()
        if len(position) != 8 * self.count or len(velocity) != 8 * self.count:
            raise ValueError(f'expected {self.count} joint values')
        parts = [_CLOCK.pack(ENCAPSULATION, *_split_ns(nanoseconds)), self._head, position,
                 self._middle, velocity]
        if effort is None:
            parts.append(self._tail)
        else:
            parts += [self._effort_head, struct.pack('<d', effort), self._link_efforts]
        return b''.join(parts)


def motor_msg(voltage: float, current: float, nanoseconds: int,
              out: Optional[BatteryState] = None) -> BatteryState:
    """
    Return the helix motor's supply as a BatteryState (/saw/motor), frame ``base_link``.

    ``voltage`` the supply voltage (V), ``current`` the motor current (A) drawn from it:
    BatteryState counts a discharge as negative, so the message carries -current. A NaN current
    (no motor modelled: the helix at constant frequency) stays NaN, "unmeasured" in
    BatteryState's terms, as do the charge, capacity, percentage and temperature.
    """
    msg = _header(BatteryState() if out is None else out, nanoseconds, BODY_FRAME)
    msg.voltage = float(voltage)
    msg.current = -float(current)
    for name in ('temperature', 'charge', 'capacity', 'design_capacity', 'percentage'):
        setattr(msg, name, math.nan)
    msg.power_supply_status = (BatteryState.POWER_SUPPLY_STATUS_DISCHARGING if current > 0.0
                               else BatteryState.POWER_SUPPLY_STATUS_UNKNOWN)
    msg.present = voltage > 0.0
    msg.location = 'helix motor'
    return msg


WALL_FIELDS = (PointField(name='x', offset=0, datatype=PointField.FLOAT32, count=1),
               PointField(name='y', offset=4, datatype=PointField.FLOAT32, count=1),
               PointField(name='z', offset=8, datatype=PointField.FLOAT32, count=1),
               PointField(name='deflection', offset=12, datatype=PointField.FLOAT32, count=1),
               PointField(name='surface', offset=16, datatype=PointField.UINT8, count=1))
WALL_DTYPE = np.dtype({'names': ['x', 'y', 'z', 'deflection', 'surface'],
                       'formats': ['<f4', '<f4', '<f4', '<f4', 'u1'],
                       'offsets': [0, 4, 8, 12, 16], 'itemsize': 20})


def walls_cloud(along: np.ndarray, deflection: np.ndarray, gap: float,
                nanoseconds: int) -> PointCloud2:
    """
    Return the bending walls' shape as a PointCloud2 in ``surface`` (the /saw/walls topic).

    One point per abscissa and wall: x, y of the deflected surface (the bottom at -w, the top at
    gap + w), z 0, the deflection w (m, > 0 away from the robot) and surface (0 bottom, 1 top).
    """
    m = len(along)
    points = np.zeros(2 * m, WALL_DTYPE)
    for surface, (level, sign) in enumerate(((0.0, -1.0), (gap, 1.0))):
        rows = points[surface * m:(surface + 1) * m]
        rows['x'] = along
        rows['y'] = level + sign * deflection[surface]
        rows['deflection'] = deflection[surface]
        rows['surface'] = surface
    msg = PointCloud2(height=1, width=2 * m, fields=list(WALL_FIELDS), is_bigendian=False,
                      point_step=WALL_DTYPE.itemsize, row_step=WALL_DTYPE.itemsize * 2 * m,
                      is_dense=True)
    msg.header.frame_id = SURFACE_FRAME
    time_msg(nanoseconds, msg.header.stamp)
    msg.data = points.tobytes()
    return msg


def walls_of(msg: PointCloud2) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return (along (m,), deflection (2, m)) of a /saw/walls cloud: ``walls_cloud`` read back.

    Read with numpy by the cloud's own field offsets and point_step (other fields are ignored).
    along: the bottom wall's x, increasing; deflection: bottom then top (the top's interpolated
    at those x when its points lie elsewhere), m, > 0 away from the robot. Raises ValueError for
    a cloud that is not one: fields x, y, z, deflection not FLOAT32 or surface not UINT8 (one
    each), data shorter than width * height * point_step, surface other than 0 and 1, fewer
    than two points a wall, repeated x or values not finite.
    """
    have = {f.name: f for f in msg.fields}
    wrong = [f.name for f in WALL_FIELDS if f.name not in have
             or (have[f.name].datatype, have[f.name].count) != (f.datatype, 1)]
    if wrong:
        names = {v: k for k, v in vars(PointField).items() if k.isupper() and isinstance(v, int)}
        got = ', '.join(f'{f.name} {names.get(f.datatype, f.datatype)}x{f.count}'
                        for f in msg.fields) or 'none'
        raise ValueError(f'fields {got}: expected x, y, z, deflection FLOAT32 and surface UINT8 '
                         f'(wrong or missing: {", ".join(wrong)})')
    order = '>' if msg.is_bigendian else '<'
    count = msg.width * msg.height
    try:
        dtype = np.dtype({'names': [f.name for f in WALL_FIELDS],
                          'formats': [order + 'f4'] * 4 + ['u1'],
                          'offsets': [have[f.name].offset for f in WALL_FIELDS],
                          'itemsize': msg.point_step})
        points = np.frombuffer(bytes(msg.data), dtype=dtype, count=count)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{count} points of {msg.point_step} bytes in {len(msg.data)} bytes '
                         f'of data: {exc}') from None
    if not np.isin(points['surface'], (BOTTOM, TOP)).all():
        raise ValueError('surface other than 0 (bottom) and 1 (top)')
    walls = []
    for surface in (BOTTOM, TOP):
        rows = np.sort(points[points['surface'] == surface], order='x')
        x, w = rows['x'].astype(float), rows['deflection'].astype(float)
        if len(x) < 2 or not (np.diff(x) > 0).all() or not np.isfinite(w).all():
            raise ValueError(f'{"bottom" if surface == BOTTOM else "top"} wall: two or more '
                             'points at distinct, finite x with finite deflections needed (got '
                             f'{len(x)} points)')
        walls.append((x, w))
    (along, bottom), (x_top, top) = walls
    if len(x_top) != len(along) or (x_top != along).any():
        top = np.interp(along, x_top, top)
    return along, np.stack([bottom, top])
