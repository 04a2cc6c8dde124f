"""
Track the two pink markers in a video file (a real robot's, or one the camera node wrote).

The scale is either measured (--px-per-m: pixels per metre in the plane of the robot's motion,
e.g. on a ruler in the picture) or taken from the markers themselves (--marker-spacing-m: the
distance between the two markers' centres on the robot; a first pass over the video measures it
in pixels). With both, the ruler sets the scale and the spacing helps pick the markers out. Give
the slope of the surfaces as the level camera sees them (--slope-deg), and the lens calibration
when the lens distorts (--camera-matrix and --dist-coeffs, OpenCV's model). Prints which scale
was used, the frame counts, the position, speed and pitch summary and the steady-state mean speed
over the last --steady-window seconds; --csv writes one row per frame (empty cells where nothing
was measured: lost or ambiguous markers are never filled in). The tracker's options (colour
window, region of interest, marker size, ...) are TrackerConfig's, listed below.

VIDEO may also be a recording (a bag directory or its .mcap): its camera frames, JPEG
(/saw/camera/image_raw/compressed) or raw, timed by their stamps.

A camera that is not square to the robot's plane: calibrate its lens and the plane first
(saw-ros calibrate-camera), then --camera-calibration camera.yaml --plane plane.yaml (or
--plane-points): positions in metres on the plane, perspective and lens taken out. Without a
calibration the markers' spacing changing along the track is a warning (with --px-per-m), or the
scale is measured where the robot is (--marker-spacing-m alone).

Example: saw-ros track run.mp4 --px-per-m 1200 --slope-deg 20 --csv run.csv
         saw-ros track run.mp4 --camera-calibration camera.yaml --plane plane.yaml
         saw-ros track robot.mp4 --marker-spacing-m 0.32 --roi 0,200,1280,560
         saw-ros track bags/2026-11-23_16-33-09_demo --px-per-m 1200
"""
from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path
import sys
import typing

import numpy as np

from saw_ros.cli.checks import number, output_file, spec_number, video_input
from saw_ros.cli.errors import UserError
from saw_ros.core.params import spec_entries
from saw_ros.vision import calibration
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.offline import measure_plane, measure_scale, SCALE_FRAMES  # noqa: F401
from saw_ros.vision.offline import track_video
from saw_ros.vision.tracker import scale_from_spacing, TrackerConfig, TrackStatus
from saw_ros.vision.video import VideoError

HELP = 'track the two pink markers in a video: position, speed, pitch, steady speed'

COLUMNS = ('frame', 't', 'status', 'front_x', 'front_y', 'back_x', 'back_y', 'x', 'y',
           'pitch_deg', 'vx', 'vy', 'vx_smoothed', 'vy_smoothed', 'steady_speed')


def _numbers(kind, count=None):
    """Argparse type: comma-separated numbers (``count`` of them, or any of ``count``)."""
    def parse(text: str):
        try:
            values = tuple(kind(v) for v in text.split(','))
        except ValueError:
            raise ValueError(f'{text!r} is not a comma-separated list of numbers') from None
        if count is not None and len(values) not in count:
            raise ValueError(f'{text!r}: give {" or ".join(map(str, count))} numbers')
        return values
    parse.__name__ = 'list of numbers'
    return parse


def config_options():
    """
    (field name, flag, argparse keywords) for every TrackerConfig field, from the field's type.

    Default, unit and description (its spec()): the command line, the vision node and the dataclass
    cannot disagree.
    """
    hints = typing.get_type_hints(TrackerConfig)
    for f in dataclasses.fields(TrackerConfig):
        kind = hints[f.name]
        args = typing.get_args(kind)
        if typing.get_origin(kind) is typing.Union and type(None) in args:
            kind = next(a for a in args if a is not type(None))
        if typing.get_origin(kind) is tuple:
            item = typing.get_args(kind)[0]
            kw = {'type': _numbers(item, (len(typing.get_args(kind)),)),
                  'metavar': ','.join('ABCDEFGH'[:len(typing.get_args(kind))])}
        else:
            kw = {'type': kind}
        default = f.default
        shown = 'none' if default is None else f'{default:.6g}' if isinstance(default, float) \
            else default
        unit = f", {f.metadata['unit']}" if f.metadata['unit'] else ''
        kw.update(default=default, help=f"{f.metadata['description']}{unit} (default {shown})")
        yield f.name, f.metadata.get('flag', '--' + f.name.replace('_', '-')), kw


