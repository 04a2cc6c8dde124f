"""
Contact law between a link tip and a compliant surface (paper Section 4.2, Eqs. 6-8, A.2).

Normal: Hertz with restitution hysteresis (Eq. 7), Fn = kn delta^p while the penetration grows
and e kn delta^p while it shrinks. Switching the factor between 1 and e on the sign of the rate
makes the force jump by (1 - e) kn delta^p: near equilibrium it chatters (docs/model.md section 4),
and the jumps make the motion so sensitive to tiny differences that cycles never repeat (the CCI
stays near 3 %). We keep the paper's rule for every rate faster than ``hysteresis_speed`` v0 and
make the switch continuous below it:

    factor = (1 + e)/2 + (1 - e)/2 clip(rate / v0, -1, 1),

which near rest is a Kelvin-Voigt damper. A load-unload cycle faster than v0 returns the share e
of the stored energy, exactly as Eq. 7.

Tangential: a spring anchored where the tip first touched, Ft = -kt (x - anchor), capped by
Coulomb friction |Ft| <= mu Fn; beyond the cap the tip slips and the anchor is dragged along so
that the spring holds exactly mu Fn. Losing contact forgets the anchor. The silicone's hysteresis
acts on its shear as on its indentation: the spring force carries the same factor, with the rate
of |x - anchor|. Without it a sticking contact is purely elastic and the robot's ~26 Hz
tangential mode (sqrt(n kt / m)) rings on forever, at rest and while crawling.

All arrays have shape (S, P): S scenarios, P tips. The kernel works in place on ``ContactState``
so that the 1 kHz loop allocates nothing large.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

Param = Union[float, np.ndarray]


@dataclass
class ContactLaw:
    """The contact constants of a batch, folded for the 1 kHz loop (see ``_hysteresis``)."""

    kn_mean: Param
    kn_half: Param
    kn_rate: Param
    kt_mean: Param
    kt_half: Param
    kt_rate: Param
    exponent: Param
    mu: Param

    @classmethod
    def from_values(cls, kn: Param, kt: Param, mu: Param, exponent: Param, restitution: Param,
                    hysteresis_speed: Param, dt: float) -> 'ContactLaw':
        """Fold the law's constants (scalars, or (S, P) arrays) for the 1 kHz loop."""
        mean, half = (1.0 + restitution) / 2.0, (1.0 - restitution) / 2.0
        rate = half / (hysteresis_speed * dt)
        return cls(kn * mean, kn * half, kn * rate, kt * mean, kt * half, kt * rate, exponent, mu)


class ContactState:
    """Per-tip memory of the contact law and the last step's forces."""

    def __init__(self, scenarios: int, tips: int):
        shape = (scenarios, tips)
        self.anchor = np.zeros(shape)        # x of the tangential spring's anchor, m
        self.depth = np.zeros(shape)         # penetration at the last step (>= 0), m
        self.factor = np.ones(shape)         # kn times the hysteresis factor (e..1)
        self.stretch = np.zeros(shape)       # |x - anchor| at the last step, m
        self.shear_factor = np.ones(shape)   # kt times the hysteresis factor (e..1)
        self._s = np.zeros(shape)
        self.free = np.ones(shape, bool)     # not touching
        self.normal = np.zeros(shape)        # Fn >= 0, N, pushing the tip out of the surface
        self.tangential = np.zeros(shape)    # Ft along +x on the robot, N
        self.trial = np.zeros(shape)         # the spring force before the Coulomb cap, N
        self.cap = np.zeros(shape)           # mu Fn, N
        self._d = np.zeros(shape)

    @property
    def touching(self) -> np.ndarray:
        return ~self.free

    @property
    def slipping(self) -> np.ndarray:
        """Tips held at the Coulomb cap (computed on demand: the 1 kHz loop does not need it)."""
        return ~self.free & (np.abs(self.trial) > self.cap)

    def reset(self) -> None:
        for a in (self.anchor, self.depth, self.normal, self.tangential, self.trial, self.cap):
            a[:] = 0.0
        self.factor[:] = 0.0
        self.stretch[:] = 0.0
        self.shear_factor[:] = 1.0
        self.free[:] = True


