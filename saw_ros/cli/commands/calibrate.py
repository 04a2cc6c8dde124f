r"""
Fit unknown model parameters to measured speeds and advance ratios (CMA-ES on the batched core).

Targets: a CSV of conditions with a measured speed or AR, in the format of
msg_config/reference_paper.csv (slope_deg, voltage_V, speed_cm_s, advance_ratio, source) or of
the footage campaign's footage.csv (`saw-ros campaign --videos ...`); by default the paper's stated
numbers (its three measured speeds, and the level and vertical AR of Figure 21 at 1 Hz).
Parameters: dotted names, each with its bounds (name:low:high; a bare name takes the shipped
physical bounds, see docs/calibration.md); by default the motor's hz_per_volt, resistance and
friction_torque, which the speeds pin down. OUT gets state.pkl after every generation (--resume
OUT continues), history.csv, result.json (best values, error per target, sensitivity, which
parameters the targets pin down), fit.png, sensitivity.png and convergence.png.

For example:
  saw-ros calibrate                                  # the paper's targets, the motor
  saw-ros calibrate --targets out/footage/footage.csv --out out/my_robot --params \
      motor.hz_per_volt motor.resistance:2:20 surface.restitution   # yours, your bounds
  saw-ros calibrate --resume out/my_robot --generations 60      # continue, or go further
  saw-ros calibrate --workers 2 --out docs/calibration \
      --write-config msg_config/simulator_calibrated.yaml       # the shipped calibration
  python -m saw_ros.ros.nodes.simulator --ros-args --params-file \
      msg_config/simulator_calibrated.yaml
"""
from pathlib import Path
import sys
import time

from saw_ros.analysis.shown import finite, shown
from saw_ros.cli.checks import number, output_dir, output_file, text_file, YAML_SUFFIXES
from saw_ros.cli.errors import UserError
from saw_ros.cli.pool import add_pool_arguments, pool_from_args

HELP = 'fit model parameters to measured speeds/ARs (CMA-ES), with their uncertainty'

QUICK = {'generations': 3, 'popsize': 6}


def add_arguments(p):
    p.add_argument('--targets', type=Path, default=None, metavar='CSV',
                   help="measured targets (default: the paper's three speeds and its level and "
                   'vertical AR)')
    p.add_argument('--params', nargs='+', default=None, metavar='NAME[:LOW:HIGH]',
                   help='parameters to fit (default: motor.hz_per_volt, motor.resistance, '
                   'motor.friction_torque; bare names with shipped bounds also: '
                   'surface.normal_stiffness, surface.restitution, surface.hysteresis_speed)')
    p.add_argument('--out', type=Path, default=None,
                   help='output folder (default out/calibrate/<date-time>)')
    p.add_argument('--resume', type=Path, default=None, metavar='DIR',
                   help='continue the run saved in DIR (its targets, parameters, seed)')
    p.add_argument('--generations', type=int, default=None,
                   help='CMA-ES generations (default 60; --quick 3)')
    p.add_argument('--popsize', type=int, default=None,
                   help='candidates per generation, one batch (default 24; --quick 6)')
    p.add_argument('--seed', type=int, default=1, help='random seed (default 1)')
    p.add_argument('--quick', action='store_true', help='a tiny budget (tests, a first look)')
    p.add_argument('--write-config', type=Path, default=None, metavar='PATH',
                   help='also write the calibrated simulator parameter file there (e.g. '
                   'msg_config/simulator_calibrated.yaml); not when the fit ends worse than the '
                   'parameters it started from, unless --write-worse')
    p.add_argument('--write-worse', action='store_true',
                   help='write --write-config even when the fit is worse than its start')
    p.add_argument('--quiet', action='store_true', help='no progress bar, no table')
    add_pool_arguments(p)


def command_line(args) -> str:
    """Return the command that reproduces this run (for the result and the parameter file)."""
    parts = ['saw-ros calibrate']
    if args.targets:
        parts.append(f'--targets {args.targets}')
    if args.params:
        parts.append('--params ' + ' '.join(args.params))
    if args.quick:
        parts.append('--quick')
    for flag in ('generations', 'popsize'):
        if getattr(args, flag) is not None:
            parts.append(f'--{flag} {getattr(args, flag)}')
    if args.seed != 1:
        parts.append(f'--seed {args.seed}')
    if args.workers != 1 or args.scheduler:
        parts.append(f'--scheduler {args.scheduler}' if args.scheduler else
                     f'--workers {args.workers}')
    if args.out:
        parts.append(f'--out {args.out}')
    if args.write_config:
        parts.append(f'--write-config {args.write_config}')
    if args.write_worse:
        parts.append('--write-worse')
    return ' '.join(parts)


def _value(target, value) -> str:
    """Return a target's model value as the table shows it, or 'no result' (a diverged run)."""
    return target.display(value) if finite(value) else 'no result'


def _loss(value) -> str:
    return shown(value, '.3e', why='not computed (a run diverged)')


