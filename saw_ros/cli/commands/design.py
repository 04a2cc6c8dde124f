"""
The design study (issue 31): the robot's geometry and flexures against three walls.

Sweeps the number of wave links, the amplitude, the wavelength, the tip distance (the radius at
which the link tips ride about the helix's backbone) and the link flexures' stiffness, as a
Latin hypercube or a grid, on rigid walls, the silicone sheet and the soft tissue
(docs/walls.md), at a constant motor voltage on the level. For every design: speed, AR, cost of
transport (electrical energy / (m g distance)) and vibration (the RMS normal acceleration
saw-ros compliant measures). Designs the model cannot run (links that collide, a motor that
stalls, ...) are reported with the reason, never as numbers. OUT gets design.csv (every run),
design_<wall>.png (the Pareto fronts of speed against cost of transport and against vibration,
the paper's robot marked) and summary.md (where the paper's robot sits). docs/design_study.md
explains it.

For example:
  saw-ros design                                   # the default study (about 2 minutes)
  saw-ros design --size 20 --walls rigid           # a quick look
  saw-ros design --method grid --size 3            # 3 levels of each parameter
  saw-ros design --range robot.wave_links=15:30    # another range (SI units)
  saw-ros design --scheduler tcp://host:8786       # the geometries on a Dask cluster
"""
import math
from pathlib import Path
import sys
import time

from saw_ros.cli.checks import output_dir, spec_number
from saw_ros.cli.commands.simulate import add_scenario_arguments, scenario_from_args
from saw_ros.cli.errors import UserError
from saw_ros.cli.pool import add_pool_arguments, pool_from_args
from saw_ros.core.params import Scenario

NAME = 'design'
HELP = "sweep the robot's geometry and flexures against three walls: Pareto fronts (issue 31)"
DEFAULT_OUT = Path('out') / NAME
DEFAULT_GRID = 3        # levels: 81 geometries, 3 flexures each
SHORTEST_WINDOW_S = 1.0
LONGEST_S = 60.0        # settle or measure: a minute of robot time is past any steady state


def add_arguments(p):
    from saw_ros.analysis import design
    p.add_argument('--method', choices=('lhs', 'grid'), default='lhs',
                   help='lhs: a Latin hypercube of --size geometries (default); grid: --size '
                   'levels of every parameter')
    p.add_argument('--size', type=int, default=None,
                   help=f'geometries of the hypercube (default {design.DEFAULT_SIZE}) or levels '
                   'per parameter of the grid (default {DEFAULT_GRID})')
    p.add_argument('--seed', type=int, default=design.DEFAULT_SEED,
                   help=f'seed of the hypercube (default {design.DEFAULT_SEED})')
    p.add_argument('--walls', default=','.join(design.WALLS),
                   help=f'comma-separated, of {", ".join(design.WALLS)} (default: all)')
    p.add_argument('--range', action='append', default=[], metavar='NAME=LOW:HIGH',
                   help='another range for a swept parameter, SI units, e.g. '
                   'robot.amplitude=0.015:0.019 (repeatable); swept: '
                   + ', '.join(d.name for d in design.DIMENSIONS))
    p.add_argument('--settle-s', type=float, default=design.SETTLE_S,
                   help=f'simulated time before the window, s (default {design.SETTLE_S:g})')
    p.add_argument('--measure-s', type=float, default=design.MEASURE_S,
                   help=f'the measuring window, s (default {design.MEASURE_S:g})')
    p.add_argument('--out', type=Path, default=DEFAULT_OUT,
                   help=f'output folder (default {DEFAULT_OUT})')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    add_pool_arguments(p)
    add_scenario_arguments(p)


def _ranges(texts):
    """Return the (name, low, high) of the --range flags, each end checked against its spec."""
    meta = {name: m for name, _, m in Scenario().describe()}
    out = []
    for text in texts:
        name, _, span = text.partition('=')
        low, colon, high = span.partition(':')
        if not colon:
            raise UserError(f'--range {text!r}: expects NAME=LOW:HIGH, e.g. '
                            f'robot.amplitude=0.015:0.019')
        try:
            ends = (float(low), float(high))
        except ValueError:
            raise UserError(f'--range {text!r}: LOW and HIGH must be numbers') from None
        name = name.strip()
        if not all(math.isfinite(v) for v in ends):
            raise UserError(f'--range {text!r}: LOW and HIGH must be finite numbers')
        if name in meta:
            ends = tuple(spec_number(int(v) if name == 'robot.wave_links' and v.is_integer()
                                     else v, f'--range {name}', meta[name], name=name)
                         for v in ends)
        out.append((name, ends[0], ends[1]))
    return out


