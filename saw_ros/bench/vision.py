"""
Issue 4 figures: tracker and renderer frames per second at 1280x720.

And the tracker's accuracy on clean rendered frames at the defaults against the simulation's ground
truth.

Issue 12 figures: the tracker on footage it was not tuned on (``synthetic.hard_footage``: red,
orange-red, orange and magenta clutter, three more hot-pink markers (behind the robot, ahead of
it, and one moving across in front of it), lighting gradient and flicker, sensor noise, motion
blur, barrel lens distortion with its calibration given, and the run through the .mp4 codec),
tracked as a user would (``TrackerConfig(marker_spacing=0.32)``, the robot's marker spacing):
``tracker_cluttered_speed_error_pct`` (steady speed against the true whole-cycle mean speed;
goal <= 0.5) and ``tracker_cluttered_ok_frames_pct`` (frames with both markers measured, % of
the frames where both are in full view; goal >= 99).

Issue 21 figures: footage shot the way users shoot it, drawn by our own generator
(``footage.Shot``: a textured room behind the robot, red objects, sensor noise, JPEG), tracked as
``saw-ros track`` does with the scale given and nothing else (the track's direction from the
markers' motion), against the truth: ``tracker_handheld_speed_error_pct`` (a camera drifting by
170 px over the clip and jittering by 1 px; goal <= 1), ``tracker_unknown_slope_speed_error_pct``
(a 20 degree climb; <= 1), ``tracker_cluttered_start_ok_frames_pct`` (the robot entering from
the left over red objects and two static pink discs: frames with both markers measured right, %
of those with both in full view; >= 95) and ``tracker_silent_wrong_pct`` (over those clips and
a partly hidden robot, a 3 % zoom, and the climb told the wrong slope: the share of runs that
would print a speed more than 2 % wrong without a warning; goal 0).
"""
import time

from saw_ros.core import Scenario
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.footage import Shot, track_shot
from saw_ros.vision.frames import Renderer
from saw_ros.vision.synthetic import evaluate, hard_footage, simulate_run
from saw_ros.vision.tracker import Tracker, TrackerConfig

KEYS = ('tracker_fps', 'render_fps', 'tracker_position_rms_mm', 'tracker_speed_error_pct',
        'tracker_pitch_error_deg', 'tracker_cluttered_speed_error_pct',
        'tracker_cluttered_ok_frames_pct', 'tracker_handheld_speed_error_pct',
        'tracker_unknown_slope_speed_error_pct', 'tracker_cluttered_start_ok_frames_pct',
        'tracker_silent_wrong_pct')
MARKER_SPACING = 0.32        # m, the renderer's markers at body x = +-0.16


def run(quick: bool = False) -> dict:
    scenario = Scenario()
    sim_run = simulate_run(scenario, 6.1)
    camera = CameraModel()
    renderer = Renderer(scenario.robot, scenario.conditions.gap, camera)
    n = 60 if quick else 240
    times = [2.0 + k / 60 for k in range(n)]
    poses = [sim_run.pose_at(t) for t in times]
    renderer.render(poses[0])
    start = time.perf_counter()
    frames = [renderer.render(p) for p in poses]
    render_fps = n / (time.perf_counter() - start)
    tracker = Tracker(camera)
    start = time.perf_counter()
    for t, f in zip(times, frames):
        tracker.update(f, t)
    tracker_fps = n / (time.perf_counter() - start)
    ev = evaluate(sim_run, camera, start=2.0)
    # The hard footage: from 0.5 s (the robot near the left edge, the clutter all in view) to
    # the end, steady speed over the last 4 s (quick: from 3.5 s, over 2 s).
    start, window = (3.5, 2.0) if quick else (0.5, 4.0)
    hard_camera, options, scene = hard_footage(sim_run, compression='mp4',
                                               cross_at=start + 1.0)
    hard = evaluate(sim_run, hard_camera, options,
                    TrackerConfig(marker_spacing=MARKER_SPACING, steady_window=window),
                    start=start, scene=scene)
    return {**figures(quick),
            'tracker_fps': round(tracker_fps, 1), 'render_fps': round(render_fps, 1),
            'tracker_position_rms_mm': round(ev.position_rms_mm, 4),
            'tracker_speed_error_pct': round(ev.speed_error_pct, 4),
            'tracker_pitch_error_deg': round(ev.pitch_error_deg, 4),
            'tracker_cluttered_speed_error_pct': round(hard.speed_error_pct, 4),
            'tracker_cluttered_ok_frames_pct': round(hard.ok_frames_pct, 2)}


def handheld(quick: bool = False):
    """Return the issue-21 clips: name -> (shot, slope given, config)."""
    duration, window = (4.5, 2.0) if quick else (8.0, 4.0)
    config = TrackerConfig(steady_window=window)
    return {
        'handheld': (Shot(duration=duration, drift=(170.0, 30.0), jitter=1.0), False, config),
        'climb': (Shot(duration=duration, slope_deg=20.0), False, config),
        # From the left edge: the front marker enters at 0.5 s, the back 4.6 s later.
        'entering': (Shot(duration=duration + 2.0, start_x=-0.72, pink_clutter=2), False,
                     config),
        'occluded': (Shot(duration=duration, occluder=True), False, config),
        'zoom': (Shot(duration=duration, zoom=0.03, drift=(60.0, 0.0)), False, config),
        'climb, slope given 0': (Shot(duration=duration, slope_deg=20.0), True, config),
    }


def figures(quick: bool = False) -> dict:
    """Return the issue-21 keys, from one run of every clip."""
    out = {}
    results = {}
    for name, (shot, slope_known, config) in handheld(quick).items():
        camera = shot.camera(slope_known and name != 'climb, slope given 0')
        results[name] = track_shot(shot, slope_known, config, camera)
    out['tracker_handheld_speed_error_pct'] = round(results['handheld'].speed_error_pct, 4)
    out['tracker_unknown_slope_speed_error_pct'] = round(results['climb'].speed_error_pct, 4)
    out['tracker_cluttered_start_ok_frames_pct'] = round(results['entering'].ok_frames_pct, 2)
    out['tracker_silent_wrong_pct'] = round(
        100.0 * sum(r.silent_wrong for r in results.values()) / len(results), 2)
    return out
