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
from typing import cast, Sequence, Tuple

import numba
import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core.jit import CACHE
from saw_ros.core.params import MotorParams

TWO_PI = 2.0 * math.pi
# Columns of a scenario's motor constants (MotorLaw.rows): k (N m/A), hz_per_volt, J / dt,
# R / c, the friction torque times R / c at which the helix sticks, c = J R / dt + k^2, R (ohm)
# and the Coulomb friction torque (N m).
TORQUE_CONSTANT, HZ_PER_VOLT, INERTIA_DT, R_C, STICK, C, RESISTANCE, FRICTION = range(8)
MOTOR_FIELDS = 8


@numba.njit(cache=CACHE)
def turn_helix(omega: float, load: float, voltage: float,
               motor: np.ndarray) -> Tuple[float, float, float]:
    """
    Return (w', torque k i, friction torque met) after one step from w against ``load``.

    rad/s and N m (compiled kernel); ``motor``: one motor's constants (MOTOR_FIELDS). The
    current is torque / k.
    """
    ideal = TWO_PI * (motor[HZ_PER_VOLT] * voltage)         # V / k, as 2 pi f is written
    # Without friction w' = V/k + R (J (w - V/k) / dt - load) / c: the step of the module
    # docstring arranged so that R = 0 gives V / k exactly.
    free = ideal + motor[R_C] * (motor[INERTIA_DT] * (omega - ideal) - load)
    stick = motor[STICK]
    if abs(free) <= stick:
        new = 0.0
    else:
        new = free - stick * (1.0 if free > 0.0 else -1.0)
    # The friction the step met: within [-tau_f, tau_f] while the helix sticks.
    if motor[RESISTANCE] > 0.0:
        friction = motor[C] * (free - new) / motor[RESISTANCE]
    else:
        friction = motor[FRICTION] * (0.0 if new == 0.0 else (1.0 if new > 0.0 else -1.0))
    # For R > 0 this is k (V - k w') / R exactly; for R = 0 what the ideal source supplies.
    torque = motor[INERTIA_DT] * (new - omega) + friction + load
    return new, torque, friction


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
        # The step times R: w' (J R / dt + k^2) = J R w / dt + k V - R (tau_f sign(w') + load).
        self.c = self.inertia_dt * self.resistance + self.k ** 2
        self.r_c = self.resistance / self.c
        self.stick = self.friction * self.r_c

    @property
    def ideal(self) -> np.ndarray:
        """Return the no-load helix speeds V / k (S,), rad/s, written as 2 pi f is."""
        return cast(np.ndarray, TWO_PI * (self.hz_per_volt * self.voltage))

    def rows(self) -> np.ndarray:
        """Return the constants as (S, MOTOR_FIELDS) rows, for the kernels."""
        return np.stack([self.k, self.hz_per_volt, self.inertia_dt, self.r_c, self.stick, self.c,
                         self.resistance, self.friction], axis=1)

    def set_voltage(self, voltage: ArrayLike) -> None:
        """Drive the motors at ``voltage`` (V, scalar or (S,)) from the next step on."""
        self.voltage[:] = voltage

    def step(self, omega: np.ndarray, load: np.ndarray) -> Tuple[np.ndarray, np.ndarray,
                                                                 np.ndarray]:
        """
        Return (w', torque k i, friction torque met) after one step from w against ``load``.

        All (S,) arrays, rad/s and N m. The current is torque / k.
        """
        rows = self.rows()
        out = np.empty((3, len(omega)))
        for i, (w, tau, v, motor) in enumerate(zip(omega, load, self.voltage, rows)):
            out[:, i] = turn_helix(float(w), float(tau), float(v), motor)
        return out[0], out[1], out[2]
