"""
Where the 1 kHz integrator stays stable: the contacts' stiffness against the time step.

``check(scenario)`` refuses, with the reason and what would be allowed, what the ``Simulator``
cannot step (``Simulator.set_scenarios`` calls it, the simulator node before taking a change).

The step (``dynamics``) is semi-implicit Euler: v += a dt, then x += v dt. On an undamped spring
of natural frequency omega it is stable only while omega dt < 2; beyond, every step multiplies
the error (surface.normal_stiffness 1e6 threw the robot 527 m up within a second). The rate term
of the restitution hysteresis (``contact``) acts as a damper c on top, and for a damped spring the
same step needs (omega dt)^2 < 4 - 2 c dt / m: near rest, where that term is linear, the limit is
lower; it saturates (the factor stays within [e, 1]), so it cannot make the motion grow, only
chatter. We keep omega dt <= OMEGA_DT_MAX = 1.5 (measured: with the paper's robot the tips of a
running simulation reached omega dt 2.04 at kn = 8e5 and ran on; at kn = 1e6, 2.4, it diverged
in 0.3 s).

The stiffest mode. The robot is one rigid body (mass m, pitch inertia I) on the springs of its
touching tips. A tip at (rx, ry) from the centre of mass pressing delta into a surface adds the
normal stiffness dFn/ddelta = p kn delta^(p - 1) along y, with lever arm rx for the pitch, and
the shear spring kt along x, with lever arm ry. The largest eigenvalue of M^-1 K is at most its
trace, so

    omega^2 <= sum over touching tips of p kn delta^(p-1) (1/m + rx^2/I) + kt (1/m + ry^2/I),

evaluated over one wave cycle with the robot at rest centred in the gap (how every run starts,
and the squeeze the surfaces hold it in: the measured omega of a running simulation stays within
5 % of it). In a gap wider than the robot nothing is squeezed: the robot lies on the bottom
surface, and one tip at the far end bearing its whole weight gives the bound there. kt counts
too: a shear spring beyond the limit is held by friction, but it chatters between stick and slip
at every step.

The motor (``motor``, with motor.voltage > 0) takes its back-EMF and friction implicitly, but the
load torque of the contacts explicitly. Against the contacts' stiffness seen through the helix
phase, K = d(load)/d(phase) <= sum over touching tips of p kn delta^(p-1) (dy/dphase)^2 +
kt (dx/dphase)^2, its step is semi-implicit Euler on a damped oscillator of inertia
M = J + k^2 dt / R (the rotor, plus what the implicit back-EMF adds), retaining a = J / M of the
speed per step: stable while s = K dt^2 / M < 2 (1 + a). That is omega dt < 2 for a heavy rotor
(a = 1), and for a quasi-static one (J = 0) the mechanical time constant R / k^2 against dt: at
hz_per_volt 10 Hz/V and 320 ohm the helix ran away at the first step. The same margin holds:
s <= (OMEGA_DT_MAX / 2)^2 2 (1 + a).
"""
from __future__ import annotations

import functools
import math
from typing import Callable, Tuple

import numpy as np

from saw_ros.core.kinematics import cycle_phases, link_geometry, tip_rates
from saw_ros.core.params import GRAVITY, ParameterError, RobotParams, Scenario

OMEGA_DT_MAX = 1.5          # the step's limit is 2; margin for damping and deeper contacts
PHASES = 128                # samples of one wave cycle: crest depths within 0.01 mm


@functools.lru_cache(maxsize=16)
def _tips(robot: RobotParams) -> Tuple[np.ndarray, np.ndarray]:
    """Body-frame tips over one cycle, (PHASES, 2n) complex, and +1 top / -1 bottom per tip."""
    geo = link_geometry(robot, cycle_phases(PHASES))
    n = robot.wave_links
    return (np.concatenate([geo.down_tips, geo.up_tips], axis=-1),
            np.concatenate([-np.ones(n), np.ones(n)]))


@functools.lru_cache(maxsize=1024)
def contact_omega(robot: RobotParams, kn: float, exponent: float, kt: float,
                  gap: float) -> float:
    """Return the bound on the stiffest contact mode's angular frequency, rad/s (docstring)."""
    tips, side = _tips(robot)
    m, inertia = robot.mass, robot.inertia
    rx, ry = tips.real, tips.imag
    depth = side * ry - gap / 2.0                     # at rest, centred: y = gap / 2
    touching = depth > 0.0
    normal = exponent * kn * np.where(touching, depth, 1.0) ** (exponent - 1.0)
    per_tip = normal * (1.0 / m + rx ** 2 / inertia) + kt * (1.0 / m + ry ** 2 / inertia)
    squeezed = float(np.where(touching, per_tip, 0.0).sum(axis=1).max())
    # On the bottom surface: one tip holds the weight, delta = (m g / kn)^(1/p).
    held = (m * GRAVITY / kn) ** (1.0 / exponent)
    lever = float(np.abs(rx).max())
    resting = (exponent * kn * held ** (exponent - 1.0) * (1.0 / m + lever ** 2 / inertia)
               + kt * (1.0 / m + float(np.abs(ry).max()) ** 2 / inertia))
    return math.sqrt(max(squeezed, resting))


