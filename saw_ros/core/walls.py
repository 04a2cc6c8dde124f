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
patch). Why this one: it is exact for the beam (no mesh, nothing to converge; the kernels read
the decay exp(-beta r) (cos, sin)(beta r) from a table within 6.3e-10 of its size, DECAY_ERROR),
costs one n x n matrix per surface and step, and holds every limit: EI -> 0 gives a Winkler bed
under each tip, P / (k b), a linear spring in series with the Hertz contact; EI and k -> infinity
give w -> 0, the rigid wall. Quasi-static, because the wall's own time scale is shorter than
the wave's (docs/walls.md: its mass on its foundation rings at about 110 Hz for the silicone sheet
and 40 Hz for the tissue set, against a 1-2 Hz helix and its ~12 Hz link passing). Infinite,
because the walls are long next to the decay length 1 / beta (about a centimetre).

Coupling: the forces depend on the depths, which depend on the deflections the forces make.
Each step solves it for the tips that can touch (the compiled kernel ``bend_walls``): Newton on
their deflections, wall by wall, the contact law's hysteresis factor included so that the walls
and the law agree to TOLERANCE, stepping only as far as the law's next kink (contact onset,
leaving the hysteresis band) so that it cannot cycle, from the last two steps' shapes
extrapolated. The others load nothing and read the shape.
"""
from __future__ import annotations

import math
from typing import Any, Callable, cast, Dict, List, Sequence, Tuple, TypeVar, Union

import numba
import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core.contact import DEPTH, EXPONENT, KN_HALF, KN_MEAN, KN_RATE, PENETRATION, SEEN, X
from saw_ros.core.jit import CACHE
from saw_ros.core.params import Scenario

Function = TypeVar('Function', bound=Callable[..., Any])
# numba's options for the wall kernels: cached on disk (core.jit), and without numba's
# reference counts. They allocate nothing and return no array, and the counts (an atomic
# increment and decrement for every array argument and row view, at every call) took 80 of the
# 216 ns of a Newton solve on the silicone sheet (numba 0.68.1; ``_nrt`` is numba's own switch
# for it, left out of numba's typed signature).
OPTIONS: Dict[str, Any] = {'cache': CACHE, '_nrt': False}


def kernel(function: Function) -> Function:
    """Return ``function`` compiled by numba with the wall kernels' OPTIONS."""
    return cast(Function, numba.njit(**OPTIONS)(function))


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
# Up to this beta b/2 the compliance of a wall's tips is built from one decay per gap between
# them (fill_wall): the patch's factor exp(beta b/2) stays far from overflowing, and a decay
# that underflows belongs to a pair whose compliance is below exp(-400) of a tip's own.
CHAIN_LIMIT = 300.0
# The beam's decay exp(-u) (cos u, sin u) at u = beta r, tabulated DECAY_STEPS_PER_UNIT times
# per unit of u up to DECAY_END (``decay``; beyond, 16 decay lengths away, computed): a cubic
# Hermite between the nodes, with the exact slopes (-1 + i) f, is within h^4 max|f''''| / 384
# of f (f'''' = -4 f), so within DECAY_ERROR = exp(h) h^4 / 96 = 6.3e-10 of its modulus exp(-u)
# (h = 1/64). A product of k decays (``fill_wall``'s chain) is within k DECAY_ERROR of its
# modulus, and a compliance within 2 k DECAY_ERROR of the gain 1 / (2 k b): 1e-12 m per newton
# on the silicone sheet's five tips, against a TOLERANCE of 1e-7 m. It costs 4 ns where the
# exponential, cosine and sine cost 20 (numba 0.68, this machine).
DECAY_STEPS_PER_UNIT = 64
DECAY_END = 16.0
DECAY_ERROR = math.exp(1.0 / DECAY_STEPS_PER_UNIT) / (96.0 * DECAY_STEPS_PER_UNIT ** 4)
_NODES = np.exp(np.arange(int(DECAY_END * DECAY_STEPS_PER_UNIT) + 2) / DECAY_STEPS_PER_UNIT
                * complex(-1.0, 1.0))
DECAY_TABLE = np.ascontiguousarray(np.stack([_NODES.real, _NODES.imag], axis=1))


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


