"""Measure the figures each issue names and print them (``--json``: one JSON object).

Every module in ``saw_ros/benchmarks/`` contributes its keys; ``--only`` picks modules.
"""
import importlib
import json
import pkgutil
import sys
import time

from .. import benchmarks

HELP = 'measure speed and accuracy figures (--json prints one JSON object)'


def modules():
    for info in sorted(pkgutil.iter_modules(benchmarks.__path__), key=lambda m: m.name):
        yield info.name, importlib.import_module(f'{benchmarks.__name__}.{info.name}')


def add_arguments(p):
    p.add_argument('--json', action='store_true', help='print one JSON object, nothing else')
    p.add_argument('--only', default='', help='comma-separated benchmark modules: '
                   + ', '.join(name for name, _ in modules()))
    p.add_argument('--quick', action='store_true', help='shorter runs (less precise)')


def run(args):
    wanted = {w.strip() for w in args.only.split(',') if w.strip()}
    known = {name for name, _ in modules()}
    unknown = wanted - known
    if unknown:
        from ..cli import UserError
        raise UserError(f'unknown benchmark(s) {sorted(unknown)}; known: {sorted(known)}')
    results = {}
    for name, module in modules():
        if wanted and name not in wanted:
            continue
        start = time.perf_counter()
        figures = module.run(quick=args.quick)
        results.update(figures)
        if not args.json:
            print(f'[{name}] ({time.perf_counter() - start:.1f} s)')
            for key, value in figures.items():
                print(f'  {key:32s} {value}')
        else:
            print(f'bench: {name} done in {time.perf_counter() - start:.1f} s', file=sys.stderr)
    if args.json:
        print(json.dumps(results, sort_keys=True))
    return 0
