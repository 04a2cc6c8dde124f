"""
Issue 31: the wall time of the default design study (``saw-ros design``'s defaults).

- ``design_sweep_s``: ``analysis.design.run_study`` with the defaults of ``saw-ros design`` (a
  Latin hypercube of DEFAULT_SIZE geometries on the three walls, 6 V, SETTLE_S + MEASURE_S a
  run) on a local pool of every core, the outputs (CSV, figures, summary) written to a scratch
  folder; goal <= 600 s on the slower 2-core machine (about 3 times this one's time).
- ``design_sweep_runs``: how many runs it made (the refused ones too, which cost nearly
  nothing); ``design_runs_per_s``: the runs that ran per second of wall time.
- ``design_paper_dominated_rigid``: how many designs dominate the paper's robot on the rigid
  walls in speed against cost of transport (0: it is on the front).

``--quick``: a hypercube of 20 geometries, the same duration per run.
"""
import os
from pathlib import Path
import tempfile
import time

from saw_ros.analysis import design
from saw_ros.core import Scenario
from saw_ros.core.pool import LocalPool

KEYS = ('design_sweep_s', 'design_sweep_runs', 'design_runs_per_s',
        'design_paper_dominated_rigid')


def run(quick=False):
    base = Scenario().with_values({'motor.voltage': design.VOLTAGE})
    size = 20 if quick else design.DEFAULT_SIZE
    start = time.perf_counter()
    with LocalPool(os.cpu_count() or 1) as pool, tempfile.TemporaryDirectory() as scratch:
        study = design.run_study(base, 'lhs', size, pool=pool)
        design.write_outputs(study, Path(scratch))
    seconds = time.perf_counter() - start
    ran = sum(r.ok for r in study.runs)
    place = design.standing(study, 'rigid', 'cost_of_transport')
    return {'design_sweep_s': round(seconds, 1), 'design_sweep_runs': len(study.runs),
            'design_runs_per_s': round(ran / seconds, 2),
            'design_paper_dominated_rigid': len(place['dominated_by'])}
