"""The paper's validation campaign: 20 conditions (slopes -20..20 deg x 4, 5, 6, 7 V, gap 45 mm)
through simulation, virtual camera and tracker; a table (CSV, markdown), the mean relative error
per voltage and overall, speed against slope and voltage with linear fits (Figure 17) and the AR
comparison (Figure 18).

examples:
  saw-ros campaign                                   # the paper's 20 conditions -> out/campaign
  saw-ros campaign --slopes=-20,0,20 --voltages 6,7 --out /tmp/c   # "=" before negatives
  saw-ros campaign --set motor.hz_per_volt=0.22      # calibrate the motor
"""
import sys
import time
from pathlib import Path

from saw_ros.analysis.campaign import PAPER_SLOPES_DEG, PAPER_VOLTAGES, run_campaign, summarise, write_outputs
from saw_ros.interface.config import config_path
from saw_ros.core.params import ParameterError
from saw_ros.cli.commands.simulate import add_scenario_arguments, scenario_from_args

HELP = "run the paper's 20-condition validation campaign (simulation, camera, tracker)"


def _numbers(text, name):
    try:
        values = [float(v) for v in text.split(',') if v.strip()]
    except ValueError:
        raise ParameterError(f'--{name} expects comma-separated numbers, got {text!r}') from None
    if not values:
        raise ParameterError(f'--{name} is empty')
    return values


def add_arguments(p):
    p.add_argument('--slopes', default=','.join(f'{s:g}' for s in PAPER_SLOPES_DEG),
                   help='slopes in degrees, comma-separated; write --slopes=-20,0 when the list starts '
                   'with a minus (default: -20,-10,0,10,20)')
    p.add_argument('--voltages', default=','.join(f'{v:g}' for v in PAPER_VOLTAGES),
                   help='motor voltages, comma-separated (default: 4,5,6,7)')
    p.add_argument('--out', type=Path, default=Path('out/campaign'), help='output folder')
    p.add_argument('--reference', type=Path, default=None,
                   help='CSV of measured speeds/ARs (default: the paper\'s stated points)')
    p.add_argument('--workers', type=int, default=2, help='parallel processes (2)')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    add_scenario_arguments(p)


def run(args):
    slopes = _numbers(args.slopes, 'slopes')
    voltages = _numbers(args.voltages, 'voltages')
    base = scenario_from_args(args)
    for v in voltages:
        base.with_values({'motor.voltage': v})            # validates each voltage
    reference = args.reference or config_path('reference_paper.csv')
    from tqdm import tqdm
    start = time.perf_counter()
    with tqdm(total=len(slopes) * len(voltages), unit='condition', desc='campaign',
              file=sys.stderr, disable=args.quiet, leave=False) as bar:
        results = run_campaign(slopes, voltages, base, reference, max(1, args.workers),
                               progress=bar.update)
    paths = write_outputs(results, args.out)
    summary = summarise(results)
    print(f'{len(results)} conditions in {time.perf_counter() - start:.1f} s')
    for v, e in summary['mean_relative_error_by_voltage'].items():
        print(f'  {v:g} V: mean relative error (tracking vs simulation) {100 * e:.3f} %')
    print(f'  overall: {100 * summary["mean_relative_error"]:.3f} %')
    if summary['reference_points']:
        print(f'  simulation vs the paper\'s {summary["reference_points"]} measured speeds: '
              f'{100 * summary["mean_reference_error"]:.1f} %')
    for name, path in paths.items():
        print(f'{name:10s} {path}')
    return 0
