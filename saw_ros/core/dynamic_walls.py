"""
Walls with mass and damping (issue 31): the beam on its Winkler foundation made dynamic.

core.walls keeps each surface quasi-static: EI w'''' + k w = q. With the wall's own mass m per
metre (kg/m, the strip and what moves with it) and a viscous foundation c (N s/m^2):

    m w_tt + c w_t + EI w'''' + k w = q(x, t),        w > 0 away from the robot.

Formulation (docs/walls.md says why): the exact quasi-static wall of core.walls (Hetenyi's
infinite beam, closed form) plus a dynamic correction carried by the modes of a periodic band of
wall BAND_LENGTH long, the mode-acceleration method of structural dynamics. Mode n (wavenumber
kappa_n = 2 pi n / BAND_LENGTH, complex amplitude z_n, w = Re sum z_n exp(i kappa_n x)) is an
oscillator

    m z_n'' + c z_n' + K_n z_n = g_n,    K_n = EI kappa_n^4 + k,
    g_n = weight_n sinc(kappa_n b / 2) sum_j F_j exp(-i kappa_n x_j)

(weight 1 / BAND_LENGTH for n = 0, 2 / BAND_LENGTH else; the tips' loads F_j spread over the
contact width b), stepped exactly over dt under a load ramping linearly from the last step's
to this step's (a first-order hold: the 2 x 2 matrix exponential of each mode plus the ramp's
particular solution; unconditionally stable at any stiffness, no numerical damping, second
order in dt for a load that moves). The wall is

    w(x) = w_quasi_static(F)(x) + Re sum_n (z_n - g_n / K_n) exp(i kappa_n x):

the modes carry only what the wall's inertia and damping add to the quasi-static shape. With
m = 0 the correction is exactly zero (z_n = g_n / K_n) and the wall is core.walls' to the digit:
the massless limit is the quasi-static wall by construction (a massless wall with damping
relaxes towards it: a Kelvin-Voigt foundation). The modes beyond the band's last
keep their quasi-static share (the closed form holds all of it), so the truncation costs only
the dynamic correction of wavenumbers far beyond the foundation's beta = (k / 4 EI)^(1/4).

Coupling into the simulator's step (``DynamicWalls``, ``swing_walls``, ``load_walls``): the
loads between two steps are not known there, so each mode takes its step-end load held over the
step (implicit in it, stable against any contact; the ramp above is for loads known in
advance). The deflection at the tips after the step is then linear in the step-end loads,
w = free + G F, G = G_quasi_static - H, H_ij = sum_n Phi00_n weight_n sinc_n / K_n
cos(kappa_n (x_i - x_j)), so the same Newton solve as core.walls balances it with the contact
law. Only the modes the step resolves are dynamic (``resolved_modes``); the others follow
their loads, which makes a wall too light for the step the quasi-static wall exactly.
``DynamicWall.free_deflection`` and ``compliance`` are the same map for the ramp.

Kernels: numba-compiled loops over plain arrays into preallocated outputs (the compiled core's
style); the class holds the state and the constants.
"""
from __future__ import annotations

import math
from typing import Any, Callable, cast, Sequence, Tuple, TypeVar

import numba
import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core.contact import DEPTH, EXPONENT, NORMAL, PENETRATION, SEEN, X
from saw_ros.core.jit import CACHE
from saw_ros.core.params import Scenario, SurfaceParams, WallDynamicsParams
from saw_ros.core.walls import balance_wall, BETA, CHOSEN, close_step, fill_wall, GAIN, HALF
from saw_ros.core.walls import deflection as quasi_static_deflection
from saw_ros.core.walls import ITSELF, LARGEST, LOADS, PATCH_IM, PATCH_RE, REACH, retire_solved
from saw_ros.core.walls import SOLVED, SOLVED_BEFORE, SOLVED_COUNT, TOLERANCE_COLUMN, Walls
from saw_ros.core.walls import WORK_ROWS

# The band: a periodic wall 2 m long, far longer than the decay length 1 / beta (about 1 cm for
# the walls of docs/walls.md) and than the robot (0.35 m): its images are 2 m away. 512 modes
# reach kappa = 1608 /m, 14 to 18 times beta for the sheet and the tissue set, where a moving
# load's correction has fallen as kappa^-6 (tests/core/test_dynamic_walls.py measures it).
BAND_LENGTH = 2.0
BAND_MODES = 512

Function = TypeVar('Function', bound=Callable[..., Any])


def compiled(function: Function) -> Function:
    """Return ``function`` compiled by numba (nopython, cached on disk: core.jit), typed."""
    return cast(Function, numba.njit(cache=CACHE)(function))


