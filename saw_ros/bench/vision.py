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

Issue 32 figures: a camera that is not square to the robot's plane. The lens calibrated from a
board waved in front of it (``footage.BoardClip``, 1280x720, f = 1200 px, barrel k1 = -0.12):
``camera_calibration_focal_error_pct`` (<= 0.5) and ``camera_calibration_reprojection_px``
(RMS, <= 0.3); the robot filmed at yaw +-18 deg and pitch 10 deg through that lens
(``footage.Shot``), the plane from a board lying in it: ``tracker_perspective_speed_error_pct``
(the worse clip, <= 0.5); the same clips with only a ruler scale (at the picture's centre) or only
the marker spacing: ``tracker_perspective_uncalibrated_silent_wrong_pct`` (runs more than 1 %
wrong without a warning; goal 0).
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
        'tracker_silent_wrong_pct', 'camera_calibration_focal_error_pct',
        'camera_calibration_reprojection_px', 'tracker_perspective_speed_error_pct',
        'tracker_perspective_uncalibrated_silent_wrong_pct')
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
    return {**figures(quick), **perspective_figures(quick),
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


def perspective_figures(quick: bool = False) -> dict:
    """Return the issue-32 keys: the lens calibrated, and the clips with and without it."""
    from saw_ros.vision import calibration, perspective
    from saw_ros.vision.footage import BoardClip
    from saw_ros.vision.offline import measure_plane, track_video
    barrel = (-0.12, 0.02, 0.0, 0.0)
    board = calibration.Board.parse('chessboard:9x6:0.025')
    clip = BoardClip(board, width=1280, height=720, focal=1200.0, dist_coeffs=barrel,
                     views=12 if quick else 20, near=0.6, far=1.0)
    lens = calibration.calibrate(calibration.detect_views(clip.frames(), board, clip.size))
    out = {'camera_calibration_focal_error_pct': round(
        100.0 * abs(float(lens.focal) / clip.focal - 1), 4),
           'camera_calibration_reprojection_px': round(lens.rms_px, 4)}
    duration, window = (4.5, 2.0) if quick else (8.0, 4.0)
    config = TrackerConfig(steady_window=window)
    errors, silent, runs = [], 0, 0
    for yaw in ((18.0,) if quick else (18.0, -18.0)):
        # The robot starts left of the centre and ends right of it: a ruler at the centre is
        # wrong on both sides (scale = f / distance = 1200 px/m there, square).
        shot = Shot(duration=duration, yaw_deg=yaw, pitch_deg=10.0, dist_coeffs=barrel,
                    start_x=-0.3)
        kw = {'center_x': 0.0, 'center_y': shot.track_y}
        truth = shot.mean_speed()
        view, why = calibration.Detector(board).find(shot.board_still(board, at=-0.1 + 0.03j))
        if view is None:
            raise RuntimeError(f'the board lying in the plane was not found: {why}')
        lens_kw = lens.camera_kw()
        undistort = CameraModel(width=shot.width, height=shot.height, **lens_kw).undistort
        plane, _ = calibration.plane_from_view(view, undistort)
        results, _ = track_video(shot, dict(kw, plane=tuple(plane.ravel()), **lens_kw), config,
                                 slope_known=False)
        errors.append(100.0 * abs(_steady(results) / truth - 1))
        # Uncalibrated: a ruler at the picture's centre, or the marker spacing alone.
        results, tracker = track_video(shot, dict(kw, scale=shot.ruler_scale()), config,
                                       slope_known=False)
        along = None if tracker.slope_used is None else perspective.fit(
            *perspective.along_track(results, tracker.camera, tracker.slope_used))
        warned = bool(tracker.warnings) or (along is not None and along.significant)
        silent += abs(_steady(results) / truth - 1) > 0.01 and not warned
        measured = measure_plane(shot, kw, config, shot.spacing, slope_known=False)
        if measured is None:
            raise RuntimeError('the marker spacing was not measured on the perspective clip')
        results, tracker = track_video(shot, measured.camera_kw(kw), config, slope_known=False)
        silent += abs(_steady(results) / truth - 1) > 0.01 and not tracker.warnings
        runs += 2
    out['tracker_perspective_speed_error_pct'] = round(max(errors), 4)
    out['tracker_perspective_uncalibrated_silent_wrong_pct'] = round(100.0 * silent / runs, 2)
    return out


def _steady(results) -> float:
    """Return the last steady speed of a run (inf without one: as wrong as can be)."""
    return next((r.steady_speed for r in reversed(results) if r.steady_speed is not None),
                float('inf'))
