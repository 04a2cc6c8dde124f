"""
Walls that bend (issue 23): each surface an elastic beam on an elastic foundation.

The paper keeps both surfaces flat and rigid behind their contact springs ("contact
flexibility") and sets aside "structural flexibility, in which the surface is bendable" (its
Section 1), though its motivation, a vessel such as the intestine, bends as a whole. Here each
surface may be an Euler-Bernoulli beam of bending stiffness EI (N m^2, the strip the robot
touches) resting on a Winkler foundation of stiffness k (N/m per metre of length: N/m^2), the
tissue or frame behind it:

    EI w'''' + k w = q(x),        w > 0 away from the robot,

loaded by the tips' normal forces, each spread over the contact width b (m) of a tip, and the
contact law's penetration is measured against the deflected surface: a wall pushed away
relieves the tip that pushed it, and its neighbours (docs/walls.md).

Formulation: quasi-static, the closed-form Green's function of the infinite beam on a Winkler
foundation (Hetenyi 1946), superposed over the tips. For a load P spread uniformly over
[-b/2, b/2], with beta = (k / (4 EI))^(1/4) and D(u) = exp(-beta u) cos(beta u):

    inside (|r| <= b/2):  w(r) = P / (2 k b) (2 - D(b/2 + r) - D(b/2 - r))
    outside:              w(r) = P / (2 k b) (D(|r| - b/2) - D(|r| + b/2))

(the point load's P beta / (2 k) exp(-beta |r|) (cos + sin)(beta |r|) integrated over the
patch). Why this one: it is exact for the beam (no mesh, nothing to converge), costs one n x n
matrix of exponentials per surface and step, and holds every limit: EI -> 0 gives a Winkler bed
under each tip, P / (k b), a linear spring in series with the Hertz contact; EI and k -> infinity
give w -> 0, the rigid wall. Quasi-static, because the wall's own time scale is shorter than
the wave's (docs/walls.md: its mass on its foundation rings at about 110 Hz for the silicone sheet
and 40 Hz for the tissue set, against a 1-2 Hz helix and its ~12 Hz link passing). Infinite,
because the walls are long next to the decay length 1 / beta (about a centimetre).

Coupling: the forces depend on the depths, which depend on the deflections the forces make.
Each step solves it for the tips that can touch (``Walls.solve``): Newton on their deflections,
the contact law's hysteresis factor included so that the walls and the law agree to TOLERANCE,
stepping only as far as the law's next kink (contact onset, leaving the hysteresis band) so
that it cannot cycle, from the last step's shape. The others load nothing and read the shape.
"""
from __future__ import annotations

from typing import Any, Callable, cast, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core.contact import ContactLaw, ContactState
from saw_ros.core.params import Scenario

# Newton steps per time step at most, from the last step's shape, until the deflections agree
# with the contact law's forces within TOLERANCE (m): usually one or two.
MAX_NEWTON = 12
TOLERANCE = 1e-9
# Tips that can touch: within this share of the last step's largest deflection, plus MIN_MARGIN
# (m), of the rigid surface (Walls.solve).
CANDIDATE_MARGIN = 0.1
MIN_MARGIN = 1e-4


def _patch(r: ArrayLike, beta: Union[float, np.ndarray],
           half: Union[float, np.ndarray]) -> np.ndarray:
    """Return the bracket of the patch load's deflection at distance r (module docstring)."""
    r = np.abs(r)
    d: Callable[[Any], Any] = lambda u: np.exp(-beta * u) * np.cos(beta * u)  # noqa: E731
    return cast(np.ndarray, np.where(r <= half, 2.0 - d(half + r) - d(np.abs(half - r)),
                                     d(np.abs(r - half)) - d(r + half)))


def deflection(r: ArrayLike, load: float, foundation: float, bending: float,
               width: float) -> np.ndarray:
    """
    Return how far (m) the wall gives at ``r`` (m) from the centre of a load over ``width``.

    ``load`` N, ``foundation`` k N/m^2, ``bending`` EI N m^2, ``width`` b m (module docstring).
    """
    beta = (foundation / (4.0 * bending)) ** 0.25
    return load / (2.0 * foundation * width) * _patch(np.asarray(r, float), beta, width / 2.0)


