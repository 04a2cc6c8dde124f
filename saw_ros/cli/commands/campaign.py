"""
The paper's validation campaign.

20 conditions (slopes -20..20 deg x 4, 5, 6, 7 V, gap 45 mm) through simulation, virtual camera and
tracker; a table (CSV, markdown), the mean relative error per voltage and overall, speed against
slope and voltage with linear fits (Figure 17) and the AR comparison (Figure 18).

For example:
  saw-ros campaign                                   # the paper's 20 conditions
      # -> out/campaign/paper (with --videos: out/campaign/footage); --out docs/campaign
      # refreshes the committed copy
  saw-ros campaign --slopes=-20,0,20 --voltages 6,7 --out /tmp/c   # "=" before negatives
  saw-ros campaign --set motor.hz_per_volt=0.22      # calibrate the motor
  saw-ros campaign --videos samples/footage/manifest.csv
      # your robot's footage: one row per run (video, slope_deg, voltage_V or frequency_hz,
      # px_per_m or marker_spacing_m, notes); each video tracked, the condition simulated
  saw-ros campaign --scheduler tcp://host:8786       # simulate and track on a Dask cluster
"""
import math
from pathlib import Path
import sys
import time

from saw_ros.analysis.campaign import (PAPER_SLOPES_DEG, PAPER_VOLTAGES, run_campaign,
                                       summarise, write_outputs)
from saw_ros.analysis.compare import load_reference
from saw_ros.analysis.shown import finite, shown
from saw_ros.cli.checks import output_dir, spec_numbers, text_file, video_input
from saw_ros.cli.commands.simulate import add_scenario_arguments, scenario_from_args
from saw_ros.cli.errors import UserError
from saw_ros.cli.pool import add_pool_arguments, pool_from_args
from saw_ros.core.params import ParameterError
from saw_ros.interface.config import config_path

HELP = "run the paper's 20-condition validation campaign (simulation, camera, tracker)"
# The two modes each have their own folder: one does not overwrite the other's table.
DEFAULT_OUT = Path('out/campaign/paper')
FOOTAGE_OUT = Path('out/campaign/footage')


def add_arguments(p):
    p.add_argument('--slopes', default=','.join(f'{s:g}' for s in PAPER_SLOPES_DEG),
                   help='slopes in degrees, comma-separated; write --slopes=-20,0 when the list '
                   'starts with a minus (default: -20,-10,0,10,20)')
    p.add_argument('--voltages', default=','.join(f'{v:g}' for v in PAPER_VOLTAGES),
                   help='motor voltages, comma-separated (default: 4,5,6,7)')
    p.add_argument('--out', type=Path, default=None,
                   help=f'output folder (default {DEFAULT_OUT}, with --videos {FOOTAGE_OUT})')
    p.add_argument('--videos', type=Path, default=None, metavar='MANIFEST.csv',
                   help='recorded runs instead of the virtual camera: a CSV with columns video '
                   '(a file, or a folder of frame images with its fps), slope_deg, voltage_V or '
                   'frequency_hz, px_per_m or marker_spacing_m, fps, notes, and for a camera '
                   'not square to the robot camera_calibration and plane (saw-ros '
                   "calibrate-camera's files; paths relative to it); --slopes/--voltages/"
                   '--reference do not apply')
    p.add_argument('--reference', type=Path, default=None,
                   help="CSV of measured speeds/ARs (default: the paper's stated points)")
    add_pool_arguments(p)
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    add_scenario_arguments(p)


