"""
The DC motor that turns the helix (docs/motor.md), for S scenarios at once.

Constants at the helix shaft (after the gearbox): k = 1 / (2 pi hz_per_volt) (V s/rad = N m/A),
winding resistance R, Coulomb friction tau_f, inertia J. One step of dt from helix speed w
against a load torque tau_load:

    J (w' - w) / dt = k i - tau_f sign(w') - tau_load,    i = (V - k w') / R.

Back-EMF and friction are taken at the new speed w' (implicit): they cannot make the step ring,
for any J >= 0 (J = 0 is the quasi-static law w' = (V - R (tau_load + tau_f) / k) / k). The
load torque is the last step's: core.stability bounds it against the helix's inertia
J + k^2 dt / R (the paper's motor uses 0.0001 of that limit, 0.03 at J = 0). Friction
holds a helix whose drive cannot beat it at exactly 0 instead of chattering about it. Multiplied
by R the step never divides by R, so R = 0 is the ideal stiff source, w' = V / k.
"""
from __future__ import annotations

import math
from typing import Sequence, Tuple

import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core.params import MotorParams

TWO_PI = 2.0 * math.pi


class MotorLaw:
    """The folded constants of S motors and their implicit step (module docstring)."""

    def __init__(self, motors: Sequence[MotorParams], dt: float):
        self.dt = dt
        self.voltage = np.array([m.voltage for m in motors])
        self.k = np.array([m.torque_constant for m in motors])
        self.resistance = np.array([m.resistance for m in motors])
        self.friction = np.array([m.friction_torque for m in motors])
        self.inertia_dt = np.array([m.inertia for m in motors]) / dt
        # V / k written as the constant-frequency path writes 2 pi f, so that R = 0 turns the
        # helix bit for bit as conditions.frequency = hz_per_volt V does.
        self.hz_per_volt = np.array([m.hz_per_volt for m in motors])
        self.ideal = np.array([TWO_PI * (m.hz_per_volt * m.voltage) for m in motors])
        # The step times R: w' (J R / dt + k^2) = J R w / dt + k V - R (tau_f sign(w') + load).
        self.c = self.inertia_dt * self.resistance + self.k ** 2
        self.r_c = self.resistance / self.c
        self.stick = self.friction * self.r_c
        self._has_r = self.resistance > 0.0
        self._safe_r = np.where(self._has_r, self.resistance, 1.0)

    def set_voltage(self, voltage: ArrayLike) -> None:
        """Drive the motors at ``voltage`` (V, scalar or (S,)) from the next step on."""
        self.voltage[:] = voltage
        # The same expression as __init__'s, so a command equal to motor.voltage changes nothing.
        np.multiply(TWO_PI, self.hz_per_volt * self.voltage, out=self.ideal)

    def step(self, omega: np.ndarray, load: np.ndarray) -> Tuple[np.ndarray, np.ndarray,
                                                                 np.ndarray]:
        """
        Return (w', torque k i, friction torque met) after one step from w against ``load``.

        All (S,) arrays, rad/s and N m. The current is torque / k.
        """
        # Without friction w' = V/k + R (J (w - V/k) / dt - load) / c: the step above, arranged
        # so that R = 0 gives V / k exactly.
        free = self.ideal + self.r_c * (self.inertia_dt * (omega - self.ideal) - load)
        new = np.where(np.abs(free) <= self.stick, 0.0, free - self.stick * np.sign(free))
        # The friction the step met: within [-tau_f, tau_f] while the helix sticks.
        friction = np.where(self._has_r, self.c * (free - new) / self._safe_r,
                            self.friction * np.sign(new))
        # For R > 0 this is k (V - k w') / R exactly; for R = 0 what the ideal source supplies.
        torque = self.inertia_dt * (new - omega) + friction + load
        return new, torque, friction