# Columns of a scenario's walls (Walls.constants[s]): 1 where its walls bend, beta (1/m), half
# the contact width (m), the gain 1 / (2 k b) (m/N), the tolerance of the solve (m), the patch's
# constants of ``fill_wall`` (``patch_constants``: a tip's compliance under its own load, m/N,
# and the complex factor of the loads outside a patch); then what the solve keeps: the largest
# deflection of the last step (m), the depth below which a tip cannot touch (m, < 0), the
# Newton iterations and the steps short of the tolerance so far, and how many tips the last
# step solved for on the bottom wall (SOLVED_COUNT) and on the top one (SOLVED_COUNT + 1).
ACTIVE, BETA, HALF, GAIN, TOLERANCE_COLUMN, ITSELF, PATCH_RE, PATCH_IM = range(8)
LARGEST, REACH, ITERATIONS, UNCONVERGED, SOLVED_COUNT = range(8, 13)
WALL_FIELDS = 14
# Rows of a scenario's per-tip wall state (Walls.state[s], (WALL_ROWS, 2, n): bottom wall, top
# wall): the deflection the last step solved at each tip (0: not solved for), the one before
# (read only where the last step solved), each tip's load on its wall (N), and the tips the
# last step solved for (indices along the wall, the first walls[SOLVED_COUNT + wall] of each
# wall's row).
SOLVED, SOLVED_BEFORE, LOADS, CHOSEN = range(4)
WALL_ROWS = 4
# Scratch rows of bend_walls before its two n x n matrices.
WORK_ROWS = 11


@kernel
def patch_bracket(r: float, beta: float, half: float) -> float:
    """Return the bracket of a patch load's deflection at distance r >= 0 (module docstring)."""
    if r <= half:
        u, v = half + r, abs(half - r)
        return 2.0 - math.exp(-beta * u) * math.cos(beta * u) - \
            math.exp(-beta * v) * math.cos(beta * v)
    u, v = r - half, r + half
    return math.exp(-beta * u) * math.cos(beta * u) - math.exp(-beta * v) * math.cos(beta * v)


@kernel
def decay(u: float) -> Tuple[float, float]:
    """
    Return exp(-u) (cos u, sin u) for u >= 0, within DECAY_ERROR exp(-u) (its comment).

    Between the nodes k h and (k + 1) h of DECAY_TABLE, f = exp((-1 + i) u) by the cubic
    Hermite of its values and slopes (-1 + i) f; from DECAY_END on (or not finite), computed.
    """
    if not u < DECAY_END:
        far = math.exp(-u)
        return far * math.cos(u), far * math.sin(u)
    s = u * DECAY_STEPS_PER_UNIT
    k = int(s)
    t = s - k
    a_re, a_im = DECAY_TABLE[k, 0], DECAY_TABLE[k, 1]
    b_re, b_im = DECAY_TABLE[k + 1, 0], DECAY_TABLE[k + 1, 1]
    # The Hermite basis; the slopes' terms carry h = 1 / DECAY_STEPS_PER_UNIT.
    t2 = t * t
    t3 = t2 * t
    at_b = 3.0 * t2 - 2.0 * t3
    at_a = 1.0 - at_b
    slope_a = (t3 - 2.0 * t2 + t) / DECAY_STEPS_PER_UNIT
    slope_b = (t3 - t2) / DECAY_STEPS_PER_UNIT
    re = at_a * a_re + at_b * b_re - slope_a * (a_re + a_im) - slope_b * (b_re + b_im)
    im = at_a * a_im + at_b * b_im + slope_a * (a_re - a_im) + slope_b * (b_re - b_im)
    return re, im


@kernel
def patch_constants(beta: float, half: float, gain: float) -> Tuple[float, float, float]:
    """
    Return a tip's own compliance and the factor c of the loads outside a patch (m/N).

    Outside a patch gain (D(r - b/2) - D(r + b/2)) = Re(exp(z r) c), z = -(1 - i) beta,
    c = gain (exp(-z b/2) - exp(z b/2)): the decay exp(z r) apart from what depends on the
    patch alone (0 where beta b/2 > CHAIN_LIMIT: ``fill_wall`` does not use it there). Under
    its own load a tip gives gain (2 - 2 D(b/2)).
    """
    rise = np.exp(complex(-beta, beta) * half)
    c = gain * (1.0 / rise - rise) if beta * half <= CHAIN_LIMIT else 0.0j
    return gain * (2.0 - 2.0 * rise.real), c.real, c.imag


