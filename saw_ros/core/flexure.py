"""
A compliant robot (issue 31): each wave link on a flexure between it and the helix/backbone.

The paper's second remedy for the vertical vibration is "a monolithic compliant robot
structure": one printed part whose hinges are springs. Here each wave link, of mass m, follows
its kinematic target (core.kinematics) through a flexure of stiffness k and damping c normal to
the backbone; e is the link's deflection from its target (m, + along the body's normal, y):

    m e'' + c e' + k e = F_bottom - F_top,

F the normal loads of the link's bottom and top tips (> 0 pushing the tip away from its wall:
up for the bottom tip, down for the top one). The backbone (and through it the helix and the
body) receives the flexure's force, which over a step carries the same impulse as the tips'
loads less what the link's own momentum took:

    reaction = F - m (e'_after - e'_before) / dt,    F = F_bottom - F_top at the step's end.

Integration, and why: the flexure is stiff against the step (k 1e4 N/m on a 4 g link rings at
250 Hz, beyond 1e6 N/m faster than 1 / dt), so it is stepped exactly, as each mode of
core.dynamic_walls is: the oscillator's 2 x 2 matrix exponential (dynamic_walls.mode_propagator)
advances (e, e') without error and unconditionally stable at any stiffness, with no numerical
damping to hide a vibration the flexure would pass, under a load that varies linearly over the
step from the last step's value to this one's (a first-order hold: second order in dt,
tests/core/test_flexure.py measures it against smaller steps). A load held constant instead
(zero-order) kicks an undamped stiff flexure at every step: at k = 1e9 N/m its ringing moved the
reaction by 1e-3 of the load within 0.2 s; the ramp's kicks are 1 / (omega dt) of those. The
step-end load makes the deflection after the step linear in it, e = free + C F, so that the
contact solve balances it implicitly (``balance_links``): rigid flexures (k -> inf) give C -> 0,
e -> 0 and a reaction equal to the step-end load, the rigid robot's step (its semi-implicit
Euler applies the step-end contact forces over the step, and so does the reaction above).
"""
from __future__ import annotations

import math
from typing import Sequence, Tuple

import numpy as np

from saw_ros.core.contact import DEPTH, EXPONENT, KN_HALF, KN_MEAN, KN_RATE, NORMAL
from saw_ros.core.contact import PENETRATION, SEEN, X
from saw_ros.core.dynamic_walls import _free_at, _free_modes, _tip_table, compiled, HELD
from saw_ros.core.dynamic_walls import mode_propagator, oscillator_step, STATE_ROWS, TABLE
from saw_ros.core.dynamic_walls import WALL_STATE
from saw_ros.core.params import FlexureParams, SurfaceParams
from saw_ros.core.walls import balance_wall, BETA, CHOSEN, close_step, fill_wall, GAIN, HALF
from saw_ros.core.walls import ITSELF, LOADS, PATCH_IM, PATCH_RE, REACH, retire_solved, SOLVED
from saw_ros.core.walls import SOLVED_BEFORE, TOLERANCE_COLUMN

# The link solve (balance_links): Newton safeguarded by bisection on each link's deflection,
# to this tolerance (m), a thousandth of core.walls' TOLERANCE; a few iterations a link.
TOLERANCE = 1e-10
MAX_ITERATIONS = 60


