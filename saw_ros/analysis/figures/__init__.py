"""
Reproduce the paper's figures and hold our model against its claims (issue 7).

``reproduce(out_dir)`` runs the sweeps (one batch of the vectorised core), writes one CSV and one
PNG per figure into ``out_dir/figures`` and the fidelity report ``out_dir/fidelity.md``.
No rclpy here: the figures need only the numpy core and matplotlib (Agg).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
import time
from typing import Dict, List, Optional, Sequence

from saw_ros.analysis.figures import claims as claims_mod
from saw_ros.analysis.figures import plots as render, sweeps
from saw_ros.analysis.figures.sweeps import FIGURES
from saw_ros.core.pool import Pool

__all__ = ['FIGURES', 'reproduce', 'Result']


@dataclass
class Result:
    data: sweeps.Data
    claims: List[claims_mod.Claim]
    files: List[Path]
    report: Optional[Path]
    elapsed: float
    timings: Dict[str, float]


def reproduce(out_dir, figures: Sequence[str] = FIGURES, quick: bool = False,
              progress: bool = False, command: str = 'saw-ros figures',
              write_report: bool = True, pool: Optional[Pool] = None) -> Result:
    """
    Run the sweeps (on ``pool`` if given: see ``sweeps.run_waves``), write figures and report.

    Return what was computed, the claims, the files written and the timings.
    """
    start = time.perf_counter()
    out_dir = Path(out_dir)
    fig_dir = out_dir / 'figures'
    fig_dir.mkdir(parents=True, exist_ok=True)
    bar = None
    if progress:
        import sys
        from tqdm import tqdm
        bar = tqdm(total=0, unit='step', unit_scale=True, desc='figures', file=sys.stderr,
                   leave=False)

    def on_total(n):
        if bar is not None:
            bar.total = n
            bar.refresh()

    data = sweeps.compute(figures, quick, progress=bar.update if bar is not None else None,
                          on_total=on_total, pool=pool)
    if bar is not None:
        bar.close()
    t0 = time.perf_counter()
    files = []
    for f in data.figures:
        files += render.RENDER[f](data, fig_dir)
    data.timings['render_s'] = time.perf_counter() - t0
    claims = claims_mod.evaluate(data)
    elapsed = time.perf_counter() - start
    report_path = None
    if write_report:
        report_path = out_dir / 'fidelity.md'
        report_path.write_text(render.report(data, claims, 'figures', elapsed, command))
    data.timings['total_s'] = time.perf_counter() - start
    return Result(data, claims, files, report_path, elapsed, data.timings)