@kernel
def fill_wall(x: np.ndarray, count: int, beta: float, half: float, gain: float, itself: float,
              c_re: float, c_im: float, g: np.ndarray) -> None:
    """
    Fill g[:count, :count] (m/N): the deflection at tip i per newton on tip j of one wall.

    ``itself``, ``c_re``, ``c_im``: ``patch_constants``. Outside a patch g_ij =
    Re(exp(z r_ij) c). Where the abscissae x[:count] are monotone (the tips of a wall in their
    order along it), the decay from tip j to tip i is the product of the decays over the gaps
    between them, exp(z r_ij) = exp(z r_(i-1)j) exp(z r_i(i-1)): one exponential, cosine and
    sine per tip instead of per pair, read from a table (``decay``). Its real part is kept in
    g[i, j] and its imaginary part in g[j, i] until the pair's value replaces both. Otherwise,
    or for a patch far wider than the decay length (c would overflow), each pair on its own:
    gain (D(r - b/2) - D(r + b/2)) = Re(exp(z (r - b/2)) gain (1 - exp(z b))), bounded factors.
    Under a patch (two tips closer than half a contact width) the patch formula.
    """
    rising = falling = True
    for i in range(1, count):
        rising = rising and x[i] >= x[i - 1]
        falling = falling and x[i] <= x[i - 1]
    chain = (rising or falling) and beta * half <= CHAIN_LIMIT
    if not chain:
        c = gain * (1.0 - np.exp(complex(-beta, beta) * (2.0 * half)))
        c_re, c_im = c.real, c.imag
    for i in range(count):
        g[i, i] = itself
        if chain:
            if i > 0:
                # exp(z r_i(i-1)), then on along the row: exp(z r_ij) from exp(z r_(i-1)j).
                step_re, step_im = decay(beta * abs(x[i] - x[i - 1]))
                g[i, i - 1], g[i - 1, i] = step_re, step_im
                for j in range(i - 1):
                    re, im = g[i - 1, j], g[j, i - 1]
                    g[i, j] = re * step_re - im * step_im
                    g[j, i] = re * step_im + im * step_re
        else:
            for j in range(i):
                g[i, j], g[j, i] = decay(beta * max(abs(x[i] - x[j]) - half, 0.0))
    for i in range(count):
        for j in range(i):
            r = abs(x[i] - x[j])
            if r < half:
                value = gain * patch_bracket(r, beta, half)
            else:
                value = g[i, j] * c_re - g[j, i] * c_im
            g[i, j] = value
            g[j, i] = value


@kernel
def fill_compliance(x: np.ndarray, count: int, beta: float, half: float, gain: float,
                    g: np.ndarray) -> None:
    """Fill g[:count, :count] (m/N) for tips at x[:count] in any order (``fill_wall``)."""
    itself, c_re, c_im = patch_constants(beta, half, gain)
    fill_wall(x, count, beta, half, gain, itself, c_re, c_im, g)


@kernel
def solve_in_place(a: np.ndarray, b: np.ndarray, count: int) -> None:
    """
    Solve a[:count, :count] y = b[:count] by Gaussian elimination, no pivoting; y in b.

    For ``balance_wall``'s Jacobian a = I + G S, G a compliance (symmetric, positive
    semi-definite) and S >= 0 diagonal: its leading minors are those of I + S^1/2 G S^1/2
    (Sylvester's determinant identity), a matrix of eigenvalues >= 1, so every pivot is at
    least 1 and the elimination keeps to the row order. G is positive definite for tips a
    contact width or more apart, as a wall's tips are (one link's pitch: over 1 s of the
    silicone sheet and of the soft tissue its smallest eigenvalue was 0.47 and 0.086 of its
    largest, every pivot 1 or more). Tips under one patch on a foundation far stiffer than its
    beam can make the patch kernel indefinite: there nothing bounds the pivots, the Newton
    steps stop at the law's kinks and a non-finite state stops the run (DivergenceError).
    ``a`` is left holding its elimination, with each pivot's reciprocal on the diagonal.
    """
    for k in range(count):
        inverse = 1.0 / a[k, k]
        a[k, k] = inverse
        for i in range(k + 1, count):
            f = a[i, k] * inverse
            for j in range(k + 1, count):
                a[i, j] -= f * a[k, j]
            b[i] -= f * b[k]
    for k in range(count - 1, -1, -1):
        total = b[k]
        for j in range(k + 1, count):
            total -= a[k, j] * b[j]
        b[k] = total * a[k, k]


