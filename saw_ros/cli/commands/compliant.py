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
metre against the rigid robot at the same speed. OUT gets report.md, compliant.csv,
compliant.png, closed_loop.csv and closed_loop.png.

For example:
  saw-ros compliant                          # 6 V on the level (about a minute)
  saw-ros compliant --quick                  # four stiffnesses, one damping ratio
  saw-ros compliant --out docs/compliant_robot   # the committed report
"""
from pathlib import Path

from saw_ros.cli.checks import output_dir
from saw_ros.cli.commands.simulate import add_scenario_arguments, scenario_from_args
from saw_ros.cli.errors import UserError

NAME = 'compliant'
HELP = 'link flexures against the vibration (paper Sec. 8, issue 31)'
DEFAULT_VOLTAGE = 6.0


def add_arguments(p):
    add_scenario_arguments(p)
    p.add_argument('--quick', action='store_true', help='four stiffnesses, one damping ratio')
    p.add_argument('--out', type=Path, default=Path('out') / NAME,
                   help=f'output folder (default out/{NAME})')
    p.add_argument('--quiet', action='store_true', help='no progress bar')


def run(args) -> int:
    from saw_ros.analysis import compliant
    if args.voltage is None:
        args.voltage = DEFAULT_VOLTAGE
    base = scenario_from_args(args)
    if base.surface.foundation_stiffness > 0.0:
        raise UserError('saw-ros compliant replays rigid walls: bending walls (surface.'
                        'foundation_stiffness > 0) are not replayed open loop')
    out = output_dir(args.out, '--out')
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
    else:
        print('closed loop skipped: the equal-speed comparison needs the motor (--voltage > 0)')
    print(f'wrote {out}/report.md and its csv and png files')
    return 0