def run_videos(args):
    """--videos: track each recorded run, simulate its condition, compare (analysis.footage)."""
    from saw_ros.analysis.footage import ManifestError, load_manifest, run_footage, \
        write_footage_outputs
    from saw_ros.vision.video import VideoError
    base = scenario_from_args(args)
    out = output_dir(args.out or FOOTAGE_OUT, '--out')
    text_file(args.videos, '--videos', 'manifest (CSV)')
    start = time.perf_counter()
    try:
        runs = load_manifest(args.videos)
        for r in runs:               # every video readable before the first is tracked
            if r.video.is_dir():     # a folder of frames: every image must decode
                from saw_ros.vision.video import FrameFolder
                FrameFolder(r.video, r.fps)
            else:
                video_input(r.video, f'--videos {args.videos}: video')
            try:
                r.scenario(base)
            except ParameterError as exc:
                raise UserError(f'--videos {args.videos}: {r.video.name}: {exc}') from None
        results = run_footage(runs, base)
    except (ManifestError, VideoError) as exc:
        raise UserError(str(exc)) from exc
    paths = write_footage_outputs(results, out)
    summary = summarise([r.condition for r in results])
    print(f'{len(results)} videos in {time.perf_counter() - start:.1f} s')
    for r in results:
        c, m = r.condition, r.measured
        measured = (f'{100 * c.v_tracked:.3f} cm/s (AR {c.ar_tracked:.4f}, ' if
                    finite(c.v_tracked) else 'no speed (') + f'{m.frames_ok}/{m.frames} frames ok)'
        simulated = (f'{100 * c.v_sim:.3f} cm/s (AR {c.ar_sim:.4f})' if finite(c.v_sim) else
                     'no steady speed')
        print(f'  {r.run.video.name}: {c.slope_deg:g} deg, {c.frequency:.3f} Hz: measured '
              f'{measured}, simulated {simulated}: '
              f'{shown(c.relative_error, ".2f", " %", "no error", 100)}')
        if c.note:
            print(f'    why: {c.note}')
    return _summary(summary, 'footage vs simulation', '.2f', paths)


def _summary(summary, what: str, spec: str, paths) -> int:
    """Print the means and the files; exit code 1 when a row could not be compared."""
    missing = summary['rows'] - summary['compared']
    over = (f' (over {summary["compared"]} of {summary["rows"]} rows)' if
            missing and summary['compared'] else '')
    why = 'not computed: no row here has both speeds (see why above)'
    for v, e in summary['mean_relative_error_by_voltage'].items():
        print(f'  {v:g} V: mean relative error ({what}) {shown(e, spec, " %", why, 100)}')
    print(f'  overall: {shown(summary["mean_relative_error"], spec, " %", why, 100)}{over}')
    for name, path in paths.items():
        print(f'{name:10s} {path}')
    if missing:
        print(f'saw-ros campaign: {missing} of {summary["rows"]} rows could not be compared '
              f'(the reasons above and in campaign.md)', file=sys.stderr)
        return 1
    return 0


def run(args):
    if args.videos is not None:
        return run_videos(args)
    slopes = spec_numbers(args.slopes, 'slopes', 'conditions.slope', math.pi / 180.0, 'deg')
    voltages = spec_numbers(args.voltages, 'voltages', 'motor.voltage')
    base = scenario_from_args(args)
    for v in voltages:
        base.with_values({'motor.voltage': v})            # validates each voltage
    out = output_dir(args.out or DEFAULT_OUT, '--out')
    reference = args.reference or config_path('reference_paper.csv')
    # A reference that does not parse is found now, not after the whole campaign ran.
    text_file(reference, '--reference', 'reference file (CSV)')
    try:
        load_reference(reference)
    except ValueError as exc:
        raise UserError(f'--reference {exc}') from None
    from tqdm import tqdm
    start = time.perf_counter()
    with pool_from_args(args) as pool, \
            tqdm(total=len(slopes) * len(voltages), unit='condition', desc='campaign',
                 file=sys.stderr, disable=args.quiet, leave=False) as bar:
        results = run_campaign(slopes, voltages, base, reference, progress=bar.update,
                               pool=pool)
    paths = write_outputs(results, out)
    summary = summarise(results)
    print(f'{len(results)} conditions in {time.perf_counter() - start:.1f} s')
    for r in results:
        if r.note:
            print(f'  {r.slope_deg:g} deg, {r.voltage:g} V: no comparison: {r.note}')
    if summary['reference_points']:
        print(f'  simulation vs the paper\'s {summary["reference_points"]} measured speeds: '
              f'{100 * summary["mean_reference_error"]:.1f} %')
    return _summary(summary, 'tracking vs simulation', '.3f', paths)