@kernel
def balance_wall(depth: np.ndarray, w: np.ndarray, g: np.ndarray, before: np.ndarray,
                 count: int, law: np.ndarray, scale: float, tolerance: float,
                 work: np.ndarray, jacobian: np.ndarray, force: np.ndarray) -> Tuple[int, bool]:
    """
    Newton on one wall's deflections w[:count] until the contact law's forces make them.

    ``depth`` the tips' depths into the rigid wall, ``w`` the first guess (solved in place),
    ``g`` the compliance, ``before`` the law's last depths, ``law`` its folded constants
    (core.contact's LAW_FIELDS), ``scale`` the convergence test's scale (p times twice a tip's
    own compliance), ``work`` rows 0-2 a scratch. Leaves the forces in ``force``; returns
    (iterations, converged).
    """
    mean, half, rate, p = law[KN_MEAN], law[KN_HALF], law[KN_RATE], law[EXPONENT]
    band = half / rate
    slope, step, curvature = work[0], work[1], work[2]
    converged = False
    iteration = 0
    for iteration in range(MAX_NEWTON):
        for i in range(count):
            # The normal law of core.contact at this depth, hysteresis factor included:
            # F = (k_mean + clip((delta - before) rate, -k_half, k_half)) delta^p.
            delta = max(depth[i] - w[i], 0.0)
            change = (delta - before[i]) * rate
            factor = max(min(change, half), -half) + mean
            root = math.sqrt(delta) if p == 1.5 else delta ** (p - 1.0)
            loading = rate if abs(change) < half else 0.0     # the band's rate term
            force[i] = factor * (root * delta)
            slope[i] = factor * root * p + loading * (root * delta)
            # F'' delta / p, for the convergence test below (times delta: no division).
            curvature[i] = ((p - 1.0) * factor + 2.0 * loading * delta) * root
        # residual = w - G F; d residual / d w = I + G diag(slope)  (delta = d - w).
        for i in range(count):
            carried = 0.0
            for j in range(count):
                carried += g[i, j] * force[j]
                jacobian[i, j] = g[i, j] * slope[j]
            jacobian[i, i] += 1.0
            step[i] = w[i] - carried
        solve_in_place(jacobian, step, count)
        # The law is smooth between its kinks only (contact; leaving or entering the
        # hysteresis band, on either side): a step that would carry a tip across one stops just
        # past it, the next starts from the other side's slope. The residual is monotone in w,
        # so this cannot cycle.
        # Converged when what the step leaves of the residual, G F'' step^2 / 2 (twice the
        # tip's own compliance for its neighbours'), is below the tolerance at every tip (both
        # sides times its depth); in the law's straight parts (free, or a linear law) the step
        # is exact.
        fraction = 1.0
        left = 0.0
        for i in range(count):
            ahead, change = depth[i] - w[i], step[i]
            for a in (ahead - before[i] + band, ahead - before[i] - band, ahead):
                b = a + change
                if a * b < 0.0:
                    fraction = min(fraction, a / (a - b))
            left = max(left, curvature[i] * change * change * scale - tolerance * max(ahead, 0.0))
        if fraction < 1.0:
            fraction = min(fraction * (1.0 + 1e-6) + 1e-12, 1.0)
        for i in range(count):
            w[i] -= fraction * step[i]
        if left <= 0.0 and fraction == 1.0:
            converged = True
            break
    return iteration + 1, converged