@compiled
def _project(forces: np.ndarray, x: np.ndarray, kappa1: float, shape: np.ndarray,
             out_re: np.ndarray, out_im: np.ndarray) -> None:
    """g_n = shape_n sum_j F_j exp(-i kappa_n x_j), kappa_n = n kappa1, into out_re, out_im."""
    for n in range(shape.size):
        out_re[n] = 0.0
        out_im[n] = 0.0
    for j in range(forces.size):
        f = forces[j]
        if f == 0.0:
            continue
        c1 = math.cos(kappa1 * x[j])
        s1 = math.sin(kappa1 * x[j])
        c = 1.0
        s = 0.0
        for n in range(shape.size):
            out_re[n] += f * c
            out_im[n] -= f * s
            c, s = c * c1 - s * s1, s * c1 + c * s1
    for n in range(shape.size):
        out_re[n] *= shape[n]
        out_im[n] *= shape[n]


@compiled
def _advance(start_re: np.ndarray, start_im: np.ndarray, end_re: np.ndarray,
             end_im: np.ndarray, stiffness: np.ndarray, damping: float, dt: float,
             phi: np.ndarray, z_re: np.ndarray, z_im: np.ndarray, v_re: np.ndarray,
             v_im: np.ndarray) -> None:
    """
    Step every mode exactly over dt under its load ramping from ``start`` to ``end``.

    The ramp g(t) = g0 + g' t has the particular solution g(t) / K - c g' / K^2; the rest
    (z - that, z' - g' / K) is advanced by Phi.
    """
    for n in range(stiffness.size):
        k = stiffness[n]
        for part in range(2):
            if part == 0:
                g0, g1, z, v = start_re[n], end_re[n], z_re[n], v_re[n]
            else:
                g0, g1, z, v = start_im[n], end_im[n], z_im[n], v_im[n]
            slope = (g1 - g0) / dt
            shift = damping * slope / (k * k)
            u = z - g0 / k + shift
            w = v - slope / k
            z = g1 / k - shift + phi[0, n] * u + phi[1, n] * w
            v = slope / k + phi[2, n] * u + phi[3, n] * w
            if part == 0:
                z_re[n], v_re[n] = z, v
            else:
                z_im[n], v_im[n] = z, v


@compiled
def _synthesise(a_re: np.ndarray, a_im: np.ndarray, kappa1: float, x: np.ndarray,
                out: np.ndarray) -> None:
    """out_i = Re sum_n a_n exp(i kappa_n x_i), kappa_n = n kappa1."""
    for i in range(x.size):
        c1 = math.cos(kappa1 * x[i])
        s1 = math.sin(kappa1 * x[i])
        c = 1.0
        s = 0.0
        total = 0.0
        for n in range(a_re.size):
            total += a_re[n] * c - a_im[n] * s
            c, s = c * c1 - s * s1, s * c1 + c * s1
        out[i] = total


@compiled
def _held_compliance(x: np.ndarray, kappa1: float, gain: np.ndarray, out: np.ndarray) -> None:
    """out_ij = sum_n gain_n cos(kappa_n (x_i - x_j)): what the held loads' modes take back."""
    for i in range(x.size):
        for j in range(i, x.size):
            r = kappa1 * (x[i] - x[j])
            c1 = math.cos(r)
            s1 = math.sin(r)
            c = 1.0
            s = 0.0
            total = 0.0
            for n in range(gain.size):
                total += gain[n] * c
                c, s = c * c1 - s * s1, s * c1 + c * s1
            out[i, j] = total
            out[j, i] = total


@compiled
def oscillator_step(stiffness: float, mass: float, damping: float, dt: float) -> np.ndarray:
    """
    Return Phi (4,): the exact step over ``dt`` of m u'' + c u' + K u = 0, m > 0.

    Phi00, Phi01, Phi10, Phi11 of exp(A dt), A = [[0, 1], [-K/m, -c/m]]: with the mean
    eigenvalue l = -c / 2m and d = sqrt(l^2 - K/m), exp(A t) = exp(l t) (cosh(d t) I +
    sinh(d t) / d (A - l I)), from the two exponentials exp((l +- d) t) so that stiff,
    overdamped modes do not overflow.
    """
    mean = -damping / (2.0 * mass)
    split = np.sqrt(complex(mean * mean - stiffness / mass))
    e1, e2 = np.exp((mean + split) * dt), np.exp((mean - split) * dt)
    even = (e1 + e2) / 2.0                                # exp(l t) cosh(d t)
    if abs(split * dt) < 1e-6:                            # exp(l t) sinh(d t) / d
        odd = dt * np.exp(mean * dt) + 0j
    else:
        odd = (e1 - e2) / (2.0 * split)
    phi = np.empty(4)
    phi[0] = (even - mean * odd).real
    phi[1] = odd.real
    phi[2] = (-stiffness / mass * odd).real
    phi[3] = (even + (-damping / mass - mean) * odd).real
    return phi


