"""
Issue 31 figures: walls with mass and damping (core.dynamic_walls), link flexures (core.flexure).

- ``moving_load_deflection_error_pct``: a unit load crossing the dynamic wall at 0.5 and 0.9 of
  its critical speed, the soft-tissue and silicone-sheet sets (docs/walls.md) with a tenth of
  critical damping, against the closed-form steady deflection (Fryba), largest difference over
  +-6 decay lengths around the load, % of the peak; the worst of the four (goal <= 1).
- ``critical_speed_error_pct``: where the closed form's deflection under the load peaks (1 %
  of critical damping; a parabola through the peak of a 0.07 % grid that misses v_cr) against
  (4 k EI / m^2)^(1/4), the tissue set.
- ``ring_down_frequency_error_pct``: a uniform free vibration of the simulated tissue wall,
  its frequency from the zero crossings against sqrt(k/m - (c/2m)^2).
- ``dynamic_wall_energy_balance_pct``: over 0.3 s of a pulsing and a moving load, work done
  against the energy held plus dissipated, % of the work.
- ``flexure_harmonic_error_pct``: a TPU link (docs/model.md) driven at the 12 Hz link passing
  into a linear contact, its deflection's amplitude at dt = 1 ms against the closed form.
- ``dynamic_wall_steps_per_s``: steps per second of one dynamic wall (512 modes) under 20 tip
  loads, compiled.

Coupled into the simulator's step (the tissue set of docs/walls.md: k 9e3 N/m^2, EI 1.2e-5
N m^2, 0.13 kg/m, a tenth of critical damping), each against the quasi-static tissue walls
(null where a run was pushed through its wall, or no stall lies between 1e3 and 1e5 N/m^2):

- ``dynamic_walls_massless_limit_max_dev``: the default scenario on the tissue walls with
  walls.mass 0, stepped through the modes' solve (in a batch with the tissue's mass), against
  the quasi-static step alone: the largest difference of x, y (m) and pitch (rad) over 4 s.
- ``core_steps_per_s_dynamic_walls`` and ``dynamic_walls_core_speed_ratio``: one scenario on
  the tissue walls with mass (``Simulator.run``), and its ratio to the rigid walls' rate
  measured in the same run (``core_steps_per_s_rigid_here``).
- ``tissue_quasi_static_ar``, ``tissue_dynamic_ar``, ``tissue_dynamic_speed_change_pct``: the
  advance ratio over 6 s level, and the mean speed's change with the walls' mass, %.
- ``tissue_45deg_dynamic_speed_change_pct``: the same climbing at 45 degrees (vertically the
  robot slides down on the tissue walls either way: AR -1.96 and -1.83).
- ``tissue_quasi_static_gap_mm``, ``tissue_dynamic_gap_mm``: the surfaces' separation at the
  robot's centre of mass (the gap plus both walls' deflection there), mean over the last 3 s.
- ``tissue_stall_foundation_quasi_static``, ``tissue_stall_foundation_dynamic``: climbing
  vertically on the tissue's EI, the softest foundation k (N/m^2) on which the robot still
  climbs (AR >= analysis.walls_study.STALL_AR over 4 s; bisection in log k to 2 %, a tenth of
  critical damping at every k); ``tissue_heavy_stall_foundation`` with ten times the mass;
  not in --quick.
- ``tissue_heavy_dynamic_speed_change_pct``, ``tissue_heavy_45deg_speed_change_pct``: level
  and at 45 degrees, with ten times the tissue's mass (1.3 kg/m: the tissue moving behind the
  wall).
"""
import math
import time

import numpy as np

from saw_ros.analysis.walls_study import STALL_AR
from saw_ros.bench.core import run_rate
from saw_ros.core.dynamic_walls import critical_speed, DynamicWall, moving_load_deflection
from saw_ros.core.dynamic_walls import ring_down
from saw_ros.core.dynamics import DivergenceError, Simulator
from saw_ros.core.flexure import balance_links, elastic_law, Flexures, transmissibility
from saw_ros.core.metrics import analyse
from saw_ros.core.params import FlexureParams, Scenario

