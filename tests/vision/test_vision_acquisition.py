"""
The tracker on footage it was not tuned on (issue 12).

A pink colour window that refuses red and orange, acquisition among clutter (third pink markers,
magenta, red), tracking through a pink thing passing the robot, lens distortion with its
calibration, compression; the scale from the marker spacing; TrackerConfig's fields on the command
line.
"""

import cv2
import numpy as np
import pytest

from saw_ros.cli.commands import track
from saw_ros.cli.main import main
from saw_ros.core import Scenario
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.frames import Renderer, RenderOptions
from saw_ros.vision.scene import Clutter, ORANGE_RED, SceneOptions
from saw_ros.vision.synthetic import evaluate, frames, hard_footage
from saw_ros.vision.tracker import detect, Tracker, TrackerConfig, TrackStatus
from saw_ros.vision.video import VideoWriter

SPACING = 0.32                  # m, the renderer's markers


# RGB, and whether a marker window should take it.
COLOURS = {
    'renderer pink': ((255, 60, 170), True), 'hot pink': ((255, 105, 180), True),
    'deep pink': ((255, 20, 147), True), 'fluorescent pink, warm light': ((240, 60, 110), True),
    'shocking pink': ((252, 15, 192), True), 'magenta': ((230, 20, 230), True),
    'red': ((255, 0, 0), False), 'camera red': ((200, 30, 40), False),
    'crimson': ((220, 20, 60), False), 'red-orange': ((255, 40, 20), False),
    'tomato': ((255, 99, 71), False), 'orange-red': ((255, 69, 0), False),
    'orange': ((255, 150, 20), False), 'violet': ((138, 43, 226), False),
}