def mode_propagator(stiffness: np.ndarray, mass: float, damping: float,
                    dt: float) -> np.ndarray:
    """
    Return Phi (4, N): the exact step over ``dt`` of m u'' + c u' + K u = 0, per mode.

    ``oscillator_step`` of each mode. Without mass a damped mode relaxes, c u' + K u = 0:
    u <- exp(-K dt / c) u and u' = -K u / c; without mass or damping it has no dynamics (all
    zeros: it sits at its load's rest).
    """
    k = np.asarray(stiffness, float)
    if mass == 0.0:
        phi = np.zeros((4, k.size))
        if damping > 0.0:
            phi[0] = np.exp(-k * dt / damping)
            phi[2] = -k / damping * phi[0]
        return phi
    return np.stack([oscillator_step(float(x), mass, damping, dt) for x in k], axis=1)


class DynamicWall:
    """
    One wall with mass and damping (module docstring), stepped under loads ramping over a step.

    ``foundation`` k N/m^2, ``bending`` EI N m^2, ``width`` b m (the contact width), ``mass``
    m kg/m, ``damping`` c N s/m^2, ``dt`` s.
    """

    @classmethod
    def of(cls, surface: SurfaceParams, walls: WallDynamicsParams, dt: float) -> 'DynamicWall':
        """Return the dynamic wall of a scenario's surface and wall dynamics."""
        return cls(surface.foundation_stiffness, surface.bending_stiffness,
                   surface.contact_width, walls.mass, walls.damping, dt)

    def __init__(self, foundation: float, bending: float, width: float, mass: float,
                 damping: float, dt: float, length: float = BAND_LENGTH,
                 modes: int = BAND_MODES):
        if foundation <= 0.0 or bending <= 0.0 or width <= 0.0 or dt <= 0.0:
            raise ValueError('a dynamic wall needs k, EI, b and dt > 0')
        if mass < 0.0 or damping < 0.0:
            raise ValueError("a wall's mass and damping are >= 0")
        self.foundation, self.bending, self.width = foundation, bending, width
        self.mass, self.damping, self.dt, self.length = mass, damping, dt, length
        self.kappa1 = 2.0 * math.pi / length
        kappa = self.kappa1 * np.arange(modes)
        self.stiffness = bending * kappa ** 4 + foundation            # K_n, N/m^2
        weight = np.full(modes, 2.0 / length)
        weight[0] = 1.0 / length
        # weight_n sinc(kappa_n b / 2) (np.sinc(u) is sin(pi u) / (pi u))
        self.shape = weight * np.sinc(kappa * width / (2.0 * math.pi))
        self.phi = mode_propagator(self.stiffness, mass, damping, dt)
        # What a newton of step-end load at a tip takes from each mode's correction z - g/K
        # after the step, m/N (compliance): the ramp's -c g'/K^2 and its homogeneous rest.
        k, p = self.stiffness, self.phi
        self.held_gain = (damping * (1.0 - p[0]) / (k * dt) + p[1] / dt) / k * self.shape
        self.z_re, self.z_im = np.zeros(modes), np.zeros(modes)      # m
        self.v_re, self.v_im = np.zeros(modes), np.zeros(modes)      # m/s
        self.g_re, self.g_im = np.zeros(modes), np.zeros(modes)      # step-end loads, N/m
        self._start_re, self._start_im = np.zeros(modes), np.zeros(modes)
        self._zeros = np.zeros(modes)
        self.loads = np.zeros(0)                                      # N
        self.at = np.zeros(0)                                         # m
        self.work = 0.0           # done by the loads on the band's modes, J
        self.dissipated = 0.0     # in the foundation's damping (trapezoid in time), J

    @property
    def weights(self) -> np.ndarray:
        """Return each mode's share of the band in its energy: L for n = 0, L / 2 else (m)."""
        out = np.full(self.stiffness.size, self.length / 2.0)
        out[0] = self.length
        return out

    def step(self, loads: ArrayLike, at: ArrayLike) -> None:
        """Advance one dt to the tips' ``loads`` (N, > 0 away) at ``at`` (m), from the last."""
        self.loads = np.array(loads, float)
        self.at = np.array(at, float)
        z_re, z_im = self.z_re.copy(), self.z_im.copy()
        power_before = self._dissipation_rate()
        self._start_re[:], self._start_im[:] = self.g_re, self.g_im
        _project(self.loads, self.at, self.kappa1, self.shape, self.g_re, self.g_im)
        if self.mass == 0.0 and self.damping == 0.0:      # the modes follow their loads at once
            np.divide(self.g_re, self.stiffness, out=self.z_re)
            np.divide(self.g_im, self.stiffness, out=self.z_im)
        else:
            _advance(self._start_re, self._start_im, self.g_re, self.g_im, self.stiffness,
                     self.damping, self.dt, self.phi, self.z_re, self.z_im, self.v_re,
                     self.v_im)
        # The work of the loads over the step, g . dz per mode, g the step's mean load (the
        # ramp's work to third order in dt).
        mean_re = 0.5 * (self._start_re + self.g_re)
        mean_im = 0.5 * (self._start_im + self.g_im)
        self.work += float(self.weights @ (mean_re * (self.z_re - z_re)
                                           + mean_im * (self.z_im - z_im)))
        self.dissipated += 0.5 * self.dt * (power_before + self._dissipation_rate())

    def _dissipation_rate(self) -> float:
        return float(self.damping * (self.weights @ (self.v_re ** 2 + self.v_im ** 2)))

    def energy(self) -> float:
        """Return the band's energy, J: kinetic, bending and foundation, mode by mode."""
        kinetic = self.mass * (self.v_re ** 2 + self.v_im ** 2)
        elastic = self.stiffness * (self.z_re ** 2 + self.z_im ** 2)
        return float(self.weights @ (kinetic + elastic) / 2.0)

    def correction(self, x: ArrayLike) -> np.ndarray:
        """Return what the wall's mass and damping add to its quasi-static shape at ``x``, m."""
        x = np.atleast_1d(np.asarray(x, float))
        out = np.empty(x.size)
        _synthesise(self.z_re - self.g_re / self.stiffness, self.z_im - self.g_im / self.stiffness,
                    self.kappa1, x, out)
        return out

    def deflection(self, x: ArrayLike) -> np.ndarray:
        """Return the wall's deflection at ``x`` (m, > 0 away from the robot) after the step."""
        x = np.atleast_1d(np.asarray(x, float))
        out = self.correction(x)
        for load, centre in zip(self.loads, self.at):
            out += quasi_static_deflection(x - centre, load, self.foundation, self.bending,
                                           self.width)
        return out

    def free_deflection(self, x: ArrayLike) -> np.ndarray:
        """
        Return the correction at ``x`` after a step whose loads ramp to none (m): the free part.

        The deflection after a step to loads F at ``x`` is this plus ``compliance(x) @ F``
        (module docstring).
        """
        x = np.atleast_1d(np.asarray(x, float))
        out = np.empty(x.size)
        z_re, z_im = self.z_re.copy(), self.z_im.copy()
        if self.mass == 0.0 and self.damping == 0.0:
            z_re[:], z_im[:] = 0.0, 0.0
        else:
            _advance(self.g_re, self.g_im, self._zeros, self._zeros, self.stiffness,
                     self.damping, self.dt, self.phi, z_re, z_im, self.v_re.copy(),
                     self.v_im.copy())
        _synthesise(z_re, z_im, self.kappa1, x, out)
        return out

    def compliance(self, x: ArrayLike) -> np.ndarray:
        """Return G (m, m), m/N: the deflection at x_i after the step per step-end N at x_j."""
        x = np.atleast_1d(np.asarray(x, float))
        r = x[:, None] - x[None, :]
        g = quasi_static_deflection(r, 1.0, self.foundation, self.bending, self.width)
        held = np.empty((x.size, x.size))
        _held_compliance(x, self.kappa1, self.held_gain, held)
        return g - held