def add_arguments(p):
    p.add_argument('video', help='video file (.mp4, .avi, ... anything OpenCV reads), or a '
                   "recording's directory or .mcap (its camera frames)")
    g = p.add_argument_group('scale and camera')
    g.add_argument('--px-per-m', type=float, default=None,
                   help='pixels per metre in the plane of motion (a ruler in the picture); '
                        'without it --marker-spacing-m sets the scale')
    g.add_argument('--slope-deg', type=float, default=None,
                   help='slope of the surfaces as the level camera sees them, degrees (default: '
                        "the direction of the markers' own motion, printed)")
    g.add_argument('--center-x', type=float, default=CameraModel.center_x,
                   help=f'surface-frame x seen at the image centre, m (an origin; speeds do not '
                        f'depend on it; the camera node default is {CameraModel.center_x:g})')
    g.add_argument('--center-y', type=float, default=CameraModel.center_y,
                   help='surface-frame y seen at the image centre, m')
    g.add_argument('--mirror', action='store_true',
                   help='the robot travels towards the left of the image')
    g.add_argument('--fps', type=float, default=0.0,
                   help='frame rate, when the file does not say it or says it wrongly')
    g.add_argument('--camera-matrix', type=_numbers(float, (4,)), default=None,
                   metavar='FX,FY,CX,CY', help='camera matrix of the lens calibration, px '
                                               '(with --dist-coeffs)')
    g.add_argument('--dist-coeffs', type=_numbers(float, (4, 5, 8)), default=None,
                   metavar='K1,K2,P1,P2[,K3]', help='lens distortion coefficients (OpenCV '
                                                    'order): marker centres are undistorted')
    g.add_argument('--camera-calibration', type=Path, default=None, metavar='CAMERA.yaml',
                   help='the lens: a ROS camera calibration YAML (saw-ros calibrate-camera, or '
                        "ROS camera_calibration's): marker centres are undistorted")
    g.add_argument('--plane', type=Path, default=None, metavar='PLANE.yaml',
                   help='the plane of motion (saw-ros calibrate-camera --plane-output): '
                        "positions in metres on it, whatever the camera's angle to it")
    g.add_argument('--plane-points', default=None, metavar='U,V,X,Y;...',
                   help='the plane of motion from 4 or more picture points (px, as in the '
                        'video) with their plane coordinates (m, x along the track, y up)')
    g.add_argument('--csv', type=Path, default=None, help='write one row per frame here')
    g.add_argument('--plot', type=Path, default=None, metavar='PATH.png',
                   help='write the tracked position and speed over time to this PNG')
    g.add_argument('--quiet', action='store_true', help='no progress bar')
    m = p.add_argument_group('markers and tracker (saw_ros.vision.tracker.TrackerConfig)')
    for name, flag, kw in config_options():
        m.add_argument(flag, dest=name, **kw)


def config_from_args(args) -> TrackerConfig:
    return TrackerConfig(**{name: getattr(args, name) for name, _, _ in config_options()})


def _cells(k, r):
    def xy(p):
        return ('', '') if p is None else (f'{p.real:.6f}', f'{p.imag:.6f}')
    return [k, f'{r.t:.6f}', r.status.value, *xy(r.front), *xy(r.back), *xy(r.position),
            '' if r.pitch is None else f'{math.degrees(r.pitch):.4f}', *xy(r.velocity),
            *xy(r.velocity_smoothed), '' if r.steady_speed is None else f'{r.steady_speed:.6f}']


