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
from typing import Dict, List, Optional, Sequence, Union

from saw_ros.analysis.figures import claims as claims_mod
from saw_ros.analysis.figures import plots as render, sweeps
from saw_ros.analysis.figures.sweeps import FIGURES
from saw_ros.core.params import Scenario
from saw_ros.core.pool import Pool
from saw_ros.interface.config import config_path, load_scenario

CALIBRATED_FILE = 'simulator_calibrated.yaml'

__all__ = ['Calibrated', 'EXTRAS', 'FIGURES', 'reproduce', 'Result']
# Beyond the paper's figures: the same questions on walls that bend (analysis.walls_study).
EXTRAS = ('walls',)


@dataclass
class Result:
    data: sweeps.Data
    claims: List[claims_mod.Claim]
    files: List[Path]
    report: Optional[Path]
    elapsed: float
    timings: Dict[str, float]
    calibrated: Optional['Calibrated'] = None


@dataclass
class Calibrated:
    """The same claims with a calibrated parameter set (msg_config/simulator_calibrated.yaml)."""

    path: Path
    values: Dict[str, float]           # the parameters that differ from the defaults
    trained: List[str]                 # claim ids the calibration was fitted to
    data: sweeps.Data
    claims: List[claims_mod.Claim]


def calibrated_file() -> Optional[Path]:
    """Return msg_config/simulator_calibrated.yaml if it exists (the shipped calibrated set)."""
    path = config_path(CALIBRATED_FILE)
    return path if path.exists() else None


def reproduce(out_dir, figures: Sequence[str] = FIGURES, quick: bool = False,
              progress: bool = False, command: str = 'saw-ros figures',
              write_report: bool = True, pool: Optional[Pool] = None,
              calibrated: Union[str, Path, None] = 'shipped') -> Result:
    """
    Run the sweeps (on ``pool`` if given: see ``sweeps.run_waves``), write figures and report.

    ``calibrated``: a calibrated simulator parameter file whose claims the report shows beside
    the defaults' ('shipped': msg_config/simulator_calibrated.yaml if it exists; None: defaults
    only). The figures are drawn with the defaults. Return what was computed, the claims, the
    files written and the timings.
    """
    start = time.perf_counter()
    with_walls = 'walls' in figures
    figures = [f for f in figures if f not in EXTRAS]
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

    if calibrated == 'shipped':
        calibrated = calibrated_file()
    cal_path = Path(calibrated) if calibrated is not None else None
    cal_base = load_scenario(cal_path) if cal_path is not None else None

    def on_total_both(n):
        on_total(n * (2 if cal_base is not None else 1))   # both parameter sets, one bar

    update = bar.update if bar is not None else None
    data = sweeps.compute(figures, quick, progress=update, on_total=on_total_both, pool=pool)
    cal = None
    if cal_base is not None and cal_path is not None:
        t0 = time.perf_counter()
        cal_data = sweeps.compute(figures, quick, progress=update, pool=pool, base=cal_base)
        from saw_ros.analysis.calibrate import trained_claims_of
        defaults = Scenario().flat()
        cal = Calibrated(cal_path, {k: v for k, v in cal_base.flat().items()
                                    if v != defaults[k]},
                         trained_claims_of(calibrated), cal_data, claims_mod.evaluate(cal_data))
        data.timings['calibrated_s'] = time.perf_counter() - t0
    if bar is not None:
        bar.close()
    t0 = time.perf_counter()
    files = []
    for f in data.figures:
        files += render.RENDER[f](data, fig_dir)
    data.timings['render_s'] = time.perf_counter() - t0
    claims = claims_mod.evaluate(data)
    walls_text = ''
    if with_walls:
        from saw_ros.analysis import walls_study
        t0 = time.perf_counter()
        walls = walls_study.compute(quick, pool)
        files += walls_study.write(walls, fig_dir)
        walls_text = walls_study.report_section(walls)
        data.timings['walls_s'] = time.perf_counter() - t0
    elapsed = time.perf_counter() - start
    report_path = None
    if write_report:
        report_path = out_dir / 'fidelity.md'
        report_path.write_text(render.report(data, claims, 'figures', elapsed, command, cal)
                               + walls_text)
    data.timings['total_s'] = time.perf_counter() - start
    return Result(data, claims, files, report_path, elapsed, data.timings, cal)