@functools.lru_cache(maxsize=1024)
def phase_stiffness(robot: RobotParams, kn: float, exponent: float, kt: float,
                    gap: float) -> float:
    """Return the bound on d(load torque)/d(phase), N m/rad, that the motor's step meets."""
    tips, side = _tips(robot)
    rates = tip_rates(robot, cycle_phases(PHASES))
    depth = side * tips.imag - gap / 2.0
    touching = depth > 0.0
    normal = exponent * kn * np.where(touching, depth, 1.0) ** (exponent - 1.0)
    per_tip = normal * rates.imag ** 2 + kt * rates.real ** 2
    squeezed = float(np.where(touching, per_tip, 0.0).sum(axis=1).max())
    held = float((robot.mass * GRAVITY / kn) ** (1.0 / exponent))
    resting = (exponent * kn * float(held ** (exponent - 1.0)) * float((rates.imag ** 2).max())
               + kt * float((rates.real ** 2).max()))
    return max(squeezed, resting)


def _motor_margin(scenario: Scenario, inertia: float) -> float:
    """Return s / its allowed value for the motor's step (<= 1: stable with the margin)."""
    motor, surface, dt = scenario.motor, scenario.surface, scenario.integration.dt
    stiffness = phase_stiffness(scenario.robot, surface.normal_stiffness,
                                surface.hertz_exponent, surface.tangential_stiffness,
                                scenario.conditions.gap)
    k = motor.torque_constant
    # R = 0 is an ideal source (w' = V / k): no step of its own, nothing to ring.
    if motor.resistance == 0.0:
        return 0.0
    mass = inertia + k * k * dt / motor.resistance
    retained = inertia / mass
    return stiffness * dt * dt / mass / ((OMEGA_DT_MAX / 2.0) ** 2 * 2.0 * (1.0 + retained))


def _largest(stable: Callable[[float], bool], value: float) -> float:
    """Return the largest x in (0, value] for which ``stable(x)`` (monotonic) holds."""
    low, high = 0.0, value
    for _ in range(60):
        mid = (low + high) / 2.0
        low, high = (mid, high) if stable(mid) else (low, mid)
    return low


def check(scenario: Scenario) -> None:
    """Raise ParameterError, with the reason and what would be allowed, if ``scenario`` rings."""
    robot, surface, dt = scenario.robot, scenario.surface, scenario.integration.dt
    kn, p, kt = surface.normal_stiffness, surface.hertz_exponent, surface.tangential_stiffness
    gap = scenario.conditions.gap
    omega = contact_omega(robot, kn, p, kt, gap)
    if omega * dt <= OMEGA_DT_MAX:
        _check_motor(scenario)
        return
    kn_max = _largest(lambda k: contact_omega(robot, k, p, kt, gap) * dt <= OMEGA_DT_MAX, kn)
    kt_max = _largest(lambda k: contact_omega(robot, kn, p, k, gap) * dt <= OMEGA_DT_MAX, kt)
    allowed = [f'surface.normal_stiffness <= {kn_max:.4g} N/m^{p:g}' if kn_max > 0.0 else '',
               f'surface.tangential_stiffness <= {kt_max:.4g} N/m' if kt_max > 0.0 else '',
               f'integration.dt <= {OMEGA_DT_MAX / omega:.3g} s']
    raise ParameterError(
        f'the contacts are too stiff for integration.dt = {dt:g} s (surface.normal_stiffness = '
        f'{kn:g} N/m^{p:g}, surface.tangential_stiffness = {kt:g} N/m, conditions.gap = '
        f'{gap:g} m): they would ring at {omega / (2.0 * math.pi):.0f} Hz, and the step is '
        f'stable up to omega dt = {OMEGA_DT_MAX:g}, here {omega * dt:.2f}; allowed with the '
        f'other values: {", or ".join(a for a in allowed if a)}')


def _check_motor(scenario: Scenario) -> None:
    """Raise ParameterError if the motor's step would ring against the contacts (docstring)."""
    motor, dt = scenario.motor, scenario.integration.dt
    if motor.voltage <= 0.0 or _motor_margin(scenario, motor.inertia) <= 1.0:
        return
    # The smallest rotor inertia that would do, with the rest as it is.
    top = 1.0
    while _motor_margin(scenario, top) > 1.0 and top < 1e12:
        top *= 2.0
    needed = top - _largest(lambda j: _motor_margin(scenario, top - j) <= 1.0, top)
    helix = motor.inertia + motor.torque_constant ** 2 * dt / motor.resistance
    raise ParameterError(
        f'the motor cannot be stepped at integration.dt = {dt:g} s against these contacts: '
        f'with motor.inertia = {motor.inertia:g} kg m^2, motor.resistance = '
        f'{motor.resistance:g} ohm and motor.hz_per_volt = {motor.hz_per_volt:g} Hz/V the '
        f'helix (inertia plus k^2 dt / R: {helix:.3g} kg m^2) would ring against the load; '
        f'allowed with the other values: motor.inertia >= {needed:.3g} kg m^2, or a smaller '
        f'motor.resistance or motor.hz_per_volt')