def _source(path, fps: float):
    """Return the frames to track: a recording's camera stream, a folder of frames, a video."""
    from saw_ros.analysis.bag_frames import BagFrames
    p = Path(path)
    # A killed recorder's bag has no metadata.yaml yet: its .mcap files make it a bag too.
    if p.suffix == '.mcap' or (p.is_dir() and ((p / 'metadata.yaml').exists()
                                               or any(p.glob('*.mcap')))):
        from saw_ros.bag.reader import BagReadError
        try:
            source = BagFrames(p)
        except BagReadError as exc:
            raise UserError(str(exc)) from None
        missing = source.reader.shortfall()
        if missing:           # tracked all the same: say that the end of the run is not there
            print(f'saw-ros track: warning: {missing}', file=sys.stderr)
        return source
    if p.is_dir():
        from saw_ros.vision.video import FrameFolder, frame_files, IMAGE_EXTENSIONS
        try:
            frame_files(p)
        except VideoError:
            raise UserError(f'VIDEO {path}: is a folder with no frame images '
                            f'({", ".join(IMAGE_EXTENSIONS)}): give a video file, a recording '
                            'or a folder of frames') from None
        if not fps > 0:
            raise UserError(f'VIDEO {path}: a folder of frames says no frame rate: give --fps')
        try:
            return FrameFolder(p, fps)
        except VideoError as exc:
            raise UserError(f'VIDEO {path}: {exc}') from None
    return video_input(path, 'VIDEO', fps)


