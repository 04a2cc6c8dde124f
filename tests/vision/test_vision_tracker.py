"""The tracker against rendered runs whose truth is known (the core simulation)."""
import math

import numpy as np
import pytest

from saw_ros.core import Scenario
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.frames import Renderer, RenderOptions
from saw_ros.vision.synthetic import evaluate, simulate_run
from saw_ros.vision.tracker import steady_speed, Tracker, TrackStatus


def test_clean_frames_meet_the_accuracy_goals(level_run):
    ev = evaluate(level_run, start=2.0)
    assert all(r.status == TrackStatus.OK for r in ev.results)
    assert ev.position_rms_mm <= 0.3
    assert ev.pitch_error_deg <= 0.5
    assert ev.speed_error_pct <= 0.5, (ev.speed, ev.true_speed)


def test_inclined_clean_frames():
    slope = math.radians(20)
    run = simulate_run(Scenario().with_values({'conditions.slope': slope}), 6.1)
    ev = evaluate(run, camera=CameraModel(slope=slope), start=2.0)
    assert ev.position_rms_mm <= 0.3 and ev.pitch_error_deg <= 0.5
    assert ev.speed_error_pct <= 0.5


@pytest.mark.parametrize('brightness', [0.6, 1.4])
def test_noise_blur_brightness_and_hidden_markers(level_run, brightness):
    def hidden(k):                      # 5 consecutive frames without each marker
        return ('front',) if 60 <= k < 65 else (('back',) if 150 <= k < 155 else ())
    ev = evaluate(level_run, options=RenderOptions(noise=10, exposure=1 / 60,
                                                   brightness=brightness, seed=7),
                  start=2.0, hidden=hidden)
    assert ev.speed_error_pct <= 2.0, (ev.speed, ev.true_speed)
    lost = [k for k, r in enumerate(ev.results) if r.status != TrackStatus.OK]
    assert lost == list(range(60, 65)) + list(range(150, 155))
    assert [ev.results[k].status for k in (60, 150)] == ['front lost', 'back lost']
    for k in lost:                       # nothing made up on those frames
        r = ev.results[k]
        assert r.position is None and r.pitch is None and r.velocity is None
    assert ev.lost_frames == 10


def test_frames_without_markers_give_no_position(level_run):
    s = Scenario()
    cam = CameraModel()
    r = Renderer(s.robot, s.conditions.gap, cam)
    tracker = Tracker(cam)
    blank = np.zeros((720, 1280, 3), np.uint8)
    out = [tracker.update(blank, 0.0),
           tracker.update(r.render(level_run.pose_at(1.0), ('front', 'back')), 1 / 60),
           tracker.update(None, 2 / 60)]
    assert [o.status for o in out] == ['both lost'] * 3
    assert all(o.position is None and o.front is None for o in out)
    assert tracker.counters.ok == 0 and tracker.counters.front_lost == 3


def test_front_and_back_keep_their_identity(level_run, mirrored_tracking):
    """
    The robot drives left to right through the picture.

    A mirrored camera (robot travelling left) must not swap them, and a third pink blob near a
    marker is not taken for it (more in test_vision_acquisition.py).
    """
    r, tracker = mirrored_tracking
    img = r.render(level_run.pose_at(2.5))
    fp, _ = r.marker_pixels(level_run.pose_at(2.5))
    u, v = int(fp.real) + 20, int(fp.imag)
    img[v - 6:v + 7, u - 6:u + 7] = (170, 60, 255)
    res = tracker.update(img, 2.5)
    front, back = r.marker_surface(level_run.pose_at(2.5))
    assert res.ok and abs(res.front - front) < 3e-4 and abs(res.back - back) < 3e-4


def test_steady_speed_helper():
    t = np.arange(0, 5, 1 / 60)
    assert steady_speed(t, 0.05 * t + 0.01, 4.0) == pytest.approx(0.05)
    assert steady_speed(t[:2], t[:2], 4.0) is None
