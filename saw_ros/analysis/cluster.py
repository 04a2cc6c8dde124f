"""
Sweeps past one machine: a pool that runs the jobs on a Dask distributed cluster.

``DaskPool(address)`` has the interface of ``core.pool.LocalPool`` (``workers``, ``map``,
``close``, a context manager), so ``simulate(..., pool=)``, the figure sweeps, the campaign and
the calibration take either. ``pool_from(scheduler, workers)`` picks one: the local pool when
``scheduler`` is None, else the cluster at that address.

What goes over the wire: each job (a batch of scenarios and its settings) and the function that
runs it, pickled, and the result back (ARs, or a trajectory). The function is pickled by
reference, so every worker needs saw_ros installed (the same version); a worker without it is
named when the pool connects. ``distributed`` is imported only when a scheduler is given: the
core and the local runs never need it.
"""
from __future__ import annotations

import importlib.util
from typing import Callable, Iterable, Iterator, Optional

from saw_ros.core.pool import LocalPool, Pool, PoolError

CONNECT_TIMEOUT_S = 10.0


class DaskPool:
    """
    The workers of the Dask scheduler at ``address``; ``workers`` is their threads in all.

    Raises ``PoolError`` (one line) when the scheduler does not answer within ``timeout``
    seconds, has no worker, or a worker cannot import saw_ros.
    """

    def __init__(self, address: str, timeout: float = CONNECT_TIMEOUT_S):
        try:
            import distributed
        except ImportError:
            raise PoolError('--scheduler needs the Python package distributed '
                            '(pip install -r requirements.txt)') from None
        self.address = address
        try:
            # Checked first: a Client given a malformed address hangs for seconds when collected.
            distributed.comm.get_address_host_port(address)
        except ValueError as exc:
            raise PoolError(f'{address!r} is not a Dask scheduler address such as '
                            f'tcp://host:8786 ({_one_line(exc)})') from None
        try:
            self.client = distributed.Client(address, timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise PoolError(f'cannot reach the Dask scheduler at {address} within {timeout:g} s '
                            f'({_one_line(exc)})') from None
        try:
            self.workers = self._threads()
            if not self.workers:
                try:
                    self.client.wait_for_workers(1, timeout=timeout)
                except (OSError, TimeoutError):
                    raise PoolError(f'the Dask scheduler at {address} has no worker '
                                    f'(waited {timeout:g} s)') from None
                self.workers = self._threads()
            self.check_workers()
        except BaseException:
            self.client.close()
            raise

    def __repr__(self) -> str:
        return f'DaskPool({self.address!r}, workers={self.workers})'

    def _threads(self) -> int:
        info = self.client.scheduler_info(n_workers=-1)['workers']
        return sum(int(w.get('nthreads', 1)) for w in info.values())

    def check_workers(self) -> None:
        """Raise ``PoolError`` naming the workers that cannot import saw_ros."""
        # A lambda is pickled by value (cloudpickle), so it runs on a worker without saw_ros,
        # where a function of this module would itself fail to unpickle; it uses stdlib only.
        origins = self.client.run(
            lambda: getattr(importlib.util.find_spec('saw_ros'), 'origin', None),
            on_error='return')
        missing = sorted(w for w, origin in origins.items() if not isinstance(origin, str))
        if missing:
            raise PoolError(f'saw_ros is not importable on Dask worker(s) {", ".join(missing)} '
                            f"of {self.address}: install it in every worker's environment")

    # Named as Executor.map and Client.map are, which every reader of a pool expects.
    def map(self, function: Callable, jobs: Iterable) -> Iterator:  # noqa: A003
        """Yield ``function(job)`` for every job, in order, computed on the cluster."""
        # pure=False: equal jobs are still separate tasks (no key hashing of large batches).
        futures = self.client.map(function, list(jobs), pure=False)
        try:
            for future in futures:
                try:
                    yield future.result()
                except ImportError as exc:
                    self.check_workers()
                    raise PoolError(f'a Dask worker of {self.address} failed to import: '
                                    f'{_one_line(exc)}') from None
        finally:
            self.client.cancel(futures)

    def close(self) -> None:
        """Disconnect (the cluster keeps running)."""
        self.client.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _one_line(exc: BaseException) -> str:
    return ' '.join(str(exc).split()) or type(exc).__name__


def pool_from(scheduler: Optional[str] = None, workers: int = 1,
              timeout: float = CONNECT_TIMEOUT_S) -> Pool:
    """
    Return the pool to run on: ``LocalPool(workers)``, or ``DaskPool(scheduler)`` if given.

    ``workers`` does not apply to a cluster: it runs as many jobs at once as it has threads.
    """
    if scheduler:
        return DaskPool(scheduler, timeout)
    return LocalPool(workers)
