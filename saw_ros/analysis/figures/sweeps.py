"""
The sweeps behind the paper's figures, computed with the batched core (no rclpy, no plotting).

Every wave point of every figure is gathered first, duplicates removed (the default case appears
in Figures 9, 10, 11 and 21), and the lot is stepped as one batch by ``core.dynamics.simulate``,
or, given a pool of several workers (local processes or a Dask cluster), as ``pool.workers``
batches cut by ``core.pool.batches``: the same cut for every pool of that size, hence the same
numbers. The worm points are closed-form or quasi-static and cost nothing.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from saw_ros.core import worm as worm_model
from saw_ros.core.dynamics import DivergenceError, simulate
from saw_ros.core.metrics import analyse, settling_time, velocity_cci
from saw_ros.core.params import Scenario
from saw_ros.core.pool import batches, Pool
from saw_ros.core.statics import FIGURE4_CASES, minimal_normal_forces, top_surface_needed_above

FIGURES = ('4', '7', '8', '9', '10', '11', '20', '21')

GAPS_MM = (40.0, 45.0, 50.0)
COFS = (0.2, 0.5, 1.0)
FIG10_SLOPES = (0.0, 30.0, 60.0, 90.0)


@dataclass(frozen=True)
class Grid:
    slopes: Tuple[float, ...]        # deg
    stiffness: Tuple[float, ...]     # N/m
    duration: float                  # s of simulated time per wave point
    record_every: int = 5            # 5 ms samples for AR (the core steps at 1 ms)


FULL = Grid(tuple(float(s) for s in range(0, 91, 5)),
            tuple(float(k) for k in range(100, 1001, 50)), 4.0)
QUICK = Grid((0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0),
             (100.0, 200.0, 300.0, 400.0, 600.0, 800.0, 1000.0), 3.0)

# A wave point: (slope deg, gap mm, kt N/m, mu). The defaults are the paper's set-up.
Point = Tuple[float, float, float, float]
DEFAULT_KT = Scenario().surface.tangential_stiffness
DEFAULT_GAP_MM = Scenario().conditions.gap * 1000.0
DEFAULT_MU = Scenario().surface.friction_coefficient
FIG21_KT = round(worm_model.FIGURE21_STIFFNESS, 1)


def point(slope=0.0, gap=DEFAULT_GAP_MM, kt=DEFAULT_KT, mu=DEFAULT_MU) -> Point:
    return (float(slope), float(gap), float(kt), float(mu))


def scenario_of(p: Point, base: Scenario = Scenario()) -> Scenario:
    slope, gap, kt, mu = p
    return base.with_values({'conditions.slope': math.radians(slope),
                             'conditions.gap': gap / 1000.0,
                             'surface.tangential_stiffness': kt,
                             'surface.friction_coefficient': mu})


def wave_points(figure: str, grid: Grid) -> List[Point]:
    if figure == '9':
        return [point(s, gap=g) for g in GAPS_MM for s in grid.slopes]
    if figure in ('10', '20'):
        return [point(s, kt=k) for s in FIG10_SLOPES for k in grid.stiffness]
    if figure == '11':
        return [point(s, mu=mu) for mu in COFS for s in grid.slopes]
    if figure == '21':
        return [point(s, kt=kt, mu=mu) for kt in (FIG21_KT, DEFAULT_KT) for mu in COFS
                for s in grid.slopes]
    return []


@dataclass
class Data:
    """Everything the figures, CSVs and claims need."""

    grid: Grid
    figures: Tuple[str, ...]
    wave_ar: Dict[Point, float] = field(default_factory=dict)        # nan: diverged
    timeseries: Optional[dict] = None                                 # Figures 7 and 8
    timings: Dict[str, float] = field(default_factory=dict)
    base: Scenario = field(default_factory=Scenario)                  # the wave's parameters
    wave_batches: int = 1                                             # parts the pool ran

    def ar(self, **kw) -> float:
        return self.wave_ar[point(**kw)]


def run_wave_batch(points: Sequence[Point], grid: Grid,
                   progress: Optional[Callable[[int], None]] = None,
                   base: Scenario = Scenario()) -> Dict[Point, float]:
    """
    AR of every point, one batch.

    A batch that diverges is split until the culprit is alone (its AR is then nan).
    """
    if not points:
        return {}
    scenarios = [scenario_of(p, base) for p in points]
    try:
        tr = simulate(scenarios, grid.duration, record_every=grid.record_every,
                      progress=(lambda n: progress(n * len(points))) if progress else None)
    except DivergenceError:
        if len(points) == 1:
            return {points[0]: float('nan')}
        half = len(points) // 2
        out = run_wave_batch(points[:half], grid, progress, base)
        out.update(run_wave_batch(points[half:], grid, progress, base))
        return out
    robot = scenarios[0].robot
    return {p: analyse(tr.t, tr.q[:, i], robot, scenarios[i].frequency).advance_ratio
            for i, p in enumerate(points)}


def _wave_job(job) -> Dict[Point, float]:
    points, grid, base = job
    return run_wave_batch(points, grid, base=base)


def run_waves(points: Sequence[Point], grid: Grid,
              progress: Optional[Callable[[int], None]] = None,
              pool: Optional[Pool] = None, base: Scenario = Scenario()) -> Dict[Point, float]:
    """
    AR of every point: one batch here, or ``pool.workers`` batches run by ``pool``.

    ``progress(n)`` counts scenario-steps (per batch when a pool runs them).
    """
    parts = batches(list(points), pool.workers if pool is not None else 1)
    if pool is None or len(parts) == 1:
        return run_wave_batch(points, grid, progress, base)
    steps = int(round(grid.duration / Scenario().integration.dt))
    out: Dict[Point, float] = {}
    for part, ars in zip(parts, pool.map(_wave_job, [(part, grid, base) for part in parts])):
        out.update(ars)
        if progress:
            progress(steps * len(part))
    return out


def run_timeseries(duration: float = 4.0, base: Scenario = Scenario()) -> dict:
    """Figures 7 and 8: the default case (of ``base``) from rest at 1 Hz, every 1 ms recorded."""
    sc = base
    tr = simulate(sc, duration)
    t, q = tr.t, tr.q[:, 0]
    f = sc.frequency
    m = analyse(t, q, sc.robot, f)
    tc, indices = velocity_cci(t, q, f)
    settle = {name: {thr: settling_time(tc, idx, thr) for thr in (0.02, 0.002)}
              for name, idx in indices.items()}
    return {'t': t, 'q': q, 'metrics': m, 'cci_t': tc, 'cci': indices, 'settle': settle,
            'frequency': f}


def figure4_table(step_deg: float = 1.0):
    slopes = np.arange(0.0, 90.0 + 1e-9, step_deg)
    rows = []
    for case in FIGURE4_CASES:
        b, t, tot = minimal_normal_forces(np.radians(slopes), case.external_force, case.mu)
        for s, bi, ti, si in zip(slopes, b, t, tot):
            rows.append((case.name, case.external_force, case.mu, s, bi, ti, si))
    thresholds = {c.name: top_surface_needed_above(c.external_force, c.mu) for c in FIGURE4_CASES}
    return rows, thresholds


def worm_ar(slope_deg, kt, mu, model='closed_form') -> worm_model.WormResult:
    sc = scenario_of(point(slope_deg, kt=kt, mu=mu))
    if model == 'closed_form':
        return worm_model.closed_form(sc)
    return worm_model.contact_law(sc)[0]


def compute(figures: Sequence[str] = FIGURES, quick: bool = False, progress=None,
            on_total: Optional[Callable[[int], None]] = None, pool: Optional[Pool] = None,
            base: Scenario = Scenario()) -> Data:
    """
    Run every sweep the requested figures need (the wave batch on ``pool``, if given).

    The wave runs with the parameters of ``base`` (the defaults, or a calibrated set); the worm
    stays the paper's (worm.py, calibrated at the defaults).

    ``on_total(n)`` is told the number of scenario-steps first; ``progress(n)`` then counts them.
    """
    import time
    grid = QUICK if quick else FULL
    figures = tuple(f for f in FIGURES if f in set(figures))
    data = Data(grid, figures, base=base)
    points = list(dict.fromkeys(p for f in figures for p in wave_points(f, grid)))
    steps = int(round(grid.duration / Scenario().integration.dt))
    ts_duration = 4.0
    ts_steps = int(round(ts_duration / Scenario().integration.dt)) \
        if {'7', '8'} & set(figures) else 0
    if on_total:
        on_total(len(points) * steps + ts_steps)
    start = time.perf_counter()
    data.wave_ar = run_waves(points, grid, progress, pool, base)
    data.wave_batches = len(batches(points, pool.workers if pool is not None else 1))
    data.timings['wave_batch_s'] = time.perf_counter() - start
    if ts_steps:
        start = time.perf_counter()
        data.timeseries = run_timeseries(ts_duration, base)
        if progress:
            progress(ts_steps)
        data.timings['timeseries_s'] = time.perf_counter() - start
    return data