class Flexures:
    """The flexures of n wave links of one robot: their state and the step's constants."""

    def __init__(self, flexure: FlexureParams, links: int, dt: float):
        if flexure.stiffness <= 0.0:
            raise ValueError('flexure.stiffness = 0 means rigid links: no flexures to step')
        self.params, self.dt = flexure, dt
        self.phi = mode_propagator(np.array([flexure.stiffness]), flexure.link_mass,
                                   flexure.damping, dt)[:, 0].copy()
        k, c, p = flexure.stiffness, flexure.damping, self.phi
        # The deflection after a step per newton of step-end load on the link (m/N): the ramp's
        # particular solution F/k - c F'/k^2, less what the homogeneous part takes back.
        self.compliance = (1.0 / k - c / (k * k * dt) * (1.0 - p[0]) - p[1] / (k * dt))
        self.load = np.zeros(links)              # the last step-end load, N (+ y)
        self.deflection = np.zeros(links)        # e, m
        self.rate = np.zeros(links)              # e', m/s
        self.reaction = np.zeros(links)          # on the backbone over the last step, N (+ y)
        self.free = np.zeros(links)              # the deflection after the step without loads

    def prepare(self) -> np.ndarray:
        """Return the deflection each link reaches at the step's end under no load (m)."""
        _free(self.deflection, self.rate, self.load, self.params.stiffness,
              self.params.damping, self.dt, self.phi, self.free)
        return self.free

    def advance(self, load: np.ndarray) -> None:
        """Step the links over dt to their net step-end loads ``load`` (N, + y), from the last."""
        _advance(load, self.params.stiffness, self.params.damping, self.params.link_mass,
                 self.dt, self.phi, self.load, self.deflection, self.rate, self.reaction)

    def energy(self) -> float:
        """Return the flexures' energy, J: the links' relative motion and the springs."""
        m, k = self.params.link_mass, self.params.stiffness
        return float(0.5 * (m * self.rate @ self.rate + k * self.deflection @ self.deflection))


@compiled
def _ramp(e: float, rate: float, start: float, end: float, k: float, c: float, dt: float,
          phi: np.ndarray) -> Tuple[float, float]:
    """
    Return (e, e') after dt of m e'' + c e' + k e = F(t), F linear from ``start`` to ``end``.

    The ramp's particular solution x_p = F(t) / k - c F' / k^2, plus the homogeneous rest
    (e - x_p, e' - F' / k) advanced by the exact propagator ``phi``.
    """
    slope = (end - start) / dt
    shift = c * slope / (k * k)
    u = e - start / k + shift
    v = rate - slope / k
    return (end / k - shift + phi[0] * u + phi[1] * v,
            slope / k + phi[2] * u + phi[3] * v)


@compiled
def _free(e: np.ndarray, rate: np.ndarray, load: np.ndarray, k: float, c: float, dt: float,
          phi: np.ndarray, out: np.ndarray) -> None:
    """out_i: where link i is after the step if its load ramps from its last to 0."""
    for i in range(e.size):
        out[i], _ = _ramp(e[i], rate[i], load[i], 0.0, k, c, dt, phi)


@compiled
def _advance(end: np.ndarray, k: float, c: float, mass: float, dt: float, phi: np.ndarray,
             load: np.ndarray, e: np.ndarray, rate: np.ndarray, reaction: np.ndarray) -> None:
    """Step each link exactly under its ramping load; the backbone's reaction keeps the impulse."""
    for i in range(e.size):
        before = rate[i]
        e[i], rate[i] = _ramp(e[i], before, load[i], end[i], k, c, dt, phi)
        load[i] = end[i]
        reaction[i] = end[i] - mass * (rate[i] - before) / dt


def contact_law(surface: SurfaceParams, dt: float) -> np.ndarray:
    """
    Return the contact law's normal constants for the link solve: (4,) array.

    k_mean = kn (1 + e) / 2, k_half = kn (1 - e) / 2, k_rate = k_half / (v0 dt) and the
    exponent: core.contact's folding (ContactLaw.from_values) of the paper's law with its
    hysteresis factor, F = (k_mean + clip((d - d_before) k_rate, -k_half, k_half)) d^p.
    """
    half = surface.normal_stiffness * (1.0 - surface.restitution) / 2.0
    return np.array([surface.normal_stiffness * (1.0 + surface.restitution) / 2.0, half,
                     half / (surface.hysteresis_speed * dt), surface.hertz_exponent])


def elastic_law(stiffness: float, exponent: float) -> np.ndarray:
    """Return the constants of the law F = kn d^p without hysteresis (``contact_law``)."""
    return np.array([stiffness, 0.0, 0.0, exponent])