def hysteresis_factor(rate: ArrayLike, restitution: Param, hysteresis_speed: Param) -> np.ndarray:
    """
    Return the force factor for a deformation rate (m/s): 1 loading, e unloading.

    Linear between -v0 and v0 (pure, for tests and plots).
    """
    return (1.0 + restitution) / 2.0 + (1.0 - restitution) / 2.0 * np.clip(
        np.asarray(rate, float) / hysteresis_speed, -1.0, 1.0)


def _hysteresis(gain: np.ndarray, now: np.ndarray, before: np.ndarray, stiffness_mean: Param,
                stiffness_half_span: Param, rate_gain: Param) -> None:
    """
    Set gain = k ((1 + e)/2 + (1 - e)/2 clip(rate / v0, -1, 1)) from the change of ``now``.

    With the constants folded: k (1 + e)/2, k (1 - e)/2 and k (1 - e)/2 / (v0 dt).
    """
    np.subtract(now, before, out=gain)
    gain *= rate_gain
    np.minimum(gain, stiffness_half_span, out=gain)    # two ufuncs: np.clip is 3x slower here
    np.maximum(gain, -stiffness_half_span, out=gain)
    gain += stiffness_mean


def contact_step(state: ContactState, penetration: np.ndarray, x: np.ndarray,
                 law: ContactLaw) -> Tuple[np.ndarray, np.ndarray]:
    """
    Advance the contact law one step for tips at ``penetration`` and abscissa ``x``.

    ``law`` holds the folded constants (scalars, or (S, P) arrays where scenarios differ):
    kn_mean, kn_half, kn_rate, kt_mean, kt_half, kt_rate (see ``_hysteresis``), exponent, mu.
    Fills ``state.normal`` and ``state.tangential`` and updates the memory.
    """
    was_free = state.free
    free = np.less_equal(penetration, 0.0)
    d = np.maximum(penetration, 0.0, out=state._d)
    _hysteresis(state.factor, d, state.depth, law.kn_mean, law.kn_half, law.kn_rate)
    state.depth, state._d = d, state.depth         # keep d; recycle the old buffer
    # The exponent is a float, or an (S, P) array when the scenarios of a batch differ in it.
    if isinstance(law.exponent, float) and law.exponent == 1.5:
        fn = np.sqrt(d, out=state.normal)
        fn *= d                                    # d^1.5, three times faster than power()
    else:
        fn = np.power(d, law.exponent, out=state.normal)
    fn *= state.factor                             # kn times the hysteresis factor

    # Anchor at first touch: tips that were free take their current position.
    np.copyto(state.anchor, x, where=was_free)
    trial = np.subtract(state.anchor, x, out=state.trial)     # -(x - anchor)
    stretch = np.abs(trial, out=state._s)
    gain = state.shear_factor
    _hysteresis(gain, stretch, state.stretch, law.kt_mean, law.kt_half, law.kt_rate)
    trial *= gain                                              # -kt g (x - anchor)
    cap = np.multiply(fn, law.mu, out=state.cap)
    ft = np.minimum(trial, cap, out=state.tangential)
    np.maximum(ft, np.negative(cap, out=state._d), out=ft)
    # Sticking tips keep their anchor (x + Ft / (kt g) equals it); slipping tips drag it so that
    # the spring holds exactly mu Fn; free tips get Ft = 0 and take a new anchor when they touch.
    # The stretch remembered for the next rate is the spring's after the slip, not the trial's.
    offset = np.divide(ft, gain, out=state.anchor)
    np.abs(offset, out=state.stretch)
    offset += x
    state.free = free
    return fn, ft
