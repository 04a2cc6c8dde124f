"""
The paper's second remedy (Section 8): link flexures against the vibration.

"The utilization of a monolithic compliant robot structure": every wave link on a flexure of
stiffness k and damping c (core.flexure). The rigid robot's run gives every tip's penetration;
the flexure links are driven through them with the simulator's contact law, and the body's
normal force and its RMS fluctuation (shape-drive's vibration measure) are compared with the
rigid links', for stiffnesses from 300 to 1e5 N/m and three damping ratios, and for the printed
TPU and nylon sets of docs/compliant_robot.md. Open loop: the body keeps the rigid run's motion
(its mean height re-balanced), so these are the forcing's reductions. Then closed loop: the
compliant robot itself (the flexures in the compiled step), its speed, vibration and energy per
metre against the rigid robot at the same speed, on the level and on every slope of --slopes
(level to vertical: the best structure on each, and the one that is good on all, alone and with
its drive shaped on each slope by shape-drive's search). OUT gets report.md, compliant.csv,
compliant.png, closed_loop.csv, closed_loop.png, slopes.csv and slopes.png.

For example:
  saw-ros compliant                          # 6 V, level to vertical (85 s at load 4-5)
  saw-ros compliant --quick                  # four stiffnesses, one damping ratio, a short search
  saw-ros compliant --slopes=-30,0,30,60,90  # "=" before a list that starts with a minus
  saw-ros compliant --out docs/compliant_robot   # the committed report
"""
import math
from pathlib import Path
import sys

from saw_ros.cli.checks import output_dir, spec_numbers
from saw_ros.cli.commands.simulate import add_scenario_arguments, scenario_from_args
from saw_ros.cli.errors import UserError

NAME = 'compliant'
HELP = 'link flexures against the vibration (paper Sec. 8, issue 31)'
DEFAULT_VOLTAGE = 6.0
SLOPES_DEG = (0.0, 45.0, 90.0)     # the "level to vertical"
QUICK_GENERATIONS, QUICK_POPULATION = 4, 6      # --quick: the shaped drive's search a first look


def add_arguments(p):
    add_scenario_arguments(p)
    p.add_argument('--quick', action='store_true', help='four stiffnesses, one damping ratio')
    p.add_argument('--slopes', default=','.join(f'{s:g}' for s in SLOPES_DEG),
                   help='slopes of the closed loop, degrees (+ climbs), comma-separated; write '
                   '--slopes=-30,0 when the list starts with a minus (default: '
                   f'{",".join(f"{s:g}" for s in SLOPES_DEG)})')
    p.add_argument('--out', type=Path, default=Path('out') / NAME,
                   help=f'output folder (default out/{NAME})')
    p.add_argument('--quiet', action='store_true', help='no progress bar')


def run(args) -> int:
    if args.voltage is None:
        args.voltage = DEFAULT_VOLTAGE
    base = scenario_from_args(args)
    if base.surface.foundation_stiffness > 0.0:
        raise UserError('saw-ros compliant replays rigid walls: bending walls (surface.'
                        'foundation_stiffness > 0) are not replayed open loop')
    slopes = spec_numbers(args.slopes, 'slopes', 'conditions.slope', math.pi / 180.0, 'deg')
    out = output_dir(args.out, '--out')
    from saw_ros.core.dynamics import DivergenceError
    try:
        _study(args, base, slopes, out)
    except DivergenceError as exc:
        # The robot at the base scenario leaves the model (a slope of --slopes that does is
        # reported in its row instead): the run says so in one line.
        print(f'saw-ros {NAME}: {exc}', file=sys.stderr)
        return 3
    print(f'wrote {out}/report.md and its csv and png files')
    return 0


