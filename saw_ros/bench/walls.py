"""
Issue 23 figures: walls that bend (core.walls).

- ``bending_point_load_error_pct``: the simulation's wall (``Walls.compliance`` with one loaded
  tip and a 0.1 mm contact width) against Hetenyi's closed form for a point load on an infinite
  beam on a Winkler foundation, largest difference over 8 cm of wall, % of the peak.
- ``bending_fd_error_pct``: three tip loads on the silicone sheet against an independent
  finite-difference solution of EI w'''' + k w = q (h = 0.1 mm, a 40 cm beam with free ends),
  largest difference, % of the peak.
- ``core_steps_per_s_bending`` and ``batch_scenario_steps_per_s_bending``: core.Simulator steps
  per second with the silicone sheet's walls, one scenario (``Simulator.run``: the loop inside
  the kernel) and the 256-scenario batch of the core bench in one simulate call (both cores);
  ``bending_core_speed_ratio`` and ``bending_batch_speed_ratio``: over the rigid walls' figures
  measured in this same run.
- ``rigid_limit_max_dev``: the stiffest walls the ranges allow (k = 1e10 N/m^2, EI = 1e4 N m^2)
  against rigid ones over 4 s, largest deviation of x, y (m) or pitch (rad).
- ``rigid_step_cpu_ns`` and ``bending_step_cpu_ns``: CPU nanoseconds of this process per step of
  ``Simulator.run`` with rigid walls and with the silicone sheet's, the best of runs taken in
  turn; ``bending_cpu_speed_ratio`` the first over the second: the speed ratio a loaded machine
  does not move (its wall-clock figures wait for a core; CPU time does not count the wait).
- ``compliant_bending_step_cpu_ns``: the same with the printed TPU flexures (bench.compliant's
  TPU) on the silicone sheet (core.flexure.flex_walls: walls and links in one solve), taken in
  the same turns; ``compliant_bending_cpu_speed_ratio`` the rigid step's CPU time over it.
"""
import time

import numpy as np

from saw_ros.bench.compliant import TPU
from saw_ros.bench.core import batch_scenarios, run_rate, step_cpu_ns
from saw_ros.core import Scenario, Simulator
from saw_ros.core.dynamics import simulate
from saw_ros.core.walls import deflection, finite_difference_deflection, point_deflection
from saw_ros.core.walls import Walls

KEYS = ('bending_point_load_error_pct', 'bending_fd_error_pct', 'core_steps_per_s_bending',
        'batch_scenario_steps_per_s_bending', 'bending_core_speed_ratio',
        'bending_batch_speed_ratio', 'rigid_limit_max_dev', 'rigid_step_cpu_ns',
        'bending_step_cpu_ns', 'bending_cpu_speed_ratio', 'compliant_bending_step_cpu_ns',
        'compliant_bending_cpu_speed_ratio')
SHEET = {'surface.foundation_stiffness': 1.5e5, 'surface.bending_stiffness': 6.25e-4}
STIFFEST = {'surface.foundation_stiffness': 1e10, 'surface.bending_stiffness': 1e4}


def point_load_error() -> float:
    scenario = Scenario().with_values(dict(SHEET, **{'surface.contact_width': 1e-4}))
    walls = Walls([scenario], Simulator(scenario).table.side)
    n = walls.n
    along = np.linspace(-0.04, 0.04, n)
    x = np.concatenate([along, along])[None, :]
    centre = n // 2
    field = walls.compliance(x)[0, 0][:, centre]           # m per newton on the centre tip
    s = scenario.surface
    exact = point_deflection(along - along[centre], 1.0, s.foundation_stiffness,
                             s.bending_stiffness)
    return float(100.0 * np.abs(field - exact).max() / exact.max())


def finite_difference_error() -> float:
    s = Scenario().with_values(SHEET).surface
    loads, at = [1.0, 0.6, 0.3], [0.0, 0.011, 0.025]
    x, w = finite_difference_deflection(loads, at, s.foundation_stiffness, s.bending_stiffness,
                                        s.contact_width, 0.4, 1e-4)
    exact = np.sum([deflection(x - c, f, s.foundation_stiffness, s.bending_stiffness,
                               s.contact_width) for f, c in zip(loads, at)], axis=0)
    return float(100.0 * np.abs(w - exact).max() / exact.max())


def _batch_rate(scenarios, duration) -> float:
    simulate(scenarios[:2], 0.01)                  # compiled
    start = time.perf_counter()
    simulate(scenarios, duration, record_every=10)
    return len(scenarios) * duration / 0.001 / (time.perf_counter() - start)


def run(quick=False):
    duration = 1.0 if quick else 5.0
    rigid = run_rate(Simulator(Scenario()), duration)
    bending = run_rate(Simulator(Scenario().with_values(SHEET)), duration)
    duration = 0.3 if quick else 1.0
    scenarios = batch_scenarios(256)
    rigid_batch = _batch_rate(scenarios, duration)
    bending_batch = _batch_rate([s.with_values(SHEET) for s in scenarios], duration)
    a, b = Simulator(Scenario()), Simulator(Scenario().with_values(STIFFEST))
    deviation = 0.0
    for _ in range(int(round((1.0 if quick else 4.0) / a.dt))):
        a.step()
        b.step()
        deviation = max(deviation, float(np.abs(a.q[:3] - b.q[:3]).max()))
    rigid_ns, bending_ns, compliant_ns = step_cpu_ns(
        [Simulator(Scenario()), Simulator(Scenario().with_values(SHEET)),
         Simulator(Scenario().with_values(dict(SHEET, **TPU)))], 0.3 if quick else 1.0)
    return {'bending_point_load_error_pct': round(point_load_error(), 6),
            'bending_fd_error_pct': round(finite_difference_error(), 6),
            'core_steps_per_s_bending': round(bending),
            'batch_scenario_steps_per_s_bending': round(bending_batch),
            'bending_core_speed_ratio': round(bending / rigid, 3),
            'bending_batch_speed_ratio': round(bending_batch / rigid_batch, 3),
            'rigid_limit_max_dev': float(f'{deviation:.3g}'),
            'rigid_step_cpu_ns': round(rigid_ns), 'bending_step_cpu_ns': round(bending_ns),
            'bending_cpu_speed_ratio': round(rigid_ns / bending_ns, 3),
            'compliant_bending_step_cpu_ns': round(compliant_ns),
            'compliant_bending_cpu_speed_ratio': round(rigid_ns / compliant_ns, 3)}
