"""Numpy -> message conversions of the simulator, without any node."""
import array
import math
from typing import Optional, Sequence

from geometry_msgs.msg import WrenchStamped
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from saw_ros.core import link_geometry, Scenario, Simulator
from saw_ros.core.kinematics import JointTable
from saw_ros.interface import urdf
from saw_ros.ros import conversions as conv
from sensor_msgs.msg import JointState, PointCloud2, PointField


# -- rclpy message builders: the reference every CDR encoder below is checked against ---------

def _header(msg, nanoseconds: int, frame: str):
    conv.time_msg(nanoseconds, msg.header.stamp)
    msg.header.frame_id = frame
    return msg


def clock_msg(nanoseconds: int, out: Optional[Clock] = None) -> Clock:
    msg = Clock() if out is None else out
    conv.time_msg(nanoseconds, msg.clock)
    return msg


def contacts_msg(points: np.ndarray, nanoseconds: int,
                 out: Optional[PointCloud2] = None) -> PointCloud2:
    """PointCloud2 (height 1, dense) of CONTACT_DTYPE points, in ``surface``."""
    msg = _header(PointCloud2() if out is None else out, nanoseconds, conv.SURFACE_FRAME)
    if out is None or len(msg.fields) != len(conv.CONTACT_FIELDS):
        msg.fields = conv.CONTACT_FIELDS
    msg.height = 1
    msg.width = len(points)
    msg.is_bigendian = False
    msg.point_step = conv.CONTACT_DTYPE.itemsize
    msg.row_step = conv.CONTACT_DTYPE.itemsize * len(points)
    msg.is_dense = True
    data = array.array('B')
    data.frombytes(np.ascontiguousarray(points, conv.CONTACT_DTYPE).tobytes())
    msg.data = data
    return msg


def point_msg(x: float, y: float, ns: int):
    from geometry_msgs.msg import PointStamped
    msg = PointStamped()
    conv.time_msg(ns, msg.header.stamp)
    msg.header.frame_id = conv.SURFACE_FRAME
    msg.point.x, msg.point.y = x, y
    return msg


def wrench_msg(fx: float, fy: float, mz: float, nanoseconds: int,
               out: Optional[WrenchStamped] = None) -> WrenchStamped:
    """Net contact force (fx, fy, 0) and moment (0, 0, mz) on the robot, in ``base_link``."""
    msg = _header(WrenchStamped() if out is None else out, nanoseconds, conv.BODY_FRAME)
    f, t = msg.wrench.force, msg.wrench.torque
    f.x, f.y, f.z = float(fx), float(fy), 0.0
    t.x, t.y, t.z = 0.0, 0.0, float(mz)
    return msg


def joint_state_msg(names: Sequence[str], phase: float, omega: float, angles: np.ndarray,
                    rates: np.ndarray, nanoseconds: int,
                    out: Optional[JointState] = None) -> JointState:
    """
    ``helix``: phase in [0, 2 pi) and speed omega = 2 pi f.

    Then ``base_link_joint`` and ``link_00``..: ``angles`` (rad, relative to the body x axis) and
    ``rates`` (rad/s).
    """
    msg = JointState() if out is None else out
    conv.time_msg(nanoseconds, msg.header.stamp)
    msg.header.frame_id = conv.BODY_FRAME
    if out is None or len(msg.name) != len(names):
        msg.name = list(names)
    position = array.array('d', (float(phase),))
    position.frombytes(np.ascontiguousarray(angles, float).tobytes())
    msg.position = position
    velocity = array.array('d', (float(omega),))
    velocity.frombytes(np.ascontiguousarray(rates, float).tobytes())
    msg.velocity = velocity
    return msg


def test_stamps_are_exact_integer_nanoseconds():
    dt_ns = conv.dt_nanoseconds(0.001)
    assert dt_ns == 1_000_000
    # 1 h of 1 kHz steps: no float drift, seconds roll over exactly.
    stamp = conv.time_msg(3_600_000 * dt_ns + 999 * dt_ns)
    assert (stamp.sec, stamp.nanosec) == (3600, 999_000_000)
    assert conv.stamp_ns(stamp) == 3_600_999_000_000
    assert clock_msg(2 * dt_ns).clock.nanosec == 2_000_000
    with pytest.raises(ValueError):
        conv.dt_nanoseconds(1e-10)