def _walls(text):
    from saw_ros.analysis.design import WALLS
    walls = [w.strip() for w in text.split(',') if w.strip()]
    if not walls:
        raise UserError('--walls is empty')
    unknown = [w for w in walls if w not in WALLS]
    if unknown:
        raise UserError(f'--walls {text!r}: unknown {", ".join(unknown)}; known: '
                        f'{", ".join(WALLS)}')
    return tuple(dict.fromkeys(walls))


def run(args) -> int:
    from saw_ros.analysis import design
    size = args.size
    if size is None:
        size = design.DEFAULT_SIZE if args.method == 'lhs' else DEFAULT_GRID
    if args.method == 'lhs' and size < 1:
        raise UserError(f'--size {size}: a hypercube needs at least 1 geometry')
    if args.method == 'grid' and size < 2:
        raise UserError(f'--size {size}: a grid needs at least 2 levels per parameter')
    if args.seed < 0:
        raise UserError(f'--seed {args.seed}: must be 0 or more')
    for flag, value in (('--settle-s', args.settle_s), ('--measure-s', args.measure_s)):
        if not (math.isfinite(value) and 0.0 <= value <= LONGEST_S):
            raise UserError(f'{flag} {value:g}: must be a time in [0, {LONGEST_S:g}] s')
    if args.measure_s < SHORTEST_WINDOW_S:
        raise UserError(f'--measure-s {args.measure_s:g}: the window must hold at least '
                        f'{SHORTEST_WINDOW_S:g} s (a helix turn lasts 0.6-1.1 s at 4-7 V; a '
                        f"speed over part of one is not the robot's)")
    walls = _walls(args.walls)
    try:
        dimensions = design.check_dimensions(_ranges(args.range))
    except ValueError as exc:
        raise UserError(f'--range {exc}') from None
    if args.voltage is None:
        args.voltage = design.VOLTAGE
    base = scenario_from_args(args)
    if base.motor.voltage <= 0.0:
        raise UserError('--voltage 0: the cost of transport needs the motor (a voltage > 0)')
    if base.surface.foundation_stiffness > 0.0 or base.flexure.stiffness > 0.0:
        raise UserError('the study sets the walls and the flexures itself: leave '
                        'surface.foundation_stiffness and flexure.stiffness at 0 (use --walls '
                        'and --range flexure.stiffness=LOW:HIGH)')
    # At least this many runs (three continuous dimensions, each wall): refused before drawing
    # a grid that would not fit in memory.
    least = (size if args.method == 'lhs' else size ** 3) * len(walls)
    if least <= design.LARGEST_STUDY:
        designs = design.draw(args.method, size, args.seed, dimensions)
        least = design.runs_in(designs, walls)
    if least > design.LARGEST_STUDY:
        raise UserError(f'--size {size}: {least} runs or more, more than the '
                        f'{design.LARGEST_STUDY} runs a study may make; a smaller --size')
    total = least
    out = output_dir(args.out, '--out')
    from tqdm import tqdm
    start = time.perf_counter()
    pool = pool_from_args(args)
    try:
        with tqdm(total=total, unit='run', desc=NAME, file=sys.stderr, disable=args.quiet,
                  leave=False) as bar:
            study = design.run_study(base, args.method, size, args.seed, walls, args.settle_s,
                                     args.measure_s, dimensions, pool, bar.update)
    finally:
        pool.close()
    seconds = time.perf_counter() - start
    paths = design.write_outputs(study, out, seconds)
    ok = sum(r.ok for r in study.runs)
    print(f'{len(study.runs)} runs in {seconds:.1f} s: {ok} ran, {len(study.runs) - ok} could '
          f'not (the reasons in design.csv)')
    for wall in walls:
        for measure, label, unit in design.MEASURES:
            print(design.standing_text(study, wall, measure, label, unit).replace(
                '- speed', f'{wall}: speed', 1))
    for name, path in paths.items():
        print(f'{name:8s} {path}')
    return 0
