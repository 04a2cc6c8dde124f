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
wall by wall, the contact law's hysteresis factor included so that the walls and the law agree
to TOLERANCE, stepping only as far as the law's next kink (contact onset, leaving the
hysteresis band) so that it cannot cycle, from the last two steps' shapes extrapolated. The
others load nothing and read the shape.
"""
from __future__ import annotations

from typing import Any, Callable, cast, List, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core.contact import ContactLaw, ContactState
from saw_ros.core.params import Scenario

# Newton steps per time step at most, from the last two steps' shapes, until the deflections
# agree with the contact law's forces within TOLERANCE (m): usually one (two or three for soft
# tissue). 0.1 um, because over 4 s it moves the pose by 3e-8 m, against 8e-5 m between
# integration.dt 1 ms and 0.5 ms (tests/core/test_walls.py keeps it so), at 1.1 iterations a
# step for the silicone sheet against 1.7 for 1e-9.
MAX_NEWTON = 12
TOLERANCE = 1e-7
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
        count = len(scenarios)
        self.active = np.array([x.foundation_stiffness > 0.0 for x in s])
        # Inactive scenarios of a mixed batch get harmless finite constants and a zero gain.
        k = np.array([x.foundation_stiffness if x.foundation_stiffness > 0 else 1.0 for x in s])
        ei = np.array([x.bending_stiffness for x in s])
        b = np.array([x.contact_width for x in s])
        self.beta = (k / (4.0 * ei)) ** 0.25
        self.half = b / 2.0
        self.gain = np.where(self.active, 1.0 / (2.0 * k * b), 0.0)    # m/N before the D terms
        # D(u) = exp(-beta u) cos(beta u) = Re exp(z u), z = -(1 - i) beta: one exp. Outside a
        # patch, D(r - b/2) - D(r + b/2) = Re(exp(z (r - b/2)) (1 - exp(z b))): bounded factors
        # however wide the patch is against the decay length. Under it, 2 - 2 D(b/2).
        z = -(1.0 - 1.0j) * self.beta
        column: Callable[[np.ndarray], np.ndarray] = lambda a: a[:, None, None, None]  # noqa: E731
        self._z, self._half = column(z), column(self.half)
        self._outside = column(self.gain * (1.0 - np.exp(z * b)))
        self._under = self.gain * (2.0 - 2.0 * np.exp(z * self.half).real)
        self._compliant = np.repeat(2.0 * self._under, 2)[:, None]     # per wall (2 S, 1)
        # What the outside formula gives a tip on itself (r = 0), replaced by _under, per size.
        itself = self._under - (np.exp(z * self.half) * self._outside[:, 0, 0, 0]).real
        self._on_itself = [itself[:, None, None, None] * np.eye(m) for m in range(n + 1)]
        self._rows = (np.arange(2 * count) * n).reshape(count, 2, 1)   # (S, 2, n) -> flat
        self.largest = np.zeros(count)                      # the largest deflection, m
        # Tips shallower than this (m, < 0: outside the rigid surface) cannot touch (solve).
        self._reach = np.full((count, 1, 1), -MIN_MARGIN)
        self.iterations = 0                                 # Newton iterations so far
        self.unconverged = 0        # steps that ended at MAX_NEWTON, short of TOLERANCE
        self._x = np.zeros((count, 2, n))                   # where the tips were, m
        # The deflection the last two steps solved at each tip (0 where a tip was not solved
        # for), for the next step's first guess.
        self._solved = np.zeros((count, 2, n))
        self._solved_before = np.zeros((count, 2, n))
        # Which tips the last step solved for (flat indices) and their loads, N.
        self._flat = np.zeros((count, 2, 0), int)
        self._loads = np.zeros((count, 2, 0))
        self._shape: Optional[np.ndarray] = np.zeros((count, 2, n))
        self._eyes = [np.eye(k) for k in range(n + 1)]

    @property
    def forces(self) -> np.ndarray:
        """Return each tip's load on its wall (S, 2, n), N: bottom tips, then top."""
        out = np.zeros((len(self.beta), 2, self.n))
        out.ravel()[self._flat] = self._loads
        return out

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

    @property
    def solved(self) -> np.ndarray:
        """Return the deflection the last step solved at each tip (S, P), m (0: not solved)."""
        return self._solved.reshape(len(self.beta), 2 * self.n)

    def reset(self) -> None:
        self.largest[:] = 0.0
        self._reach[:] = -MIN_MARGIN
        self._solved[:] = 0.0
        self._solved_before[:] = 0.0
        self._flat = self._flat[..., :0]
        self._loads = self._loads[..., :0]
        self._shape = np.zeros_like(self._x)

    def _by_surface(self, values: Any) -> Any:
        """Return (S, P) as an (S, 2, n) view, bottom tips then top tips; scalars stay scalars."""
        if not isinstance(values, np.ndarray):
            return values
        return values.reshape(len(self.beta), 2, self.n)

    def compliance(self, x: np.ndarray) -> np.ndarray:
        """
        Return G (S, 2, m, m), m/N: deflection at tip i per newton on tip j of the same surface.

        ``x`` (S, P), or by surface (S, 2, m): the tips' abscissae.
        """
        xs = self._by_surface(x) if np.ndim(x) == 2 else x
        r = np.abs(xs[..., :, None] - xs[..., None, :])
        g = (np.exp(self._z * np.abs(r - self._half)) * self._outside).real
        m = xs.shape[-1]
        g += self._on_itself[m]
        # Two tips closer than half a contact width (wide contacts only): the patch formula.
        under = r < self._half
        if np.count_nonzero(under) > under.size // m:
            beta = np.broadcast_to(self.beta[:, None, None, None], r.shape)[under]
            half = np.broadcast_to(self._half, r.shape)[under]
            gain = np.broadcast_to(self.gain[:, None, None, None], r.shape)[under]
            g[under] = gain * _patch(r[under], beta, half)
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
        count = int((d > self._reach).sum(axis=-1).max())
        self._x[:] = self._by_surface(x)
        self._shape = None
        # The last two steps' solutions; the older buffer takes this step's.
        last, prior = self._solved, self._solved_before
        self._solved, self._solved_before = prior, last
        if count == 0:
            prior[:] = 0.0
            self._flat = self._flat[..., :0]
            self._loads = self._loads[..., :0]
            self.largest[:] = 0.0
            self._reach[:] = -MIN_MARGIN
            return penetration.copy()
        flat = np.argsort(d, axis=-1)[..., -count:]        # (S, 2, K): the deepest
        flat += self._rows
        # One row per wall of each scenario (2 S, K) from here: each is solved on its own.
        flat = flat.reshape(-1, count)
        take: Callable[[Any], Any] = lambda a: (  # noqa: E731
            a.ravel()[flat] if isinstance(a, np.ndarray) else a)
        dk = penetration.ravel()[flat]
        # First guess: the deflection of the last two steps, extrapolated (it moves smoothly;
        # a tip not solved for before starts from 0 and settles in the first Newton step).
        w = last.ravel()[flat]
        w += w
        w -= prior.ravel()[flat]
        prior[:] = 0.0
        w, force = self._balance(dk, w, self.compliance(x.ravel()[flat].reshape(
            -1, 2, count)).reshape(-1, count, count), state.depth.ravel()[flat],
            [take(v) for v in (law.kn_mean, law.kn_half, law.kn_rate, law.exponent)])
        self._flat, self._loads = flat.reshape(-1, 2, count), force.reshape(-1, 2, count)
        # This step's solution; a tip solved for the first time is its own before (no trend).
        fresh = last.ravel()[flat] == 0.0
        if fresh.any():
            last.ravel()[flat[fresh]] = w[fresh]
        prior.ravel()[flat] = w
        self.largest[:] = w.reshape(-1, 2 * count).max(axis=1)
        np.multiply(self.largest[:, None, None], -CANDIDATE_MARGIN, out=self._reach)
        self._reach -= MIN_MARGIN
        depth = penetration.copy()
        depth.ravel()[flat] = dk - w
        return depth

    def shape(self, x_tips: np.ndarray, samples: np.ndarray) -> np.ndarray:
        """
        Return each wall's deflection (S, 2, m) at abscissae ``samples`` (m), from the forces.

        Bottom first, top second; > 0 away from the robot. Rigid scenarios: zeros.
        """
        out = np.zeros((len(self.beta), 2, len(samples)))
        xs = self._by_surface(x_tips)
        forces = self.forces
        for i in np.flatnonzero(self.active):
            for k in range(2):
                r = samples[:, None] - xs[i, k][None, :]
                out[i, k] = self.gain[i] * _patch(r, self.beta[i], self.half[i]) @ forces[i, k]
        return out

    def _balance(self, dk: np.ndarray, w: np.ndarray, g: np.ndarray, before: np.ndarray,
                 constants: List[Any]) -> Tuple[np.ndarray, np.ndarray]:
        """
        Return the deflections (N, K) that the contact law's forces make, and those forces.

        One row per wall: ``dk`` the tips' depths into the rigid wall, ``w`` a first guess,
        ``g`` (N, K, K) the compliance, ``before`` the law's last depths; ``constants`` the
        law's k_mean, k_half, k_rate and exponent (scalars or (N, K)). Newton on w, the
        contact law's hysteresis factor included, per wall; the walls that have converged
        leave the iteration.
        """
        mean, half, rate, p = constants
        rows = np.arange(len(dk))                            # the walls still iterating
        solved, loads = np.empty_like(w), np.empty_like(w)
        # The convergence test's scale, p times twice each tip's own compliance (see below).
        scale = p * self._compliant
        eye = self._eyes[dk.shape[1]]
        # The law's kinks in the depth: leaving its hysteresis band on either side (loading or
        # unloading faster than hysteresis_speed), and contact.
        kinks = np.stack((before - half / rate, before + half / rate, np.zeros_like(before)))
        for iteration in range(MAX_NEWTON):
            delta = dk - w
            touching = np.maximum(delta, 0.0)
            # The normal law of core.contact at this depth, hysteresis factor included:
            # F = (k_mean + clip((delta - before) rate, -k_half, k_half)) delta^p.
            change = touching - before
            change *= rate
            factor = np.minimum(change, half)
            np.maximum(factor, -half, out=factor)
            factor += mean
            root = touching ** (p - 1.0)
            power = root * touching
            force = factor * power
            slope = factor * root
            slope *= p
            loading = (np.abs(change) < half) * rate          # the band's rate term, N/m^(p+1)
            slope += loading * power
            residual = w - (g @ force[..., None])[..., 0]
            # d residual / d w = I + G diag(slope)  (delta = d - w).
            jacobian = g * slope[..., None, :]
            jacobian += eye
            step = np.linalg.solve(jacobian, residual[..., None])[..., 0]
            # The law is smooth between its kinks only (contact; leaving or entering the
            # hysteresis band, on either side): a step that would carry a tip across one stops
            # just past it, the next starts from the other side's slope. The residual is
            # monotone in w, so this cannot cycle.
            ahead = delta - kinks
            behind = ahead + step
            crosses = ahead * behind < 0.0
            kinked = crosses.any()
            if kinked:
                to_kink = np.where(crosses, ahead / np.where(crosses, ahead - behind, 1.0), 1.0)
                fraction = np.minimum(to_kink.min(axis=(0, 2)) * (1.0 + 1e-6) + 1e-12, 1.0)
                w -= fraction[:, None] * step
            else:
                w -= step
            # Converged when what the step leaves of the residual, G F'' step^2 / 2 (twice the
            # tip's own compliance for its neighbours'), is below TOLERANCE; in the law's
            # straight parts (free, or a linear law) the step is exact.
            left = (p - 1.0) * factor
            left /= np.maximum(touching, 1e-300)
            left += loading + loading                          # F'' / (p delta^(p-1))
            left *= root
            left *= step * step
            left *= scale
            done = left.max(axis=1) < TOLERANCE
            if kinked:
                done &= fraction == 1.0
            if done.all():
                break
            if done.any():
                solved[rows[done]], loads[rows[done]] = w[done], force[done]
                going = ~done
                rows, dk, w, g = rows[going], dk[going], w[going], g[going]
                before, force = before[going], force[going]
                kinks = kinks[:, going]
                scale = scale[going]
                mean, half, rate, p = (v[going] if isinstance(v, np.ndarray) else v
                                       for v in (mean, half, rate, p))
        self.iterations += iteration + 1
        if not done.all():
            self.unconverged += 1
        solved[rows], loads[rows] = w, force
        return solved, loads


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