def critical_speed(foundation: float, bending: float, mass: float) -> float:
    """Return where an undamped wall resonates under a moving load, (4 k EI / m^2)^(1/4), m/s."""
    return float((4.0 * foundation * bending / mass ** 2) ** 0.25)


def ring_down(foundation: float, mass: float, damping: float) -> Tuple[float, float]:
    """Return a uniform free vibration's (angular frequency, decay rate), rad/s and 1/s."""
    decay = damping / (2.0 * mass)
    return math.sqrt(foundation / mass - decay ** 2), decay


def moving_load_deflection(xi: ArrayLike, load: float, speed: float, foundation: float,
                           bending: float, mass: float, damping: float) -> np.ndarray:
    """
    Return the steady deflection (m) under a point load moving at ``speed`` (m/s), at xi = x - v t.

    The closed form of an infinite beam on a damped Winkler foundation (Fryba, *Vibration of
    Solids and Structures under Moving Loads*, 1972/1999, ch. 6): in the load's frame
    EI W'''' + m v^2 W'' - c v W' + k W = P delta(xi), solved by the roots s of
    EI s^4 + m v^2 s^2 - c v s + k = 0, the two with Re s < 0 ahead of the load (xi > 0), the
    two with Re s > 0 behind it, joined at the load by W, W', W'' continuous and
    EI [W'''] = P. At rest it is Hetenyi's P beta / 2k exp(-beta |xi|) (cos + sin)(beta |xi|).
    """
    roots = np.roots([bending, 0.0, mass * speed ** 2, -damping * speed, foundation])
    ahead, behind = roots[roots.real < 0.0], roots[roots.real > 0.0]
    if len(ahead) != 2 or len(behind) != 2:
        raise ValueError(f'no steady deflection at {speed:g} m/s without damping: the critical '
                         f'speed {critical_speed(foundation, bending, mass):g} m/s')
    a = np.array([[s ** p for s in ahead] + [-(s ** p) for s in behind] for p in range(4)])
    amplitudes = np.linalg.solve(a, np.array([0.0, 0.0, 0.0, load / bending], complex))
    xi = np.asarray(xi, float)
    out = np.zeros(xi.shape, complex)
    front = xi >= 0.0
    for amplitude, s in zip(amplitudes[:2], ahead):
        out[front] += amplitude * np.exp(s * xi[front])
    for amplitude, s in zip(amplitudes[2:], behind):
        out[~front] += amplitude * np.exp(s * xi[~front])
    return out.real


