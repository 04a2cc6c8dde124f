"""CDR readers and writers of saw_ros.ros.cdr against rclpy's own serialisation."""
import math

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from saw_ros.core.params import RobotParams
from saw_ros.interface import urdf
from saw_ros.ros import cdr
from saw_ros.ros import conversions as conv
from sensor_msgs.msg import Image, JointState


def _joint_state(names, positions, ns, frame=''):
    msg = JointState()
    conv.time_msg(ns, msg.header.stamp)
    msg.header.frame_id = frame
    msg.name = list(names)
    msg.position = [float(v) for v in positions]
    msg.velocity = [0.5] * len(positions)
    return msg


@pytest.mark.parametrize('frame', ['', 'b', 'base_link', 'abcdefg'])
def test_joint_position_reads_the_named_joint_whatever_the_layout(frame):
    names = ['helix'] + [f'wave_link_{i}' for i in range(1, 4)] + ['x']
    values = [2.5, -0.1, 0.2, 0.3, 7.0]
    reader = cdr.JointPosition('helix')
    for ns in (1_000_000, 3_600_999_000_000):
        data = serialize_message(_joint_state(names, values, ns, frame))
        assert reader(data) == (ns, 2.5)
    # Another joint, another position in the list; the layout cache follows a change of names.
    assert cdr.JointPosition('x')(data) == (3_600_999_000_000, 7.0)
    moved = serialize_message(_joint_state(['a', 'helix'], [1.0, -4.25], 2_000_000, frame))
    assert reader(moved) == (2_000_000, -4.25)
    assert reader(serialize_message(_joint_state(['a'], [1.0], 5, frame))) == (5, None)
    # Named but without positions: None, not a neighbour's value.
    assert reader(serialize_message(_joint_state(['helix'], [], 6, frame))) == (6, None)


def test_joint_positions_reads_several_named_joints_none_where_missing():
    names = ['helix', 'link_00_flex', 'x', 'link_01_flex']
    reader = cdr.JointPositions(['link_00_flex', 'link_01_flex', 'link_02_flex', 'helix'])
    data = serialize_message(_joint_state(names, [2.5, -1e-3, 7.0, 2e-3], 9, 'base_link'))
    assert reader(data) == (9, [-1e-3, 2e-3, None, 2.5])
    # Positions shorter than the names: the joints past them have none.
    assert reader(serialize_message(_joint_state(names, [2.5, -1e-3], 10, ''))) == \
        (10, [-1e-3, None, None, 2.5])


def test_joint_position_of_the_simulators_encoder():
    names = urdf.joint_names(RobotParams(wave_links=4))
    encoder = conv.JointStateCdr(names)
    angles = np.linspace(-0.2, 0.2, len(names) - 1)
    data = encoder(1.234, 6.28, angles, np.zeros_like(angles), 7_000_000)
    msg = deserialize_message(data, JointState)
    i = list(msg.name).index('helix')
    assert cdr.JointPosition('helix')(data) == (7_000_000, msg.position[i])


def test_pose_stamped_ns_and_stamp_ns():
    for frame in ('surface', '', 'xy'):
        msg = conv.pose_msg(0.1, 0.0225, -0.3, 3_600_999_000_001)
        msg.header.frame_id = frame
        data = serialize_message(msg)
        t, x, y, theta = cdr.pose_stamped_ns(data)
        assert (t, x, y) == (3_600_999_000_001, 0.1, 0.0225)
        assert math.isclose(theta, -0.3)
        assert cdr.header_stamp_ns(data) == t
    clock = serialize_message(Clock(clock=conv.time_msg(42_000_000)))
    assert cdr.header_stamp_ns(clock) == 42_000_000
    assert cdr.header_stamp_ns(conv.clock_cdr(42_000_000)) == 42_000_000


def _image(width, height, encoding, frame, ns, step=None):
    rng = np.random.default_rng(width)
    channels = 3
    pixels = rng.integers(0, 256, (height, width, channels), dtype=np.uint8)
    msg = Image()
    conv.time_msg(ns, msg.header.stamp)
    msg.header.frame_id = frame
    msg.height, msg.width, msg.encoding = height, width, encoding
    msg.step = step or width * channels
    msg.data = pixels.tobytes()
    return msg, pixels


@pytest.mark.parametrize('frame,encoding', [('saw_camera', 'bgr8'), ('', 'rgb8'),
                                            ('cam', 'bgr8'), ('abcd', 'rgb8')])
def test_image_cdr_is_what_rclpy_serialises_and_image_view_reads_it(frame, encoding):
    msg, pixels = _image(7, 5, encoding, frame, 16_666_667)
    ours = cdr.ImageCdr(7, 5, encoding, 21, frame)(pixels, 16_666_667)
    theirs = serialize_message(msg)
    # Same message for rclpy; same length (rclpy's buffer may be longer, docs/ros-notes.md,
    # and leaves its alignment padding uninitialised, so the bytes are not compared).
    assert deserialize_message(ours, Image) == msg
    assert len(theirs) >= len(ours) == 4 + 8 + 4 + len(frame) + 1 + (-(len(frame) + 1) % 4) \
        + 8 + 4 + 5 + 3 + 4 + 4 + pixels.nbytes
    view = cdr.ImageView(ours)
    assert (view.stamp_ns, view.frame_id, view.height, view.width, view.encoding,
            view.is_bigendian, view.step) == (16_666_667, frame, 5, 7, encoding, 0, 21)
    assert bytes(view.data) == pixels.tobytes()
    assert cdr.ImageView(theirs).data.tobytes() == pixels.tobytes()
    with pytest.raises(ValueError):
        cdr.ImageCdr(7, 5, encoding, 21, frame)(pixels[:4], 0)
    with pytest.raises(ValueError):
        cdr.ImageView(ours[:-3])
    with pytest.raises(ValueError):
        cdr.ImageView(b'\x07' * 40)


def test_image_view_is_zero_copy():
    msg, pixels = _image(640, 360, 'bgr8', 'saw_camera', 1)
    data = bytearray(serialize_message(msg))
    view = cdr.ImageView(data)
    arr = np.frombuffer(view.data, np.uint8)
    data[-1] ^= 0xFF
    assert arr[-1] == pixels.ravel()[-1] ^ 0xFF


def test_restamp_gives_the_message_serialized_with_the_new_stamp():
    from sensor_msgs.msg import CameraInfo
    info = CameraInfo(width=1280, height=720, k=[900.0, 0, 640, 0, 900, 360, 0, 0, 1])
    info.header.frame_id = 'saw_camera'
    conv.time_msg(1_000_000_000, info.header.stamp)
    before = serialize_message(info)
    conv.time_msg(12_345_678_901, info.header.stamp)
    assert cdr.restamp(before, 12_345_678_901) == serialize_message(info)
    assert cdr.header_stamp_ns(cdr.restamp(before, 16_666_667)) == 16_666_667