@compiled
def _law(depth: float, before: float, law: np.ndarray) -> Tuple[float, float]:
    """Return the normal law's force and its slope at ``depth`` after ``before`` (0 outside)."""
    return _hertz(depth, before, law[0], law[1], law[2], law[3])


@compiled
def _hertz(depth: float, before: float, mean: float, half: float, rate: float,
           exponent: float) -> Tuple[float, float]:
    """
    ``_law`` on the constants themselves: force and slope, a square root where p = 1.5.

    Through pow the power cost some 40 ns a call: ``flex_links`` took 2 200 ns a step of the
    TPU set (8 touching links, 5.5 calls each), 450 with the root and one call an iteration.
    """
    if depth <= 0.0:
        return 0.0, 0.0
    change = (depth - before) * rate
    factor = mean + max(min(change, half), -half)
    root = math.sqrt(depth) if exponent == 1.5 else depth ** (exponent - 1.0)
    slope = exponent * factor * root
    if abs(change) < half:
        slope += rate * root * depth
    return factor * root * depth, slope


@compiled
def _deflection(bottom: float, top: float, before_bottom: float, before_top: float,
                free: float, guess: float, compliance: float, mean: float, half: float,
                rate: float, exponent: float) -> float:
    """
    Return one link's deflection e at the step's end (``balance_link``), Newton from ``guess``.

    A link whose tips stay out of their walls at its free deflection has e = free. Otherwise
    the residual r(e) = e - free - C (F_bottom - F_top) rises with e, and the root is bracketed
    without evaluating the law: at e = max(bottom, free) the bottom tip is out of its wall
    (r >= 0), at min(-top, free) the top tip (r <= 0). Each iteration evaluates the law once.
    """
    if bottom - free <= 0.0 and top + free <= 0.0:
        return free
    low, high = min(-top, free), max(bottom, free)
    e = min(max(guess, low), high)
    for iteration in range(MAX_ITERATIONS):
        fb, sb = _hertz(bottom - e, before_bottom, mean, half, rate, exponent)
        ft, st = _hertz(top + e, before_top, mean, half, rate, exponent)
        residual = e - free - compliance * (fb - ft)
        if residual > 0.0:
            high = min(high, e)
        else:
            low = max(low, e)
        step = residual / (1.0 + compliance * (sb + st))
        e -= step
        if abs(step) < TOLERANCE:
            break
        # Strictly inside: on the linear law's hysteresis kinks Newton can hop between two
        # points that are already the bracket's ends, never converging (7 links in 2 000 steps
        # ran all MAX_ITERATIONS so); the bisection breaks the cycle.
        if not low < e < high:
            e = 0.5 * (low + high)
        if high - low < TOLERANCE:
            break
    return e


@compiled
def balance_link(bottom: float, top: float, before_bottom: float, before_top: float,
                 free: float, compliance: float, law: np.ndarray) -> Tuple[float, float, float]:
    """
    Return one link's deflection e and its tips' loads (F_bottom, F_top) at the step's end.

    ``bottom``, ``top``: the tips' depths into their walls at the link's target (m, > 0
    inside); the link at e presses its bottom tip bottom - e deep and its top tip top + e;
    e = free + C (F_bottom - F_top), F the contact law ``law`` (``contact_law``) after the last
    step's depths. The law rises with the depth, so the right-hand side falls as e rises: the
    root is single and bracketed (``_deflection``). Newton from free inside the bracket,
    bisection when a step would leave it (the law's kinks: contact, the hysteresis band's ends).
    """
    e = _deflection(bottom, top, before_bottom, before_top, free, free, compliance, law[0],
                    law[1], law[2], law[3])
    fb, _ = _law(bottom - e, before_bottom, law)
    ft, _ = _law(top + e, before_top, law)
    return e, fb, ft


