"""
Measure the figures each issue names and print them (``--json``: one JSON object).

Every module in ``saw_ros/bench/`` contributes its keys; ``--only`` picks modules. Subprocess logs
go to one folder per run (``--logs``, default ``out/bench_<date-time>/``, made and printed on
stderr when a module first needs it). A module that fails anyway (an exception) does not end the
bench: its keys are null, ``bench_errors`` says why (the traceback is in
``<logs>/<module>.error``), the other modules run and the exit code is 1.
"""
import importlib
import json
import os
import pkgutil
import sys
import time
import traceback

from saw_ros import bench as benchmarks
from saw_ros.cli.checks import output_dir
from saw_ros.cli.errors import UserError

HELP = 'measure speed and accuracy figures (--json prints one JSON object)'


def modules():
    """Yield (name, module) of every benchmark module: those with KEYS (not loadgen, a tool)."""
    for info in sorted(pkgutil.iter_modules(benchmarks.__path__), key=lambda m: m.name):
        module = importlib.import_module(f'{benchmarks.__name__}.{info.name}')
        if hasattr(module, 'KEYS'):
            yield info.name, module


def add_arguments(p):
    p.add_argument('--json', action='store_true', help='print one JSON object, nothing else')
    p.add_argument('--only', default='', help='comma-separated benchmark modules: '
                   + ', '.join(name for name, _ in modules()))
    p.add_argument('--quick', action='store_true', help='shorter runs (less precise)')
    p.add_argument('--logs', default='', help='folder for the subprocess logs (default '
                   'out/bench_<date-time>)')


def run(args):
    wanted = {w.strip() for w in args.only.split(',') if w.strip()}
    known = {name for name, _ in modules()}
    unknown = wanted - known
    if unknown:
        raise UserError(f'unknown benchmark(s) {sorted(unknown)}; known: {sorted(known)}')
    if args.logs:
        output_dir(args.logs, '--logs')
        os.environ[benchmarks.LOGS_ENV] = args.logs
    results, errors = {}, {}
    for name, module in modules():
        if wanted and name not in wanted:
            continue
        start = time.perf_counter()
        try:
            figures = module.run(quick=args.quick)
        except Exception as exc:  # noqa: BLE001  (one module's failure is not the bench's)
            error = benchmarks.logs_root() / f'{name}.error'
            error.write_text(traceback.format_exc())
            errors[name] = f'{type(exc).__name__}: {exc} (see {error})'
            print(f'bench: {name} failed: {errors[name]}', file=sys.stderr, flush=True)
            figures = dict.fromkeys(getattr(module, 'KEYS', ()))
        results.update(figures)
        if not args.json:
            print(f'[{name}] ({time.perf_counter() - start:.1f} s)')
            for key, value in figures.items():
                print(f'  {key:32s} {value}')
        else:
            print(f'bench: {name} done in {time.perf_counter() - start:.1f} s', file=sys.stderr)
    if errors:
        results['bench_errors'] = errors
    if args.json:
        print(json.dumps(results, sort_keys=True))
    elif errors:
        print('failed: ' + '; '.join(f'{n}: {e}' for n, e in errors.items()))
    return 1 if errors else 0
