"""Track the two pink markers in a video file (a real robot's, or one the camera node wrote).

Needs the scale (--px-per-m: pixels per metre in the plane of the robot's motion, e.g. measured
on a ruler in the picture) and the slope of the surfaces as the level camera sees them
(--slope-deg). Prints the position, speed and pitch summary and the steady-state mean speed over
the last --steady-window seconds; --csv writes one row per frame (empty cells where nothing was
measured: lost or ambiguous markers are never filled in).

Example: saw-ros track run.mp4 --px-per-m 1200 --slope-deg 20 --csv run.csv
"""
from __future__ import annotations

import csv
import math
import sys
from pathlib import Path

import numpy as np

from ..vision.camera import CameraModel
from ..vision.tracker import OK, Tracker, TrackerConfig
from ..vision.video import VideoError, read_frames, video_info

HELP = 'track the two pink markers in a video: position, speed, pitch, steady speed'

COLUMNS = ('frame', 't', 'status', 'front_x', 'front_y', 'back_x', 'back_y', 'x', 'y',
           'pitch_deg', 'vx', 'vy', 'vx_smoothed', 'vy_smoothed', 'steady_speed')


def add_arguments(p):
    p.add_argument('video', help='video file (.mp4, .avi, ... anything OpenCV reads)')
    p.add_argument('--px-per-m', type=float, required=True,
                   help='pixels per metre in the plane of motion')
    p.add_argument('--slope-deg', type=float, default=0.0,
                   help='slope of the surfaces as the level camera sees them, degrees')
    p.add_argument('--center-x', type=float, default=0.33,
                   help='surface-frame x seen at the image centre, m (an origin; speeds do not '
                        'depend on it; the camera node default is 0.33)')
    p.add_argument('--center-y', type=float, default=0.0225,
                   help='surface-frame y seen at the image centre, m')
    p.add_argument('--mirror', action='store_true',
                   help='the robot travels towards the left of the image')
    p.add_argument('--fps', type=float, default=0.0,
                   help='frame rate, when the file does not say it or says it wrongly')
    p.add_argument('--steady-window', type=float, default=4.0,
                   help='window of the steady-state mean speed, s (default 4)')
    p.add_argument('--smooth-window', type=float, default=0.25,
                   help='window of the smoothed speed, s (default 0.25)')
    p.add_argument('--gate', type=float, default=40.0,
                   help='largest marker motion from its prediction between frames, px')
    p.add_argument('--csv', type=Path, default=None, help='write one row per frame here')


def track_video(path, camera_kw: dict, config: TrackerConfig, fps: float = 0.0):
    """FrameResults of every frame of a video; the camera's size comes from the file."""
    _, _, width, height = video_info(path)
    tracker = Tracker(CameraModel(width=width, height=height, **camera_kw), config)
    results = [tracker.update(frame, t) for _, t, frame in read_frames(path, fps or None)]
    return results, tracker


def _cells(k, r):
    def xy(p):
        return ('', '') if p is None else (f'{p.real:.6f}', f'{p.imag:.6f}')
    return [k, f'{r.t:.6f}', r.status, *xy(r.front), *xy(r.back), *xy(r.position),
            '' if r.pitch is None else f'{math.degrees(r.pitch):.4f}', *xy(r.velocity),
            *xy(r.velocity_smoothed), '' if r.steady_speed is None else f'{r.steady_speed:.6f}']


def run(args):
    from ..cli import UserError
    if not args.px_per_m > 0:
        raise UserError(f'--px-per-m = {args.px_per_m} must be > 0')
    try:
        config = TrackerConfig(steady_window=args.steady_window,
                               smooth_window=args.smooth_window, gate=args.gate)
        results, tracker = track_video(
            args.video, dict(scale=args.px_per_m, slope=math.radians(args.slope_deg),
                             center_x=args.center_x, center_y=args.center_y,
                             mirror=args.mirror), config, args.fps)
    except (VideoError, ValueError) as exc:
        raise UserError(str(exc)) from exc
    if args.csv is not None:
        with open(args.csv, 'w', newline='') as f:
            w = csv.writer(f)
            w.writerow(COLUMNS)
            for k, r in enumerate(results):
                w.writerow(_cells(k, r))
    c = tracker.counters
    ok = [r for r in results if r.status == OK]
    print(f'{args.video}: {c.frames} frames over {results[-1].t:.3f} s; ok {c.ok}, '
          f'front lost {c.front_lost}, back lost {c.back_lost}, ambiguous {c.ambiguous}, '
          f'longest run of bad frames {c.longest_not_ok}')
    if len(ok) < 2:
        print('too few frames with both markers: no position or speed', file=sys.stderr)
        return 1
    x = np.array([r.position.real for r in ok])
    pitch = np.degrees([r.pitch for r in ok])
    v = np.array([r.velocity.real for r in ok if r.velocity is not None])
    print(f'position x: {x[0] * 100:.2f} -> {x[-1] * 100:.2f} cm '
          f'(travel {(x[-1] - x[0]) * 100:.2f} cm in {ok[-1].t - ok[0].t:.3f} s)')
    if v.size:
        print(f'speed (instantaneous): mean {v.mean() * 100:.3f} cm/s, '
              f'min {v.min() * 100:.3f}, max {v.max() * 100:.3f}')
    print(f'pitch: mean {pitch.mean():.3f} deg, min {pitch.min():.3f}, max {pitch.max():.3f}')
    steady = results[-1].steady_speed if results[-1].ok else next(
        (r.steady_speed for r in reversed(ok) if r.steady_speed is not None), None)
    if steady is None:
        print(f'steady-state speed: not available (the run is shorter than '
              f'{args.steady_window * config.steady_fill:g} s of tracked frames)')
    else:
        print(f'steady-state speed (last {args.steady_window:g} s): {steady * 100:.3f} cm/s')
    if args.csv is not None:
        print(f'per-frame table: {args.csv}')
    return 0