def point_deflection(r: ArrayLike, load: float, foundation: float, bending: float) -> np.ndarray:
    """Hetenyi's point load on an infinite beam on a Winkler foundation (m at distance r)."""
    beta = (foundation / (4.0 * bending)) ** 0.25
    u = beta * np.abs(np.asarray(r, float))
    return cast(np.ndarray,
                load * beta / (2.0 * foundation) * np.exp(-u) * (np.cos(u) + np.sin(u)))


class Walls:
    """
    The bending walls of S scenarios stepped together (only those with foundation_stiffness > 0).

    ``side``: -1 for the bottom surface's tips, +1 for the top's (kinematics.TipTable.side: the
    bottom tips first, then as many top tips), so that an (S, P) array of the tips is an
    (S, 2, n) view by surface.
    """

    def __init__(self, scenarios: Sequence[Scenario], side: np.ndarray):
        s = [sc.surface for sc in scenarios]
        n = len(side) // 2
        if not ((side[:n] < 0).all() and (side[n:] > 0).all() and len(side) == 2 * n):
            raise ValueError('the walls expect the bottom tips first, then as many top tips')
        self.n = n
        self.active = np.array([x.foundation_stiffness > 0.0 for x in s])
        # Inactive scenarios of a mixed batch get harmless finite constants and a zero gain.
        k = np.array([x.foundation_stiffness if x.foundation_stiffness > 0 else 1.0 for x in s])
        ei = np.array([x.bending_stiffness for x in s])
        b = np.array([x.contact_width for x in s])
        self.beta = (k / (4.0 * ei)) ** 0.25
        self.half = b / 2.0
        self.gain = np.where(self.active, 1.0 / (2.0 * k * b), 0.0)    # m/N before the D terms
        count = len(scenarios)
        # (1 - i) beta: D(u) = exp(-beta u) cos(beta u) = Re exp(-(1 - i) beta u), one exp.
        self._decay = ((1.0 - 1.0j) * self.beta)[:, None, None, None]
        self._half = self.half[:, None, None, None]
        self._gain = self.gain[:, None, None, None]
        self.forces = np.zeros((count, 2, n))               # each tip's load on its wall, N
        self.largest = np.zeros(count)                      # the largest deflection, m
        self._x = np.zeros((count, 2, n))                   # where the tips were, m
        self._shape: Optional[np.ndarray] = np.zeros((count, 2, n))

    @property
    def shape_by_surface(self) -> np.ndarray:
        """Return the deflection at each tip (S, 2, n), m, > 0 away: bottom tips, then top."""
        if self._shape is None:     # computed when asked: the step itself needs only the loaded
            self._shape = (self.compliance(self._x) @ self.forces[..., None])[..., 0]
        return self._shape

    @property
    def deflection(self) -> np.ndarray:
        """Return the deflection at each tip (S, P), m, > 0 away from the robot."""
        return self.shape_by_surface.reshape(len(self.beta), 2 * self.n)

    def reset(self) -> None:
        self.forces[:] = 0.0
        self.largest[:] = 0.0
        self._shape = np.zeros_like(self.forces)

    def _by_surface(self, values: Any) -> Any:
        """Return (S, P) as an (S, 2, n) view, bottom tips then top tips; scalars stay scalars."""
        if np.ndim(values) == 0:
            return values
        return np.reshape(values, (len(self.beta), 2, self.n))

    def compliance(self, x: np.ndarray, sources: Optional[np.ndarray] = None) -> np.ndarray:
        """
        Return G, m/N: deflection at tip i per newton on tip j of the same surface.

        ``x`` (S, P) or by surface (S, 2, n): the tips' abscissae; ``sources`` (S, 2, m): the
        loaded tips' (default: the same tips, G is then (S, 2, n, n)).
        """
        xs = self._by_surface(x) if np.ndim(x) == 2 else x
        src = xs if sources is None else sources
        r = np.abs(xs[..., :, None] - src[..., None, :])
        # Outside the patch: D(r - b/2) - D(r + b/2) (module docstring).
        g = (np.exp(self._decay * np.abs(r - self._half) * -1.0)
             - np.exp(self._decay * (r + self._half) * -1.0)).real
        # Inside it (a tip on itself, or two tips closer than b/2): 2 - D(b/2 + r) - D(b/2 - r).
        inside = r <= self._half
        if inside.any():
            beta = np.broadcast_to(self.beta[:, None, None, None], r.shape)[inside]
            half = np.broadcast_to(self._half, r.shape)[inside]
            g[inside] = _patch(r[inside], beta, half)
        g *= self._gain
        return cast(np.ndarray, g)

    def solve(self, penetration: np.ndarray, x: np.ndarray, state: ContactState,
              law: ContactLaw) -> np.ndarray:
        """
        Return the depth (S, P) the contact law sees: ``penetration`` less the walls' deflection.

        ``penetration``: against the rigid surfaces (> 0 inside); ``state``, ``law``: the
        contact law's memory and constants (core.contact), whose normal force the deflection
        must balance. Keeps the deflection at each tip (``deflection``) and the forces.

        Only the tips that can touch are solved for: those deeper than CANDIDATE_MARGIN of the
        last step's largest deflection below the rigid surface (a wall rises towards a tip by
        at most exp(-3 pi / 4) sin(3 pi / 4) = 7 % of the deflection beside it, Hetenyi), the
        same number K of them per surface across the batch (the deepest), the rest loads
        nothing and only reads the shape.
        """
        d = self._by_surface(penetration)
        xs = self._by_surface(x)
        margin = CANDIDATE_MARGIN * self.largest[:, None, None] + MIN_MARGIN
        count = int((d > -margin).sum(axis=-1).max())
        self._x[:] = xs
        self._shape = None
        if count == 0:
            self.forces[:] = 0.0
            self.largest[:] = 0.0
            return penetration.copy()
        pick = np.argsort(-d, axis=-1)[..., :count]                 # (S, 2, K), deepest first
        take: Callable[[Any], Any] = lambda a: (  # noqa: E731
            a if np.ndim(a) == 0 else np.take_along_axis(self._by_surface(a), pick, axis=-1))
        xk = np.take_along_axis(xs, pick, axis=-1)
        g = self.compliance(xk)                                      # (S, 2, K, K)
        dk = np.take_along_axis(d, pick, axis=-1)
        before = take(state.depth)                                   # the law's memory
        constants = (law.kn_mean, law.kn_half, law.kn_rate, law.exponent)
        mean, half, rate, p = (take(v) for v in constants)
        # The normal law's kinks in the depth: contact at 0, and where its hysteresis factor
        # leaves the band (loading/unloading faster than hysteresis_speed).
        width = half / rate
        eye = np.eye(count)
        # Warm start: the last step's loads on these tips where they are now (a step moves
        # them by less than a tenth of a millimetre).
        w = (g @ np.take_along_axis(self.forces, pick, axis=-1)[..., None])[..., 0]
        for _ in range(MAX_NEWTON):
            delta = dk - w
            touching = np.maximum(delta, 0.0)
            # The normal law of core.contact at this depth, hysteresis factor included:
            # F = (k_mean + clip((delta - before) rate, -k_half, k_half)) delta^p.
            change = (touching - before) * rate
            band = np.abs(change) < half
            factor = mean + np.clip(change, -half, half)
            power = touching ** p
            force = factor * power
            residual = w - (g @ force[..., None])[..., 0]
            open_ = np.abs(residual).max(axis=-1) > TOLERANCE         # (S, 2) still to solve
            if not open_.any():
                break
            slope = factor * p * touching ** (p - 1.0)
            slope += np.where(band & (delta > 0.0), rate * power, 0.0)
            # d residual / d w = I + G diag(slope)  (delta = d - w), for the walls not there yet.
            step = np.zeros_like(w)
            if open_.all():
                step = np.linalg.solve(eye + g * slope[..., None, :], residual[..., None])[..., 0]
            else:
                step[open_] = np.linalg.solve(eye + g[open_] * slope[open_][:, None, :],
                                              residual[open_][..., None])[..., 0]
            # The law is smooth between its kinks only: a step that would carry a tip across
            # one stops just past it (the next step starts from the other side's slope). The
            # residual is monotone in w, so this cannot cycle.
            new = delta + step
            fraction = 1.0
            for kink in (0.0, before - width, before + width):
                crosses = (delta - kink) * (new - kink) < 0.0
                if crosses.any():
                    to_kink = np.where(crosses, (kink - delta) / np.where(crosses, step, 1.0),
                                       1.0)
                    fraction = np.minimum(fraction, to_kink.min(axis=-1, keepdims=True)
                                          * (1.0 + 1e-6) + 1e-12)
            w -= np.minimum(fraction, 1.0) * step
        self.forces[:] = 0.0
        np.put_along_axis(self.forces, pick, force, axis=-1)
        self.largest[:] = w.max(axis=(1, 2))
        # The others are not touching (shallower than the margin, more than any uplift): the
        # contact law sees them free with or without the shape, which is computed when asked.
        depth = self._by_surface(penetration.copy())
        np.put_along_axis(depth, pick, dk - w, axis=-1)
        return cast(np.ndarray, depth.reshape(penetration.shape))

    def shape(self, x_tips: np.ndarray, samples: np.ndarray) -> np.ndarray:
        """
        Return each wall's deflection (S, 2, m) at abscissae ``samples`` (m), from the forces.

        Bottom first, top second; > 0 away from the robot. Rigid scenarios: zeros.
        """
        out = np.zeros((len(self.beta), 2, len(samples)))
        xs = self._by_surface(x_tips)
        for i in np.flatnonzero(self.active):
            for k in range(2):
                r = samples[:, None] - xs[i, k][None, :]
                out[i, k] = self.gain[i] * _patch(r, self.beta[i], self.half[i]) @ \
                    self.forces[i, k]
        return out