KEYS = ('moving_load_deflection_error_pct', 'critical_speed_error_pct',
        'ring_down_frequency_error_pct', 'dynamic_wall_energy_balance_pct',
        'flexure_harmonic_error_pct', 'dynamic_wall_steps_per_s',
        'dynamic_walls_massless_limit_max_dev', 'core_steps_per_s_dynamic_walls',
        'core_steps_per_s_rigid_here', 'dynamic_walls_core_speed_ratio', 'tissue_quasi_static_ar',
        'tissue_dynamic_ar', 'tissue_dynamic_speed_change_pct',
        'tissue_45deg_dynamic_speed_change_pct', 'tissue_quasi_static_gap_mm',
        'tissue_dynamic_gap_mm', 'tissue_stall_foundation_quasi_static',
        'tissue_stall_foundation_dynamic', 'tissue_heavy_stall_foundation',
        'tissue_heavy_dynamic_speed_change_pct', 'tissue_heavy_45deg_speed_change_pct')
TISSUE = (9e3, 1.2e-5, 0.13)            # k N/m^2, EI N m^2, m kg/m (docs/walls.md)
SHEET = (1.5e5, 6.25e-4, 0.33)
TPU = FlexureParams(stiffness=2000.0, damping=0.5, link_mass=0.004)


def moving_load_error(wall_set, fraction, dt=5e-5, duration=0.3) -> float:
    k, ei, m = wall_set
    damping = 0.1 * 2.0 * math.sqrt(k * m)
    speed = fraction * critical_speed(k, ei, m)
    wall = DynamicWall(k, ei, 1e-4, m, damping, dt)
    steps = int(round(duration / dt))
    for i in range(1, steps + 1):
        wall.step([1.0], [speed * i * dt - 0.3])
    beta = (k / (4.0 * ei)) ** 0.25
    xi = np.linspace(-6.0 / beta, 6.0 / beta, 241)
    w = wall.deflection(speed * steps * dt - 0.3 + xi)
    exact = moving_load_deflection(xi, 1.0, speed, k, ei, m, damping)
    return float(100.0 * np.abs(w - exact).max() / np.abs(exact).max())


def critical_speed_error() -> float:
    k, ei, m = TISSUE
    critical = critical_speed(k, ei, m)
    speeds = critical * np.linspace(0.8003, 1.2003, 601)
    beta = (k / (4.0 * ei)) ** 0.25
    xi = np.linspace(-3.0 / beta, 3.0 / beta, 241)
    damping = 0.01 * 2.0 * math.sqrt(k * m)
    peaks = [moving_load_deflection(xi, 1.0, v, k, ei, m, damping).max() for v in speeds]
    i = int(np.argmax(peaks))
    a, b, c = peaks[i - 1], peaks[i], peaks[i + 1]
    peak = speeds[i] + 0.5 * (a - c) / (a - 2.0 * b + c) * (speeds[1] - speeds[0])
    return float(100.0 * abs(peak / critical - 1.0))


def ring_down_error(dt=1e-4) -> float:
    k, ei, m = TISSUE
    damping = 0.1 * 2.0 * math.sqrt(k * m)
    wall = DynamicWall(k, ei, 0.005, m, damping, dt)
    wall.z_re[0] = 1e-3
    w = np.empty(4000)
    for i in range(w.size):
        wall.step([], [])
        w[i] = wall.deflection([0.3])[0]
    t = dt * np.arange(1, w.size + 1)
    up = np.flatnonzero((w[:-1] < 0) & (w[1:] >= 0))
    crossings = t[up] - w[up + 1] * dt / (w[up + 1] - w[up])
    omega, _ = ring_down(k, m, damping)
    return float(100.0 * abs(2.0 * math.pi / np.diff(crossings).mean() / omega - 1.0))