@compiled
def balance_links(bottom: np.ndarray, top: np.ndarray, before_bottom: np.ndarray,
                  before_top: np.ndarray, free: np.ndarray, compliance: float, law: np.ndarray,
                  deflection: np.ndarray, force_bottom: np.ndarray,
                  force_top: np.ndarray) -> None:
    """
    Solve each link's deflection against its tips' contacts (``balance_link``), arrays (n,).

    The last depths ``before_bottom``, ``before_top`` become this step's.
    """
    for i in range(free.size):
        e, fb, ft = balance_link(bottom[i], top[i], before_bottom[i], before_top[i], free[i],
                                 compliance, law)
        deflection[i], force_bottom[i], force_top[i] = e, fb, ft
        before_bottom[i] = max(bottom[i] - e, 0.0)
        before_top[i] = max(top[i] + e, 0.0)


# The flexures in the compiled step (core.dynamics.advance_scenario): a scenario's constants
# (FLEX_FIELDS: on, k, c, m, the step's compliance C, dt, the propagator Phi, and the step
# ``_ramp`` as the 2 x 4 matrix it is: (e, e') after the step from (e, e', the last load, this
# step's load), row by row) and its links' state (FLEX_ROWS x n: deflection, rate, the last
# step-end load, and the inertial share of the reaction the body gets through the link's bottom
# tip this step).
FLEX_ON, FLEX_STIFFNESS, FLEX_DAMPING, FLEX_MASS, FLEX_COMPLIANCE, FLEX_DT, FLEX_PHI = range(7)
FLEX_RAMP = FLEX_PHI + 4
FLEX_FIELDS = FLEX_RAMP + 8
DEFLECTION, RATE, LOAD, INERTIAL = range(4)
FLEX_ROWS = 4


def flexure_constants(flexures: Sequence[FlexureParams], dt: float) -> np.ndarray:
    """Return the (S, FLEX_FIELDS) constants of S scenarios' flexures (rigid: all zero)."""
    out = np.zeros((len(flexures), FLEX_FIELDS))
    for row, f in zip(out, flexures):
        if f.stiffness > 0.0:
            flexures_of_one = Flexures(f, 1, dt)
            row[FLEX_ON], row[FLEX_STIFFNESS], row[FLEX_DAMPING] = 1.0, f.stiffness, f.damping
            row[FLEX_MASS], row[FLEX_COMPLIANCE] = f.link_mass, flexures_of_one.compliance
            row[FLEX_DT] = dt
            row[FLEX_PHI:FLEX_RAMP] = flexures_of_one.phi
            # _ramp is linear in (e, e', start, end): its columns are its images of the unit
            # vectors. The step then takes 8 products a link instead of _ramp's 6 divisions.
            for j in range(4):
                unit = [0.0] * 4
                unit[j] = 1.0
                row[FLEX_RAMP + j], row[FLEX_RAMP + 4 + j] = _ramp(
                    unit[0], unit[1], unit[2], unit[3], f.stiffness, f.damping, dt,
                    flexures_of_one.phi)
    return out


@compiled
def _ramped(e: float, rate: float, start: float, end: float,
            constants: np.ndarray) -> Tuple[float, float]:
    """Return ``_ramp``'s (e, e') from the scenario's FLEX_RAMP matrix (``flexure_constants``)."""
    r = constants[FLEX_RAMP:FLEX_RAMP + 8]
    return (r[0] * e + r[1] * rate + r[2] * start + r[3] * end,
            r[4] * e + r[5] * rate + r[6] * start + r[7] * end)


