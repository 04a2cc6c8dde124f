"""The checks every guarded subscription runs (saw_ros.interface.message_checks), no ROS."""
import math

import cv2
import numpy as np
import pytest
from saw_ros.interface import message_checks as checks
from saw_ros.interface.message_checks import Refused

ENCODINGS = ('bgr8', 'rgb8')
MAX_PIXELS = 1280 * 720


def kind(call, *args, **kwargs):
    """Return the kind of the refusal ``call`` raises (None when it takes the message)."""
    try:
        call(*args, **kwargs)
    except Refused as exc:
        return exc.kind
    return None


@pytest.mark.parametrize('values, expected', [
    ((0.0, -1.5, 1e300), None),
    ((0.0, math.nan), 'not finite'),
    ((math.inf,), 'not finite'),
    ((-math.inf, 0.0), 'not finite'),
])
def test_finite(values, expected):
    assert kind(checks.finite, 'x', values) == expected


@pytest.mark.parametrize('x, y, q, expected', [
    (0.1, 0.02, (0.0, 0.0, 0.0, 1.0), None),
    (checks.POSITION_LIMIT, -checks.POSITION_LIMIT, (0.0, 0.0, 0.0, 1.0), None),   # the edge
    (np.nextafter(checks.POSITION_LIMIT, math.inf), 0.0, (0, 0, 0, 1.0), 'out of range'),
    (1e300, 0.0, (0, 0, 0, 1.0), 'out of range'),
    (math.nan, 0.0, (0, 0, 0, 1.0), 'not finite'),
    (0.0, 0.0, (0.0, 0.0, math.nan, 1.0), 'not finite'),
    (0.0, 0.0, (0.0, 0.0, 0.0, 0.0), 'not a rotation'),
])
def test_pose(x, y, q, expected):
    assert kind(checks.pose, x, y, q) == expected


def test_frame_names_what_it_expected():
    assert kind(checks.frame, 'surface', ('surface',)) is None
    with pytest.raises(Refused, match="frame_id 'map', expected 'surface'"):
        checks.frame('map', ('surface',))


@pytest.mark.parametrize('sizes, expected', [
    ((3, 3, 3, 3), None), ((3, 3, 0, 0), None), ((0, 0, 0, 0), None),
    ((3, 2, 3, 3), 'mis-sized arrays'), ((3, 3, 4, 3), 'mis-sized arrays'),
    ((1, 1, 1, 1000), 'mis-sized arrays'),
])
def test_joint_arrays(sizes, expected):
    assert kind(checks.joint_arrays, *sizes) == expected


@pytest.mark.parametrize('header, expected', [
    ((1280, 720, 'bgr8', 3840, 3840 * 720), None),
    ((1280, 720, 'rgb8', 4000, 4000 * 720), None),                  # rows padded
    ((0, 720, 'bgr8', 0, 0), 'empty image'),
    ((1280, 0, 'bgr8', 3840, 0), 'empty image'),
    ((1281, 720, 'bgr8', 3843, 3843 * 720), 'image too large'),     # one column past the limit
    ((100000, 100000, 'bgr8', 300000, 0), 'image too large'),       # before the data is looked at
    ((1280, 720, 'mono16', 2560, 2560 * 720), 'wrong encoding'),
    ((1280, 720, 'bgr8', 3839, 3839 * 720), 'step mismatch'),
    ((1280, 720, 'bgr8', 3840, 3840 * 720 - 1), 'data too short'),
])
def test_image_header(header, expected):
    assert kind(checks.image_header, *header, ENCODINGS, MAX_PIXELS) == expected


def _encoded(ext, w, h):
    ok, buf = cv2.imencode(ext, np.zeros((h, w, 3), np.uint8))
    assert ok
    return buf.tobytes()


@pytest.mark.parametrize('ext', ['.jpg', '.png'])
def test_compressed_size_is_read_from_the_header(ext):
    assert checks.compressed_size(_encoded(ext, 64, 48)) == (64, 48)