def test_pose_twist_wrench_frames_and_values():
    pose = conv.pose_msg(0.1, 0.0225, 0.3, 5_000_000)
    assert pose.header.frame_id == 'surface'
    assert (pose.pose.position.x, pose.pose.position.y, pose.pose.position.z) == (0.1, 0.0225, 0)
    q = pose.pose.orientation
    assert (q.x, q.y) == (0.0, 0.0) and math.isclose(q.z ** 2 + q.w ** 2, 1.0)
    assert math.isclose(conv.pitch_of(q), 0.3)
    twist = conv.twist_msg(0.05, -0.01, 0.2, 5_000_000)
    assert twist.header.frame_id == 'surface'
    assert (twist.twist.linear.x, twist.twist.linear.y, twist.twist.angular.z) == \
        (0.05, -0.01, 0.2)
    wrench = wrench_msg(1.0, 2.0, 0.01, 5_000_000)
    assert wrench.header.frame_id == 'base_link'
    assert (wrench.wrench.force.x, wrench.wrench.force.y, wrench.wrench.torque.z) == (1.0, 2.0,
                                                                                      0.01)
    # Filling a message in place gives the same message as building it.
    again = conv.pose_msg(0.1, 0.0225, 0.3, 5_000_000, out=conv.pose_msg(9, 9, 9, 1))
    assert again == pose


def _hand_points():
    # Two wave links; columns: down tips (bottom) of links 0, 1, then up tips (top) of 0, 1.
    tips = np.array([0.10 - 0.001j, 0.09 + 0.0j, 0.10 + 0.046j, 0.09 + 0.044j])
    normal = np.array([2.0, 0.0, 0.5, 0.0])
    tangential = np.array([-0.3, 0.0, 0.1, 0.0])
    touching = np.array([True, False, True, False])
    slipping = np.array([False, False, True, False])
    return conv.contact_points(tips, normal, tangential, touching, slipping)


def test_contact_points_only_tips_in_contact_with_link_and_surface():
    points = _hand_points()
    assert len(points) == 2
    assert points['link'].tolist() == [0, 0]
    assert points['surface'].tolist() == [conv.BOTTOM, conv.TOP]
    assert points['slipping'].tolist() == [0, 1]
    np.testing.assert_allclose(points['y'], [-0.001, 0.046], rtol=1e-6)
    assert (points['z'] == 0).all()


def test_contacts_cloud_is_self_describing_and_round_trips():
    points = _hand_points()
    msg = contacts_msg(points, 7_000_000)
    assert msg.header.frame_id == 'surface'
    assert (msg.height, msg.width, msg.is_dense, msg.is_bigendian) == (1, 2, True, False)
    assert msg.point_step == 24 and msg.row_step == 48 and len(msg.data) == 48
    types = {f.name: f.datatype for f in msg.fields}
    assert types == {'x': PointField.FLOAT32, 'y': PointField.FLOAT32, 'z': PointField.FLOAT32,
                     'normal_force': PointField.FLOAT32,
                     'tangential_force': PointField.FLOAT32, 'link': PointField.UINT16,
                     'surface': PointField.UINT8, 'slipping': PointField.UINT8}
    assert all(f.count == 1 for f in msg.fields)
    # Through CDR and back, read by field name.
    back = conv.points_of(deserialize_message(serialize_message(msg), PointCloud2))
    for name in points.dtype.names:
        np.testing.assert_array_equal(back[name], points[name])
    empty = contacts_msg(points[:0], 8_000_000, out=msg)
    assert (empty.width, len(empty.data), empty.row_step) == (0, 0, 0)


def test_wrench_is_the_core_net_force_and_moment_about_the_com():
    """
    The simulator publishes the net force and moment the core accelerated the body with.

    The sums over the tips in contact, the moment taken at the tip positions about the COM.
    """
    sim = Simulator(Scenario())
    for _ in range(299):
        sim.step()
    com = sim.q[:2, 0].copy()
    sim.step()
    c = sim.contacts
    fx, fy, mz = sim.contact_wrench[:, 0]
    side = sim.table.side
    fx_i, fy_i = c.tangential[0], -side * c.normal[0]
    assert math.isclose(fx, fx_i.sum(), rel_tol=1e-9, abs_tol=1e-9)
    assert math.isclose(fy, fy_i.sum(), rel_tol=1e-9, abs_tol=1e-9)
    r = sim.tip_positions[0] - complex(*com)
    assert math.isclose(mz, (r.real * fy_i - r.imag * fx_i).sum(), rel_tol=1e-6, abs_tol=1e-9)
    # In base_link axes: the same force turned by -theta.
    fxb, fyb = conv.body_axes(fx, fy, 0.5)
    assert math.isclose(fxb, math.cos(0.5) * fx + math.sin(0.5) * fy, rel_tol=1e-9)
    assert math.isclose(fyb, -math.sin(0.5) * fx + math.cos(0.5) * fy, rel_tol=1e-9)


