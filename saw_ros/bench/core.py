"""
Physics core throughput (the compiled kernels, issue 30): one scenario, batches, compilation.

- ``core_steps_per_s``: one scenario stepped by ``Simulator.run`` (the loop over steps inside
  the kernel, as simulate, the campaign and the figures step it); ``core_step_calls_per_s``:
  one ``Simulator.step()`` call a step, the simulator node's path at 1 kHz.
- ``batch_scenario_steps_per_s``: the 256-scenario sweep in one ``simulate`` call (spread over
  a thread a core, ``dynamics.spread``); ``batch_single_process_scenario_steps_per_s``: the same
  on one thread;
  ``batch_pool_scenario_steps_per_s``: the same cut in two by the local process pool.
- ``batch_scaling_4096_ratio``: one process stepping 1, 16, 256, 1024 and 4096 scenarios of the
  sweep (repeated) on one thread, 4096 against the best size of the same run
  (``batch_scaling_scenario_steps_per_s`` the five rates).
- ``core_jit_cold_s``: a fresh Python compiling every kernel into an empty cache (a temporary
  NUMBA_CACHE_DIR) and stepping; ``core_jit_warm_s``: the same process again, kernels loaded
  from that cache; ``core_jit_cold_cpu_s`` and ``core_jit_warm_cpu_s`` their CPU seconds (the
  wall clock of a loaded machine is mostly waiting).
"""
import math
import os
from pathlib import Path
import resource
import subprocess
import sys
import tempfile
import time

import numba
import numpy as np

from saw_ros.core import Scenario, Simulator
from saw_ros.core.dynamics import simulate

KEYS = ['core_steps_per_s', 'core_step_calls_per_s', 'batch_scenario_steps_per_s',
        'batch_single_process_scenario_steps_per_s', 'batch_pool_scenario_steps_per_s',
        'batch_scaling_scenario_steps_per_s', 'batch_scaling_4096_ratio', 'core_jit_cold_s',
        'core_jit_warm_s', 'core_jit_cold_cpu_s', 'core_jit_warm_cpu_s']
SCALING = (1, 16, 256, 1024, 4096)
# What the cold start compiles: every kernel (one scenario's step, a parallel batch, a motor,
# bending walls), as the first simulate of a campaign or the simulator node would.
WARM_UP = ('from saw_ros.core.dynamics import warm_up; warm_up()')


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


def run_rate(sim, duration, repeats=3):
    """Return the best steps per second of ``sim.run(duration)`` (kernels already compiled)."""
    sim.run(0.05)
    best = 0.0
    for _ in range(repeats):
        start = time.perf_counter()
        sim.run(duration, record_every=10)
        best = max(best, duration / sim.dt / (time.perf_counter() - start))
    return best


def step_cpu_ns(sims, duration, repeats=5):
    """Return each simulator's least CPU ns per step of ``run(duration)``, the runs in turn."""
    for sim in sims:
        sim.run(0.05)                                # compiled, contacts settled
    best = [math.inf] * len(sims)
    for _ in range(repeats):
        for k, sim in enumerate(sims):
            start = time.process_time()
            sim.run(duration, record_every=10)
            used = time.process_time() - start
            best[k] = min(best[k], used / round(duration / sim.dt) * 1e9)
    return best


def one_thread(function):
    """Call ``function()`` with numba's parallel kernels on one thread."""
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        return function()
    finally:
        numba.set_num_threads(threads)


def scaling(quick=False):
    """Return scenario-steps per second for each batch size of SCALING, one process, one thread."""
    sweep = batch_scenarios(256)
    budget = 2e5 if quick else 1e6                 # scenario-steps per size
    rates = {}
    for size in SCALING:
        scenarios = (sweep * (size // len(sweep) + 1))[:size]
        sim = Simulator(scenarios)
        steps = max(20, int(budget / size))
        rates[size] = size * one_thread(lambda: run_rate(sim, steps * sim.dt, repeats=2))
    return rates


def jit_start() -> tuple:
    """
    Return s for a fresh Python to compile every kernel into an empty cache, s to load it.

    Wall-clock seconds, and the CPU seconds of the same two processes (what a loaded machine
    does not inflate): (cold, warm, cold CPU, warm CPU).
    """
    times, cpu = [], []
    with tempfile.TemporaryDirectory(prefix='saw_ros_numba_') as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for _ in range(2):
            used = resource.getrusage(resource.RUSAGE_CHILDREN)
            start = time.perf_counter()
            subprocess.run([sys.executable, '-c', WARM_UP], env=env, check=True,
                           cwd=Path(__file__).resolve().parents[2])
            times.append(time.perf_counter() - start)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu.append(after.ru_utime + after.ru_stime - used.ru_utime - used.ru_stime)
    return times[0], times[1], cpu[0], cpu[1]


def batch_scenarios(count=256):
    """Return a realistic sweep: slopes 0-90 deg by COF by gap, all different."""
    grid = [(s, mu, g) for g in (0.040, 0.045, 0.050) for mu in (0.2, 0.5, 1.0)
            for s in np.linspace(0, 90, 29)]
    return [Scenario().with_values({'conditions.slope': math.radians(s),
                                    'surface.friction_coefficient': mu, 'conditions.gap': g})
            for s, mu, g in grid[:count]]


def _batch_rate(scenarios, duration, workers=1) -> float:
    simulate(scenarios[:2], 0.01)                  # compiled
    start = time.perf_counter()
    simulate(scenarios, duration, record_every=10, workers=workers)
    return len(scenarios) * duration / 0.001 / (time.perf_counter() - start)


def run(quick=False):
    cold, warm, cold_cpu, warm_cpu = jit_start()
    single = run_rate(Simulator(Scenario()), 1.0 if quick else 5.0)
    calls = _rate(Simulator(Scenario()), 2000 if quick else 10000)
    scenarios = batch_scenarios(256)
    duration = 0.5 if quick else 2.0
    both_cores = _batch_rate(scenarios, duration)
    one_process = one_thread(lambda: _batch_rate(scenarios, duration))
    pool = one_thread(lambda: _batch_rate(scenarios, duration, workers=2))
    rates = scaling(quick)
    return {'core_steps_per_s': round(single),
            'core_step_calls_per_s': round(calls),
            'batch_scenario_steps_per_s': round(both_cores),
            'batch_single_process_scenario_steps_per_s': round(one_process),
            'batch_pool_scenario_steps_per_s': round(pool),
            'batch_scaling_scenario_steps_per_s': {str(k): round(v) for k, v in rates.items()},
            'batch_scaling_4096_ratio': round(rates[4096] / max(rates.values()), 3),
            'core_jit_cold_s': round(cold, 2), 'core_jit_warm_s': round(warm, 2),
            'core_jit_cold_cpu_s': round(cold_cpu, 2), 'core_jit_warm_cpu_s': round(warm_cpu, 2)}
