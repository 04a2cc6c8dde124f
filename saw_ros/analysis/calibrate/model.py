"""
The model under the targets: every candidate under every target condition, as one batch.

Candidates that change the robot's geometry go in batches of their own (the engine steps one
robot at a time). The objective is the mean squared relative error over the targets.
"""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from saw_ros.analysis.calibrate.targets import Target
from saw_ros.core.dynamics import DivergenceError, simulate
from saw_ros.core.metrics import analyse
from saw_ros.core.params import ParameterError, Scenario
from saw_ros.core.pool import batches, Pool


# A candidate whose simulation diverged or never moved: as bad as a 300 % error on every target.
FAILED_LOSS = 9.0
RECORD_EVERY = 5             # 5 ms samples for speed and AR, as the figure sweeps


def sweeps_duration() -> float:
    """Return the simulated time per point of the figure sweeps (full grids), s."""
    from saw_ros.analysis.figures.sweeps import FULL
    return FULL.duration


def _outcome(target: Target, scenario: Scenario, t, q, omega=None) -> float:
    """
    Return the model's speed or AR of one recorded run.

    ``omega``: the helix speed of a run the motor drove; its AR is then taken at the mean helix
    frequency the load left it, as the paper's AR divides by the wave's actual speed.
    """
    m = analyse(t, q, scenario.robot, scenario.frequency, omega=omega)
    return m.v_mean if target.quantity == 'speed' else m.advance_ratio


def _simulate_group(job) -> np.ndarray:
    """
    Simulate one batch of (candidate, target) scenarios; returns the outcomes, (n,).

    A batch that diverges is split in halves until the culprits are alone (their outcome nan),
    as the figure sweeps do.
    """
    scenarios, targets, duration = job
    try:
        tr = simulate(list(scenarios), duration, record_every=RECORD_EVERY)
    except DivergenceError:
        if len(scenarios) == 1:
            return np.array([float('nan')])
        h = len(scenarios) // 2
        return np.concatenate([_simulate_group((scenarios[:h], targets[:h], duration)),
                               _simulate_group((scenarios[h:], targets[h:], duration))])
    out = np.empty(len(scenarios))
    omega = getattr(tr, 'omega', None)
    for i, (s, target) in enumerate(zip(scenarios, targets)):
        driven = omega[:, i] if omega is not None and s.motor.voltage > 0.0 else None
        try:
            out[i] = _outcome(target, s, tr.t, tr.q[:, i], driven)
        except ValueError:
            out[i] = float('nan')
    return out


class Model:
    """
    Outcomes of candidate parameter sets under every target, one batch per call.

    The scenarios of one robot geometry are cut into ``pool.workers`` batches
    (``core.pool.batches``, the cut the sweeps use) and run by ``pool``: this process without one,
    local processes or a Dask cluster with one.
    """

    def __init__(self, targets: Sequence[Target], base: Optional[Scenario] = None,
                 pool: Optional[Pool] = None, duration: Optional[float] = None):
        self.targets = list(targets)
        self.base = base or Scenario()
        self.pool = pool
        self.measured = np.array([t.measured for t in self.targets])
        # One duration for every candidate, fixed from the defaults' no-load frequencies: a
        # candidate's outcomes must not depend on which others share its batch. The figure
        # sweeps' 4 s (so the AR targets read as the claims do), longer where a slow helix needs
        # it to settle (about 1 s) and then turn two whole cycles.
        self.duration = duration or max(
            sweeps_duration(), *(1.0 + 2.0 / max(s.frequency, 0.05)
                                 for s in self.scenarios({})))

    def scenarios(self, values: Dict[str, float]) -> List[Scenario]:
        candidate = self.base.with_values(values)
        return [candidate.with_values(t.condition()) for t in self.targets]

    def outcomes(self, candidates: Sequence[Dict[str, float]]) -> np.ndarray:
        """Return (candidates, targets) outcomes; nan where a run diverged or did not move."""
        n_t = len(self.targets)
        groups: Dict[Tuple, List[Tuple[int, Scenario, Target]]] = {}
        for c, values in enumerate(candidates):
            try:
                scenarios = self.scenarios(values)
            except ParameterError:
                continue                     # an impossible set (e.g. a robot that cannot fit)
            for k, s in enumerate(scenarios):
                key = (s.robot, s.integration.dt)
                groups.setdefault(key, []).append((c * n_t + k, s, self.targets[k]))
        out = np.full(len(candidates) * n_t, float('nan'))
        jobs, slots = [], []
        workers = self.pool.workers if self.pool is not None else 1
        for group in groups.values():
            duration = self.duration
            for items in batches(group, workers):
                jobs.append((tuple(s for _, s, _ in items), tuple(t for _, _, t in items),
                             duration))
                slots.append([i for i, _, _ in items])
        mapper = self.pool.map if self.pool is not None else map
        for idx, result in zip(slots, mapper(_simulate_group, jobs)):
            out[idx] = result
        return out.reshape(len(candidates), n_t)

    def losses(self, outcomes: np.ndarray) -> np.ndarray:
        """Mean squared relative error of each candidate; FAILED_LOSS if any target failed."""
        rel = (outcomes - self.measured) / self.measured
        loss = np.mean(rel ** 2, axis=1)
        bad = ~np.isfinite(loss) | np.any(outcomes <= 0, axis=1)
        loss[bad] = FAILED_LOSS
        return loss
