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

from concurrent.futures import CancelledError
import importlib.util
import logging
import threading
import time
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
        self.timeout = timeout
        try:
            # Checked first: a Client given a malformed address hangs for seconds when collected.
            distributed.comm.get_address_host_port(address)
        except ValueError as exc:
            raise PoolError(f'{address!r} is not a Dask scheduler address such as '
                            f'tcp://host:8786 ({_one_line(exc)})') from None
        # The client's reconnection attempts log tracebacks at ERROR once the scheduler is
        # gone; what went wrong is said in one PoolError instead. Restored on close().
        self._quiet = _Quiet(('distributed.client', 'distributed.comm', 'distributed.core'))
        try:
            self.client = _connect(distributed, address, timeout)
        except BaseException:
            self._quiet.restore()
            raise
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
            self.close()
            raise

    def __repr__(self) -> str:
        return f'DaskPool({self.address!r}, workers={self.workers})'

    def _threads(self) -> int:
        try:
            info = self.client.scheduler_info(n_workers=-1)['workers']
        except Exception as exc:  # noqa: BLE001  (a server that answered, but not as Dask)
            raise PoolError(f'{self.address} answered, but not as a Dask scheduler '
                            f'({_one_line(exc)})') from None
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
                yield self._result(future)
        finally:
            try:
                self.client.cancel(futures)
            except Exception:  # noqa: BLE001  (the scheduler is gone: nothing to cancel)
                pass

    def _result(self, future):
        """
        Return the result of one job; PoolError if the scheduler is lost while waiting.

        A job may run as long as it needs, but a scheduler that stays unreachable for the
        connection timeout is lost: the client would otherwise try to reconnect for ever.
        """
        from distributed import TimeoutError as DaskTimeout
        unreachable = None
        while True:
            try:
                return future.result(timeout=1.0)
            except ImportError as exc:
                self.check_workers()
                raise PoolError(f'a Dask worker of {self.address} failed to import: '
                                f'{_one_line(exc)}') from None
            except (DaskTimeout, TimeoutError):
                pass
            except (CancelledError, OSError) as exc:   # CommClosedError is an OSError
                raise PoolError(f'lost the Dask scheduler at {self.address} mid-run (the '
                                f'connection closed: {type(exc).__name__})') from None
            if self.client.status == 'running':
                unreachable = None
            elif unreachable is None:
                unreachable = time.monotonic()
            elif time.monotonic() - unreachable > self.timeout:
                raise PoolError(f'lost the Dask scheduler at {self.address} mid-run (unreachable '
                                f'for {self.timeout:g} s)')

    def close(self) -> None:
        """Disconnect (the cluster keeps running)."""
        try:
            self.client.close(timeout=self.timeout)
        except Exception:  # noqa: BLE001  (the scheduler is gone: nothing to close)
            pass
        finally:
            self._quiet.restore()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class _Quiet:
    """Loggers raised to CRITICAL until ``restore()``."""

    def __init__(self, names):
        self._levels = {name: logging.getLogger(name).level for name in names}
        for name in names:
            logging.getLogger(name).setLevel(logging.CRITICAL)

    def restore(self) -> None:
        for name, level in self._levels.items():
            logging.getLogger(name).setLevel(level)


def _connect(distributed, address: str, timeout: float):
    """
    Return a Client of the scheduler at ``address``; PoolError within about ``timeout`` s.

    A probe shakes hands first, bounded by ``timeout``: distributed bounds the TCP connection
    but not the handshake after it, so a server that accepts and never answers (not Dask) held
    the Client for ever, and one that answers something else raised whatever its bytes made of
    the frames (a MemoryError for 2.8 EiB); a Client that failed so also printed a traceback
    when collected. The probe runs on a thread of its own, given up on after the timeout.
    """
    import asyncio

    async def shake():
        comm = await asyncio.wait_for(distributed.comm.connect(address, timeout=timeout),
                                      timeout)
        await comm.close()

    out: dict = {}

    def probe():
        try:
            asyncio.run(shake())
        except BaseException as exc:  # noqa: BLE001  (reported below, in one line)
            out['error'] = exc

    thread = threading.Thread(target=probe, name='dask-probe', daemon=True)
    thread.start()
    thread.join(timeout + 2.0)
    exc = out.get('error')
    if thread.is_alive() or isinstance(exc, TimeoutError):
        raise PoolError(f'no Dask scheduler answered at {address} within {timeout:g} s '
                        '(nothing there, or something else listens)')
    if isinstance(exc, OSError):
        raise PoolError(f'cannot reach the Dask scheduler at {address} within {timeout:g} s '
                        f'({_one_line(exc)})')
    if exc is not None:
        raise PoolError(f'{address} does not answer as a Dask scheduler '
                        f'({type(exc).__name__}: {_one_line(exc)[:200]})')
    try:
        return distributed.Client(address, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as refused:
        raise PoolError(f'cannot reach the Dask scheduler at {address} within {timeout:g} s '
                        f'({_one_line(refused)})') from None


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
