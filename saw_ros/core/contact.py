"""Contact law between a link tip and a compliant surface (paper Section 4.2, Eqs. 6-8, A.2).

Normal: Hertz with restitution hysteresis, Fn = kn delta^p while the penetration grows and
e kn delta^p while it shrinks. Which branch applies is decided against the deepest penetration of
the current contact episode (model.md section 6): a tip is loading only while it presses deeper
than it ever has since it touched. Comparing with the previous step instead would flip between the
branches at every micro-vibration near equilibrium (chatter).

Tangential: a spring anchored where the tip first touched, Ft = -kt (x - anchor), capped by
Coulomb friction |Ft| <= mu Fn; beyond the cap the tip slips and the anchor is dragged along so
that the spring holds exactly mu Fn. Losing contact forgets the anchor.

All arrays have shape (S, P): S scenarios, P tips. The kernel works in place on ``ContactState``
so that the 1 kHz loop allocates nothing large.
"""
from __future__ import annotations

import numpy as np


class ContactState:
    """Per-tip memory of the contact law and the last step's forces."""

    def __init__(self, scenarios: int, tips: int):
        shape = (scenarios, tips)
        self.anchor = np.zeros(shape)        # x of the tangential spring's anchor, m
        self.deepest = np.zeros(shape)       # deepest penetration of this contact episode, m
        self.free = np.ones(shape, bool)     # not touching
        self.loading = np.zeros(shape, bool)
        self.normal = np.zeros(shape)        # Fn >= 0, N, pushing the tip out of the surface
        self.tangential = np.zeros(shape)    # Ft along +x on the robot, N
        self.trial = np.zeros(shape)         # the spring force before the Coulomb cap, N
        self.cap = np.zeros(shape)           # mu Fn, N
        self._d = np.zeros(shape)
        self._root = np.zeros(shape)
        self._gain = np.zeros(shape)

    @property
    def touching(self):
        return ~self.free

    @property
    def slipping(self):
        """Tips held at the Coulomb cap (computed on demand: the 1 kHz loop does not need it)."""
        return ~self.free & (np.abs(self.trial) > self.cap)

    def reset(self):
        for a in (self.anchor, self.deepest, self.normal, self.tangential, self.trial, self.cap):
            a[:] = 0.0
        self.free[:] = True
        self.loading[:] = False


def normal_force(penetration, deepest, kn, exponent, restitution):
    """Hertz force with hysteresis for given penetration(s) and episode depth(s) (pure, for tests
    and plots): loading (penetration >= deepest) gives kn d^p, unloading e kn d^p."""
    d = np.maximum(penetration, 0.0)
    f = kn * d ** exponent
    return np.where(d >= deepest, f, restitution * f)


def contact_step(state: ContactState, penetration, x, kn, kn_unloading, exponent, kt, inv_kt,
                 mu):
    """Advance the contact law one step for tips at ``penetration`` and abscissa ``x``.

    Parameters are scalars or arrays broadcastable to (S, P); ``kn_unloading`` is e kn.
    Fills ``state.normal`` and ``state.tangential`` and updates the memory.
    """
    was_free = state.free
    free = np.less_equal(penetration, 0.0)
    d = np.maximum(penetration, 0.0, out=state._d)
    if exponent == 1.5:
        hertz = np.sqrt(d, out=state._root)
        hertz *= d                           # d^1.5, three times faster than power()
    else:
        hertz = np.power(d, exponent, out=state._root)
    loading = np.greater_equal(d, state.deepest, out=state.loading)
    np.maximum(state.deepest, d, out=state.deepest)
    np.copyto(state.deepest, 0.0, where=free)  # a new episode starts from zero depth
    gain = state._gain
    np.copyto(gain, kn_unloading)
    np.copyto(gain, kn, where=loading)
    fn = np.multiply(hertz, gain, out=state.normal)

    # Anchor at first touch: tips that were free take their current position.
    np.copyto(state.anchor, x, where=was_free)
    trial = np.subtract(state.anchor, x, out=state.trial)
    trial *= kt                               # -kt (x - anchor)
    cap = np.multiply(fn, mu, out=state.cap)
    ft = np.minimum(trial, cap, out=state.tangential)
    np.maximum(ft, np.negative(cap, out=state._d), out=ft)
    # Sticking tips keep their anchor (x + Ft / kt equals it); slipping tips drag it so that the
    # spring holds exactly mu Fn; free tips get Ft = 0 and take a new anchor when they touch.
    np.multiply(ft, inv_kt, out=state.anchor)
    state.anchor += x
    state.free = free
    return fn, ft
