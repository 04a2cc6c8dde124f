"""
What a Dask cluster costs over the local pool (issue 13): the same figure sweep on both.

A two-worker Dask cluster on this machine (one thread each, processes) against ``LocalPool(2)``:
the wave sweep of every figure (``--quick``: the coarse grid), cut into the same two batches,
once each. ``dask_overhead_pct`` is (t_dask - t_local) / t_local * 100. The cluster's start-up
is not counted: a short sweep runs first in this process (the local pool's forks inherit its
modules and tables) and on the cluster (its workers import and build theirs), then the clock.
"""
import time

KEYS = ['dask_overhead_pct', 'dask_sweep_s', 'local_sweep_s']


def _timed(function, *args) -> float:
    start = time.perf_counter()
    function(*args)
    return time.perf_counter() - start


def run(quick=False):
    import distributed

    from saw_ros.analysis.cluster import DaskPool
    from saw_ros.analysis.figures import sweeps
    from saw_ros.core.pool import LocalPool
    grid = sweeps.QUICK if quick else sweeps.FULL
    points = list(dict.fromkeys(p for f in sweeps.FIGURES for p in sweeps.wave_points(f, grid)))
    warm = sweeps.Grid(grid.slopes, grid.stiffness, 0.05, grid.record_every)
    local = LocalPool(2)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=':0') as cluster, \
            DaskPool(cluster.scheduler_address) as dask:
        sweeps.run_waves(points, warm)              # here, for the local pool's forks
        sweeps.run_waves(points, warm, pool=dask)   # in both Dask workers
        t_local = _timed(sweeps.run_waves, points, grid, None, local)
        t_dask = _timed(sweeps.run_waves, points, grid, None, dask)
    return {'dask_overhead_pct': round((t_dask - t_local) / t_local * 100.0, 1),
            'dask_sweep_s': round(t_dask, 3), 'local_sweep_s': round(t_local, 3)}
