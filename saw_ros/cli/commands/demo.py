"""
The main job: the full ROS graph on the default scenario, then the comparison and a report.

Starts simulator, camera, vision, comparison and recorder as separate processes in a private DDS
domain, runs about 10 s of simulated time, prints the comparison (AR of simulation and tracking,
their relative error, v_theory), leaves the recording in bags/ and the report (report.png,
comparison.json, camera.mp4, the nodes' logs) in the output folder it names. The recording holds
every topic but the raw camera frames (their JPEG stream is in; camera.mp4 is made from it after
the run, outside the live graph). Ctrl-C stops every process it started. Exit code 1 if any node
failed.
"""
from pathlib import Path
import sys
import time

from saw_ros.analysis.bag_frames import bag_video
from saw_ros.analysis.report import format_comparison, write_report
from saw_ros.bag.reader import BagReadError
from saw_ros.cli.checks import number, output_dir, spec_number
from saw_ros.cli.commands.simulate import add_scenario_arguments, scenario_from_args
from saw_ros.cli.errors import UserError
from saw_ros.core.drive import CONTROLLER_PARAMETERS
from saw_ros.graph.pipeline import PipelineError, run_pipeline
from saw_ros.interface.config import config_path

HELP = 'run the full pipeline (simulator, camera, vision, comparison, recorder) and report'
FOXGLOVE_PORT = 8765        # the bridge's default (msg_config/foxglove_bridge.yaml), Foxglove's


def add_arguments(p):
    p.add_argument('--duration', type=float, default=10.0, help='simulated seconds (10)')
    # 0.5: on this 2-core machine the five nodes recording everything (camera JPEG included)
    # lose nothing at 0.5 and saturate near 0.65 (bench key pipeline_images_max_realtime_factor);
    # the default keeps that margin.
    p.add_argument('--real-time-factor', type=float, default=0.5,
                   help='simulated seconds per wall second (0.5)')
    p.add_argument('--out', type=Path, help='output folder (default out/demo_<date-time>)')
    p.add_argument('--no-video', action='store_true', help='do not write camera.mp4')
    p.add_argument('--controller', action='store_true',
                   help='also run speed_controller, holding --target-cm-s through the camera '
                   '(docs/drive.md)')
    p.add_argument('--target-cm-s', type=float, default=5.0,
                   help="the controller's target speed, cm/s (5)")
    p.add_argument('--foxglove', action='store_true',
                   help='also run foxglove_bridge: watch the run live in Foxglove at '
                   f'ws://127.0.0.1:{FOXGLOVE_PORT} (docs/viewers.md)')
    add_scenario_arguments(p)


def run(args):
    from saw_ros.core import Scenario
    scenario = scenario_from_args(args)
    number(args.duration, '--duration', 's', 0.0, None, low_open=True)
    # The simulator node's range for its real_time_factor.
    number(args.real_time_factor, '--real-time-factor', '', 0.0, None,
           description='simulated seconds per wall second, 0 = as fast as possible')
    controller = None
    if args.controller:
        meta = next(m for name, _, m in CONTROLLER_PARAMETERS if name == 'target_speed')
        spec_number(args.target_cm_s, '--target-cm-s', meta, 0.01, 'cm/s', 'target_speed')
        controller = {'target_speed': args.target_cm_s / 100.0}
    if args.out is not None:
        output_dir(args.out, '--out')
    defaults = Scenario().flat()
    changed = {k: v for k, v in scenario.flat().items()
               if v != defaults[k] and k != 'integration.duration'}
    out = args.out or Path('out') / time.strftime('demo_%Y-%m-%d_%H-%M-%S')
    print(f'saw-ros demo: simulator, camera, vision, comparison, recorder'
          f'{", speed_controller" if controller else ""}'
          f'{", foxglove_bridge" if args.foxglove else ""}; {args.duration:g} s '
          f'of simulated time at real-time factor {args.real_time_factor:g}; output {out}',
          flush=True)
    foxglove = {'port': FOXGLOVE_PORT} if args.foxglove else None
    if foxglove:
        print(f'live in Foxglove: ws://127.0.0.1:{FOXGLOVE_PORT} (Foxglove app: Open connection > '
              'Foxglove WebSocket; layout: docs/foxglove_layout.json)', flush=True)
    spinner = _Spinner(args.duration / max(args.real_time_factor, 0.1))
    try:
        result = run_pipeline(out, args.duration, args.real_time_factor, changed,
                              reference_file=config_path('reference_paper.csv'),
                              progress=spinner, controller=controller, foxglove=foxglove)
    except PipelineError as exc:
        spinner.close()
        print(f'saw-ros demo: {exc}', file=sys.stderr)
        return 1
    spinner.close()
    print(format_comparison(result.comparison))
    failed = {k: v for k, v in result.exit_codes.items() if v != 0}
    if result.bag_dir is not None and result.bag_dir.exists():
        print(f'recording           {result.bag_dir}')
        if result.comparison:
            print(f'report              '
                  f'{write_report(result.bag_dir, result.comparison, result.out_dir)}')
        if not args.no_video:
            try:
                frames, fps = bag_video(result.bag_dir, out / 'camera.mp4')
            except BagReadError as exc:
                raise UserError(str(exc)) from None
            print(f'camera video        {out / "camera.mp4"} ({frames} frames, {fps:g} fps)')
    print(f'comparison (JSON)   {out / "comparison.json"}')
    print(f'node logs           {out / "logs"}')
    if failed:
        print(f'saw-ros demo: nodes failed: {failed}', file=sys.stderr)
        return 1
    if result.comparison.get('status') != 'steady':
        print(f'saw-ros demo: the comparison did not reach steady state within the '
              f'{args.duration:g} s simulated: run longer (--duration {2 * args.duration:g})',
              file=sys.stderr)
        return 1
    return 0


class _Spinner:
    """A progress bar over the expected wall time of the run."""

    def __init__(self, expected_s):
        from tqdm import tqdm
        self.start = time.monotonic()
        # disable=None: a bar on a terminal only, not a log of carriage returns in a file.
        self.bar = tqdm(total=round(expected_s, 1), unit='s', desc='running graph', disable=None,
                        file=sys.stderr, leave=False,
                        bar_format='{desc}: {bar} {n:.0f}/{total:.0f} s wall')

    def __call__(self):
        self.bar.n = min(self.bar.total, round(time.monotonic() - self.start, 1))
        self.bar.refresh()

    def close(self):
        self.bar.close()