# -- in the compiled step: each bending wall of a scenario a dynamic wall ---------------------
# In the step the tips' loads are not known between the steps' ends: each mode is stepped
# exactly under its step-end load held over the step (z <- g/K + Phi (z - g/K, z')), implicit in
# that load like the quasi-static solve. The ramp of DynamicWall.step (second order for a load
# known in advance) set light walls ringing against the stiff contact: its amplification
# reached 3.7 per step (m 0.018 kg/m undamped, K 1e3 N/m^2, contact 1e8 N/m^2; 1.05 for the
# tissue's foundation at 1e-3 kg/m), and the held load stays within 1 over m 1e-6 to 100 kg/m,
# damping ratios 0 to 10, K 1e3 to 1e8 and contacts 10 to 1e8 at dt 1 ms (docs/walls.md). It is
# first order in dt, as the body's semi-implicit Euler is. Held loads ring a mode the step
# cannot resolve (a staircase load excites it by the load's change over K each step, forever
# without damping): only the modes whose slowest rate the step resolves (rate dt <= RESOLVED,
# ``resolved_modes``) are dynamic, the faster ones follow their loads at once, as they do in the
# physical wall under the robot's smooth loads. So a wall light enough (all its modes too fast)
# is the quasi-static wall exactly: the massless limit.
RESOLVED = 1.0
# Rows of a scenario's modes (DynamicWalls.modes[s], (TABLE + 4 n, modes), n tips a wall): each
# mode's K_n (N/m^2), its load shape weight_n sinc_n (1/m), its exact step Phi (4 rows), what a
# newton of step-end load takes from its correction (Phi00 shape / K, m/N); the settings row (1
# where the walls are dynamic, kappa1 1/m, and the step's bound on each wall's free correction,
# m); per wall (bottom, top) the modes' z and z' (m, m/s) and step-end loads g (N/m), real and
# imaginary parts; then scratch: the free correction's modes, and cos (kappa_m x_p) and
# sin (kappa_m x_p) of the 2 n tips.
STIFFNESS, SHAPE, PHI, HELD = 0, 1, 2, 6
SETTINGS = 7
ON, KAPPA1, BOUND = range(3)
WALL_STATE = 8
Z_RE, Z_IM, V_RE, V_IM, G_RE, G_IM = range(6)
STATE_ROWS = 6
FREE_RE = WALL_STATE + 2 * STATE_ROWS
FREE_IM = FREE_RE + 1
TABLE = FREE_IM + 1


@compiled
def _free_modes(modes: np.ndarray, base: int) -> float:
    """
    Set FREE_RE, FREE_IM to a wall's modes after a step under no load: Phi applied to them.

    ``base`` the wall's first state row. The correction those modes make is what the wall does
    by itself over the step (the step-end load's share, -Phi00 g / K, comes with the solve).
    Returns the sum of |Re| + |Im| over them: a bound on that correction anywhere (m).
    """
    bound = 0.0
    for m in range(modes.shape[1]):
        for part in range(2):
            z = modes[PHI, m] * modes[base + Z_RE + part, m] + \
                modes[PHI + 1, m] * modes[base + V_RE + part, m]
            modes[FREE_RE + part, m] = z
            bound += abs(z)
    return bound


@compiled
def _tip_table(modes: np.ndarray, p: int, x: float) -> None:
    """Fill the scratch rows of tip p with cos (kappa_m x) and sin (kappa_m x) of every mode."""
    tips = (modes.shape[0] - TABLE) // 2
    kappa1 = modes[SETTINGS, KAPPA1]
    c1, s1 = math.cos(kappa1 * x), math.sin(kappa1 * x)
    c, s = 1.0, 0.0
    for m in range(modes.shape[1]):
        modes[TABLE + p, m] = c
        modes[TABLE + tips + p, m] = s
        c, s = c * c1 - s * s1, s * c1 + c * s1