def run(args):
    try:
        config = config_from_args(args)
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    if args.px_per_m is not None:
        (_, _, scale), = spec_entries(CameraModel, ('scale',))
        spec_number(args.px_per_m, '--px-per-m', scale)
    number(args.fps, '--fps', 'Hz (0: the rate the file says)', 0.0, None)
    (_, _, slope), = spec_entries(CameraModel, ('slope',))
    if args.slope_deg is not None:
        spec_number(args.slope_deg, '--slope-deg', slope, math.pi / 180.0, 'deg')
    number(args.center_x, '--center-x', 'm')
    number(args.center_y, '--center-y', 'm')
    if args.csv is not None:
        output_file(args.csv, '--csv', ('.csv',))
    if args.plot is not None:
        output_file(args.plot, '--plot', ('.png',))
    if args.plane is not None and args.plane_points is not None:
        raise UserError('give the plane once: --plane (a file) or --plane-points')
    planar = args.plane is not None or args.plane_points is not None
    if planar and args.px_per_m is not None:
        raise UserError('--px-per-m and a plane (--plane, --plane-points) both set the scale: '
                        'the plane measures in metres, leave --px-per-m out')
    if not planar and args.px_per_m is None and config.marker_spacing is None:
        raise UserError('give the scale: --px-per-m (pixels per metre, from a ruler in the '
                        "picture), --marker-spacing-m (the markers' distance on the robot) or "
                        'the plane (--plane, --plane-points)')
    if (args.dist_coeffs is None) != (args.camera_matrix is None):
        raise UserError('--dist-coeffs and --camera-matrix go together (the lens calibration)')
    if args.camera_calibration is not None and args.dist_coeffs is not None:
        raise UserError('give the lens once: --camera-calibration or --camera-matrix with '
                        '--dist-coeffs')
    slope_known = args.slope_deg is not None
    camera_kw = {'slope': math.radians(args.slope_deg or 0.0), 'center_x': args.center_x,
                 'center_y': args.center_y, 'mirror': args.mirror}
    if args.dist_coeffs is not None:
        camera_kw.update(dist_coeffs=args.dist_coeffs, dist_matrix=args.camera_matrix)
    source = _source(args.video, args.fps)
    lens = None
    try:
        if args.camera_calibration is not None:
            lens = calibration.read_lens(args.camera_calibration)
            if (lens.width, lens.height) != tuple(source.size):
                raise UserError(f'--camera-calibration {args.camera_calibration}: calibrated '
                                f'for {lens.width}x{lens.height} pictures, the video is '
                                f'{source.size[0]}x{source.size[1]} (the same camera and mode '
                                'are needed)')
            camera_kw.update(lens.camera_kw())
        if planar:
            camera_kw['plane'] = tuple(_plane(args, camera_kw, source.size).ravel())
            scale = CameraModel(width=source.size[0], height=source.size[1], **camera_kw).scale
            scale_text = (f'scale: metres on the plane ({args.plane or "--plane-points"}; '
                          f"{scale:.2f} px/m at the picture's centre)")
        elif args.px_per_m is not None:
            scale = args.px_per_m
            scale_text = f'scale: {scale:g} px/m (--px-per-m)'
        else:
            measured = measure_plane(source, camera_kw, config, config.marker_spacing,
                                     slope_known=slope_known)
            if measured is None:
                raise UserError('the marker spacing could not be measured: no frame with both '
                                'markers told apart (try --roi around the track, or give '
                                '--px-per-m)')
            scale, n, spread = measured.scale, measured.frames, measured.spread
            camera_kw = measured.camera_kw(camera_kw)
            if measured.plane is not None:
                along = measured.along
                scale_text = (f'scale: from the marker spacing {config.marker_spacing:g} m '
                              f'(--marker-spacing-m) where the robot is, frame by frame: '
                              f"{scale:.2f} px/m at the picture's centre, changing by "
                              f"{100 * along.change:+.1f} % over the robot's travel ({n} "
                              'frames; perspective: the camera is not square to the plane, '
                              'calibrate the plane for the best measure)')
            else:
                scale_text = (f'scale: {scale:.2f} px/m from the marker spacing '
                              f'{config.marker_spacing:g} m (--marker-spacing-m; median of {n} '
                              f'frames, spread +-{spread:.2f} px)')
        results, tracker = track_video(Progress(source, args.quiet), dict(camera_kw, scale=scale),
                                       config, slope_known=slope_known)
    except (VideoError, ValueError) as exc:
        raise UserError(str(exc)) from exc
    if args.csv is not None:
        args.csv.parent.mkdir(parents=True, exist_ok=True)
        with open(args.csv, 'w', newline='') as f:
            w = csv.writer(f)
            w.writerow(COLUMNS)
            for k, r in enumerate(results):
                w.writerow(_cells(k, r))
    c = tracker.counters
    # Frames of a static pair dropped for the moving robot are not the robot's.
    since = -math.inf if tracker.switched_at is None else tracker.switched_at
    ok = [r for r in results if r.status is TrackStatus.OK and r.t > since]
    print(f'{args.video}: {c.frames} frames over {results[-1].t:.3f} s; ok {c.ok}, '
          f'front lost {c.front_lost}, back lost {c.back_lost}, ambiguous {c.ambiguous}, '
          f'partly hidden {c.partial}, longest run of bad frames {c.longest_not_ok}')
    print(scale_text)
    if slope_known:
        print(f'slope: {args.slope_deg:g} deg (--slope-deg)')
    elif tracker.slope_used is None:
        print("slope: not known (the markers did not move far enough to show the track's "
              'direction; give --slope-deg)')
    for note in tracker.notes:
        print(note)
    warnings = list(tracker.warnings)
    if args.px_per_m is not None:
        warnings += scale_warnings(results, tracker, args.px_per_m, config.marker_spacing)
    for warning in warnings:
        print(f'saw-ros track: warning: {warning}', file=sys.stderr)
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
    steady = next((r.steady_speed for r in reversed(ok) if r.steady_speed is not None), None)
    if steady is None:
        print(f'steady-state speed: not available (the run is shorter than '
              f'{config.steady_window * config.steady_fill:g} s of tracked frames): track a '
              f'longer clip, or give a shorter --steady-window)')
    else:
        print(f'steady-state speed (last {config.steady_window:g} s): {steady * 100:.3f} cm/s')
    if args.csv is not None:
        print(f'per-frame table: {args.csv}')
    if args.plot is not None:
        plot(args.plot, args.video, results, steady, config)
        print(f'plot: {args.plot}')
    return 0


