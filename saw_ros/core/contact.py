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

All arrays have shape (S, P): S scenarios, P tips. The law is the compiled kernel
``press_tips`` (one scenario's tips, a loop over them): it works in place on the rows of one
(S, TIP_FIELDS, P) array (``ContactState.tips``), so that the 1 kHz loop allocates nothing.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import cast, Tuple, Union

import numba
import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core.jit import CACHE

Param = Union[float, np.ndarray]


# Rows of a scenario's tip state (ContactState.tips[s]), one column per tip. The contact law's
# memory: where the tangential spring is anchored (m), the depth (>= 0, m) and |x - anchor| (m)
# at the last step, the gains kn and kt times the hysteresis factor (e..1), 1 where the tip does
# not touch. Its results: Fn >= 0 pushing the tip out of the surface, Ft along +x on the robot,
# the spring force before the Coulomb cap and the cap mu Fn (N). The kinematics' output and the
# law's input: the tip's offset from the COM in surface axes (m), its abscissa (m), its
# penetration into the rigid surface (> 0 inside, m) and the depth the law sees (the
# penetration less the bending walls' deflection, m).
ANCHOR, DEPTH, FACTOR, STRETCH, SHEAR_FACTOR, FREE = 0, 1, 2, 3, 4, 5
NORMAL, TANGENTIAL, TRIAL, CAP = 6, 7, 8, 9
OFFSET_X, OFFSET_Y, X, PENETRATION, SEEN = 10, 11, 12, 13, 14
TIP_FIELDS = 15
# Columns of a scenario's folded law constants (ContactLaw.rows): k (1 + e)/2, k (1 - e)/2 and
# k (1 - e)/2 / (v0 dt) for the normal (kn) and the tangential (kt) law, the Hertz exponent and
# the friction coefficient.
KN_MEAN, KN_HALF, KN_RATE, KT_MEAN, KT_HALF, KT_RATE, EXPONENT, MU = range(8)
LAW_FIELDS = 8


@dataclass
class ContactLaw:
    """The contact constants of a batch, folded for the 1 kHz loop (see ``press_tips``)."""

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

    def rows(self, scenarios: int) -> np.ndarray:
        """Return the constants, one row of LAW_FIELDS per scenario, for the kernels."""
        out = np.empty((scenarios, LAW_FIELDS))
        for column, value in enumerate((self.kn_mean, self.kn_half, self.kn_rate, self.kt_mean,
                                        self.kt_half, self.kt_rate, self.exponent, self.mu)):
            out[:, column] = value[:, 0] if isinstance(value, np.ndarray) else value
        return out


class ContactState:
    """Per-tip memory of the contact law and the last step's forces: rows of ``tips``."""

    def __init__(self, scenarios: int, tips: int):
        self.tips = np.zeros((scenarios, TIP_FIELDS, tips))
        self.reset()

    anchor = property(lambda self: self.tips[:, ANCHOR], doc='anchor of the spring, x, m')
    depth = property(lambda self: self.tips[:, DEPTH], doc='penetration, last step (>= 0), m')
    factor = property(lambda self: self.tips[:, FACTOR], doc='kn times the hysteresis factor')
    stretch = property(lambda self: self.tips[:, STRETCH], doc='|x - anchor|, last step, m')
    shear_factor = property(lambda self: self.tips[:, SHEAR_FACTOR],
                            doc='kt times the hysteresis factor')
    normal = property(lambda self: self.tips[:, NORMAL], doc='Fn >= 0, N')
    tangential = property(lambda self: self.tips[:, TANGENTIAL], doc='Ft along +x, N')
    trial = property(lambda self: self.tips[:, TRIAL], doc='spring force before the cap, N')
    cap = property(lambda self: self.tips[:, CAP], doc='mu Fn, N')

    @property
    def free(self) -> np.ndarray:
        """Return the tips not touching (a new array)."""
        return cast(np.ndarray, self.tips[:, FREE] > 0.0)

    @property
    def touching(self) -> np.ndarray:
        return cast(np.ndarray, self.tips[:, FREE] == 0.0)

    @property
    def slipping(self) -> np.ndarray:
        """Tips held at the Coulomb cap (computed on demand: the 1 kHz loop does not need it)."""
        return cast(np.ndarray, self.touching & (np.abs(self.trial) > self.cap))

    def reset(self) -> None:
        self.tips[:, :SHEAR_FACTOR] = 0.0
        self.tips[:, NORMAL:] = 0.0
        self.tips[:, SHEAR_FACTOR] = 1.0
        self.tips[:, FREE] = 1.0


def hysteresis_factor(rate: ArrayLike, restitution: Param, hysteresis_speed: Param) -> np.ndarray:
    """
    Return the force factor for a deformation rate (m/s): 1 loading, e unloading.

    Linear between -v0 and v0 (pure, for tests and plots).
    """
    return (1.0 + restitution) / 2.0 + (1.0 - restitution) / 2.0 * np.clip(
        np.asarray(rate, float) / hysteresis_speed, -1.0, 1.0)


@numba.njit(cache=CACHE)
def _hysteresis_gain(now: float, before: float, mean: float, half: float, rate: float) -> float:
    """
    Return k ((1 + e)/2 + (1 - e)/2 clip(rate / v0, -1, 1)) from the change of a deformation.

    With the constants folded: k (1 + e)/2, k (1 - e)/2 and k (1 - e)/2 / (v0 dt).
    """
    return max(min((now - before) * rate, half), -half) + mean


@numba.njit(cache=CACHE)
def press_tips(law: np.ndarray, tips: np.ndarray) -> None:
    """
    Advance the contact law one step for one scenario's tips (compiled kernel).

    ``law``: the scenario's folded constants (LAW_FIELDS); ``tips`` (TIP_FIELDS, P): reads X
    and SEEN (the depth the law sees, > 0 inside), writes NORMAL and TANGENTIAL and the memory.
    """
    kn_mean, kn_half, kn_rate = law[KN_MEAN], law[KN_HALF], law[KN_RATE]
    kt_mean, kt_half, kt_rate = law[KT_MEAN], law[KT_HALF], law[KT_RATE]
    exponent, mu = law[EXPONENT], law[MU]
    for p in range(tips.shape[1]):
        seen, x = tips[SEEN, p], tips[X, p]
        # Normal: Fn = kn g delta^p, g the hysteresis factor of the depth's rate.
        d = max(seen, 0.0)
        factor = _hysteresis_gain(d, tips[DEPTH, p], kn_mean, kn_half, kn_rate)
        tips[FACTOR, p] = factor
        tips[DEPTH, p] = d
        # A free tip (most of them: about 8 of 38 touch) skips the square root; 0 * factor is
        # the value the full expression gives it.
        if d > 0.0:
            fn = (math.sqrt(d) * d if exponent == 1.5 else d ** exponent) * factor
        else:
            fn = 0.0 * factor
        # Tangential: a spring from the anchor (taken at first touch), its own hysteresis on
        # the stretch, capped by Coulomb friction.
        anchor = x if tips[FREE, p] > 0.0 else tips[ANCHOR, p]
        trial = anchor - x                                     # -(x - anchor)
        gain = _hysteresis_gain(abs(trial), tips[STRETCH, p], kt_mean, kt_half, kt_rate)
        tips[SHEAR_FACTOR, p] = gain
        trial *= gain                                          # -kt g (x - anchor)
        cap = fn * mu
        ft = max(min(trial, cap), -cap)
        # Sticking tips keep their anchor (x + Ft / (kt g) equals it); slipping tips drag it so
        # that the spring holds exactly mu Fn; free tips get Ft = 0 and a new anchor when they
        # touch. The stretch remembered for the next rate is the spring's after the slip. A
        # spring unloading with e -> 0 has no stiffness left (gain 0, ft 0): it sticks, and
        # keeps its anchor (0 / 0 stopped the kernel at e = 5e-324).
        if cap == 0.0 and gain > 0.0:
            offset = ft                                        # ft / gain of a free tip: +-0
        else:
            offset = ft / gain if gain != 0.0 else anchor - x
        tips[STRETCH, p] = abs(offset)
        tips[ANCHOR, p] = offset + x
        tips[TRIAL, p], tips[CAP, p] = trial, cap
        tips[NORMAL, p], tips[TANGENTIAL, p] = fn, ft
        tips[FREE, p] = 1.0 if seen <= 0.0 else 0.0


@numba.njit(cache=CACHE)
def press_all_tips(law: np.ndarray, tips: np.ndarray) -> None:
    """Run ``press_tips`` for every scenario: law (S, LAW_FIELDS), tips (S, TIP_FIELDS, P)."""
    for s in range(tips.shape[0]):
        press_tips(law[s], tips[s])


def contact_step(state: ContactState, penetration: np.ndarray, x: np.ndarray,
                 law: ContactLaw) -> Tuple[np.ndarray, np.ndarray]:
    """
    Advance the contact law one step for tips at ``penetration`` and abscissa ``x`` (S, P).

    ``law`` holds the folded constants (scalars, or (S, P) arrays where scenarios differ).
    Fills ``state.normal`` and ``state.tangential`` (returned) and updates the memory.
    """
    state.tips[:, SEEN] = penetration
    state.tips[:, X] = x
    press_all_tips(law.rows(len(state.tips)), state.tips)
    return state.normal, state.tangential