def finite_difference_deflection(loads: Sequence[float], at: Sequence[float], foundation: float,
                                 bending: float, width: float, length: float, step: float,
                                 supports: str = 'free') -> Tuple[np.ndarray, np.ndarray]:
    """
    Solve EI w'''' + k w = q on [-length/2, length/2] by central differences: (x, w), m.

    An independent check of the closed form, not used by the simulation: the loads (N) are
    spread over ``width`` around the abscissae ``at``; ``supports`` 'free' (w'' = w''' = 0 at the
    ends: a long beam approaches the infinite one) or 'simple' (w = w'' = 0: a simply supported
    span). Second order in ``step`` (tests/core/test_walls.py checks the order).
    """
    x = np.arange(-length / 2.0, length / 2.0 + step / 2.0, step)
    m = len(x)
    q = np.zeros(m)
    for load, centre in zip(loads, at):
        # Each node carries the load on its cell [x - h/2, x + h/2]: the patch's overlap with it.
        overlap = np.clip(np.minimum(x + step / 2.0, centre + width / 2.0)
                          - np.maximum(x - step / 2.0, centre - width / 2.0), 0.0, None)
        q += load / width * overlap / step
    a = np.zeros((m, m))
    stencil = bending / step ** 4 * np.array([1.0, -4.0, 6.0, -4.0, 1.0])
    for i in range(m):
        for j, c in zip(range(i - 2, i + 3), stencil):
            if 0 <= j < m:
                a[i, j] += c
        a[i, i] += foundation
    if supports == 'simple':
        # w = 0 at the ends; w'' = 0 there by the mirror ghost node w_{-1} = -w_{1}.
        for end, inner in ((0, 1), (m - 1, m - 2)):
            a[end] = 0.0
            a[end, end] = 1.0
            q[end] = 0.0
        for row, ghost_of in ((1, 1), (m - 2, m - 2)):
            a[row, ghost_of] -= stencil[0]      # w_{-1} = -w_{1}
    elif supports == 'free':
        # Free ends (no moment, no shear): ghost nodes from w'' = 0 and w''' = 0.
        for end, sign in ((0, 1), (m - 1, -1)):
            i1, i2 = end + sign, end + 2 * sign
            # w_{-1} = 2 w_0 - w_1, w_{-2} = 4 w_0 - 4 w_1 + w_2 (extrapolation of a line)
            a[end, end] += stencil[0] * 4.0 + stencil[1] * 2.0
            a[end, i1] += -stencil[0] * 4.0 - stencil[1]
            a[end, i2] += stencil[0]
            a[i1, end] += stencil[0] * 2.0
            a[i1, i1] += -stencil[0]
    else:
        raise ValueError(f'supports must be free or simple, not {supports!r}')
    return x, np.linalg.solve(a, q)
