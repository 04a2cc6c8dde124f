"""
Kinematics of the helix-driven wave (paper Section 4.1 and Appendix A.1).

Body frame: origin at the robot's centre of mass, x forward (towards the head), y normal to the
surfaces. The backbone is the wave the helix imposes on the links:

    y(X, phase) = A cos(k (X_h - X) + phase),      k = 2 pi / L, phase = omega t,

with X_h the hinge where the base link meets the head. Read literally, the paper's
``k (X_1F - X) - omega t`` sends the wave towards the tail, and a down tip at a trough then sweeps
forward, which would drive the robot tail-first. We flip the sense of the helix (``+ phase``) so
that the wave travels head-wards, the tips in contact sweep backwards, and the robot advances
head-first along +x, the way its wave travels (docs/model.md section 3).

Everything here depends on the phase only, so the dynamics uses a table of tip positions over one
wave cycle (``TipTable``) instead of solving the chain at every step (read by core.tips' kernels).
No numba here: the camera, vision and comparison nodes read these tables and formulas, and a
process that imports numba pays about 0.2 s of CPU more at every start.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import cast, Optional, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core.params import ParameterError, RobotParams


@dataclass(frozen=True)
class LinkGeometry:
    """
    Link positions in the body frame for an array of phases (leading axes = phase shape).

    Arrays of points are complex numbers x + i y (one multiply rotates them).
    """

    hinge: complex               # base-link hinge on the head
    base_angle: np.ndarray       # (...,) angle of the base link, rad (rear end up is positive)
    joints: np.ndarray           # (..., n + 1) front end of each wave link, then the last rear end
    centres: np.ndarray          # (..., n)
    angles: np.ndarray           # (..., n) direction of each wave link (rad), 0 = along +x
    up_tips: np.ndarray          # (..., n) tips that touch the top surface
    down_tips: np.ndarray        # (..., n) tips that touch the bottom surface


def hinge_x(robot: RobotParams) -> float:
    """
    Return the wave occupies the rear of the body.

    The COM sits at the middle of the robot's length (a uniform bar, as the default pitch inertia
    assumes).
    """
    tail = -robot.length / 2.0
    return tail + robot.wave_length_along_body


def backbone(robot: RobotParams, X: Union[float, np.ndarray],
             phase: Union[float, np.ndarray]) -> Tuple[np.ndarray, np.ndarray]:
    """Backbone height y and slope psi = dy/dX at body abscissa X."""
    k = 2.0 * np.pi / robot.wavelength
    arg = k * (hinge_x(robot) - X) + phase
    return robot.amplitude * np.cos(arg), robot.amplitude * k * np.sin(arg)


def base_link_angle(robot: RobotParams, phase: ArrayLike) -> np.ndarray:
    """Solve sin(theta) = (A / b0) cos(k b0 cos(theta) + phase) (paper's base link equation)."""
    phase = np.asarray(phase, dtype=float)
    A, b0 = robot.amplitude, robot.base_link_width
    k = 2.0 * np.pi / robot.wavelength
    theta = np.arcsin(np.clip(A / b0 * np.cos(k * b0 + phase), -1.0, 1.0))
    for _ in range(50):
        arg = k * b0 * np.cos(theta) + phase
        g = b0 * np.sin(theta) - A * np.cos(arg)
        dg = b0 * np.cos(theta) - A * np.sin(arg) * k * b0 * np.sin(theta)
        step = g / dg
        theta = theta - step
        if np.max(np.abs(step)) < 1e-14:
            break
    return theta


def link_geometry(robot: RobotParams, phase: ArrayLike) -> LinkGeometry:
    """
    Positions of every link for the given phase(s).

    The helix runs through the centre of every wave link and the links ride in the body's frame
    so that they "cancel out the rotational motion, and instead maintain vertical oscillation"
    (paper Section 2.1): link i's centre stays at a fixed body abscissa X_i on the backbone, and
    the rigid link (width b) turns with the backbone slope there. Its tips sit at r along the
    backbone normal n = (-psi, 1) / sqrt(1 + psi^2) (Appendix A.1). Neighbouring joints meet
    where the slope is small and open up by a few mm where it is steep, as the real links' slotted
    joints allow.

    Hanging each link from the rear joint of the one in front (a pure chain) would instead slide
    the whole wave back and forth by b0 (1 - cos theta_base), about 12 mm a cycle, and double the
    tips' speed at the crests, contradicting the rigid-surface speed 4 pi^2 A r f / L the paper
    uses for v_theory.
    """
    phase = np.asarray(phase, dtype=float)
    n, b, r = robot.wave_links, robot.link, robot.tip_distance
    hinge = complex(hinge_x(robot), 0.0)
    X = hinge.real - robot.base_link_width - b * (np.arange(n) + 0.5)
    y, psi = backbone(robot, X, phase[..., None])
    angles = np.arctan(psi)
    direction = np.exp(1j * angles)
    centres = X + 1j * y
    joints = np.concatenate([centres + 0.5 * b * direction,
                             centres[..., -1:] - 0.5 * b * direction[..., -1:]], axis=-1)
    normal = 1j * direction
    return LinkGeometry(hinge=hinge, base_angle=base_link_angle(robot, phase), joints=joints,
                        centres=centres, angles=angles, up_tips=centres + r * normal,
                        down_tips=centres - r * normal)


def tip_rates(robot: RobotParams, phase: ArrayLike) -> np.ndarray:
    """
    Return d(tip position) / d(phase) in the body frame, complex, (..., 2 n) as in ``TipTable``.

    From ``link_geometry``: a link centre X + i y(X, phase) moves by i dy/dphase, and its tips
    at +-r along the normal n = i exp(i atan psi) turn with the slope psi, dn/dphase =
    -exp(i atan psi) dpsi/dphase / (1 + psi^2). The motor's load torque is the contact forces
    against these (docs/motor.md).
    """
    phase = np.asarray(phase, dtype=float)
    n, r = robot.wave_links, robot.tip_distance
    k = 2.0 * np.pi / robot.wavelength
    X = hinge_x(robot) - robot.base_link_width - robot.link * (np.arange(n) + 0.5)
    arg = k * (hinge_x(robot) - X) + phase[..., None]
    psi = robot.amplitude * k * np.sin(arg)
    centre_rate = -1j * robot.amplitude * np.sin(arg)
    turn = np.exp(1j * np.arctan(psi)) * (robot.amplitude * k * np.cos(arg) / (1.0 + psi ** 2))
    return np.concatenate([centre_rate + r * turn, centre_rate - r * turn], axis=-1)


def base_link_end(robot: RobotParams, base_angle: ArrayLike) -> np.ndarray:
    """Rear end of the base link (it meets the backbone there), from its angle."""
    return complex(hinge_x(robot), 0.0) - robot.base_link_width * np.exp(-1j * np.asarray(
        base_angle))


def interference(robot: RobotParams, samples: int = 720) -> float:
    """
    Smallest clearance (m) between neighbouring links over a wave cycle; negative = overlap.

    Consecutive links turn about their shared joint; on the concave side their tips close in.
    A link is drawn as its spine (down tip to up tip): two links interfere when the spines of
    neighbours come closer than zero along the chain, i.e. the tips swap order, or when any two
    non-neighbouring spines cross.
    """
    geo = link_geometry(robot, np.linspace(0.0, 2.0 * np.pi, samples, endpoint=False))
    direction = np.exp(1j * geo.angles[..., :-1])  # unit vector of link i along the chain
    clearance = np.inf
    for tips in (geo.up_tips, geo.down_tips):
        # Distance of tip i+1 behind tip i, measured along link i's direction (backwards).
        gap = -((tips[..., 1:] - tips[..., :-1]) * np.conj(direction)).real
        clearance = min(clearance, float(gap.min()))
    return clearance


def check_no_interference(robot: RobotParams) -> None:
    clearance = interference(robot)
    if clearance <= 0.0:
        raise ParameterError(
            f'the links interfere: neighbouring tips overlap by {-clearance * 1000:.2f} mm over a '
            f'wave cycle (robot.tip_distance = {robot.tip_distance:g} m is too large for '
            f'robot.link_width = {robot.link:g} m at this amplitude and wavelength)')


def v_theory(robot: RobotParams, frequency: float) -> float:
    """Advance speed over a rigid surface, 4 pi^2 A r f / L (paper, from its reference [29])."""
    return 4.0 * np.pi ** 2 * robot.amplitude * robot.tip_distance * frequency / robot.wavelength


def cycle_phases(samples: int) -> np.ndarray:
    """Return the samples + 1 phases 0 .. 2 pi (both ends) a PhaseTable is built from."""
    return np.linspace(0.0, 2.0 * np.pi, samples + 1)


class PhaseTable:
    """
    Values tabulated over one wave cycle, linearly interpolated.

    The one table of the simulator (tips), the joint states and the renderer (link geometry).

    ``values`` are rows at ``cycle_phases(samples)``: row ``samples`` (phase 2 pi) equals row 0.
    The slopes get one row past the end (= the first), so a phase that rounds to
    2 pi * (1 - eps) reads index ``samples`` without a clamp in the 1 kHz loop.
    """

    def __init__(self, values: np.ndarray, samples: int):
        self.samples = samples
        self.scale = samples / (2.0 * np.pi)
        self.points = np.ascontiguousarray(values)                           # (samples + 1, K)
        slopes = np.diff(self.points, axis=0)                                 # (samples, K)
        self.slopes = np.concatenate([slopes, slopes[:1]])
        # Points and slopes in one array, for the kernels (turned_table_value).
        self.stacked = np.ascontiguousarray(np.stack([self.points, self.slopes]))

    def index(self, phase: ArrayLike) -> Tuple[np.ndarray, np.ndarray]:
        """Return (row, weight) of phase(s) in [0, 2 pi)."""
        u = np.asarray(phase) * self.scale
        i = u.astype(np.intp)
        return i, u - i

    def at(self, phase: ArrayLike, out: Optional[np.ndarray] = None,
           work: Optional[np.ndarray] = None) -> np.ndarray:
        """
        Values at phase(s) in [0, 2 pi): shape phase.shape + (K,).

        ``out`` and ``work`` (both of that shape) avoid allocations in the simulator's loop.
        """
        i, w = self.index(phase)
        w = w[..., None]
        if out is None:
            return cast(np.ndarray, self.points[i] + w * self.slopes[i])
        np.take(self.slopes, i, axis=0, out=out)
        out *= w
        out += np.take(self.points, i, axis=0, out=work)
        return out


class TipTable(PhaseTable):
    """
    Body-frame tip positions over one wave cycle (complex x + i y).

    Column order: the n down tips (bottom surface), then the n up tips (top surface).
    2048 samples put the interpolation error near 1e-8 m, far below any penetration that matters.
    """

    def __init__(self, robot: RobotParams, samples: int = 2048):
        geo = link_geometry(robot, cycle_phases(samples))
        super().__init__(np.concatenate([geo.down_tips, geo.up_tips], axis=-1), samples)
        n = robot.wave_links
        # +1 for tips pressing into the top surface, -1 for the bottom one.
        self.side = np.concatenate([-np.ones(n), np.ones(n)])

    @property
    def count(self) -> int:
        return int(self.points.shape[1])


class TipRateTable(PhaseTable):
    """
    Body-frame d(tip position) / d(phase) over one wave cycle (complex, m/rad; ``tip_rates``).

    Same columns as ``TipTable``; only built when a motor drives the helix.
    """

    def __init__(self, robot: RobotParams, samples: int = 2048):
        super().__init__(tip_rates(robot, cycle_phases(samples)), samples)


class JointTable(PhaseTable):
    """
    Base-link and wave-link angles over one wave cycle (rad, relative to the body x axis).

    ``link_geometry`` solves the base link's angle by Newton iterations: too slow for every step
    at 1 kHz. 4096 samples keep the interpolation error under 1e-5 rad.
    """

    def __init__(self, robot: RobotParams, samples: int = 4096):
        geo = link_geometry(robot, cycle_phases(samples))
        super().__init__(np.concatenate([geo.base_angle[:, None], geo.angles], axis=1), samples)
        self.derivative = self.slopes * self.scale      # d angle / d phase, per sample

    def angles_and_rates(self, phase: float,
                         omega: float = 0.0) -> Tuple[np.ndarray, np.ndarray]:
        """
        Return ([base_angle, link_00, ...], their rates in rad/s) at ``phase``.

        ``phase`` is wrapped into [0, 2 pi); the rates are for helix speed ``omega`` (rad/s).
        """
        i, w = self.index(phase % (2.0 * np.pi))
        return self.points[i] + w * self.slopes[i], self.derivative[i] * omega