def test_joint_table_matches_link_geometry():
    robot = Scenario().robot
    table = JointTable(robot)
    for phase in (0.0, 0.7, 3.0, 6.2):
        geo = link_geometry(robot, phase)
        angles, rates = table.angles_and_rates(phase, omega=2 * math.pi)
        np.testing.assert_allclose(angles[0], geo.base_angle, atol=1e-5)
        np.testing.assert_allclose(angles[1:], geo.angles, atol=1e-6)
        # Rates: derivative of the exact geometry along the phase (central difference); the
        # table's rate is its chord over one sample (2 pi / 4096): within 0.01 rad/s at 1 Hz.
        h = 1e-5
        ahead, behind = link_geometry(robot, phase + h), link_geometry(robot, phase - h)
        np.testing.assert_allclose(rates[1:], (ahead.angles - behind.angles) / (2 * h)
                                   * 2 * math.pi, atol=1e-2)
    names = urdf.joint_names(robot)[:2 + robot.wave_links]      # the angles come first
    assert names[:3] == ['helix', 'base_link_joint', 'link_00'] and names[-1] == 'link_18'
    angles, rates = table.angles_and_rates(0.7, 2 * math.pi)
    msg = joint_state_msg(names, 0.7, 2 * math.pi, angles, rates, 3_000_000)
    assert len(msg.name) == len(msg.position) == len(msg.velocity) == 21
    assert msg.position[0] == 0.7 and msg.velocity[0] == 2 * math.pi
    assert list(msg.position[1:]) == angles.tolist()


def test_cdr_encoders_match_rclpy_serialization():
    """
    The simulator publishes bytes.

    Each encoder must give exactly rclpy's CDR of the message built by the message functions.
    serialize_message may add trailing bytes and leaves padding bytes uninitialised: compare the
    prefix where ours is not padding (zero), and check that the bytes deserialize back to the same
    message.
    """
    from geometry_msgs.msg import PointStamped, PoseStamped, TwistStamped, WrenchStamped
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState

    ns = 12_345_000_000
    robot = Scenario().robot
    names = urdf.joint_names(robot)
    angles, rates = urdf.JointStateTable(robot).values_and_rates(1.3, 2 * math.pi)
    points = _hand_points()
    cases = [
        (conv.clock_cdr(ns), clock_msg(ns), Clock),
        (conv.pose_cdr(0.1, 0.02, -0.4, ns), conv.pose_msg(0.1, 0.02, -0.4, ns), PoseStamped),
        (conv.twist_cdr(0.1, -0.2, 0.3, ns), conv.twist_msg(0.1, -0.2, 0.3, ns), TwistStamped),
        (conv.point_cdr(0.25, -0.5, ns), point_msg(0.25, -0.5, ns), PointStamped),
        (conv.wrench_cdr(1.5, -2.5, 0.01, ns), wrench_msg(1.5, -2.5, 0.01, ns),
         WrenchStamped),
        (conv.ContactsCdr()(points, ns), contacts_msg(points, ns), PointCloud2),
        (conv.ContactsCdr()(points[:0], ns), contacts_msg(points[:0], ns), PointCloud2),
        (conv.JointStateCdr(names)(1.3, 2 * math.pi, angles, rates, ns),
         joint_state_msg(names, 1.3, 2 * math.pi, angles, rates, ns), JointState),
    ]
    for raw, msg, cls in cases:
        reference = np.frombuffer(serialize_message(msg), np.uint8)
        ours = np.frombuffer(raw, np.uint8)
        assert len(reference) >= len(ours), cls.__name__
        differ = np.flatnonzero(reference[:len(ours)] != ours)
        assert (ours[differ] == 0).all(), (cls.__name__, differ)
        assert deserialize_message(raw, cls) == msg, cls.__name__


