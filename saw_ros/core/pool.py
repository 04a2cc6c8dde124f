"""
Where independent jobs run: the local pool (this machine's cores) and how batches are cut.

A pool maps a picklable function over a list of jobs and yields the results in the jobs' order::

    with pool:                        # close() at the end
        for result in pool.map(function, jobs):
            ...

``pool.workers`` is how many jobs it runs at once; callers cut their work into that many jobs
with ``batches`` (a job is one batch of scenarios, the unit of work). ``LocalPool`` forks
processes on this machine (the default everywhere); ``saw_ros.analysis.cluster.DaskPool`` runs
the same jobs on a Dask cluster. Both cut with the same ``batches``, so a sweep gives the same
numbers, bit for bit, with either pool of the same size.

Why the size matters: the batched core sums each scenario's tip forces with a matrix product,
and BLAS may add the terms in another order for another number of rows, which moves the last
bit of some results (about 1e-14 relative). Cutting into the same batches gives the same rows.
"""
from __future__ import annotations

from typing import Any, Callable, Iterable, Iterator, List, Protocol, Sequence

import numpy as np

# Below this many scenarios a batch costs more in per-step overhead than a second core saves.
SMALLEST_BATCH = 16


class Pool(Protocol):
    """What ``simulate``, the sweeps and the campaign need of a pool."""

    workers: int

    # Named as Executor.map and Client.map are, which every reader of a pool expects.
    def map(self, function: Callable[[Any], Any],  # noqa: A003
            jobs: Iterable[Any]) -> Iterator[Any]:
        """Yield ``function(job)`` for every job, in order."""

    def close(self) -> None:
        """Release what the pool holds (processes, a connection)."""


class PoolError(RuntimeError):
    """A pool cannot run the jobs (scheduler unreachable, a worker without saw_ros): one line."""


def batches(items: Sequence[Any], parts: int,
            smallest: int = SMALLEST_BATCH) -> List[List[Any]]:
    """
    Cut ``items`` into at most ``parts`` contiguous batches of near-equal size, in order.

    No batch is smaller than ``smallest`` unless there is only one. The cut depends on
    ``len(items)``, ``parts`` and ``smallest`` only, never on the pool that runs the batches.
    """
    count = max(1, min(int(parts), len(items) // max(1, smallest)))
    bounds = np.linspace(0, len(items), count + 1).astype(int)
    return [list(items[a:b]) for a, b in zip(bounds[:-1], bounds[1:])]


class LocalPool:
    """
    Forked processes on this machine (``workers`` of them); in this process when 1.

    A fresh fork per ``map``: the children inherit the modules, tables and compiled kernels
    already built, so nothing but the jobs and the results is pickled.
    """

    def __init__(self, workers: int = 1):
        self.workers = max(1, int(workers))

    def __repr__(self) -> str:
        return f'LocalPool(workers={self.workers})'

    # Named as Executor.map and Client.map are, which every reader of a pool expects.
    def map(self, function: Callable[[Any], Any],  # noqa: A003
            jobs: Iterable[Any]) -> Iterator[Any]:
        """Yield ``function(job)`` for every job, in order."""
        jobs = list(jobs)
        processes = min(self.workers, len(jobs))
        if processes <= 1:
            for job in jobs:
                yield function(job)
            return
        import multiprocessing
        # The children inherit the compiled kernels if this process has them: else every child
        # of every map would load them from the disk cache again (about half a second each).
        from saw_ros.core.dynamics import warm_up
        warm_up()
        with multiprocessing.get_context('fork').Pool(processes) as pool:
            yield from pool.imap(function, jobs)

    def close(self) -> None:
        """Nothing to release: each ``map`` ends its own processes."""

    def __enter__(self) -> 'LocalPool':
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