def colour_chart(noise=0.0):
    """Discs of every colour on a grey wall, 120 px apart; their centres."""
    img = np.full((360, 1280, 3), 150, np.uint8)
    centres = {}
    for k, (name, (rgb, _)) in enumerate(COLOURS.items()):
        c = (60 + 160 * (k % 8), 90 + 180 * (k // 8))
        cv2.circle(img, c, 12, rgb[::-1], -1, cv2.LINE_AA)
        centres[name] = complex(*c)
    if noise:
        img = cv2.add(img, np.random.default_rng(1).normal(0, noise, img.shape).astype(np.int8),
                      dtype=cv2.CV_8U)
    return img, centres


@pytest.mark.parametrize('noise', [0.0, 6.0])
def test_default_window_is_pink_not_red(noise):
    img, centres = colour_chart(noise)
    found = detect(img)
    taken = {name for name, c in centres.items() if any(abs(f.p - c) < 2 for f in found)}
    assert taken == {name for name, (_, want) in COLOURS.items() if want}
    assert len(found) == len(taken)
    # The old window (hue 145..5) took the reds: what made the issue's user wait forever.
    old = detect(img, TrackerConfig(hue_min=145, hue_max=5))
    assert any(abs(f.p - centres['red-orange']) < 2 for f in old)
    assert any(abs(f.p - centres['red']) < 2 for f in old)
    # Colour signature (B - G) / (R - G): pink and magenta apart.
    colour = {name: next(f.colour for f in found if abs(f.p - centres[name]) < 2)
              for name in ('renderer pink', 'magenta')}
    assert colour['renderer pink'] == pytest.approx(110 / 195, abs=0.05)
    assert colour['magenta'] == pytest.approx(1.0, abs=0.05)


def _clutter_run(run, scene, config=TrackerConfig(), start=2.0, n=40, camera=CameraModel(),
                 hidden=lambda k: ()):
    s = run.scenario
    r = Renderer(s.robot, s.conditions.gap, camera, RenderOptions(), scene)
    tracker = Tracker(camera, config)
    out = []
    for k, t, pose, img in frames(run, r, [start + k / 60 for k in range(n)], hidden):
        res = tracker.update(img, t)
        front, back = r.marker_surface(pose)
        out.append((res, front, back))
    return out, tracker


@pytest.mark.parametrize('window', [(140, 172), (145, 5)])
def test_the_issues_orange_red_object_does_not_stop_acquisition(level_run, window):
    """
    The issue's footage: an orange-red object in a corner, larger and heavier than a marker.

    Measured from the first frame, with the new window (it is not pink) and with the old one (it is
    not the markers' colour or size, nor on their line).
    """
    scene = SceneOptions(clutter=(Clutter(ORANGE_RED, -0.12, 0.25, (0.08, 0.06), 'box'),
                                  Clutter((255, 40, 20), 0.75, -0.2, (0.05, 0.05))))
    config = TrackerConfig(hue_min=window[0], hue_max=window[1])
    out, tracker = _clutter_run(level_run, scene, config, n=30)
    assert all(res.ok for res, _, _ in out)
    assert all(abs(res.front - f) < 3e-4 and abs(res.back - b) < 3e-4 for res, f, b in out)


def test_third_pink_markers_on_the_robots_line(level_run):
    """
    Pink markers of the same size and colour on the robot's line, behind and ahead of it.

    The known spacing picks the pair at once; without it, the pair that moves as one rigid body
    does, once it has moved 4 px (ambiguous until then, never wrong). Both markers hidden for
    longer than reacquire_after: the lock is lost and what was learned of the pair with it (it
    may have been the wrong pair): acquired again the same way, once the pair has moved together
    for a few frames.
    """
    from saw_ros.vision.scene import HOT_PINK
    mid = Scenario().conditions.gap / 2
    pose = level_run.pose_at(2.0)
    scene = SceneOptions(clutter=(Clutter(HOT_PINK, pose.x - 0.16 - 0.07, mid),
                                  Clutter(HOT_PINK, pose.x + 0.16 + 0.14, mid)))
    out, _ = _clutter_run(level_run, scene, TrackerConfig(marker_spacing=SPACING))
    assert all(res.ok and abs(res.front - f) < 3e-4 and abs(res.back - b) < 3e-4
               for res, f, b in out)
    out, tracker = _clutter_run(level_run, scene, n=80,
                                hidden=lambda k: ('front', 'back') if 30 <= k < 65 else ())
    status = [res.status for res, _, _ in out]
    first = status.index(TrackStatus.OK)
    assert 1 <= first <= 8 and status[:first] == ['ambiguous'] * first
    assert status[first:60] == [TrackStatus.OK] * (30 - first) + ['both lost'] * 30
    # Lock lost (reacquire_after 30): the two pink things on the wall are a pair, but static
    # once the robot was seen moving; the robot's markers, back at frame 65, once they move.
    again = status.index(TrackStatus.OK, 65)
    assert again <= 65 + 8 and status[60:again] == ['ambiguous'] * (again - 60)
    assert status[again:] == [TrackStatus.OK] * (80 - again)
    assert all(abs(res.front - f) < 3e-4 and abs(res.back - b) < 3e-4
               for res, f, b in out if res.ok)
    assert tracker.counters.acquisitions == 2


def test_pink_things_next_to_a_tracked_marker(level_run, mirrored_tracking):
    """
    While tracking: a pink blob 20 px from the front marker is not it.

    The frame is ok, the front where it is; a pink disc overlapping the marker (one blob, twice its
    size) makes the front ambiguous; with the front hidden, two blobs equally near its expected
    place too.
    """
    r, tracker = mirrored_tracking
    pose = level_run.pose_at(2.5)
    front, _ = r.marker_surface(pose)
    fp, _ = r.marker_pixels(pose)

    def disc(img, p):
        cv2.circle(img, (int(round(p.real * 16)), int(round(p.imag * 16))), 7 * 16,
                   (170, 60, 255), -1, cv2.LINE_AA, 4)
        return img
    res = tracker.update(disc(r.render(pose), fp + 20), 2.5)
    assert res.ok and abs(res.front - front) < 3e-4
    res = tracker.update(disc(r.render(level_run.pose_at(2.52)), fp + 12j), 2.52)
    assert res.status == 'ambiguous' and res.front is None and res.back is not None
    pose = level_run.pose_at(2.54)
    fp, _ = r.marker_pixels(pose)
    img = disc(disc(r.render(pose, hidden=('front',)), fp + 12j), fp - 12j)
    res = tracker.update(img, 2.54)
    assert res.status == 'ambiguous' and res.front is None and res.position is None
    pose = level_run.pose_at(2.56)
    res = tracker.update(r.render(pose), 2.56)
    assert res.ok and abs(res.front - r.marker_surface(pose)[0]) < 3e-4


@pytest.mark.parametrize('compression', ['jpeg', 'mp4'])
def test_hard_footage_against_ground_truth(level_run, compression):
    """
    Track hard footage: speed within 0.5 %, both markers on 99 % of frames, never a wrong one.

    Clutter (red, orange-red, orange, magenta, three more pink markers, one crossing the marker
    line 25 px behind the back marker), lighting gradient and flicker, noise, motion blur, lens
    distortion (calibration given), compression. Both markers are measured on at least 99 % of
    the frames where both are in view.
    """
    camera, options, scene = hard_footage(level_run, compression, cross_at=3.2)
    config = TrackerConfig(marker_spacing=SPACING, steady_window=2.0)
    ev = evaluate(level_run, camera, options, config, start=2.5, end=5.0, scene=scene)
    assert ev.visible_frames >= 145
    assert ev.ok_frames_pct >= 99.0, [r.status for r in ev.results if not r.ok]
    assert ev.wrong_frames == 0
    assert ev.speed_error_pct <= 0.5, (ev.speed, ev.true_speed)
    assert ev.position_rms_mm <= 0.5


def test_lens_distortion_needs_its_calibration(level_run):
    """The same distorted footage, tracked with and without the lens calibration."""
    camera, options, _ = hard_footage(level_run)
    config = TrackerConfig(steady_window=2.0)
    options = RenderOptions()
    good = evaluate(level_run, camera, options, config, start=3.0, end=5.2)
    bad = evaluate(level_run, camera, options, config, start=3.0, end=5.2,
                   tracker_camera=CameraModel())
    assert good.position_rms_mm <= 0.1 and good.speed_error_pct <= 0.1
    assert bad.position_rms_mm > 10 * good.position_rms_mm
    assert bad.speed_error_pct > 5 * good.speed_error_pct


def test_config_fields_are_validated():
    for bad in ({'hue_min': 180}, {'hue_max': -1}, {'hue_min': 140.5}, {'sat_min': 300},
                {'roi': (10, 0, 5, 100)}, {'roi': (0, 0, 100)}, {'roi': (0.5, 0, 10, 10)},
                {'marker_spacing': 0.0}, {'marker_diameter': -0.01},
                {'marker_spacing': 0.01, 'marker_diameter': 0.02}, {'spacing_tolerance': 0.6},
                {'max_pitch': 2.0}, {'colour_tolerance': 0.0}, {'reacquire_after': 0}):
        with pytest.raises(ValueError):
            TrackerConfig(**bad)
    assert TrackerConfig(roi=[0, 10, 640, 700]).roi == (0, 10, 640, 700)


def test_track_options_come_from_tracker_config():
    import argparse
    import dataclasses
    p = argparse.ArgumentParser()
    track.add_arguments(p)
    args = p.parse_args(['v.mp4'])
    assert track.config_from_args(args) == TrackerConfig()
    names = {name for name, _, _ in track.config_options()}
    assert names == {f.name for f in dataclasses.fields(TrackerConfig)}
    args = p.parse_args(['v.mp4', '--roi', '0,100,1280,600', '--hue-min', '150',
                         '--marker-spacing-m', '0.3', '--marker-diameter-m', '0.01',
                         '--gate', '30'])
    config = track.config_from_args(args)
    assert (config.roi, config.hue_min, config.marker_spacing, config.marker_diameter,
            config.gate) == ((0, 100, 1280, 600), 150, 0.3, 0.01, 30.0)
    with pytest.raises(SystemExit):
        p.parse_args(['v.mp4', '--roi', '0,100,1280'])


def test_roi_limits_detection():
    img, centres = colour_chart()
    x = int(centres['hot pink'].real)
    found = detect(img, TrackerConfig(roi=(x - 40, 0, x + 40, 180)))
    assert [round(f.u) for f in found] == [x]
    assert detect(img, TrackerConfig(roi=(5000, 0, 6000, 100))) == []


def test_track_command_takes_the_scale_from_the_marker_spacing(level_run, tmp_path, capsys):
    """
    saw-ros track on cluttered footage with no ruler.

    --marker-spacing-m sets the scale (and says so); the speed is the true one.
    """
    camera, _, scene = hard_footage(level_run, compression='', cross_at=3.5)
    camera = CameraModel()                  # no lens here: the command's calibration is tested
    scene = SceneOptions(clutter=scene.clutter, gradient=0.3, flicker=0.1)   # in the bench
    s = level_run.scenario
    r = Renderer(s.robot, s.conditions.gap, camera, RenderOptions(noise=4), scene)
    times = [2.5 + k / 60 for k in range(170)]
    video = tmp_path / 'clutter.mp4'
    with VideoWriter(video, 60.0, (camera.width, camera.height)) as w:
        for _, _, _, img in frames(level_run, r, times):
            w.write(img)
    table = tmp_path / 'run.csv'
    assert main(['track', str(video), '--marker-spacing-m', '0.32', '--steady-window', '2',
                 '--csv', str(table)]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith('scale:'))
    assert 'from the marker spacing 0.32 m' in line
    scale = float(line.split()[1])
    assert scale == pytest.approx(1200.0, rel=0.002)
    # No --slope-deg: the pair is taken once it has moved together for a few frames, and the
    # track's direction is its motion's.
    ok = int(out.split(' ok ')[1].split(',')[0])
    assert 170 - 8 <= ok <= 170
    slope = next(x for x in out.splitlines() if x.startswith('slope:'))
    assert "from the markers' motion" in slope and abs(float(slope.split()[1])) < 0.3
    steady = float(next(x for x in out.splitlines() if x.startswith('steady')).split(': ')[1]
                   .split()[0]) / 100
    true = level_run.mean_speed(times[-1], 2.0)
    assert steady == pytest.approx(true, rel=0.005)
    # With a ruler, the ruler is the scale and the spacing is checked against it.
    assert main(['track', str(video), '--px-per-m', '1200', '--marker-spacing-m', '0.32']) == 0
    out = capsys.readouterr().out
    assert 'scale: 1200 px/m (--px-per-m)' in out
    spacing = float(next(x for x in out.splitlines() if x.startswith('marker spacing'))
                    .split(': ')[1].split()[0])
    assert spacing == pytest.approx(0.32, abs=0.001)
    # Neither: refused with the reason.
    assert main(['track', str(video)]) == 2
    assert '--marker-spacing-m' in capsys.readouterr().err