@compiled
def flex_links(law_row: np.ndarray, constants: np.ndarray, state: np.ndarray,
               tips: np.ndarray) -> None:
    """
    Solve one scenario's links on their flexures against their tips' contacts (kernel).

    Before the contact law (core.contact.press_tips): each link's deflection e after the step,
    balanced with the law's normal force and hysteresis (``balance_link``), moves its tips: the
    depth the law sees (SEEN) becomes SEEN - e for the bottom tip (link i), SEEN + e for the top
    tip (link n + i). ``law_row``: core.contact's LAW_FIELDS.
    """
    n = state.shape[1]
    mean, half, rate = law_row[KN_MEAN], law_row[KN_HALF], law_row[KN_RATE]
    exponent = law_row[EXPONENT]
    compliance = constants[FLEX_COMPLIANCE]
    for i in range(n):
        free, _ = _ramped(state[DEFLECTION, i], state[RATE, i], state[LOAD, i], 0.0, constants)
        # Newton from the last step's loaded deflection on this step's free one.
        e = _deflection(tips[SEEN, i], tips[SEEN, n + i], tips[DEPTH, i], tips[DEPTH, n + i],
                        free, free + compliance * state[LOAD, i], compliance, mean, half, rate,
                        exponent)
        tips[SEEN, i] -= e
        tips[SEEN, n + i] += e


@compiled
def flex_advance(constants: np.ndarray, state: np.ndarray, tips: np.ndarray) -> None:
    """
    Step one scenario's links to their tips' step-end loads; pass their inertia to the body.

    After the contact law: each link advances exactly (``_ramp``) to F = NORMAL_bottom -
    NORMAL_top; what its momentum took, -m (e'_after - e'_before) / dt, is added to its bottom
    tip's NORMAL (a bottom tip's load pushes the body up: +y), so that the body's step
    (dynamics.move_body) sums the flexures' reactions; ``flex_restore`` takes it back after.
    """
    n = state.shape[1]
    momentum_rate = constants[FLEX_MASS] / constants[FLEX_DT]
    for i in range(n):
        end = tips[NORMAL, i] - tips[NORMAL, n + i]
        before = state[RATE, i]
        e, rate = _ramped(state[DEFLECTION, i], before, state[LOAD, i], end, constants)
        state[DEFLECTION, i], state[RATE, i], state[LOAD, i] = e, rate, end
        inertial = -momentum_rate * (rate - before)
        state[INERTIAL, i] = inertial
        tips[NORMAL, i] += inertial


@compiled
def flex_restore(state: np.ndarray, tips: np.ndarray) -> None:
    """Give the tips back their contact loads once the body has stepped (``flex_advance``)."""
    for i in range(state.shape[1]):
        tips[NORMAL, i] -= state[INERTIAL, i]


def transmissibility(frequency: float, stiffness: float, damping: float, mass: float,
                     contact: float) -> Tuple[complex, complex]:
    """
    Return a link's deflection and reaction per metre of target motion into a linear contact.

    The target pressed into a contact of stiffness ``contact`` (N/m) by a harmonic d(t) at
    ``frequency`` (Hz): m e'' + c e' + k e = kc (d - e). Returns (e / d, reaction / d) as
    complex amplitudes, reaction = k e + c e' (what the backbone feels, N/m). The closed form
    the stepped flexure is checked against.
    """
    w = 2.0 * math.pi * frequency
    e = contact / (stiffness + contact - mass * w * w + 1j * w * damping)
    return e, (stiffness + 1j * w * damping) * e


@compiled
def replay_links(bottom: np.ndarray, top: np.ndarray, before_bottom: np.ndarray,
                 before_top: np.ndarray, stiffness: float, damping: float, mass: float, dt: float,
                 law: np.ndarray, reaction: np.ndarray, deflection: np.ndarray) -> None:
    """
    Drive n flexure links through T steps of prescribed tip penetrations (T, n); fill (T, n).

    The open-loop use of the flexures: the targets' penetrations into rigid walls are those of
    a run of the rigid robot, the body's motion held to that run; each step balances every link
    against its contacts (``balance_links``, ``law`` from ``contact_law``) and advances it
    (``Flexures.advance``).
    ``before_bottom``, ``before_top`` (n,): the contacts' depths the step before the first
    (the law's memory; updated). ``reaction`` gets what the backbone feels (N, + y),
    ``deflection`` e (m).
    """
    phi = oscillator_step(stiffness, mass, damping, dt)
    k, c = stiffness, damping
    compliance = 1.0 / k - c / (k * k * dt) * (1.0 - phi[0]) - phi[1] / (k * dt)
    n = bottom.shape[1]
    e, rate, load = np.zeros(n), np.zeros(n), np.zeros(n)
    free, solved = np.empty(n), np.empty(n)
    fb, ft, out = np.empty(n), np.empty(n), np.empty(n)
    for step in range(bottom.shape[0]):
        _free(e, rate, load, k, c, dt, phi, free)
        balance_links(bottom[step], top[step], before_bottom, before_top, free, compliance, law,
                      solved, fb, ft)
        _advance(fb - ft, k, c, mass, dt, phi, load, e, rate, out)
        reaction[step] = out
        deflection[step] = e