def _plane(args, camera_kw: dict, size) -> np.ndarray:
    """Return the plane's homography of --plane or --plane-points (ideal pixels -> m)."""
    try:
        if args.plane is not None:
            return calibration.read_plane(args.plane)
        image, plane = calibration.parse_plane_points(args.plane_points)
        lens = CameraModel(width=size[0], height=size[1],
                           **{k: v for k, v in camera_kw.items()
                              if k in ('dist_coeffs', 'dist_matrix')})
        ideal = lens.undistort(image[:, 0] + 1j * image[:, 1])
        h, rms = calibration.plane_from_points(np.stack([ideal.real, ideal.imag], -1), plane)
    except calibration.CalibrationError as exc:
        raise UserError(str(exc)) from None
    if len(image) > 4:
        print(f'plane: {len(image)} points, RMS {1000 * rms:.2f} mm off the homography')
    return h


def scale_warnings(results, tracker, px_per_m: float, spacing) -> list:
    """
    Return what a given scale gets wrong, one line each (empty: nothing seen).

    A given marker spacing that the scale measures otherwise, by more than the spacing's own
    spread over the frames.
    """
    out = []        # (a perspective along the track: the tracker's own warnings say it)
    if spacing is not None:
        check = scale_from_spacing(results, spacing)
        if check is not None:
            from_spacing, n, spread = check
            print(f'marker spacing measured with that scale: '
                  f'{spacing * from_spacing / px_per_m:.4f} m (--marker-spacing-m {spacing:g}; '
                  f'{n} frames)')
            # the spacing's own uncertainty: its spread over the frames, or 0.2 % at least
            allowed = max(spread / spacing, 0.002 * from_spacing)
            if abs(from_spacing - px_per_m) > allowed:
                out.append(f'--px-per-m {px_per_m:g} disagrees with the marker spacing: '
                           f'{spacing:g} m is {from_spacing:.1f} px/m (+-{allowed:.1f}, median '
                           f'of {n} frames), {100 * (px_per_m / from_spacing - 1):+.1f} %: check '
                           "the ruler, the spacing, or the camera's angle to the plane")
    return out


class Progress:
    """A frame source that shows a progress bar on stderr while its frames are read."""

    def __init__(self, source, quiet: bool = False):
        self.source, self.quiet = source, quiet

    @property
    def size(self):
        return self.source.size

    def frames(self):
        from tqdm import tqdm
        total = getattr(self.source, 'count', None)
        if total is None:
            from saw_ros.vision.video import video_info
            total = video_info(self.source.path)[1] or None
        # disable=None: only on a terminal; logs and pipes get no carriage-return lines.
        with tqdm(total=total, unit='frame', desc='track', file=sys.stderr, leave=False,
                  disable=True if self.quiet else None) as bar:
            for item in self.source.frames():
                yield item
                bar.update()


def plot(path, video, results, steady, config) -> None:
    """--plot: tracked position, instantaneous and smoothed speed, the steady-state speed."""
    from saw_ros.cli.plot import write_time_plot
    ok = [r for r in results if r.ok]
    fast = [r for r in ok if r.velocity is not None]
    smooth = [r for r in ok if r.velocity_smoothed is not None]
    levels = [] if steady is None else [(f'steady {100 * steady:.2f} cm/s', steady)]
    t_end = results[-1].t
    window = None if steady is None else (max(results[0].t, t_end - config.steady_window), t_end)
    write_time_plot(path, f'tracking {Path(str(video)).name}: {len(ok)} of {len(results)} '
                    f'frames with both markers', [('tracked', [r.t for r in ok],
                                                   [r.position.real for r in ok])],
                    [('instantaneous', [r.t for r in fast], [r.velocity.real for r in fast]),
                     ('smoothed', [r.t for r in smooth],
                      [r.velocity_smoothed.real for r in smooth])], levels, window)
