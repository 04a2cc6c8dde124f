"""
Where numba keeps the compiled core's kernels (docs/core.md): once compiled, loaded from disk.

numba checks a cached kernel against its own source file only, while a kernel compiled into
another (``advance_scenario`` calls ``press_tips``, ``bend_walls``, ...) carries its callees'
code: an edit of contact.py would leave dynamics.py's cached step stale. So the cache lives in
a folder named after a digest of every kernel module of this package: any edit of one of them
starts a fresh folder, and compiles once.

The folder is under NUMBA_CACHE_DIR where set, else in this package's ``__pycache__`` (as numba
would put it), else in the user's cache folder (``$XDG_CACHE_HOME`` or ``~/.cache``,
``saw_ros/numba``) for a read-only install. Where none can be written the kernels still run,
compiled in memory at every start, and one line says so.
"""
from __future__ import annotations

import hashlib
import logging
import os
from pathlib import Path
import shutil
import time
from typing import Iterable, List, Mapping, Optional, Tuple

from numba.core import config as numba_config

PACKAGE = Path(__file__).resolve().parent
PREFIX = 'kernels-'
# Other versions' folders are removed once nothing was written in them for this long (s): a
# process of the version before an edit may still be compiling into its folder (numba fails on
# a cache file that vanishes under it).
STALE_S = 3600.0


def kernel_sources(folder: Path = PACKAGE) -> Iterable[Path]:
    """
    Return the modules of ``folder`` that hold numba kernels, sorted.

    A kernel is declared with numba.njit or with core.dynamic_walls' ``@compiled`` (which
    calls it): flexure.py has only the latter, and its edits went unseen before.
    """
    return sorted(p for p in folder.glob('*.py')
                  if any(mark in p.read_text(encoding='utf-8')
                         for mark in ('numba.njit', '@compiled')))


def digest(sources: Iterable[Path]) -> str:
    """Return a short digest of the sources' names and contents."""
    h = hashlib.sha256()
    for path in sources:
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def writable(folder: Path) -> bool:
    """Say whether ``folder`` exists or can be made, and a file can be written in it."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f'.probe-{os.getpid()}'
        probe.write_bytes(b'')
        probe.unlink()
        return True
    except OSError:
        return False


def cache_folder(environ: Mapping[str, str] = os.environ,
                 package: Path = PACKAGE) -> Tuple[Optional[Path], List[Path]]:
    """Return (the folder to cache kernels in, or None; the places tried)."""
    tried = []
    if environ.get('NUMBA_CACHE_DIR'):
        candidates = [Path(environ['NUMBA_CACHE_DIR'])]
    else:
        user = Path(environ.get('XDG_CACHE_HOME') or Path(environ.get('HOME', '/')) / '.cache')
        candidates = [package / '__pycache__' / 'numba', user / 'saw_ros' / 'numba']
    for base in candidates:
        tried.append(base)
        if writable(base):
            return base, tried
    return None, tried


def last_written(folder: Path) -> float:
    """Return the time anything in ``folder`` was last written (its own mtime if empty)."""
    return max([p.stat().st_mtime for p in folder.rglob('*')] + [folder.stat().st_mtime])


def use_cache(environ: Mapping[str, str] = os.environ, package: Path = PACKAGE) -> bool:
    """
    Point numba's cache at this version of the kernels; return False to compile in memory.

    The folders of other versions of the kernels in the same place are removed once stale.
    """
    # numba's settings are read from the environment at import: set at run time, not typed.
    if getattr(numba_config, 'DISABLE_JIT', False):
        return False
    base, tried = cache_folder(environ, package)
    if base is None:
        logging.getLogger('saw_ros.core').warning(
            'saw_ros: no writable cache for the compiled core (tried %s): compiling in memory',
            ', '.join(map(str, tried)))
        return False
    folder = base / (PREFIX + digest(kernel_sources(package)))
    for old in base.glob(PREFIX + '*'):
        if old != folder and time.time() - last_written(old) > STALE_S:
            shutil.rmtree(old, ignore_errors=True)
    setattr(numba_config, 'CACHE_DIR', str(folder))
    return True


# Whether the kernels of this package are cached on disk (``@numba.njit(cache=CACHE)``).
CACHE = use_cache()
# No kernel is parallel (a batch is spread over Python threads, dynamics.spread), but numba's
# threading layer starts when its thread count is read (numba.get_num_threads, the count the
# batch uses): its own work queue, never the OpenMP layer numba picks where GNU OpenMP is
# installed, which kills the children the local pool forks ("fork() called from a process
# already using GNU OpenMP").
if not os.environ.get('NUMBA_THREADING_LAYER'):
    setattr(numba_config, 'THREADING_LAYER', 'workqueue')