def run(args):
    try:
        import cmaes  # noqa: F401  (the optimiser; not a rosdep key, so a ROS install may lack it)
    except ImportError:
        raise UserError('saw-ros calibrate needs the Python package cmaes: pip install '
                        'cmaes==0.13.1 (requirements.txt pins it)') from None
    from saw_ros.analysis import calibrate as cal
    budget = dict(cal.Settings().__dict__)
    if args.quick:
        budget.update(QUICK)
    for flag in ('generations', 'popsize'):
        value = getattr(args, flag)
        if value is not None:
            if value < (2 if flag == 'popsize' else 1):
                raise UserError(f'--{flag} must be at least {2 if flag == "popsize" else 1}')
            budget[flag] = value
    # The optimiser's generator takes a 32-bit seed; outside it numpy raises deep in a generation.
    number(args.seed, '--seed', '', 0, 2 ** 32 - 1)
    settings = cal.Settings(budget['generations'], budget['popsize'], args.seed, budget['sigma'])
    if args.write_worse and not args.write_config:
        raise UserError('--write-worse applies to --write-config, which was not given')
    if args.resume and (args.targets or args.params or args.out):
        raise UserError('--resume continues a saved run with its own targets, parameters and '
                        'folder: do not give --targets, --params or --out with it')
    folder = args.resume or args.out or Path('out/calibrate') / time.strftime('%Y-%m-%d_%H-%M-%S')
    output_dir(folder, '--resume' if args.resume else '--out')
    if args.targets:
        text_file(args.targets, '--targets', 'targets file (CSV)')
    if args.write_config:
        output_file(args.write_config, '--write-config', YAML_SUFFIXES)
    try:
        targets = [] if args.resume else (
            cal.load_targets(args.targets) if args.targets else cal.paper_targets())
        params = [] if args.resume else (
            cal.make_parameters(args.params) if args.params else cal.default_parameters())
        command = command_line(args)
        with pool_from_args(args) as pool:
            start = time.perf_counter()
            result = cal.calibrate(targets, params, folder, settings, resume=bool(args.resume),
                                   progress=not args.quiet, pool=pool, command=command,
                                   claims='quick' if args.quick else 'full')
        elapsed = time.perf_counter() - start
    except cal.CalibrationError as exc:
        raise UserError(str(exc)) from None
    d = result.data
    if not args.quiet:
        print(f'{"target":28s} {"measured":>12s} {"defaults":>12s} {"calibrated":>12s} '
              f'{"error":>14s}')
        for t in d['targets']:
            tg = cal.Target(t['name'], t['slope_deg'], t['quantity'], t['measured'],
                            t['voltage_V'], t['frequency_hz'])
            failed = 'no result'
            print(f'{t["label"]:28s} {tg.display(t["measured"]):>12s} '
                  f'{_value(tg, t["default"]):>12s} {_value(tg, t["calibrated"]):>12s} '
                  f'{shown(t["error_default_pct"], "5.1f", why=failed)} -> '
                  f'{shown(t["error_calibrated_pct"], "4.1f", " %", failed)}'
                  f'{"" if t["informative"] else " (no fitted parameter moves it)"}')
            if not (finite(t['default']) and finite(t['calibrated'])):
                print(f'{"":28s} no result: the simulation diverged or the robot did not move '
                      f'under this condition (outside what the model can run)')
        for p in d['parameters']:
            std = p['relative_std']
            band = f'+-{100 * std:.0f} %' if std is not None else 'unbounded'
            print(f'{p["name"]:28s} {p["value"]:12.6g} (default {p["default"]:.6g}; 1 sigma '
                  f'{band}: {"pinned down" if p["identified"] else "NOT pinned down"}'
                  f'{", at a bound" if p["at_bound"] else ""})')
    c = d['claims']
    print(f'claims held (the fidelity report, {c["grids"]} grids; trained on '
          f'{", ".join(c["trained"]) or "none"}): defaults {c["defaults"]["held_untrained"]} of '
          f'{c["defaults"]["untrained"]} not trained on, calibrated '
          f'{c["calibrated"]["held_untrained"]} of {c["calibrated"]["untrained"]} (not held: '
          f'{", ".join(c["calibrated"]["not_held"]) or "none"})')
    # A loss that could not be computed (a run that diverged) is no better than the start.
    worse = not d['loss'] <= d['loss_default']
    if args.write_config and worse and not args.write_worse:
        # A "calibrated" file that fits the targets worse than the defaults would replace better
        # parameters without a word; a short run (--quick) can end there.
        more = max(2 * d['generations'], cal.Settings().generations)
        print(f'saw-ros calibrate: did not write {args.write_config}: the best fit is worse than '
              f'the parameters it started from (mean squared relative error '
              f'{_loss(d["loss_default"])} -> {_loss(d["loss"])} after {d["generations"]} '
              f'generations);'
              f' run more generations (saw-ros calibrate --resume {folder} --generations {more})'
              f' or give --write-worse to write it anyway', file=sys.stderr)
        return 1
    if args.write_config:
        try:
            path = cal.write_calibrated_yaml(result, args.write_config, command)
        except OSError as exc:
            raise UserError(f'cannot write {args.write_config}: {exc}') from None
        print(f'calibrated parameter file: {path}', file=sys.stderr)
    print(f'{folder}: loss {_loss(d["loss_default"])} -> {_loss(d["loss"])} after '
          f'{d["generations"]} generations of {d["popsize"]}; {elapsed:.1f} s', file=sys.stderr)
    return 0
