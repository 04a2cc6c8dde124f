"""
The paper's questions again, with walls that bend (issue 23; docs/walls.md).

Sweeps of the wave robot on bending walls (core.walls): its AR against the foundation stiffness
k (the tissue or frame behind each surface) at the sheet's bending stiffness, level, 45 degrees
and vertical, and against the bending stiffness EI at the silicone sheet's foundation; with the
wall's largest deflection under the robot (the gap it opens) and the runs that could not go on
(the robot pushed through a wall: a divergence, or stalled: AR under STALL_AR). The worm of the
paper's Section 7 (core.worm, closed form) on the same walls beside it: the comparison of its
Figures 20-21 extended to bendable walls.

Every run is its own job on the pool, so that one robot pushed through its wall does not end
the batch. ``saw-ros figures`` writes walls.csv, walls.png and a section of the fidelity report.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Dict, List, Optional, Tuple

import numpy as np

from saw_ros.core import worm as worm_model
from saw_ros.core.dynamics import DivergenceError, Simulator
from saw_ros.core.metrics import analyse
from saw_ros.core.params import Scenario
from saw_ros.core.pool import LocalPool, Pool

SLOPES_DEG = (0.0, 45.0, 90.0)
FOUNDATIONS = tuple(float(k) for k in np.logspace(3.5, 7.0, 8))           # N/m^2
QUICK_FOUNDATIONS = (3e3, 3e4, 3e5, 1e7)
BENDINGS = tuple(float(e) for e in np.logspace(-6.0, -1.0, 6))            # N m^2
SHEET_FOUNDATION = 1.5e5      # N/m^2: the silicone sheet on foam of docs/walls.md
DURATION_S = 4.0              # the paper-figure sweeps' run length
STALL_AR = 0.05


@dataclass
class WallRun:
    slope_deg: float
    foundation: float            # N/m^2 (0: rigid)
    bending: float               # N m^2
    advance_ratio: float         # nan when the run could not go on
    gap_opened: float            # m: mean over the second half of the largest wall deflection
    status: str                  # 'ok', 'stalled', 'pushed through'
    worm_ar: float
    worm_slips: bool


@dataclass
class WallsData:
    runs: List[WallRun] = field(default_factory=list)
    rigid_ar: Dict[float, float] = field(default_factory=dict)


def _job(job: Tuple[Scenario, float]) -> Tuple[float, float, str]:
    scenario, duration = job
    sim = Simulator(scenario)
    steps = int(round(duration / sim.dt))
    t = np.empty(steps)
    q = np.empty((steps, 6))
    opened = np.zeros(steps)
    try:
        for k in range(steps):
            sim.step()
            t[k], q[k] = sim.t, sim.q[:, 0]
            if sim.walls is not None:
                opened[k] = sim.walls.largest[0]
    except DivergenceError:
        return math.nan, float(opened[:max(k, 1)].max()), 'pushed through'
    metrics = analyse(t, q, scenario.robot, scenario.frequency)
    ar = metrics.advance_ratio
    status = 'ok' if ar >= STALL_AR else 'stalled'
    return ar, float(opened[steps // 2:].mean()), status


def scenarios(quick: bool = False) -> List[Tuple[float, float, float]]:
    """Return the (slope deg, k, EI) of the sweep, rigid walls (k = 0) first per slope."""
    bending = Scenario().surface.bending_stiffness
    grid = [(s, 0.0, bending) for s in SLOPES_DEG]
    grid += [(s, k, bending) for s in SLOPES_DEG
             for k in (QUICK_FOUNDATIONS if quick else FOUNDATIONS)]
    grid += [(0.0, SHEET_FOUNDATION, e) for e in (BENDINGS[::2] if quick else BENDINGS)]
    return grid


def compute(quick: bool = False, pool: Optional[Pool] = None,
            base: Scenario = Scenario()) -> WallsData:
    pool = pool if pool is not None else LocalPool(1)
    grid = scenarios(quick)
    jobs = [(base.with_values({'conditions.slope': math.radians(s),
                               'surface.foundation_stiffness': k,
                               'surface.bending_stiffness': e}),
             2.5 if quick else DURATION_S) for s, k, e in grid]
    data = WallsData()
    outcomes = pool.map(_job, jobs)
    for (slope, k, e), (scenario, _), (ar, opened, status) in zip(grid, jobs, outcomes):
        worm = worm_model.closed_form(scenario)
        data.runs.append(WallRun(slope, k, e, ar, opened, status, worm.advance_ratio,
                                 worm.anchors_slip))
        if k == 0.0:
            data.rigid_ar[slope] = ar
    return data


def lowest_working_foundation(data: WallsData, slope: float) -> Optional[float]:
    """Return the softest foundation of the sweep from which on every stiffer one went 'ok'."""
    runs = sorted((r for r in data.runs if r.slope_deg == slope and r.foundation > 0
                   and r.bending == Scenario().surface.bending_stiffness),
                  key=lambda r: r.foundation)
    lowest = None
    for r in reversed(runs):
        if r.status != 'ok':
            break
        lowest = r.foundation
    return lowest


def write(data: WallsData, fig_dir) -> List:
    """walls.csv and walls.png in ``fig_dir``; return their paths."""
    import csv
    from pathlib import Path

    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt

    fig_dir = Path(fig_dir)
    csv_path = fig_dir / 'walls.csv'
    with open(csv_path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['slope_deg', 'foundation_N_m2', 'bending_N_m2', 'wave_ar', 'status',
                    'gap_opened_mm', 'worm_ar', 'worm_slips'])
        for r in data.runs:
            w.writerow([f'{r.slope_deg:g}', f'{r.foundation:.6g}', f'{r.bending:.6g}',
                        'not computed' if math.isnan(r.advance_ratio)
                        else f'{r.advance_ratio:.4f}', r.status,
                        f'{1000 * r.gap_opened:.3f}', f'{r.worm_ar:.4f}', r.worm_slips])
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    bending = Scenario().surface.bending_stiffness
    for slope, colour in zip(SLOPES_DEG, ('C0', 'C1', 'C2')):
        runs = sorted((r for r in data.runs if r.slope_deg == slope and r.foundation > 0
                       and r.bending == bending), key=lambda r: r.foundation)
        k = [r.foundation for r in runs]
        axes[0].semilogx(k, [r.advance_ratio for r in runs], 'o-', color=colour,
                         label=f'wave {slope:g} deg')
        axes[0].semilogx(k, [r.worm_ar for r in runs], 's--', color=colour, alpha=0.6,
                         label=f'worm {slope:g} deg')
        axes[0].axhline(data.rigid_ar.get(slope, math.nan), color=colour, lw=0.8, ls=':')
        for r in runs:
            if r.status != 'ok':
                axes[0].annotate(r.status, (r.foundation, 0.02), color=colour, fontsize=7,
                                 rotation=90)
        axes[1].loglog(k, [max(1000 * r.gap_opened, 1e-4) for r in runs], 'o-', color=colour,
                       label=f'{slope:g} deg')
    axes[0].set_xlabel('foundation stiffness k (N/m$^2$)')
    axes[0].set_ylabel('advance ratio')
    axes[0].set_ylim(0, 1.05)
    axes[0].set_title(f'AR on bending walls (EI {bending:g} N m$^2$); dotted: rigid')
    axes[0].legend(fontsize=7)
    axes[1].set_xlabel('foundation stiffness k (N/m$^2$)')
    axes[1].set_ylabel('largest wall deflection (mm)')
    axes[1].set_title('the gap the robot opens')
    axes[1].legend(fontsize=7)
    runs = sorted((r for r in data.runs if r.foundation == SHEET_FOUNDATION
                   and r.slope_deg == 0.0 and r.bending != bending),
                  key=lambda r: r.bending)
    axes[2].semilogx([r.bending for r in runs], [r.advance_ratio for r in runs], 'o-',
                     label='wave')
    axes[2].semilogx([r.bending for r in runs], [r.worm_ar for r in runs], 's--',
                     label='worm')
    axes[2].axhline(data.rigid_ar.get(0.0, math.nan), color='grey', lw=0.8, ls=':')
    axes[2].set_xlabel('bending stiffness EI (N m$^2$)')
    axes[2].set_ylabel('advance ratio (level)')
    axes[2].set_title(f'against EI at k = {SHEET_FOUNDATION:g} N/m$^2$')
    axes[2].set_ylim(0, 1.05)
    axes[2].legend(fontsize=7)
    fig.tight_layout()
    png = fig_dir / 'walls.png'
    fig.savefig(png, dpi=100)
    plt.close(fig)
    return [csv_path, png]


def report_section(data: WallsData) -> str:
    """Return the fidelity report's section on bending walls, every number from ``data``."""
    bending = Scenario().surface.bending_stiffness
    lines = ['', '## Walls that bend (beyond the paper)', '',
             'Every claim above is computed with rigid walls (`surface.foundation_stiffness` 0, '
             'the default): bending walls change none of them. With walls that bend '
             '([docs/walls.md](walls.md)), the wave robot against the foundation stiffness (EI '
             f'{bending:g} N m^2) and the worm (closed form) on the same walls '
             '([figures/walls.png](figures/walls.png), [figures/walls.csv](figures/walls.csv)):',
             '', '| slope | k (N/m^2) | wave AR | wave status | gap opened (mm) | worm AR |',
             '|---|---|---|---|---|---|']
    for r in data.runs:
        if r.bending != bending:
            continue
        ar = 'not computed (pushed through)' if math.isnan(r.advance_ratio) \
            else f'{r.advance_ratio:.3f}'
        k = 'rigid' if r.foundation == 0 else f'{r.foundation:.3g}'
        worm = 'slips' if r.worm_slips else f'{r.worm_ar:.3f}'
        lines.append(f'| {r.slope_deg:g} deg | {k} | {ar} | {r.status} | '
                     f'{1000 * r.gap_opened:.2f} | {worm} |')
    lines.append('')
    for slope in SLOPES_DEG:
        lowest = lowest_working_foundation(data, slope)
        lines.append(f'- {slope:g} deg: the wave robot works on every foundation of the sweep '
                     + (f'from k = {lowest:.3g} N/m^2 up.' if lowest is not None else
                        "none of the sweep's foundations: it stalls or is pushed through on "
                        'all.'))
    return '\n'.join(lines) + '\n'