@compiled
def _free_at(modes: np.ndarray, p: int) -> float:
    """Return the free correction (FREE_RE, FREE_IM) at tabled tip p, m."""
    tabled = (modes.shape[0] - TABLE) // 2
    total = 0.0
    for m in range(modes.shape[1]):
        total += modes[FREE_RE, m] * modes[TABLE + p, m] - \
            modes[FREE_IM, m] * modes[TABLE + tabled + p, m]
    return total


@compiled
def load_walls(walls: np.ndarray, state: np.ndarray, modes: np.ndarray, tips: np.ndarray) -> None:
    """
    Advance a scenario's dynamic walls over the step under the loads the law put on the tips.

    After ``swing_walls`` and the contact law (core.contact.press_tips): each wall takes the
    NORMAL force of the tips it solved for (the very forces the body gets, so that the step
    keeps action and reaction), held over the step: each mode z <- g/K + Phi (z - g/K, z').
    The forces go to the walls' LOADS (state), for their shape.
    """
    n = state.shape[2]
    tabled = (modes.shape[0] - TABLE) // 2
    for wall in range(2):
        count = int(walls[SOLVED_COUNT + wall])
        base = WALL_STATE + wall * STATE_ROWS
        chosen, loads = state[CHOSEN, wall], state[LOADS, wall]
        for k in range(count):
            i = int(chosen[k])
            loads[i] = tips[NORMAL, wall * n + i]
        for m in range(modes.shape[1]):
            k_m = modes[STIFFNESS, m]
            g_re = g_im = 0.0
            for j in range(count):
                i = int(chosen[j])
                p = wall * n + i
                g_re += loads[i] * modes[TABLE + p, m]
                g_im -= loads[i] * modes[TABLE + tabled + p, m]
            g_re *= modes[SHAPE, m]
            g_im *= modes[SHAPE, m]
            for part in range(2):
                g = g_re if part == 0 else g_im
                u = modes[base + Z_RE + part, m] - g / k_m
                v = modes[base + V_RE + part, m]
                modes[base + Z_RE + part, m] = g / k_m + modes[PHI, m] * u + \
                    modes[PHI + 1, m] * v
                modes[base + V_RE + part, m] = modes[PHI + 2, m] * u + modes[PHI + 3, m] * v
                modes[base + G_RE + part, m] = g


@compiled
def swing_walls(law: np.ndarray, walls: np.ndarray, state: np.ndarray, modes: np.ndarray,
                tips: np.ndarray, work: np.ndarray) -> None:
    """
    Solve one scenario's two dynamic walls against its tips' contact law (compiled kernel).

    core.walls.bend_walls with each wall w = free + (G_quasi_static - H) F (module docstring):
    the modes' free correction moves the surface the tips press into (SEEN = PENETRATION -
    free, for every tip it can bring within reach), and the same Newton solve
    (``balance_wall``) balances the rest with the contact law; ``load_walls`` then steps the
    modes under the law's forces. The candidates are the tips whose SEEN is within reach, so
    that a wall swinging towards a tip meets it; a tip further from its wall than the bound of
    the free correction is not tabled. Otherwise as bend_walls: the candidates in their order
    along the wall, the first guess the last two steps' deflections extrapolated (0 for a tip
    the last step did not solve for). ``modes`` the scenario's rows (TABLE + 4 n, modes);
    ``walls``, ``state``, ``work`` as bend_walls'.
    """
    n = state.shape[2]
    count_modes = modes.shape[1]
    reach = walls[REACH]
    largest = -np.inf
    most = 0
    all_converged = True
    fresh, chosen = work[3], work[4]
    x, depth, before, w, force = work[6], work[7], work[8], work[9], work[10]
    g, jacobian = work[WORK_ROWS:WORK_ROWS + n], work[WORK_ROWS + n:]
    for wall in range(2):
        first = wall * n
        # The free correction at every tip it can bring within reach of the wall.
        bound = _free_modes(modes, WALL_STATE + wall * STATE_ROWS)
        count = 0
        for i in range(n):
            p = first + i
            if tips[PENETRATION, p] + bound <= reach:
                continue
            _tip_table(modes, p, tips[X, p])
            tips[SEEN, p] = tips[PENETRATION, p] - _free_at(modes, p)
            if tips[SEEN, p] > reach:
                chosen[count] = i
                count += 1
        for k in range(count):
            i = int(chosen[k])
            p = first + i
            # The solve is for what the loads add to the free correction (the depth is less
            # it too).
            x[k], depth[k], before[k] = tips[X, p], tips[SEEN, p], tips[DEPTH, p]
            last = state[SOLVED, wall, i]
            fresh[k] = last == 0.0
            guess = 2.0 * last - state[SOLVED_BEFORE, wall, i] if last != 0.0 else 0.0
            w[k] = guess - (tips[PENETRATION, p] - tips[SEEN, p])
        retire_solved(walls, state, wall, count)
        if count == 0:
            continue
        fill_wall(x, count, walls[BETA], walls[HALF], walls[GAIN], walls[ITSELF],
                  walls[PATCH_RE], walls[PATCH_IM], g)
        # Less what the held loads' modes take back: H = sum_m held_m (C_i C_j + S_i S_j).
        for a in range(count):
            pa = first + int(chosen[a])
            for b in range(a + 1):
                pb = first + int(chosen[b])
                total = 0.0
                for m in range(count_modes):
                    total += modes[HELD, m] * (
                        modes[TABLE + pa, m] * modes[TABLE + pb, m] +
                        modes[TABLE + 2 * n + pa, m] * modes[TABLE + 2 * n + pb, m])
                g[a, b] -= total
                if b != a:
                    g[b, a] -= total
        # The convergence test's scale: p times twice the own compliance, as bend_walls' (which
        # bounds the quasi-static rows), or the largest row sum of |G| where larger (less the
        # modes' share, the neighbours' entries may outweigh the tip's own).
        scale = 2.0 * g[0, 0]
        for a in range(count):
            row = 0.0
            for b in range(count):
                row += abs(g[a, b])
            scale = max(scale, row)
        scale *= law[EXPONENT]
        iterations, converged = balance_wall(depth, w, g, before, count, law, scale,
                                             walls[TOLERANCE_COLUMN], work, jacobian, force)
        most = max(most, iterations)
        all_converged = all_converged and converged
        for k in range(count):
            i = int(chosen[k])
            p = first + i
            total = w[k] + tips[PENETRATION, p] - depth[k]     # the loads' share + the free
            state[CHOSEN, wall, k] = i
            if fresh[k] > 0.0:
                state[SOLVED_BEFORE, wall, i] = total   # solved for the first time: no trend
            state[SOLVED, wall, i] = total
            tips[SEEN, p] = depth[k] - w[k]
            largest = max(largest, total)
    close_step(walls, largest, most, all_converged)


