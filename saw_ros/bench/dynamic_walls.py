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

``dynamic_walls_massless_limit_max_dev``, ``core_steps_per_s_compliant`` and
``compliant_vibration_reduction_pct`` need the kernels coupled into the compiled step: not yet.
"""
import math
import time

import numpy as np

from saw_ros.core.dynamic_walls import critical_speed, DynamicWall, moving_load_deflection
from saw_ros.core.dynamic_walls import ring_down
from saw_ros.core.flexure import balance_links, elastic_law, Flexures, transmissibility
from saw_ros.core.params import FlexureParams

KEYS = ('moving_load_deflection_error_pct', 'critical_speed_error_pct',
        'ring_down_frequency_error_pct', 'dynamic_wall_energy_balance_pct',
        'flexure_harmonic_error_pct', 'dynamic_wall_steps_per_s')
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


def run(quick=False):
    cases = [(TISSUE, 0.5), (TISSUE, 0.9), (SHEET, 0.5), (SHEET, 0.9)]
    moving = max(moving_load_error(s, f, duration=0.15 if quick else 0.3) for s, f in cases)
    return {'moving_load_deflection_error_pct': round(moving, 4),
            'critical_speed_error_pct': round(critical_speed_error(), 4),
            'ring_down_frequency_error_pct': round(ring_down_error(), 6),
            'dynamic_wall_energy_balance_pct': round(energy_balance(), 4),
            'flexure_harmonic_error_pct': round(flexure_error(), 4),
            'dynamic_wall_steps_per_s': round(wall_rate(200 if quick else 1000))}
