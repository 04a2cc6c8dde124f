"""
Issue 31 figures: the compliant robot, link flexures in the compiled step (core.flexure).

- ``core_steps_per_s_compliant``: steps per second of ``Simulator.run`` (the loop inside the
  kernel, as bench.core's ``core_steps_per_s``) with the printed TPU flexures
  (docs/compliant_robot.md), one scenario; ``compliant_core_speed_ratio``: over the rigid
  robot's ``run_rate`` measured the same way in this run (goal >= 0.3). Not one
  ``Simulator.step()`` call a step: its ~3 us of Python dispatch would hide the kernel's cost
  and lift the ratio towards 1 (0.579 measured so, 0.117 by the run, at 32dca94).
- ``compliant_step_cpu_ns``: CPU ns of this process per step of the same run, the best of runs
  taken in turn with the rigid robot's (bench.core.step_cpu_ns); ``compliant_cpu_speed_ratio``
  the rigid step's CPU time over it: the ratio a loaded machine does not move (its wall-clock
  figures wait for a core).
- ``compliant_rigid_limit_max_dev``: flexures of 1e9 N/m against rigid links over 4 s, the
  largest deviation of x, y (m) or pitch (rad) (goal <= 1e-6).
- ``compliant_vibration_reduction_pct``: the best vibration reduction (shape-drive's RMS normal
  acceleration) against the rigid robot at the same speed, among the flexures of the default
  sweep of ``saw-ros compliant`` that keep >= 95 % of the rigid speed, 6 V on the level
  (goal >= 30); ``compliant_best_stiffness`` (N/m) and ``compliant_best_damping_ratio`` say
  which.
- ``compliant_shaped_vibration_reduction_pct``: the committed shaped drive of
  docs/compliant_robot/shaped (``saw-ros shape-drive --flexure-stiffness 1463
  --flexure-damping-ratio 0.7``) on its compliant robot against the rigid robot's constant
  voltage at the same speed, measured again (None if the rigid robot misses that speed).
"""
import json
from pathlib import Path
from typing import Optional

import numpy as np

from saw_ros.analysis import shape_drive
from saw_ros.analysis.compliant import closed_loop, DAMPING_RATIOS, STIFFNESSES
from saw_ros.bench.core import run_rate, step_cpu_ns
from saw_ros.core import Scenario, Simulator

KEYS = ('core_steps_per_s_compliant', 'compliant_core_speed_ratio', 'compliant_step_cpu_ns',
        'compliant_cpu_speed_ratio', 'compliant_rigid_limit_max_dev',
        'compliant_vibration_reduction_pct', 'compliant_best_stiffness',
        'compliant_best_damping_ratio', 'compliant_shaped_vibration_reduction_pct')
TPU = {'flexure.stiffness': 2070.0, 'flexure.damping': 0.29}
SHAPED = ('docs', 'compliant_robot', 'shaped', 'result.json')


def shaped_reduction() -> Optional[float]:
    """Return the committed shaped drive's reduction against the rigid robot at its speed, %."""
    path = Path(__file__).resolve().parents[2].joinpath(*SHAPED)
    if not path.is_file():
        raise FileNotFoundError(f'{path}: no shaped drive of the compliant robot to measure (a '
                                f'checkout has it; saw-ros shape-drive --flexure-stiffness 1463 '
                                f'--flexure-damping-ratio 0.7 makes it)')
    data = json.loads(path.read_text())
    saved = shape_drive.ShapeResult(**data['result'])
    rigid = Scenario().with_values({'motor.voltage': saved.base_voltage})
    compliant = rigid.with_values({f'flexure.{name}': value
                                   for name, value in data['flexure'].items()})
    shaped = shape_drive.evaluate(compliant, [saved.mean_voltage], [saved.coefficients],
                                  saved.harmonics)
    speed = float(shaped.speed[0])
    curve = shape_drive.ConstantCurve(rigid, saved.harmonics, points=5)
    _, matched = shape_drive.matched_constant(rigid, speed, curve, saved.harmonics)
    if abs(matched['speed'] / speed - 1.0) > shape_drive.SAME_SPEED:
        return None
    return round(100.0 * (1.0 - float(shaped.vibration[0]) / matched['vibration']), 2)


def run(quick=False):
    duration = 1.0 if quick else 5.0
    rigid = run_rate(Simulator(Scenario()), duration)
    compliant = run_rate(Simulator(Scenario().with_values(TPU)), duration)
    rigid_ns, compliant_ns = step_cpu_ns(
        [Simulator(Scenario()), Simulator(Scenario().with_values(TPU))], 0.3 if quick else 1.0)
    a = Simulator(Scenario())
    b = Simulator(Scenario().with_values({'flexure.stiffness': 1e9}))
    deviation = 0.0
    for _ in range(10 if quick else 40):
        a.run(0.1)
        b.run(0.1)
        deviation = max(deviation, float(np.abs(a.q[:3] - b.q[:3]).max()))
    base = Scenario().with_values({'motor.voltage': 6.0})
    result = closed_loop(base, STIFFNESSES[::3] if quick else STIFFNESSES,
                         DAMPING_RATIOS[-1:] if quick else DAMPING_RATIOS)
    best = result['best']
    return {'core_steps_per_s_compliant': round(compliant),
            'compliant_core_speed_ratio': round(compliant / rigid, 3),
            'compliant_step_cpu_ns': round(compliant_ns),
            'compliant_cpu_speed_ratio': round(rigid_ns / compliant_ns, 3),
            'compliant_rigid_limit_max_dev': float(f'{deviation:.3g}'),
            'compliant_vibration_reduction_pct':
                None if best is None else round(best['reduction_pct'], 2),
            'compliant_best_stiffness': None if best is None else round(best['stiffness'], 1),
            'compliant_best_damping_ratio': None if best is None else best['damping_ratio'],
            'compliant_shaped_vibration_reduction_pct': shaped_reduction()}