@compiled
def _correction_at(modes: np.ndarray, base: int, x: np.ndarray, out: np.ndarray) -> None:
    """Add to out_i the correction of the wall at ``base``: Re sum (z_m - g_m / K_m) e^(i k x)."""
    kappa1 = modes[SETTINGS, KAPPA1]
    for i in range(x.size):
        c1, s1 = math.cos(kappa1 * x[i]), math.sin(kappa1 * x[i])
        c, s = 1.0, 0.0
        total = 0.0
        for m in range(modes.shape[1]):
            k = modes[STIFFNESS, m]
            total += (modes[base + Z_RE, m] - modes[base + G_RE, m] / k) * c - \
                (modes[base + Z_IM, m] - modes[base + G_IM, m] / k) * s
            c, s = c * c1 - s * s1, s * c1 + c * s1
        out[i] += total


def dynamic(scenario: Scenario) -> bool:
    """Say whether ``scenario``'s walls bend with mass or damping (a DynamicWalls step)."""
    return scenario.surface.foundation_stiffness > 0.0 and (
        scenario.walls.mass > 0.0 or scenario.walls.damping > 0.0)


def slowest_rate(stiffness: np.ndarray, mass: float, damping: float) -> np.ndarray:
    """
    Return each mode's slowest rate, 1/s: the smallest |eigenvalue| of m z'' + c z' + K z = 0.

    sqrt(K/m) when it oscillates, the slow decay c/2m - sqrt((c/2m)^2 - K/m) when overdamped,
    K/c without mass, infinite without mass and damping (it follows its load at once).
    """
    k = np.asarray(stiffness, float)
    if mass == 0.0:
        return k / damping if damping > 0.0 else np.full(k.shape, np.inf)
    mean = damping / (2.0 * mass)
    split = mean * mean - k / mass
    with np.errstate(divide='ignore', invalid='ignore'):
        overdamped = k / (mean + np.sqrt(np.maximum(split, 0.0)))   # = mean - sqrt(split)
    return np.where(split < 0.0, np.sqrt(k / mass), overdamped)


def resolved_modes(surface: SurfaceParams, walls: WallDynamicsParams, dt: float,
                   length: float = BAND_LENGTH, limit: int = BAND_MODES) -> int:
    """
    Return how many of the band's modes the step resolves: slowest rate dt <= RESOLVED.

    K_n grows with n, so they are the first ones (at most ``limit``).
    """
    kappa = 2.0 * math.pi / length * np.arange(limit)
    k = surface.bending_stiffness * kappa ** 4 + surface.foundation_stiffness
    return int(np.count_nonzero(slowest_rate(k, walls.mass, walls.damping) * dt <= RESOLVED))