def energy_balance(dt=1e-4) -> float:
    k, ei, m = TISSUE
    wall = DynamicWall(k, ei, 0.005, m, 0.1 * 2.0 * math.sqrt(k * m), dt)
    for i in range(1, 3001):
        t = i * dt
        wall.step([1.0 + 0.5 * math.sin(2.0 * math.pi * 12.0 * t), 0.8], [0.0, 0.011 + 0.02 * t])
    return float(100.0 * abs(wall.energy() + wall.dissipated - wall.work) / wall.work)


def flexure_error(frequency=12.0, dt=1e-3) -> float:
    contact, d0, a = 1000.0, 0.002, 0.0005
    flexures = Flexures(TPU, 1, dt)
    w = 2.0 * math.pi * frequency
    steps = int(round(1.0 / dt))
    t = dt * np.arange(1, steps + 1)
    out = np.empty(steps)
    e, fb, ft, before = np.empty(1), np.empty(1), np.empty(1), np.zeros(1)
    law = elastic_law(contact, 1.0)
    for i in range(steps):
        balance_links(np.array([d0 + a * math.sin(w * t[i])]), np.array([-1.0]), before,
                      before.copy(), flexures.prepare(), flexures.compliance, law, e, fb, ft)
        flexures.advance(fb - ft)
        out[i] = flexures.deflection[0]
    late = t > 0.5
    amplitude = 2.0 * np.mean(out[late] * np.exp(-1j * w * t[late])) * 1j / a
    exact, _ = transmissibility(frequency, TPU.stiffness, TPU.damping, TPU.link_mass, contact)
    return float(100.0 * abs(amplitude - exact) / abs(exact))


def wall_rate(steps) -> float:
    k, ei, m = SHEET
    wall = DynamicWall(k, ei, 0.005, m, 0.1 * 2.0 * math.sqrt(k * m), 1e-3)
    at = np.linspace(-0.1, 0.1, 20)
    loads = np.full(20, 0.3)
    wall.step(loads, at)                      # compiled before the clock starts
    start = time.perf_counter()
    for i in range(steps):
        wall.free_deflection(at)
        wall.compliance(at)
        wall.step(loads, at + 1e-4 * i)
    return steps / (time.perf_counter() - start)


def tissue_walls(foundation=TISSUE[0], mass=0.0):
    """Return the tissue walls' parameters (a tenth of critical damping with a mass)."""
    return {'surface.foundation_stiffness': foundation, 'surface.bending_stiffness': TISSUE[1],
            'walls.mass': mass, 'walls.damping': 0.2 * math.sqrt(foundation * mass)}


def massless_limit(duration=4.0) -> float:
    """Return the largest pose difference of massless walls through the modes, against today's."""
    quasi = Scenario().with_values(tissue_walls())
    batch = Simulator([quasi, Scenario().with_values(tissue_walls(mass=TISSUE[2]))])
    through_modes = batch.run(duration, record_every=10).q[:, 0, :3]
    alone = Simulator(quasi).run(duration, record_every=10).q[:, 0, :3]
    return float(np.abs(through_modes - alone).max())


def crawl(values, duration=6.0, sample_every=10):
    """Return (AR, mean speed m/s, mean separation at the robot over the last half, m), or None."""
    scenario = Scenario().with_values(values)
    sim = Simulator(scenario)
    steps = int(round(duration / sim.dt))
    t, q, separation = np.empty(steps + 1), np.empty((steps + 1, 6)), []
    t[0], q[0] = sim.t, sim.q[:, 0]
    try:
        for k in range(1, steps + 1):
            sim.step()
            t[k], q[k] = sim.t, sim.q[:, 0]
            if k % sample_every == 0 and k > steps // 2:
                x = np.array([sim.q[0, 0]])
                w = sim.walls.shape(sim.tip_positions.real, x)[0, :, 0]
                separation.append(scenario.conditions.gap + w.sum())
    except DivergenceError:
        return None
    metrics = analyse(t, q, scenario.robot, scenario.frequency)
    return metrics.advance_ratio, metrics.v_mean, float(np.mean(separation))


