"""
The vision node on footage shot the way users shoot it (issue 21), through video_source.

Clips from our own generator (saw_ros.vision.footage: a textured room, red objects, a handheld
camera, a climb) -> video_source (a process, publishing /clock) -> the vision node (use_sim_time,
scale from px_per_m) -> /saw/tracking/*. The steady speed is the robot's, or the status says why
not: a camera that drifts is compensated; on a climb, with slope_from_motion, the slope comes
from the markers' motion (a wrong slope's warning is the tracker's test). Two pink
things at rest in view before the robot is (the issue's node published ~0 cm/s with status ok
for a robot at 7 cm/s: it had locked onto them and kept their spacing): WARN while they are
tracked, dropped for the robot once it moves in view. Every wait is on a condition.
"""
import math
import os

import numpy as np
import pytest

from saw_ros.graph.process import ManagedProcess, node_command, wait_for
from saw_ros.vision.footage import Shot
from saw_ros.vision.video import VideoWriter

pytestmark = [pytest.mark.ros, pytest.mark.slow]

# Full-size frames: the camera motion is measured on the background's texture, which needs the
# width (saw_ros.vision.egomotion warns below 960 px). No JPEG pass in the generator: the clips
# are MP4s, and the pass would cost a quarter of their rendering. 30 fps, as phones film by
# default and the footage campaign's tests take it: half the frames to render, play and track.
CLEAN = {'quality': 0, 'fps': 30.0}
STEADY = 2.0            # s, the vision node's steady window (the clips are 4 s)
CLIPS = {'handheld': Shot(duration=4.0, drift=(120.0, 20.0), jitter=1.0, **CLEAN),
         'climb': Shot(duration=4.0, slope_deg=20.0, **CLEAN),
         # Two static pink discs in view from the start, the robot's back marker from 3.4 s.
         'entering': Shot(duration=8.0, start_x=-0.6, pink_clutter=2, **CLEAN)}


@pytest.fixture(scope='module')
def clips(tmp_path_factory):
    folder = tmp_path_factory.mktemp('footage')
    out = {}
    for name, shot in CLIPS.items():
        path = folder / f'{name}.mp4'
        with VideoWriter(path, shot.fps, shot.size) as writer:
            for _, _, frame in shot.frames():
                writer.write(frame)
        out[name] = path
    return out


# The clips play at half speed (their stamps, on /clock, are the video's): what these tests ask
# is what the node makes of the footage, not whether it keeps 60 fps while the parallel suite's
# other workers hold both cores (at 1.0 it tracked 144 of 240 frames then; the bench measures
# its rate).
RATE = 0.5