class DynamicWalls(Walls):
    """
    The bending walls of S scenarios, where any has walls.mass or walls.damping > 0.

    core.walls.Walls (its constants and state, ``bend_walls``'s) plus each scenario's
    ``modes`` (S, TABLE + 4 n, modes), what ``swing_walls`` solves and advances: every bending
    wall of the batch, its modes the step resolves dynamic (``resolved_modes``), the others at
    rest on their loads (Phi 0: a quasi-static wall has none, and its numbers are the
    quasi-static step's to 1e-14 m).
    """

    def __init__(self, scenarios: Sequence[Scenario], side: np.ndarray, dt: float):
        n = len(side) // 2
        self.resolved = np.array([resolved_modes(s.surface, s.walls, dt)
                                  if s.surface.foundation_stiffness > 0.0 else 0
                                  for s in scenarios])
        # (at least the settings row's columns)
        columns = max(int(self.resolved.max()), BOUND + 2)
        self.modes = np.zeros((len(scenarios), TABLE + 4 * n, columns))
        self.modes[:, STIFFNESS] = 1.0              # harmless where the walls are rigid
        super().__init__(scenarios, side)
        for s, scenario in enumerate(scenarios):
            if scenario.surface.foundation_stiffness <= 0.0:
                continue
            surface, walls = scenario.surface, scenario.walls
            wall = DynamicWall(surface.foundation_stiffness, surface.bending_stiffness,
                               surface.contact_width, walls.mass, walls.damping, dt,
                               modes=self.modes.shape[2])
            rows = self.modes[s]
            rows[STIFFNESS], rows[SHAPE], rows[PHI:PHI + 4] = wall.stiffness, wall.shape, wall.phi
            rows[PHI:PHI + 4, self.resolved[s]:] = 0.0
            rows[HELD] = rows[PHI] * wall.shape / wall.stiffness
            rows[SETTINGS, :BOUND] = 1.0, wall.kappa1
        self.dynamic = self.modes[:, SETTINGS, ON] > 0.0

    def carry(self, before: Walls) -> None:
        """
        Take over the walls of the last parameters (``before``): new parameters mid-run.

        Where nothing of the walls changed (their constants and modes alike), they go on
        moving as they were; otherwise each dynamic wall starts at rest in the quasi-static
        shape of the last loads (the modes at g / K), which the next step's solve then meets
        (from flat, the robot would drop into walls with mass at every parameter set).
        """
        if isinstance(before, DynamicWalls) and before.modes.shape == self.modes.shape and \
                np.array_equal(before.constants[:, :LARGEST], self.constants[:, :LARGEST]) and \
                np.array_equal(before.modes[:, :SETTINGS], self.modes[:, :SETTINGS]) and \
                np.array_equal(before.modes[:, SETTINGS, :BOUND], self.modes[:, SETTINGS, :BOUND]):
            self.modes[:, WALL_STATE:] = before.modes[:, WALL_STATE:]
            self.state[:] = before.state
            self.constants[:, LARGEST:] = before.constants[:, LARGEST:]
            return
        if before.state.shape != self.state.shape:
            return
        x = self._by_surface(np.asarray(self.tip_x, float))
        loads = before.state[:, LOADS]
        for s in np.flatnonzero(self.dynamic):
            rows = self.modes[s]
            kappa = rows[SETTINGS, KAPPA1] * np.arange(rows.shape[1])
            for wall in range(2):
                base = WALL_STATE + wall * STATE_ROWS
                g = rows[SHAPE] * (loads[s, wall] @ np.exp(-1j * np.outer(x[s, wall], kappa)))
                rows[base + G_RE], rows[base + G_IM] = g.real, g.imag
                rows[base + Z_RE] = g.real / rows[STIFFNESS]
                rows[base + Z_IM] = g.imag / rows[STIFFNESS]

    def reset(self) -> None:
        """Put the walls back flat and their modes at rest."""
        super().reset()
        self.modes[:, WALL_STATE:] = 0.0

    @property
    def shape_by_surface(self) -> np.ndarray:
        """Return the deflection at each tip (S, 2, n), m, > 0 away: bottom tips, then top."""
        quasi_static = super().shape_by_surface
        x = self._by_surface(self.tip_x)
        for s in np.flatnonzero(self.dynamic):
            for wall in range(2):
                _correction_at(self.modes[s], WALL_STATE + wall * STATE_ROWS,
                               np.ascontiguousarray(x[s, wall]), quasi_static[s, wall])
        return quasi_static

    def shape(self, x_tips: np.ndarray, samples: np.ndarray) -> np.ndarray:
        """Return each wall's deflection (S, 2, m) at ``samples`` (m): quasi-static + modes."""
        out = super().shape(x_tips, samples)
        samples = np.ascontiguousarray(samples, dtype=float)
        for s in np.flatnonzero(self.dynamic):
            for wall in range(2):
                _correction_at(self.modes[s], WALL_STATE + wall * STATE_ROWS, samples,
                               out[s, wall])
        return out