def test_joint_state_carries_the_motor_torque_as_the_helix_effort():
    names = urdf.joint_names(Scenario().robot)
    angles, rates = urdf.JointStateTable(Scenario().robot).values_and_rates(0.7, 5.5)
    encode = conv.JointStateCdr(names)
    with_effort = deserialize_message(encode(0.7, 5.5, angles, rates, 3_000_000, 0.042),
                                      JointState)
    assert with_effort.name == names and with_effort.velocity[0] == 5.5
    assert len(with_effort.effort) == len(names) and with_effort.effort[0] == 0.042
    assert np.isnan(with_effort.effort[1:]).all()        # the links' efforts are not modelled
    np.testing.assert_array_equal(with_effort.position[1:], angles)
    np.testing.assert_array_equal(with_effort.velocity[1:], rates)
    without = deserialize_message(encode(0.7, 5.5, angles, rates, 3_000_000), JointState)
    assert len(without.effort) == 0 and list(without.position) == list(with_effort.position)


def test_motor_message_counts_the_drawn_current_negative():
    from sensor_msgs.msg import BatteryState
    msg = conv.motor_msg(4.0, 0.065, 10_000_000)
    assert (msg.voltage, msg.current) == (4.0, pytest.approx(-0.065))
    assert msg.header.frame_id == conv.BODY_FRAME and msg.header.stamp.nanosec == 10_000_000
    assert msg.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
    assert msg.present and math.isnan(msg.percentage) and math.isnan(msg.charge)
    # (float32 on the wire)
    assert deserialize_message(serialize_message(msg), BatteryState).current == pytest.approx(
        -0.065, rel=1e-7)
    constant = conv.motor_msg(0.0, math.nan, 20_000_000, out=msg)
    assert constant is msg and constant.voltage == 0.0 and math.isnan(constant.current)
    assert not constant.present
    assert constant.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_UNKNOWN


def test_walls_cloud_reads_back_and_other_clouds_are_refused():
    """/saw/walls: walls_of reads walls_cloud back (the camera's input) and refuses the rest."""
    along = np.linspace(-0.4, 0.6, 201)
    deflection = np.stack([3e-3 * np.exp(-((along - 0.1) / 0.02) ** 2),
                           -1e-4 * np.cos(along)])
    msg = deserialize_message(serialize_message(conv.walls_cloud(along, deflection, 0.045,
                                                                 5_000_000)), PointCloud2)
    got_along, got = conv.walls_of(msg)
    np.testing.assert_allclose(got_along, along, atol=1e-7)          # float32 on the wire
    np.testing.assert_allclose(got, deflection, atol=1e-9)
    assert got.shape == (2, 201) and got.dtype == np.float64
    # The same points in another order and layout (a field added, top wall first): same shape.
    points = conv.points_of(msg)[::-1]
    wide = np.zeros(len(points), [('surface', 'u1'), ('pad', '<f8'), ('deflection', '<f4'),
                                  ('x', '<f4'), ('y', '<f4'), ('z', '<f4')])
    for name in conv.WALL_DTYPE.names:
        wide[name] = points[name]
    fields = [PointField(name=n, offset=wide.dtype.fields[n][1], count=1,
                         datatype={'|u1': PointField.UINT8, '<f8': PointField.FLOAT64,
                                   '<f4': PointField.FLOAT32}[wide.dtype.fields[n][0].str])
              for n in wide.dtype.names]
    other = PointCloud2(height=1, width=len(wide), fields=fields, point_step=wide.itemsize,
                        row_step=wide.nbytes, is_dense=True)
    other.data = wide.tobytes()
    np.testing.assert_array_equal(conv.walls_of(other)[1], got)

    def refused(match, **change):
        bad = PointCloud2(height=msg.height, width=msg.width, fields=list(msg.fields),
                          point_step=msg.point_step, row_step=msg.row_step, is_dense=True)
        bad.data = bytes(msg.data)
        for k, v in change.items():
            setattr(bad, k, v)
        with pytest.raises(ValueError, match=match):
            conv.walls_of(bad)

    refused('wrong or missing: deflection', fields=[f for f in msg.fields
                                                    if f.name != 'deflection'])
    refused('wrong or missing: surface', fields=[
        f if f.name != 'surface' else PointField(name='surface', offset=16, count=1,
                                                 datatype=PointField.FLOAT32)
        for f in msg.fields])
    refused('fields none', fields=[])
    refused('bytes of data', width=msg.width + 1)                    # data too short
    refused('bytes of data', point_step=4)                           # fields beyond a point
    refused('top wall.*got 0 points', data=bytes(msg.data)[:20 * 201], width=201)  # bottom only
    refused('bottom wall.*got 1 points', data=bytes(msg.data)[20 * 200:], width=202)
    contacts = contacts_msg(_hand_points(), 7_000_000)               # another cloud
    with pytest.raises(ValueError, match='wrong or missing: deflection'):
        conv.walls_of(contacts)
