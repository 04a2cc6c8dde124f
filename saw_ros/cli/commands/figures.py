"""
Regenerate the paper's figures from our model and hold it against the paper's claims.

Writes one PNG and one CSV per figure into OUT/figures/ and the fidelity report OUT/fidelity.md
(the paper's value, ours, the tolerance and the verdict for every claim); OUT is out/figures
unless --out says otherwise. The committed copy lives in the repository's docs/: run
`saw-ros figures --out docs` from the repository root to refresh it.

figures: 4 (statics), 7 and 8 (time series, CCI), 9 (gap), 10 (stiffness), 11 (COF),
20 and 21 (wave against worm); and beyond the paper, walls (the wave and the worm on walls
that bend: docs/walls.md).

For example:
  saw-ros figures                          # everything into out/figures
  saw-ros figures --out docs               # refresh the committed copy
  saw-ros figures --out /tmp/repro --quick # coarse grids, a few seconds
  saw-ros figures --only 9,10 --out /tmp/repro
  saw-ros figures --workers 2              # the wave batch cut in two, one part per core
  saw-ros figures --scheduler tcp://host:8786   # the parts on a Dask cluster (docs/cluster.md)
"""
from pathlib import Path
import sys

from saw_ros.cli.checks import output_dir, params_file
from saw_ros.cli.errors import UserError
from saw_ros.cli.pool import add_pool_arguments, pool_from_args

HELP = "regenerate the paper's figures (PNG + CSV) and the fidelity report"
# Not docs/: the committed copy is refreshed on purpose only (--out docs).
DEFAULT_OUT = Path('out/figures')


def add_arguments(p):
    p.add_argument('--out', type=Path, default=DEFAULT_OUT,
                   help=f'output directory: OUT/figures/*.png|csv and OUT/fidelity.md '
                        f'(default: {DEFAULT_OUT}; --out docs refreshes the committed copy)')
    p.add_argument('--only', default='', help='comma-separated figure numbers '
                   '(4, 7, 8, 9, 10, 11, 20, 21) or walls; the report then covers their claims '
                   'only')
    p.add_argument('--quick', action='store_true', help='coarse grids and 3 s runs')
    p.add_argument('--quiet', action='store_true', help='no progress bar, no claim table')
    p.add_argument('--calibrated', default='shipped', metavar='PATH',
                   help='calibrated simulator parameter file whose claims the report shows '
                   'beside the defaults (default: msg_config/simulator_calibrated.yaml if it '
                   'exists; "none": the defaults only)')
    add_pool_arguments(p)


def run(args):
    from saw_ros.analysis.figures import EXTRAS, FIGURES, reproduce
    known = list(FIGURES) + list(EXTRAS)
    wanted = [w.strip() for w in args.only.split(',') if w.strip()] or known
    unknown = [w for w in wanted if w not in known]
    if unknown:
        raise UserError(f'unknown figure(s) {", ".join(unknown)}; known: {", ".join(known)}')
    output_dir(args.out, '--out')
    command = 'saw-ros figures' + (' --quick' if args.quick else '') + \
        (f' --only {",".join(wanted)}' if args.only else '') + \
        ('' if args.out == DEFAULT_OUT else f' --out {args.out}')
    calibrated = None if args.calibrated == 'none' else args.calibrated
    if calibrated not in (None, 'shipped'):
        params_file(calibrated, '--calibrated')
        command += f' --calibrated {calibrated}'
    with pool_from_args(args) as pool:
        result = reproduce(args.out, wanted, quick=args.quick, progress=not args.quiet,
                           command=command, pool=pool, calibrated=calibrated)
    if not args.quiet:
        for c in result.claims:
            mark = 'held' if c.held else 'NOT held'
            print(f'{c.id:3s} {mark:8s} {c.statement[:60]:60s} paper {c.paper[:14]:14s} '
                  f'ours {c.ours[:40]}')
    held = sum(1 for c in result.claims if c.held)
    cal = result.calibrated
    cal_text = '' if cal is None else (
        f', calibrated {sum(1 for c in cal.claims if c.held)} ({cal.path.name}; '
        f'{sum(1 for c in cal.claims if c.held and c.id not in cal.trained)} of '
        f'{sum(1 for c in cal.claims if c.id not in cal.trained)} not trained on)')
    print(f'{len(result.files)} files in {args.out / "figures"}; report {result.report}; '
          f'{held} of {len(result.claims)} claims held{cal_text}; {result.elapsed:.1f} s',
          file=sys.stderr)
    return 0
