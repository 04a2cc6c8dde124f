"""
What drives the helix from outside the model (issue 22; docs/drive.md).

A voltage profile over one helix turn, and a speed controller.

A profile is fed forward in the helix phase phi (rad), per scenario of a batch:

    V(phi) = V0 (1 + sum_k a_k cos(k phi) + b_k sin(k phi)),    clipped to [0, v_max],

with the harmonics k chosen by the caller. The vibration of the body sits near the link-passing
rate (one link of the nine per wavelength crosses a crest every 1/9 turn: docs/drive.md), so the
useful harmonics are the low ones (they reshape the turn) and the link-passing ones (9, 18).

The controller is a PI on the robot's speed with a feed-forward voltage and conditional
integration (the integrator holds while the output sits at a limit and the error would push it
further), the usual anti-windup of a saturating actuator. It is pure: the ``speed_controller``
node and the bench call the same ``update``.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import cast, Sequence, Union

import numpy as np

from saw_ros.core.params import ConditionParams, MotorParams, ParameterError, spec_entries
from saw_ros.core.params import spec_meta

# The tops of motor.voltage's and conditions.frequency's ranges, V and Hz.
VOLTAGE_LIMIT = float(next(spec_entries(MotorParams, ['voltage']))[2]['high'])
FREQUENCY_LIMIT = float(next(spec_entries(ConditionParams, ['frequency']))[2]['high'])


class PhaseProfile:
    """V(phi) of S scenarios: mean voltages (S,), relative Fourier coefficients (S, 2K)."""

    def __init__(self, mean: Union[float, Sequence[float], np.ndarray], harmonics: Sequence[int],
                 coefficients: Union[Sequence[Sequence[float]], np.ndarray],
                 v_max: float = VOLTAGE_LIMIT):
        self.mean = np.atleast_1d(np.asarray(mean, float))
        self.harmonics = np.asarray(harmonics, float)
        k = len(self.harmonics)
        coefficients = np.asarray(coefficients, float).reshape(len(self.mean), 2 * k)
        if not (np.isfinite(self.mean).all() and np.isfinite(coefficients).all()):
            raise ParameterError('a drive profile needs finite voltages and coefficients')
        if (self.mean < 0.0).any() or (self.mean > v_max).any():
            raise ParameterError(f"a drive profile's mean voltage must be in [0, {v_max:g}] V")
        if k and (self.harmonics < 1).any():
            raise ParameterError("a drive profile's harmonics are whole turns: 1, 2, ...")
        self.cos = coefficients[:, :k]
        self.sin = coefficients[:, k:]
        self.v_max = v_max
        self._angle = np.zeros((len(self.mean), k))

    @classmethod
    def constant(cls, mean: Union[float, Sequence[float], np.ndarray]) -> 'PhaseProfile':
        return cls(mean, (), np.zeros((np.size(mean), 0)))

    @property
    def peak(self) -> np.ndarray:
        """Return an upper bound of V over the turn, per scenario, V."""
        spread = np.abs(self.cos).sum(axis=1) + np.abs(self.sin).sum(axis=1)
        return cast(np.ndarray, np.minimum(self.mean * (1.0 + spread), self.v_max))

    def voltage(self, phase: Union[float, np.ndarray]) -> np.ndarray:
        """Return V at helix phase ``phase`` (S,), V, within [0, v_max]."""
        if not len(self.harmonics):
            return self.mean.copy()
        angle = np.multiply(np.asarray(phase, float)[:, None], self.harmonics, out=self._angle)
        shape = 1.0 + (np.cos(angle) * self.cos).sum(axis=1) + (np.sin(angle) * self.sin).sum(
            axis=1)
        return cast(np.ndarray, np.clip(self.mean * shape, 0.0, self.v_max))

    def over_turn(self, samples: int = 360) -> np.ndarray:
        """Return V over one turn, (S, samples), for plots and the mean."""
        phi = np.linspace(0.0, 2.0 * math.pi, samples, endpoint=False)
        return np.stack([self.voltage(np.full(len(self.mean), p)) for p in phi], axis=1)


@dataclass
class SpeedPI:
    """
    A PI speed controller with a feed-forward term, voltage limits and anti-windup.

    u = u_ff + kp e + ki integral(e),   e = target - speed (m/s),   u in [u_min, u_max] (V).
    """

    kp: float
    ki: float
    u_min: float = 0.0
    u_max: float = 12.0
    u_ff: float = 0.0
    integral: float = 0.0

    def update(self, target: float, speed: float, dt: float) -> float:
        """Return the new command after a feedback sample taken ``dt`` after the previous one."""
        error = target - speed
        if not math.isfinite(error) or not dt > 0.0:
            return self.output(0.0)
        candidate = self.integral + error * dt
        u = self.u_ff + self.kp * error + self.ki * candidate
        # Conditional integration: while the output is clipped and the error pushes it further
        # out, the integrator holds (otherwise it winds up and overshoots on the way back).
        if (u > self.u_max and error > 0.0) or (u < self.u_min and error < 0.0):
            return self.output(error)
        self.integral = candidate
        return self.output(error)

    def output(self, error: float) -> float:
        u = self.u_ff + self.kp * error + self.ki * self.integral
        return min(max(u, self.u_min), self.u_max)

    def reset(self) -> None:
        self.integral = 0.0


# The speed controller's parameters (name, default, spec metadata): the speed_controller node
# declares them, saw-ros demo --controller checks its flag against them.
FEEDBACKS = ('tracking', 'ground_truth', 'helix')

CONTROLLER_PARAMETERS = (
    ('target_speed', 0.05, spec_meta('m/s', 'robot speed to hold along the surfaces (+ forward)',
                                     -0.5, 0.5)),
    ('feedback', 'tracking', spec_meta('', 'what the speed is measured from', choices=FEEDBACKS,
                                       read_only=True)),
    ('kp', 40.0, spec_meta('V s/m', 'proportional gain: volts per m/s of speed error', 0.0,
                           1e4)),
    ('ki', 80.0, spec_meta('V/m', 'integral gain: volts per metre of accumulated error', 0.0,
                           1e5)),
    ('feed_forward', 0.0, spec_meta('V', 'voltage added to the PI output (the voltage that gives '
                                         'the target on the level, if known); 0 = none', 0.0,
                                    VOLTAGE_LIMIT)),
    ('voltage_min', 0.0, spec_meta('V', 'lowest voltage commanded', 0.0, VOLTAGE_LIMIT)),
    ('voltage_max', 12.0, spec_meta('V', 'highest voltage commanded', 0.0, VOLTAGE_LIMIT)),
    ('rate', 60.0, spec_meta('Hz', 'control updates per second of feedback time with the 1 kHz '
                                   'feedbacks (ground_truth, helix); tracking updates per frame',
                             0.0, 1000.0, low_open=True, read_only=True)),
    ('advance_ratio', 0.754, spec_meta(
        '', "helix feedback: robot speed over v_theory (the level AR of the paper's set-up, "
            'docs/fidelity.md)', 0.0, 1.5, low_open=True)),
)
