"""
The flags that choose where a command's sweeps run, shared by every command that runs them.

A command adds them with ``add_pool_arguments(parser)`` and gets its pool with
``pool_from_args(args)`` (close it, or use it as a context manager)::

    def add_arguments(p):
        add_pool_arguments(p)        # --workers N, --scheduler ADDRESS, --scheduler-timeout S

    def run(args):
        with pool_from_args(args) as pool:
            simulate(scenarios, pool=pool)    # or pool.map(function, jobs)

``--workers N`` (default: the local cores, or the command's ``workers=``) forks N processes on
this machine;
``--scheduler tcp://host:8786`` runs the batches on that Dask cluster instead (docs/cluster.md).
A scheduler that does not answer, or a worker without saw_ros, is a ``UserError`` (one line).
"""
import math
import os
from typing import Optional

from saw_ros.analysis.cluster import CONNECT_TIMEOUT_S, pool_from
from saw_ros.cli.errors import UserError
from saw_ros.core.pool import Pool, PoolError


def add_pool_arguments(parser, workers: Optional[int] = None) -> None:
    """
    Add --workers, --scheduler and --scheduler-timeout to ``parser`` (one group).

    ``workers``: the default number of local processes; None means every local core.
    """
    workers = workers or os.cpu_count() or 1
    g = parser.add_argument_group('where the sweeps run')
    g.add_argument('--workers', type=int, default=workers, metavar='N',
                   help=f'local processes (default {workers}: the local cores); the batch is cut '
                   'into that many parts')
    g.add_argument('--scheduler', default=None, metavar='ADDRESS',
                   help='run the batches on the Dask cluster of this scheduler, e.g. '
                   'tcp://host:8786 (docs/cluster.md); --workers then does not apply')
    g.add_argument('--scheduler-timeout', type=float, default=CONNECT_TIMEOUT_S,
                   metavar='SECONDS', help='give up connecting to the scheduler after this '
                   f'long ({CONNECT_TIMEOUT_S:g})')


def pool_from_args(args) -> Pool:
    """Return the pool the flags of ``add_pool_arguments`` chose; a ``UserError`` if it fails."""
    if args.workers < 1:
        raise UserError(f'--workers must be at least 1, got {args.workers}')
    if not args.scheduler_timeout > 0 or not math.isfinite(args.scheduler_timeout):
        raise UserError(f'--scheduler-timeout {args.scheduler_timeout:g}: must be a finite time '
                        f'> 0 s')
    try:
        return pool_from(args.scheduler, args.workers, args.scheduler_timeout)
    except PoolError as exc:
        raise UserError(str(exc)) from None
