"""
Find a voltage profile over one helix turn that calms the robot's vertical vibration.

The paper's next step (Section 8, "controlled motor activation with varying speeds"): CMA-ES
searches a mean voltage and a few Fourier harmonics of the helix phase (fed forward to the
motor) that minimise the RMS normal acceleration of the body at the same mean speed (within
2 %) and no more mean electrical power than the constant voltage. Each generation is one batch
of the core on the local cores (or a Dask cluster). OUT gets result.json, report.md and
spectrum.png (where the vibration's energy sits, before and after), profile.png, slopes.png (the
level's profile from -20 to 90 degrees) and convergence.png; docs/drive.md explains them.
On a compliant robot (links on flexures, issue 31) the vibration is minimised against the rigid
robot's constant voltage at the same speed, and the report gives both comparisons
(docs/compliant_robot.md).

For example:
  saw-ros shape-drive                       # 6 V on the level, 60 generations (a few minutes)
  saw-ros shape-drive --quick               # a first look in seconds
  saw-ros shape-drive --voltage 5 --set surface.tangential_stiffness=600 --out out/soft
  saw-ros shape-drive --out docs/shape_drive  # the committed report
  saw-ros shape-drive --flexure-stiffness 1463 --flexure-damping-ratio 0.7 --generations 100 \
      --out docs/compliant_robot/shaped       # flexures and shaped drive against the rigid robot
"""
import contextlib
import math
from pathlib import Path

from saw_ros.analysis import shape_drive
from saw_ros.cli.checks import number, output_dir, spec_number
from saw_ros.cli.commands.simulate import add_scenario_arguments, scenario_from_args
from saw_ros.cli.errors import UserError
from saw_ros.cli.pool import add_pool_arguments, pool_from_args

NAME = 'shape-drive'
HELP = 'find a voltage profile over the helix turn that calms the vibration (paper Sec. 8)'
DEFAULT_VOLTAGE = 6.0
QUICK = {'generations': 4, 'population': 6}


def add_arguments(p):
    add_scenario_arguments(p)
    p.add_argument('--generations', type=int, default=60, help='CMA-ES generations (default 60)')
    p.add_argument('--population', type=int, default=12,
                   help='candidates per generation, one batch (default 12)')
    p.add_argument('--seed', type=int, default=1, help='random seed (default 1)')
    p.add_argument('--quick', action='store_true', help='a tiny budget (tests, a first look)')
    p.add_argument('--flexure-stiffness', type=float, metavar='N/M',
                   help='each link on a flexure of this stiffness (flexure.stiffness; 0 = rigid): '
                   "the drive is then shaped against the rigid robot's vibration")
    p.add_argument('--flexure-damping-ratio', type=float, metavar='ZETA',
                   help="the flexures' damping as a ratio c / (2 sqrt(k m)) (sets "
                   'flexure.damping; docs/compliant_robot.md: 0.7 is the best)')
    p.add_argument('--out', type=Path, default=Path('out') / NAME,
                   help=f'output folder (default out/{NAME})')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    add_pool_arguments(p)


def with_flexures(base, args):
    """Return ``base`` with the flexure flags: the stiffness, and the damping from its ratio."""
    meta = {name: m for name, _, m in base.describe()}
    values = {}
    if args.flexure_stiffness is not None:
        values['flexure.stiffness'] = spec_number(
            args.flexure_stiffness, '--flexure-stiffness', meta['flexure.stiffness'],
            name='flexure.stiffness')
    stiffness = values.get('flexure.stiffness', base.flexure.stiffness)
    if args.flexure_damping_ratio is not None:
        ratio = number(args.flexure_damping_ratio, '--flexure-damping-ratio', low=0.0,
                       description='c / (2 sqrt(k m))')
        if stiffness <= 0.0:
            raise UserError('--flexure-damping-ratio: the links are rigid; give them flexures '
                            '(--flexure-stiffness > 0)')
        damping = ratio * 2.0 * math.sqrt(stiffness * base.flexure.link_mass)
        values['flexure.damping'] = spec_number(
            damping, f'--flexure-damping-ratio {ratio:g}: flexure.damping',
            meta['flexure.damping'], name='flexure.damping')
    return base.with_values(values)


def run(args) -> int:
    if args.voltage is None:
        args.voltage = DEFAULT_VOLTAGE
    base = with_flexures(scenario_from_args(args), args)
    # A compliant robot is shaped against the rigid one (issue 31): the paper's two remedies
    # together, against the robot the paper built.
    rigid = None if base.flexure.stiffness <= 0.0 else base.with_values(
        {'flexure.stiffness': 0.0, 'flexure.damping': 0.0})
    if base.motor.voltage <= 0.0:
        raise UserError("--voltage must be above 0 V: the profile shapes the motor's voltage")
    if args.quick:
        args.generations, args.population = QUICK['generations'], QUICK['population']
    for flag, value, low in (('--generations', args.generations, 1),
                             ('--population', args.population, 4)):
        if value < low:
            raise UserError(f'{flag} {value}: must be at least {low}')
    out = output_dir(args.out, '--out')
    bar = None
    if not args.quiet:
        from tqdm import tqdm
        bar = tqdm(total=args.generations, unit='generation', desc=NAME, disable=None)

    def progress(generation, best):
        if bar is not None:
            bar.set_postfix_str(f'vibration x {best:.3f}')
            bar.update(1)

    with contextlib.closing(pool_from_args(args)) as pool:
        result = shape_drive.optimise(base, pool, args.generations, args.population,
                                      seed=args.seed, progress=progress, reference=rigid)
    if bar is not None:
        bar.close()
    summary = shape_drive.write_report(result, base, out)
    if result.feasible:
        print(f'vibration {result.matched["vibration"]:.3f} m/s^2 RMS (constant '
              f'{result.matched_voltage:.3f} V) -> {result.shaped["vibration"]:.3f} (shaped) at '
              f'the same speed: {summary["vibration_reduction_pct"]:.1f} % less, power '
              f'{summary["power_change_pct"]:+.2f} %; speed {summary["speed_change_pct"]:+.2f} % '
              f'off the constant {base.motor.voltage:g} V')
    else:
        print(f'no profile met the constraints in {args.generations} generations (speed within '
              f'{100 * shape_drive.SPEED_TOLERANCE:g} %, power no higher): the constant '
              f'{base.motor.voltage:g} V stands; run more generations (--generations)')
    if result.reference is not None and summary['reference_reduction_pct'] is None:
        print(f'no comparison with the rigid robot: at a constant voltage it did not reach the '
              f'shaped drive\'s {100 * result.shaped["speed"]:.3f} cm/s (nearest '
              f'{100 * result.reference["speed"]:.3f} cm/s at {result.reference_voltage:.3f} V)')
    elif result.reference is not None:
        print(f'against the rigid robot at the same speed (constant {result.reference_voltage:.3f}'
              f' V, {result.reference["vibration"]:.3f} m/s^2 RMS): '
              f'{summary["reference_reduction_pct"]:.1f} % less vibration, '
              f'{result.shaped["power"] / result.shaped["speed"]:.2f} J/m against '
              f'{result.reference["power"] / result.reference["speed"]:.2f} J/m')
    print(f'wrote {out}/report.md, result.json and the plots')
    return 0