@kernel
def retire_solved(walls: np.ndarray, state: np.ndarray, wall: int, count: int) -> None:
    """
    Make the last step's solution of ``wall`` this step's "before"; ``count`` tips are solved now.

    Only the tips it solved for hold anything (the rows stay 0 elsewhere): they start empty.
    """
    for k in range(int(walls[SOLVED_COUNT + wall])):
        i = int(state[CHOSEN, wall, k])
        state[SOLVED_BEFORE, wall, i] = state[SOLVED, wall, i]
        state[SOLVED, wall, i] = 0.0
        state[LOADS, wall, i] = 0.0
    walls[SOLVED_COUNT + wall] = count


@kernel
def close_step(walls: np.ndarray, largest: float, most: int, all_converged: bool) -> None:
    """Keep a step's bookkeeping: iterations, convergence, and the next step's reach."""
    if largest == -np.inf:
        walls[LARGEST] = 0.0
        walls[REACH] = -MIN_MARGIN
        return
    walls[ITERATIONS] += most
    if not all_converged:
        walls[UNCONVERGED] += 1.0
    walls[LARGEST] = largest
    walls[REACH] = largest * -CANDIDATE_MARGIN - MIN_MARGIN


@kernel
def bend_walls(law: np.ndarray, walls: np.ndarray, state: np.ndarray, tips: np.ndarray,
               work: np.ndarray) -> None:
    """
    Solve one scenario's two walls against its tips' contact law (compiled kernel).

    Sets the tips' SEEN depth (core.contact's rows) to the PENETRATION less the walls'
    deflection. Only the tips that can touch are solved for: those deeper than
    CANDIDATE_MARGIN of the last step's largest deflection below the rigid surface (a wall
    rises towards a tip by at most exp(-3 pi / 4) sin(3 pi / 4) = 7 % of the deflection
    beside it, Hetenyi), in their order along the wall; the others load nothing and read the
    shape. First guess: the last two steps' deflections extrapolated (a tip the last step did
    not solve for starts from 0). ``walls``: the scenario's WALL_FIELDS, ``state``
    (WALL_ROWS, 2, n), ``work`` a scratch (WORK_ROWS + 2 n, n) array.
    """
    n = state.shape[2]
    reach = walls[REACH]
    largest = -np.inf
    most = 0
    all_converged = True
    fresh = work[5]
    x, depth, before, w, force = work[6], work[7], work[8], work[9], work[10]
    g, jacobian = work[WORK_ROWS:WORK_ROWS + n], work[WORK_ROWS + n:]
    # The candidates of both walls in one pass (two chains side by side), each index written
    # in any case and kept where the tip can touch: no branch to mispredict.
    bottom = top = 0
    for i in range(n):
        work[3, bottom] = i
        work[4, top] = i
        bottom += tips[PENETRATION, i] > reach
        top += tips[PENETRATION, n + i] > reach
    for wall in range(2):
        first = wall * n
        chosen = work[3 + wall]
        count = top if wall else bottom
        for k in range(count):
            i = int(chosen[k])
            p = first + i
            x[k], depth[k], before[k] = tips[X, p], tips[PENETRATION, p], tips[DEPTH, p]
            last = state[SOLVED, wall, i]
            fresh[k] = last == 0.0
            w[k] = 2.0 * last - state[SOLVED_BEFORE, wall, i] if last != 0.0 else 0.0
        retire_solved(walls, state, wall, count)
        if count == 0:
            continue
        fill_wall(x, count, walls[BETA], walls[HALF], walls[GAIN], walls[ITSELF],
                  walls[PATCH_RE], walls[PATCH_IM], g)
        scale = law[EXPONENT] * 2.0 * g[0, 0]
        iterations, converged = balance_wall(depth, w, g, before, count, law, scale,
                                             walls[TOLERANCE_COLUMN], work, jacobian, force)
        most = max(most, iterations)
        all_converged = all_converged and converged
        for k in range(count):
            i = int(chosen[k])
            state[CHOSEN, wall, k] = i
            if fresh[k] > 0.0:
                state[SOLVED_BEFORE, wall, i] = w[k]    # solved for the first time: no trend
            state[SOLVED, wall, i] = w[k]
            state[LOADS, wall, i] = force[k]
            tips[SEEN, first + i] = depth[k] - w[k]
            largest = max(largest, w[k])
    close_step(walls, largest, most, all_converged)


