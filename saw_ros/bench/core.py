"""Physics core throughput: one scenario, and a batch of 256 stepped together."""
import math
import time

import numpy as np

from saw_ros.core import Scenario, Simulator
from saw_ros.core.dynamics import simulate

KEYS = ['core_steps_per_s', 'batch_scenario_steps_per_s',
        'batch_single_process_scenario_steps_per_s']


def _rate(sim, steps, repeats=3):
    for _ in range(100):          # warm the caches and the contacts
        sim.step()
    best = 0.0
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(steps):
            sim.step()
        best = max(best, steps / (time.perf_counter() - start))
    return best


def batch_scenarios(count=256):
    """Return a realistic sweep: slopes 0-90 deg by COF by gap, all different."""
    grid = [(s, mu, g) for g in (0.040, 0.045, 0.050) for mu in (0.2, 0.5, 1.0)
            for s in np.linspace(0, 90, 29)]
    return [Scenario().with_values({'conditions.slope': math.radians(s),
                                    'surface.friction_coefficient': mu, 'conditions.gap': g})
            for s, mu, g in grid[:count]]


def run(quick=False):
    single = _rate(Simulator(Scenario()), 2000 if quick else 10000)
    scenarios = batch_scenarios(256)
    one_process = 256 * _rate(Simulator(scenarios), 100 if quick else 400)
    duration = 0.5 if quick else 2.0
    start = time.perf_counter()
    simulate(scenarios, duration, record_every=10, workers=2)
    both_cores = 256 * duration / 0.001 / (time.perf_counter() - start)
    return {'core_steps_per_s': round(single),
            'batch_scenario_steps_per_s': round(both_cores),
            'batch_single_process_scenario_steps_per_s': round(one_process)}