def _study(args, base, slopes, out) -> None:
    """Open loop, then the closed loop on the level and on every slope; write the report."""
    from saw_ros.analysis import compliant
    stiffnesses = compliant.STIFFNESSES[::3] if args.quick else compliant.STIFFNESSES
    ratios = compliant.DAMPING_RATIOS[1:2] if args.quick else compliant.DAMPING_RATIOS
    measure = 1.0 if args.quick else compliant.MEASURE_S
    bar = None
    if not args.quiet:
        from tqdm import tqdm
        bar = tqdm(total=len(stiffnesses) * len(ratios), unit='flexure', desc=NAME,
                   disable=None)
    run_ = compliant.rigid_run(base, measure=measure)
    rows = compliant.sweep(run_, stiffnesses, ratios,
                           progress=None if bar is None else bar.update)
    if bar is not None:
        bar.close()
    printed = compliant.printed_rows(run_, compliant.LINK_MASS)
    compliant.write_report(rows, printed, run_, base, out)
    print(f'rigid {run_.vibration:.3f} m/s^2 RMS; ' + ', '.join(
        f'{r["name"]} ({r["stiffness"]:.0f} N/m) {r["reduction_pct"]:.1f} % less'
        for r in printed) + ' (open loop: the body held to the rigid run)')
    if base.motor.voltage > 0.0:
        result = compliant.closed_loop(base, stiffnesses, ratios)
        compliant.write_closed_loop(result, base, out)
        best = result['best']
        if best is not None:
            print(f'closed loop: best {best["stiffness"]:.0f} N/m, damping ratio '
                  f'{best["damping_ratio"]:g}: {best["reduction_pct"]:.1f} % less vibration '
                  f'than the rigid robot at the same speed, at {100 * best["speed_share"]:.1f} % '
                  f'of its speed')
        else:
            print('closed loop: no flexure of the sweep keeps 95 % of the rigid speed with a '
                  'reduction')
        _slopes(base, slopes, stiffnesses, ratios, result, out, args.quiet, args.quick)
    else:
        print('closed loop and --slopes skipped: the equal-speed comparison needs the motor '
              '(--voltage > 0)')


def _slopes(base, slopes, stiffnesses, ratios, level, out, quiet, quick) -> None:
    """Run the closed loop on every slope (the base slope's run reused); report and print."""
    from saw_ros.analysis import compliant
    from tqdm import tqdm
    bar = None
    if not quiet:
        bar = tqdm(total=len(slopes), unit='slope', desc='slopes', disable=None)
    study = compliant.closed_loop_slopes(
        base, slopes, stiffnesses, ratios, progress=None if bar is None else bar.update,
        done={round(math.degrees(base.conditions.slope), 9): level})
    if bar is not None:
        bar.close()
    best = study['robust']
    shaped = None
    if best is not None:
        # The one structure for every slope, with its drive shaped on each (the two remedies).
        generations = QUICK_GENERATIONS if quick else compliant.SHAPED_GENERATIONS
        bar = None
        if not quiet:
            bar = tqdm(total=len(slopes) * generations, unit='generation', desc='shaped drive',
                       disable=None)
        shaped = compliant.shaped_slopes(
            base, slopes, best['stiffness'], best['damping_ratio'], generations=generations,
            population=QUICK_POPULATION if quick else compliant.SHAPED_POPULATION,
            progress=None if bar is None else bar.update)
        if bar is not None:
            bar.close()
    compliant.write_slopes(study, base, out, shaped)
    for r in study['slopes']:
        b = r.get('best')
        print(f'{r["slope_deg"]:g} deg: ' + (
            f'not run: {r["error"]}' if 'error' in r else
            'no flexure keeps 95 % of the rigid speed with a reduction' if b is None else
            f'best {b["stiffness"]:.0f} N/m, damping ratio {b["damping_ratio"]:g}: '
            f'{b["reduction_pct"]:.1f} % less vibration at {100 * b["speed_share"]:.1f} % of '
            f'the rigid speed'))
    print('no single flexure keeps 95 % of the rigid speed with a reduction on every slope'
          if best is None else
          f'on every slope: {best["stiffness"]:.0f} N/m, damping ratio {best["damping_ratio"]:g}, '
          f'{compliant.least_text(best["least"])}')
    for r in shaped or ():
        print(f'{r["slope_deg"]:g} deg with its shaped drive: ' + (
            f'not run: {r["error"]}' if 'error' in r else
            f'{r["reduction_pct"]:.1f} % less vibration than the rigid robot at the same speed '
            f'(the drive takes {r["drive_pct"]:.1f} % off the flexures alone)'
            if math.isfinite(r['reduction_pct']) else r['why']))