def test_compressed_image():
    jpeg = _encoded('.jpg', 64, 48)
    assert kind(checks.compressed_image, 'jpeg', jpeg, 64 * 48, 10 ** 6) is None
    assert kind(checks.compressed_image, 'jpeg', b'', 64 * 48, 10 ** 6) == 'empty image'
    assert kind(checks.compressed_image, 'jpeg', b'\x00' * 100, 64 * 48, 10 ** 6) == \
        'not an image'
    assert kind(checks.compressed_image, 'jpeg', jpeg, 64 * 48 - 1, 10 ** 6) == \
        'image too large'
    assert kind(checks.compressed_image, 'jpeg', jpeg, 64 * 48, len(jpeg) - 1) == \
        'image too large'
    # A JPEG header declaring 65535 x 65535 pixels (4 bytes of the SOF changed): refused unread.
    sof = jpeg.index(b'\xff\xc0')
    huge = jpeg[:sof + 5] + b'\xff\xff\xff\xff' + jpeg[sof + 9:]
    assert checks.compressed_size(huge) == (65535, 65535)
    assert kind(checks.compressed_image, 'jpeg', huge, MAX_PIXELS, 10 ** 6) == 'image too large'


def test_camera_matrix():
    k = [900.0, 0.0, 640.0, 0.0, 900.0, 360.0, 0.0, 0.0, 1.0]
    assert kind(checks.camera_matrix, k, 1280, 720, MAX_PIXELS) is None
    assert kind(checks.camera_matrix, k[:8], 1280, 720, MAX_PIXELS) == 'mis-sized arrays'
    assert kind(checks.camera_matrix, [math.nan] + k[1:], 1280, 720, MAX_PIXELS) == 'not finite'
    assert kind(checks.camera_matrix, [0.0] + k[1:], 1280, 720, MAX_PIXELS) == 'no focal length'
    assert kind(checks.camera_matrix, k, 1281, 720, MAX_PIXELS) == 'image too large'


def test_one_stray_stamp_is_refused_a_restarted_stream_is_taken():
    order = checks.StampOrder(restart_after=3)
    for t in (10, 20, 20, 30):
        order.check(t)                  # forward, and a repeat, taken
    assert kind(order.check, 0) == 'stamp went back'       # one pose at time 0
    order.check(40)                     # the stream goes on: the stray one changed nothing
    assert order.last == 40 and not order.restarted
    # A replay restarted: 3 stamps in a row behind the last, each later than the one before.
    assert kind(order.check, 1) == 'stamp went back'
    assert kind(order.check, 2) == 'stamp went back'
    order.check(3)
    assert order.restarted and order.last == 3
    order.check(4)
    assert not order.restarted


def test_a_streak_that_is_not_in_order_does_not_restart():
    order = checks.StampOrder(restart_after=3)
    order.check(100)
    for t in (5, 4, 3, 2, 1):           # going back among themselves: each starts a new streak
        assert kind(order.check, t) == 'stamp went back'
    assert order.last == 100


def test_a_leap_ahead_is_refused_with_max_leap():
    order = checks.StampOrder(restart_after=2, max_leap=10)
    order.check(0)
    order.check(10)                     # at the limit
    assert kind(order.check, 10 ** 18) == 'stamp leapt ahead'
    order.check(11)
    assert order.last == 11


def test_frame_gaps_count_the_frames_missing_by_their_stamps():
    gaps = checks.FrameGaps()
    period = 16_666_667                          # 60 fps, in ns
    stamps = [k * period for k in range(100) if k not in (10, 11, 12, 50)]
    reported = [gaps.add(t) for t in stamps]
    assert gaps.missed == 4 and gaps.period == period
    assert reported[10] == 3 and reported[47] == 1 and sum(reported) == 4
    # A frame late by less than half a period, and a replay from the start: nothing counted.
    assert gaps.add(stamps[-1] + period + period // 3) == 0
    assert gaps.add(0) == 0 and gaps.add(period) == 0 and gaps.missed == 4