class Walls:
    """
    The bending walls of S scenarios stepped together (only those with foundation_stiffness > 0).

    ``side``: -1 for the bottom surface's tips, +1 for the top's (kinematics.TipTable.side: the
    bottom tips first, then as many top tips), so that an (S, P) array of the tips is an
    (S, 2, n) view by surface. The class holds the constants and the state ``bend_walls``
    advances (``constants``, ``state``); the step itself is the kernel's.
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
        self.constants = np.zeros((count, WALL_FIELDS))
        self.constants[:, ACTIVE] = self.active
        self.constants[:, BETA] = self.beta
        self.constants[:, HALF] = self.half
        self.constants[:, GAIN] = self.gain
        self.constants[:, TOLERANCE_COLUMN] = TOLERANCE
        for row in self.constants:
            row[ITSELF:PATCH_IM + 1] = patch_constants(row[BETA], row[HALF], row[GAIN])
        self.state = np.zeros((count, WALL_ROWS, 2, n))
        self.largest = self.constants[:, LARGEST]           # the largest deflection, m
        # The tips' abscissae (S, P), m: the simulator's, to draw the shape from the loads.
        self.tip_x = np.zeros((count, 2 * n))
        self.reset()

    @property
    def iterations(self) -> int:
        """Return the Newton iterations so far (each step counts its walls' most)."""
        return int(self.constants[:, ITERATIONS].sum())

    @property
    def unconverged(self) -> int:
        """Return the scenario-steps whose solve ended at MAX_NEWTON, short of the tolerance."""
        return int(self.constants[:, UNCONVERGED].sum())

    @property
    def forces(self) -> np.ndarray:
        """Return each tip's load on its wall (S, 2, n), N: bottom tips, then top."""
        return self.state[:, LOADS].copy()

    @property
    def solved_tips(self) -> List[np.ndarray]:
        """Return the flat (S P) indices of the tips the last step solved for, per wall (2 S)."""
        found = []
        for s in range(len(self.beta)):
            for wall in range(2):
                count = int(self.constants[s, SOLVED_COUNT + wall])
                chosen = self.state[s, CHOSEN, wall, :count].astype(int)
                found.append(chosen + (2 * s + wall) * self.n)
        return found

    @property
    def shape_by_surface(self) -> np.ndarray:
        """Return the deflection at each tip (S, 2, n), m, > 0 away: bottom tips, then top."""
        return cast(np.ndarray, (self.compliance(self.tip_x) @ self.forces[..., None])[..., 0])

    @property
    def deflection(self) -> np.ndarray:
        """Return the deflection at each tip (S, P), m, > 0 away from the robot."""
        return self.shape_by_surface.reshape(len(self.beta), 2 * self.n)

    @property
    def solved(self) -> np.ndarray:
        """Return the deflection the last step solved at each tip (S, P), m (0: not solved)."""
        return self.state[:, SOLVED].reshape(len(self.beta), 2 * self.n)

    def reset(self) -> None:
        self.constants[:, LARGEST:] = 0.0
        self.constants[:, REACH] = -MIN_MARGIN
        self.state[:] = 0.0

    def _by_surface(self, values: Any) -> Any:
        """Return (S, P) as an (S, 2, n) view, bottom tips then top tips; scalars stay scalars."""
        if not isinstance(values, np.ndarray):
            return values
        return values.reshape(len(self.beta), 2, self.n)

    def compliance(self, x: np.ndarray) -> np.ndarray:
        """
        Return G (S, 2, m, m), m/N: deflection at tip i per newton on tip j of the same surface.

        ``x`` (S, P), or by surface (S, 2, m): the tips' abscissae (``fill_compliance``).
        """
        xs = self._by_surface(x) if np.ndim(x) == 2 else np.asarray(x)
        m = xs.shape[-1]
        g = np.zeros(xs.shape + (m,))
        for i in range(xs.shape[0]):
            for wall in range(xs.shape[1]):
                fill_compliance(np.ascontiguousarray(xs[i, wall], dtype=float), m,
                                float(self.beta[i]), float(self.half[i]), float(self.gain[i]),
                                g[i, wall])
        return g

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