def _run(path, shot, ros_context, tmp_path, **params):
    """Return (steady speed messages, status messages) of the vision node on a clip."""
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import TwistStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    from saw_ros.ros.nodes.vision import VisionNode
    from saw_ros.ros.qos import STREAM_QOS

    vision = VisionNode(context=ros_context, parameter_overrides=[
        Parameter('use_sim_time', value=True), Parameter('steady_window', value=STEADY),
        Parameter('px_per_m', value=shot.scale), Parameter('center_x', value=0.0),
        Parameter('center_y', value=shot.track_y),
        *(Parameter(k, value=v) for k, v in params.items())])
    probe = Node('probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    for n in (vision, probe):
        executor.add_node(n)
    got = {'steady': [], 'status': []}
    probe.create_subscription(TwistStamped, '/saw/tracking/steady_speed', got['steady'].append,
                              STREAM_QOS)
    probe.create_subscription(DiagnosticArray, '/saw/tracking/status', got['status'].append,
                              STREAM_QOS)
    source = ManagedProcess('video_source', node_command(
        'video_source', params={'path': str(path), 'publish_clock': True, 'rate': RATE,
                                'wait_for_subscribers': 1}), dict(os.environ), tmp_path)
    spin = lambda t: executor.spin_once(timeout_sec=t)   # noqa: E731
    frames = len(shot.times)
    try:
        assert wait_for(lambda: source.returncode is not None, 60.0, spin=spin), \
            source.output()[-2000:]
        assert source.returncode == 0, source.output()[-2000:]
        # (A frame or two may be dropped on a busy machine: wait for the end of the clip.)
        end = int((frames - 3) / shot.fps * 1e9)
        assert wait_for(lambda: got['status'] and _stamp_ns(got['status'][-1]) >= end, 20.0,
                        spin=spin), (len(got['status']), source.output()[-2000:])
        # A tracker slower than the stream (a busy machine) loses the oldest frames of its
        # queue: each loss is reported by the node (frames_missed, from the stamps' gaps).
        missed = int(_values(got['status'][-1])['frames_missed'])
        assert len(got['status']) + missed >= frames - 3, (len(got['status']), missed, frames)
        assert len(got['status']) >= frames // 2, (len(got['status']), missed, frames)
    finally:
        source.stop()
        executor.shutdown()
        for n in (vision, probe):
            n.destroy_node()
    return got['steady'], got['status']


def _stamp_ns(msg):
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def _level(name):
    from diagnostic_msgs.msg import DiagnosticStatus
    return getattr(DiagnosticStatus, name)


def _values(status):
    return {kv.key: kv.value for kv in status.status[0].values}


def _true_speed(shot, t_last):
    """Return the least-squares speed of the true centre over the node's steady window."""
    t = shot.times[shot.times >= t_last - STEADY - 1e-9]
    x = [0.5 * sum(shot.truth(float(s))).real for s in t]
    return np.polyfit(t, x, 1)[0]


def test_a_drifting_camera_gives_the_robots_speed(clips, ros_context, tmp_path):
    shot = CLIPS['handheld']
    steady, status = _run(clips['handheld'], shot, ros_context, tmp_path)
    messages = [s.status[0].message for s in status]
    assert messages.count('ok') >= len(messages) - 10, messages
    last = steady[-1]
    t_last = last.header.stamp.sec + last.header.stamp.nanosec * 1e-9
    # Without the camera's motion taken out, the speed would be 120 px / 4 s = 2.5 cm/s low.
    assert last.twist.linear.x == pytest.approx(_true_speed(shot, t_last), rel=0.01)
    values = _values(status[-1])
    assert float(values['camera_shift_px']) == pytest.approx(122.0, abs=4.0)
    assert values['warnings'] == '' and status[-1].status[0].level == _level('OK')


def test_on_a_climb_the_motion_gives_the_slope(clips, ros_context, tmp_path):
    # slope_from_motion: the slope used is the motion's, the speed the robot's, no warning. (A
    # climb told slope 0, cos(20) low and warned on every frame, is tracker behaviour:
    # tests/vision/test_vision_footage.py; the node's WARN level for a warning is the static
    # pair's test below.)
    shot = CLIPS['climb']
    steady, status = _run(clips['climb'], shot, ros_context, tmp_path, slope_from_motion=True)
    values = _values(status[-1])
    assert float(values['slope_deg']) == pytest.approx(20.0, abs=0.3)
    assert values['warnings'] == '' and status[-1].status[0].level == _level('OK')
    last = steady[-1]
    t_last = last.header.stamp.sec + last.header.stamp.nanosec * 1e-9
    assert last.twist.linear.x == pytest.approx(_true_speed(shot, t_last), rel=0.01)
    assert math.isfinite(last.twist.linear.x)


def test_a_static_pink_pair_is_never_a_trusted_speed(clips, ros_context, tmp_path):
    from diagnostic_msgs.msg import DiagnosticStatus
    shot = CLIPS['entering']
    steady, status = _run(clips['entering'], shot, ros_context, tmp_path)
    level = {(s.header.stamp.sec, s.header.stamp.nanosec): s.status[0].level for s in status}
    wrong = [m for m in steady if abs(m.twist.linear.x - shot.speed) > 0.02 * shot.speed]
    assert wrong, 'the static pair was never tracked: the test tests nothing'
    # Every speed more than 2 % off (the static pair's, ~0) came with a WARN status (of the
    # frames whose status arrived: on a busy machine a message may be lost).
    stamps = [(m.header.stamp.sec, m.header.stamp.nanosec) for m in wrong]
    seen = [level[k] for k in stamps if k in level]
    assert len(seen) >= 0.8 * len(stamps) and all(v == DiagnosticStatus.WARN for v in seen)
    values = _values(status[-1])
    assert 'static pair was dropped' in values['notes'] and values['warnings'] == ''
    last = steady[-1]
    t_last = last.header.stamp.sec + last.header.stamp.nanosec * 1e-9
    assert last.twist.linear.x == pytest.approx(_true_speed(shot, t_last), rel=0.01)