# The scratch of ``flex_walls`` (rows of (FLEX_WORK_ROWS + 4 n, 2 n)), before its two 2n x 2n
# matrices: rows 0-2 balance_wall's, then the links' free deflections, where each link's bottom
# and top tips sit in the solve (-1: not in it), whether a tip is solved for the first time,
# the tips' abscissae, depths, the law's last depths, the solve's unknowns and forces, and each
# link's net step-end load.
FREE_ROW, BOTTOM_AT, TOP_AT, FRESH, X_ROW, DEPTH_ROW, BEFORE_ROW, GIVE, FORCE, NET = range(3, 13)
FLEX_WORK_ROWS = 13


@compiled
def flex_walls(law: np.ndarray, walls: np.ndarray, state: np.ndarray, modes: np.ndarray,
               swinging: bool, constants: np.ndarray, flex_state: np.ndarray,
               tips: np.ndarray, work: np.ndarray) -> None:
    """
    Solve one scenario's two bending walls and its links' flexures together (kernel).

    A tip's depth is its penetration into the rigid wall less the wall's deflection there less
    its link's flexure deflection (e, + y: SEEN - e for a bottom tip, SEEN + e for a top one).
    The flexure is a compliance in series with the wall: e = free + C (F_bottom - F_top)
    (``_ramp``, ``Flexures.compliance``), so the tips' total give u (the wall's deflection plus
    the loaded part of e, signed as it deepens the tip's contact) is u = (G + C B) F, B the
    links' +1 on each tip of the solve and -1 between the two tips of one link. One Newton on
    both walls at once (core.walls.balance_wall) on that compliance, the walls' blocks
    (core.walls.fill_wall; for walls with mass less their held modes, as
    core.dynamic_walls.swing_walls) joined only where a link has both tips in the solve: the
    contact law, the walls and the flexures agree to the walls' TOLERANCE at the step's end.

    The tips solved for: those within the walls' reach of their wall once their link's free
    deflection (and, for walls with mass, the wall's free motion) is counted; after the solve a
    tip left out whose link's loaded deflection brought it within reach joins them and the
    solve repeats, so that no tip left out touches. ``modes``: the walls' modes (used where
    ``swinging``), ``constants``, ``flex_state``: the flexures' (FLEX_FIELDS, FLEX_ROWS x n);
    ``work`` a scratch (FLEX_WORK_ROWS + 4 n, 2 n).
    """
    n = state.shape[2]
    reach = walls[REACH]
    c_flex = constants[FLEX_COMPLIANCE]
    free, bottom_at, top_at = work[FREE_ROW], work[BOTTOM_AT], work[TOP_AT]
    fresh, x, depth, before = work[FRESH], work[X_ROW], work[DEPTH_ROW], work[BEFORE_ROW]
    u, force, net = work[GIVE], work[FORCE], work[NET]
    g = work[FLEX_WORK_ROWS:FLEX_WORK_ROWS + 2 * n]
    jacobian = work[FLEX_WORK_ROWS + 2 * n:]
    tabled = (modes.shape[0] - TABLE) // 2
    count_modes = modes.shape[1]
    largest_free = 0.0
    for i in range(n):
        free[i], _ = _ramped(flex_state[DEFLECTION, i], flex_state[RATE, i],
                             flex_state[LOAD, i], 0.0, constants)
        largest_free = max(largest_free, abs(free[i]))
        bottom_at[i] = top_at[i] = -1.0
    # The walls' own motion over the step (walls with mass): SEEN = PENETRATION - free
    # correction at every tip it and the free deflections can bring within reach.
    # (The modes' scratch holds one wall's free modes at a time: ``freed`` says whose.)
    bottom_bound = top_bound = 0.0
    freed = -1
    if swinging:
        for wall in range(2):
            bound = _free_modes(modes, WALL_STATE + wall * STATE_ROWS)
            if wall:
                top_bound = bound
            else:
                bottom_bound = bound
            freed = wall
            for p in range(wall * n, wall * n + n):
                if tips[PENETRATION, p] + bound + largest_free > reach:
                    _tip_table(modes, p, tips[X, p])
                    tips[SEEN, p] = tips[PENETRATION, p] - _free_at(modes, p)
    # The tips that can touch: each wall's in their order along it, bottom wall first.
    count = 0
    for wall in range(2):
        sign = 1.0 - 2.0 * wall
        for i in range(n):
            if tips[SEEN, wall * n + i] - sign * free[i] > reach:
                if wall == 0:
                    bottom_at[i] = count
                else:
                    top_at[i] = count
                count += 1
    most = 0
    all_converged = True
    for attempt in range(2 * n + 1):
        # The solve's tips, in order: x, depth less the free deflection, the law's last depth,
        # and the first guess (the last two steps' wall deflections extrapolated, the last
        # step's load on the flexure).
        for wall in range(2):
            sign = 1.0 - 2.0 * wall
            at = top_at if wall else bottom_at
            bound = top_bound if wall else bottom_bound
            for i in range(n):
                if at[i] < 0.0:
                    continue
                k, p = int(at[i]), wall * n + i
                if swinging and tips[PENETRATION, p] + bound + largest_free <= reach:
                    if freed != wall:                       # joined after the solve
                        _free_modes(modes, WALL_STATE + wall * STATE_ROWS)
                        freed = wall
                    _tip_table(modes, p, tips[X, p])
                    tips[SEEN, p] = tips[PENETRATION, p] - _free_at(modes, p)
                x[k], before[k] = tips[X, p], tips[DEPTH, p]
                depth[k] = tips[SEEN, p] - sign * free[i]
                last = state[SOLVED, wall, i]
                fresh[k] = last == 0.0
                guess = 2.0 * last - state[SOLVED_BEFORE, wall, i] if last != 0.0 else 0.0
                u[k] = (guess - (tips[PENETRATION, p] - tips[SEEN, p]) +
                        sign * c_flex * flex_state[LOAD, i])
        bottoms = 0
        for i in range(n):
            bottoms += bottom_at[i] >= 0.0
        for k in range(count):
            for j in range(count):
                g[k, j] = 0.0
        for wall in range(2):
            first = bottoms if wall else 0
            size = count - bottoms if wall else bottoms
            if size == 0:
                continue
            block = g[first:first + size, first:first + size]
            fill_wall(x[first:first + size], size, walls[BETA], walls[HALF], walls[GAIN],
                      walls[ITSELF], walls[PATCH_RE], walls[PATCH_IM], block)
            if swinging:
                # Less what the held loads' modes take back (swing_walls).
                at = top_at if wall else bottom_at
                for i in range(n):
                    if at[i] < 0.0:
                        continue
                    a, pa = int(at[i]), wall * n + i
                    for j in range(i + 1):
                        if at[j] < 0.0:
                            continue
                        b, pb = int(at[j]), wall * n + j
                        total = 0.0
                        for m in range(count_modes):
                            total += modes[HELD, m] * (
                                modes[TABLE + pa, m] * modes[TABLE + pb, m] +
                                modes[TABLE + tabled + pa, m] * modes[TABLE + tabled + pb, m])
                        g[a, b] -= total
                        if b != a:
                            g[b, a] -= total
        # The flexures in series: C on each tip, -C between a link's two tips.
        for i in range(n):
            if bottom_at[i] >= 0.0:
                g[int(bottom_at[i]), int(bottom_at[i])] += c_flex
            if top_at[i] >= 0.0:
                g[int(top_at[i]), int(top_at[i])] += c_flex
            if bottom_at[i] >= 0.0 and top_at[i] >= 0.0:
                g[int(bottom_at[i]), int(top_at[i])] -= c_flex
                g[int(top_at[i]), int(bottom_at[i])] -= c_flex
        # The convergence test's scale: p times the largest of twice a tip's own compliance
        # and a row's sum of |G| (swing_walls').
        scale = 0.0
        for k in range(count):
            row = 0.0
            for j in range(count):
                row += abs(g[k, j])
            scale = max(scale, 2.0 * g[k, k], row)
        scale *= law[EXPONENT]
        if count > 0:
            iterations, converged = balance_wall(depth, u, g, before, count, law, scale,
                                                 walls[TOLERANCE_COLUMN], work, jacobian,
                                                 force)
            most = max(most, iterations)
            all_converged = all_converged and converged
        # The law's forces where the solve ended (balance_wall leaves those before its last
        # step), so that the walls' loads, the links' and the law's are one set.
        for k in range(count):
            delta = max(depth[k] - u[k], 0.0)
            change = (delta - before[k]) * law[KN_RATE]
            factor = max(min(change, law[KN_HALF]), -law[KN_HALF]) + law[KN_MEAN]
            root = math.sqrt(delta) if law[EXPONENT] == 1.5 else delta ** (law[EXPONENT] - 1.0)
            force[k] = factor * (root * delta)
        # Each link's net load and deflection; a tip left out that it brings within reach
        # joins the solve (once: it stays in).
        joined = False
        for i in range(n):
            net[i] = (force[int(bottom_at[i])] if bottom_at[i] >= 0.0 else 0.0) - \
                (force[int(top_at[i])] if top_at[i] >= 0.0 else 0.0)
            e = free[i] + c_flex * net[i]
            if bottom_at[i] < 0.0 and tips[SEEN, i] - e > reach:
                bottom_at[i] = 0.5          # placed below, after the bottom tips before it
                joined = True
            if top_at[i] < 0.0 and tips[SEEN, n + i] + e > reach:
                top_at[i] = 0.5
                joined = True
        if not joined:
            break
        count = 0
        for wall in range(2):
            at = top_at if wall else bottom_at
            for i in range(n):
                if at[i] >= 0.0:
                    at[i] = count
                    count += 1
    # The walls' bookkeeping (bend_walls, swing_walls) and the depths the law sees.
    largest = -np.inf
    for wall in range(2):
        sign = 1.0 - 2.0 * wall
        at = top_at if wall else bottom_at
        solved = 0
        for i in range(n):
            solved += at[i] >= 0.0
        retire_solved(walls, state, wall, solved)
        solved = 0
        for i in range(n):
            p = wall * n + i
            e = free[i] + c_flex * net[i]
            if at[i] < 0.0:
                tips[SEEN, p] -= sign * e
                continue
            k = int(at[i])
            # The wall's deflection: the give less the flexure's loaded part, plus its free
            # correction (walls with mass).
            total = u[k] - sign * c_flex * net[i] + tips[PENETRATION, p] - tips[SEEN, p]
            state[CHOSEN, wall, solved] = i
            solved += 1
            if fresh[k] > 0.0:
                state[SOLVED_BEFORE, wall, i] = total   # solved for the first time: no trend
            state[SOLVED, wall, i] = total
            state[LOADS, wall, i] = force[k]
            tips[SEEN, p] = depth[k] - u[k]
            largest = max(largest, total)
    close_step(walls, largest, most, all_converged)
