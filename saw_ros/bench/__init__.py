"""
Benchmarks for ``saw-ros bench``.

One module per area, each with ``KEYS`` (the JSON keys it reports) and ``run(quick: bool) ->
dict``. They measure rates and ratios in one run, never assert.

A module that runs nodes as subprocesses keeps their logs in ``log_dir(module)``: a folder of
``out/bench_<date-time>/`` (one per bench run; ``saw-ros bench --logs DIR`` or the environment
variable ``SAW_BENCH_LOGS`` choose another), printed on stderr when first used. A subprocess
that does not finish in time is a failed rung (its log says where it stood), never a crash.
"""
import os
from pathlib import Path
import sys
import time
from typing import List

LOGS_ENV = 'SAW_BENCH_LOGS'
_announced: List[Path] = []


def logs_root() -> Path:
    """Return the folder of this bench run's logs (made and announced on first use)."""
    root = os.environ.get(LOGS_ENV)
    if not root:
        root = str(Path('out') / time.strftime('bench_%Y-%m-%d_%H-%M-%S'))
        os.environ[LOGS_ENV] = root
    path = Path(root).resolve()
    path.mkdir(parents=True, exist_ok=True)
    if not _announced:
        _announced.append(path)
        print(f'bench: subprocess logs in {path}', file=sys.stderr, flush=True)
    return path


def log_dir(module: str) -> Path:
    """``logs_root()/<module>``, created."""
    path = logs_root() / module
    path.mkdir(parents=True, exist_ok=True)
    return path


def tail(path: Path, lines: int = 5) -> str:
    """Return the last lines of a log, for a failed rung's report."""
    try:
        return '\n'.join(Path(path).read_text(errors='replace').splitlines()[-lines:])
    except OSError:
        return ''