def climbs(foundation, mass, duration=4.0) -> bool:
    """Say whether the robot climbs vertically on tissue walls of this foundation and mass."""
    scenario = Scenario().with_values({**tissue_walls(foundation, mass),
                                       'conditions.slope': math.pi / 2})
    try:
        tr = Simulator(scenario).run(duration)
    except DivergenceError:
        return False
    return analyse(tr.t, tr.q[:, 0], scenario.robot, scenario.frequency).advance_ratio >= STALL_AR


def stall_foundation(mass, low=1e3, high=1e5, share=0.02):
    """Return the softest foundation that still climbs (bisection in log k, N/m^2), or None."""
    if not climbs(high, mass) or climbs(low, mass):
        return None                                   # not bracketed: no number
    while high / low > 1.0 + share:
        middle = math.sqrt(low * high)
        low, high = (low, middle) if climbs(middle, mass) else (middle, high)
    return high


def run(quick=False):
    cases = [(TISSUE, 0.5), (TISSUE, 0.9), (SHEET, 0.5), (SHEET, 0.9)]
    moving = max(moving_load_error(s, f, duration=0.15 if quick else 0.3) for s, f in cases)
    duration = 1.0 if quick else 5.0
    rigid = run_rate(Simulator(Scenario()), duration)
    swinging = run_rate(Simulator(Scenario().with_values(tissue_walls(mass=TISSUE[2]))),
                        duration)
    span = 3.0 if quick else 6.0
    quasi, dynamic, heavy = (crawl(tissue_walls(mass=m), span) for m in
                             (0.0, TISSUE[2], 10 * TISSUE[2]))
    slope = {'conditions.slope': math.pi / 4}
    up_quasi, up_dynamic, up_heavy = (crawl({**tissue_walls(mass=m), **slope}, span)
                                      for m in (0.0, TISSUE[2], 10 * TISSUE[2]))

    def change(a, b):
        return round(100.0 * (b[1] / a[1] - 1.0), 3) if a and b else None

    def rounded(value, digits=None):
        return None if value is None else round(value, digits)

    out = {'moving_load_deflection_error_pct': round(moving, 4),
           'critical_speed_error_pct': round(critical_speed_error(), 4),
           'ring_down_frequency_error_pct': round(ring_down_error(), 6),
           'dynamic_wall_energy_balance_pct': round(energy_balance(), 4),
           'flexure_harmonic_error_pct': round(flexure_error(), 4),
           'dynamic_wall_steps_per_s': round(wall_rate(200 if quick else 1000)),
           'dynamic_walls_massless_limit_max_dev': float(f'{massless_limit():.3g}'),
           'core_steps_per_s_dynamic_walls': round(swinging),
           'core_steps_per_s_rigid_here': round(rigid),
           'dynamic_walls_core_speed_ratio': round(swinging / rigid, 4),
           'tissue_quasi_static_ar': round(quasi[0], 5) if quasi else None,
           'tissue_dynamic_ar': round(dynamic[0], 5) if dynamic else None,
           'tissue_dynamic_speed_change_pct': change(quasi, dynamic),
           'tissue_45deg_dynamic_speed_change_pct': change(up_quasi, up_dynamic),
           'tissue_quasi_static_gap_mm': round(1e3 * quasi[2], 3) if quasi else None,
           'tissue_dynamic_gap_mm': round(1e3 * dynamic[2], 3) if dynamic else None,
           'tissue_heavy_dynamic_speed_change_pct': change(quasi, heavy),
           'tissue_heavy_45deg_speed_change_pct': change(up_quasi, up_heavy)}
    if not quick:
        out['tissue_stall_foundation_quasi_static'] = rounded(stall_foundation(0.0))
        out['tissue_stall_foundation_dynamic'] = rounded(stall_foundation(TISSUE[2]))
        out['tissue_heavy_stall_foundation'] = rounded(stall_foundation(10 * TISSUE[2]))
    return out
