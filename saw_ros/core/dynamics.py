"""
Rigid-body dynamics of the robot between the surfaces (paper Section 4.3, pseudo-code A.2).

The robot is one rigid body (COM x, y, pitch theta) whose links move with the prescribed wave.
At every step: tips from the kinematics table, contact forces, then semi-implicit Euler,

    v_i = v_(i-1) + a_i dt,    x_i = x_(i-1) + v_i dt,

with gravity (-g sin alpha, -g cos alpha) in the surface frame and F_ext along -x at the COM.

S scenarios that share one robot geometry and time step are stepped together as (S, P) arrays
(P = 2 n tips). One scenario is simply S = 1: the same code, the same numbers.

The helix turns at the constant conditions.frequency (the paper's simulation), or, where
motor.voltage > 0, at a speed omega that is a state: the DC motor of docs/motor.md against the
load torque of the contact forces, with the back-EMF and the Coulomb friction taken implicitly
so that the paper's motor is stable at dt = 1 ms with any rotor inertia J >= 0 (core.stability
refuses a motor too light for the step, its load torque being explicit).
"""
from __future__ import annotations

from dataclasses import dataclass
import functools
import math
from typing import Any, Callable, cast, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core import stability
from saw_ros.core.contact import contact_step, ContactLaw, ContactState, Param
from saw_ros.core.drive import FREQUENCY_LIMIT, PhaseProfile, VOLTAGE_LIMIT
from saw_ros.core.kinematics import check_no_interference, TipRateTable, TipTable
from saw_ros.core.motor import MotorLaw
from saw_ros.core.params import ParameterError, PLACEMENT_SHARE, RobotParams, Scenario
from saw_ros.core.pool import batches, LocalPool, Pool
from saw_ros.core.walls import Walls

GRAVITY = 9.81  # m/s^2
TWO_PI = 2.0 * math.pi
# Faster than this (m/s, or rad/s of pitch) the state left the model: the fastest wave allowed
# (5 Hz) drives the robot at 0.35 m/s, and a robot thrown by a tether force (external_force
# 1e9 N sent it to x = -4.8e10 m) or falling through a surface moves orders of magnitude faster.
MAX_SPEED = 100.0


class DivergenceError(RuntimeError):
    """The simulation left the physically possible: it stops instead of returning garbage."""


@functools.lru_cache(maxsize=16)
def tip_table(robot: RobotParams) -> TipTable:
    check_no_interference(robot)
    return TipTable(robot)


@functools.lru_cache(maxsize=16)
def tip_rate_table(robot: RobotParams) -> TipRateTable:
    return TipRateTable(robot)


@dataclass
class Trajectory:
    """
    Recorded states of S scenarios: t (n,), q (n, S, 6) with columns x, y, theta, vx, vy, w.

    ``omega`` (n, S): the helix speed, rad/s, over the step that ended at each sample. When a
    motor drove any scenario also its torque at the helix (N m) and current (A), (n, S); NaN for
    the scenarios of the batch turned at constant frequency. With ``contacts=True`` also the
    per-tip normal and tangential forces (n, S, P), N.
    """

    t: np.ndarray
    q: np.ndarray
    scenarios: Sequence[Scenario]
    normal: Optional[np.ndarray] = None
    tangential: Optional[np.ndarray] = None
    omega: Optional[np.ndarray] = None
    torque: Optional[np.ndarray] = None
    current: Optional[np.ndarray] = None


class Simulator:
    """Steps S scenarios together; ``Simulator(scenario)`` is the one-scenario case."""

    def __init__(self, scenarios: Union[Scenario, Sequence[Scenario]]):
        if isinstance(scenarios, Scenario):
            scenarios = [scenarios]
        scenarios = list(scenarios)
        if not scenarios:
            raise ParameterError('a simulation needs at least one scenario')
        self.robot = scenarios[0].robot
        self.dt = scenarios[0].integration.dt
        for s in scenarios[1:]:
            if s.robot != self.robot or s.integration.dt != self.dt:
                raise ParameterError('scenarios stepped together must share the robot and '
                                     'integration.dt; run them in separate batches')
        self.table = tip_table(self.robot)
        self.count = len(scenarios)
        tips = self.table.count
        self.contacts = ContactState(self.count, tips)
        self.q = np.zeros((6, self.count))       # x, y, theta, vx, vy, w
        self.phase = np.zeros(self.count)
        self.omega = np.zeros(self.count)        # helix speed, rad/s
        # The motor of the last step, per scenario (NaN where no motor drives the helix): torque
        # k i at the helix (N m), current (A), the load torque of the contacts and the friction
        # torque it met (N m).
        self.motor_torque = np.full(self.count, np.nan)
        self.current = np.full(self.count, np.nan)
        self.load_torque = np.full(self.count, np.nan)
        self.friction_torque = np.full(self.count, np.nan)
        self.steps = 0
        self._forces = np.zeros((3, self.count))
        # Net contact force (fx, fy, surface axes, N) and moment about the COM (N m) of the last
        # step, per scenario: what the step accelerated the body with.
        self.contact_wrench = np.zeros((3, self.count))
        self._rot = np.zeros((self.count, 1), complex)
        self._body = np.zeros((self.count, tips), complex)
        self._gathered = np.zeros((self.count, tips), complex)
        self._x = np.zeros((self.count, tips))                 # world tip abscissae, m
        self._work = np.zeros((self.count, tips))
        self._ones = np.ones(tips)
        self.penetration = np.zeros((self.count, tips))        # > 0 inside a surface, m
        # What the contact law sees: the penetration, less the bending walls' deflection.
        self.depth = self.penetration
        # The drive from outside (core.drive, issue 22): a commanded voltage (V, (S,)) or helix
        # frequency (Hz, (S,)) that overrides motor.voltage / conditions.frequency until cleared,
        # or a voltage profile over the helix turn. None: the parameters drive.
        self.commanded_voltage: Optional[np.ndarray] = None
        self.commanded_frequency: Optional[np.ndarray] = None
        self.profile: Optional[PhaseProfile] = None
        self.scenarios = scenarios
        self.set_scenarios(scenarios)
        self.reset()

    # -- parameters ----------------------------------------------------------------------------
    def set_scenarios(self, scenarios: Sequence[Scenario]) -> None:
        """Take new parameters (same robot and dt) at once, keeping the current state."""
        if len(scenarios) != self.count:
            raise ParameterError(f'expected {self.count} scenarios, got {len(scenarios)}')
        for s in scenarios:
            if s.robot != self.robot or s.integration.dt != self.dt:
                raise ParameterError('robot geometry and integration.dt cannot change during a '
                                     'run; start a new simulation')
            # Contacts too stiff for the step would ring up to NaN: refused with the limit.
            # (Here, not in the Scenario: the worm model takes any stiffness.)
            stability.check(s)
        self.scenarios = list(scenarios)

        cond = [s.conditions for s in scenarios]
        tips = self.table.count

        def per_scenario(get: Callable[[Scenario], float]) -> Param:
            """
            Return a scalar where every scenario agrees, else one value per scenario.

            Sweeps vary one or two parameters: scalar operands are the cheapest. The values per
            scenario are broadcast to (S, P) once (a same-shape operand is 2-3x faster than an (S,
            1) column broadcast at every step).
            """
            values = np.array([get(s) for s in scenarios], dtype=float)
            if np.all(values == values[0]):
                return float(values[0])
            return np.repeat(values[:, None], tips, axis=1)

        surface: Callable[[str], Param] = lambda name: per_scenario(  # noqa: E731
            lambda s: getattr(s.surface, name))
        self.law = ContactLaw.from_values(
            kn=surface('normal_stiffness'), kt=surface('tangential_stiffness'),
            mu=surface('friction_coefficient'), exponent=surface('hertz_exponent'),
            restitution=surface('restitution'), hysteresis_speed=surface('hysteresis_speed'),
            dt=self.dt)
        self._max_penetration = np.array([s.surface.max_penetration for s in scenarios])
        # Bending walls where any scenario has them (core.walls); None: rigid, as the paper's.
        # New parameters start the walls from the last forces' shape again at the next step.
        self.walls = (Walls(scenarios, self.table.side)
                      if any(s.surface.foundation_stiffness > 0.0 for s in scenarios) else None)
        self._max_penetration_any = float(self._max_penetration.min())
        gap = np.array([[s.conditions.gap] for s in scenarios])
        self._gap = gap[:, 0]
        side = self.table.side
        # penetration = side * (y - level): top surface at y = gap, bottom at y = 0.
        self._level = np.where(side > 0, gap, 0.0) * side           # (S, P)
        self._side = side
        self._omega_dt = np.array([TWO_PI * s.frequency * self.dt for s in scenarios])
        if self.commanded_frequency is not None:
            self._omega_dt = TWO_PI * self.commanded_frequency * self.dt
        self._set_motor(scenarios)
        mass = np.array([s.robot.mass for s in scenarios])
        inertia = np.array([s.robot.inertia for s in scenarios])
        self._inv_inertia = (1.0 / np.stack([mass, mass, inertia])) * self.dt
        slope = np.array([c.slope for c in cond])
        f_ext = np.array([c.external_force for c in cond])
        # Constant accelerations (gravity, tether) times dt, per degree of freedom.
        self._bias_dt = np.stack([-GRAVITY * np.sin(slope) - f_ext / mass,
                                  -GRAVITY * np.cos(slope), np.zeros(self.count)]) * self.dt

    def reset(self) -> None:
        """
        Go back to the initial state (model.md): centred in the gap, at rest, wave phase 0.

        Time goes on (``t`` counts every step since the start), so that what a reset is logged
        with, or a later divergence reported at, is the time of the run.
        """
        self.q[:] = 0.0
        self.q[1] = [s.conditions.gap / 2.0 for s in self.scenarios]
        self.phase[:] = 0.0
        # A motor starts at rest; a constant-frequency helix turns from the first step.
        self.omega[:] = np.where(self.driven, 0.0, self._omega_dt / self.dt)
        for a in (self.motor_torque, self.current, self.load_torque, self.friction_torque):
            a[:] = np.nan
        self.contacts.reset()
        if self.walls is not None:
            self.walls.reset()

    def _set_motor(self, scenarios: Sequence[Scenario]) -> None:
        """Fold the motor constants of the scenarios that a motor drives (docs/motor.md)."""
        self.driven = np.array([s.motor.voltage > 0.0 for s in scenarios])
        self.motor_on = bool(self.driven.any())
        # A scenario that leaves its motor (or never had one) turns at its constant speed now.
        constant = ~self.driven
        self.omega[constant] = self._omega_dt[constant] / self.dt
        for a in (self.motor_torque, self.current, self.load_torque, self.friction_torque):
            a[constant] = np.nan
        if not self.motor_on:
            return
        self.rate_table = tip_rate_table(self.robot)
        tips = self.table.count
        self._rate = np.zeros((self.count, tips), complex)
        self._rate_work = np.zeros((self.count, tips), complex)
        self.motor = MotorLaw([s.motor for s in scenarios], self.dt)
        self._constant_omega = self._omega_dt / self.dt
        if self.commanded_voltage is not None:
            self.motor.set_voltage(self.commanded_voltage)
        self._set_runaway()

    def _set_runaway(self) -> None:
        # A helix faster than this was driven by something no surface can supply.
        ideal = np.abs(self.motor.ideal)
        if self.profile is not None:
            ideal = np.maximum(ideal, TWO_PI * self.motor.hz_per_volt * self.profile.peak)
        self._runaway = 5.0 * (ideal + self._constant_omega) + 1.0

    # -- the drive from outside (core.drive) ----------------------------------------------------
    def command_voltage(self, voltage: Optional[ArrayLike]) -> None:
        """
        Drive the motor at ``voltage`` (V; scalar or (S,)) from the next step; None: motor.voltage.

        Only scenarios whose motor is modelled (motor.voltage > 0 in their parameters) take a
        voltage: 0 V then stops the helix against its friction, it does not leave the motor out.
        """
        if voltage is None:
            self.commanded_voltage = None
            if self.motor_on:
                self.motor.set_voltage([s.motor.voltage for s in self.scenarios])
                self._set_runaway()
            return
        if not self.motor_on:
            raise ParameterError('no motor is modelled (motor.voltage = 0): command the helix '
                                 'frequency instead')
        voltage = self._commanded(voltage, 'voltage', VOLTAGE_LIMIT, 'V')
        self.commanded_voltage = voltage
        self.motor.set_voltage(voltage)
        self._set_runaway()

    def _commanded(self, values: ArrayLike, what: str, limit: float, unit: str) -> np.ndarray:
        """Return a command per scenario (S,), or raise ParameterError naming what is wrong."""
        values = np.broadcast_to(np.asarray(values, float), (self.count,)).copy()
        if not (np.isfinite(values).all() and (values >= 0.0).all() and (values <= limit).all()):
            raise ParameterError(f'commanded {what} {values} is invalid: must be finite, in '
                                 f'[0, {limit:g}] {unit}')
        return values

    def command_frequency(self, frequency: Optional[ArrayLike]) -> None:
        """Turn the helix at ``frequency`` (Hz) where no motor is modelled; None: the parameter."""
        if frequency is None:
            self.commanded_frequency = None
            self._omega_dt = np.array([TWO_PI * s.frequency * self.dt for s in self.scenarios])
        else:
            frequency = self._commanded(frequency, 'frequency', FREQUENCY_LIMIT, 'Hz')
            self.commanded_frequency = frequency
            self._omega_dt = TWO_PI * frequency * self.dt
        constant = ~self.driven
        self.omega[constant] = self._omega_dt[constant] / self.dt
        if self.motor_on:
            self._constant_omega = self._omega_dt / self.dt
            self._set_runaway()

    def set_profile(self, profile: Optional[PhaseProfile]) -> None:
        """Feed the motor ``profile``'s voltage at every step (None: stop feeding it)."""
        if profile is not None and not self.motor_on:
            raise ParameterError('a voltage profile needs the motor (motor.voltage > 0)')
        if profile is not None and len(profile.mean) != self.count:
            raise ParameterError(f'expected a profile for {self.count} scenarios, got '
                                 f'{len(profile.mean)}')
        self.profile = profile
        if profile is None:
            self.command_voltage(self.commanded_voltage)
        else:
            self._set_runaway()

    def _motor_step(self) -> None:
        """
        Step the helix speed: the motor against the contacts of this step (docs/motor.md).

        tau_load = -sum over tips of F . dr/dphase (F the surface's force on the tip, world
        axes; dr/dphase the body-frame rate turned by the pitch): the torque the helix needs
        to move the tips against their contact forces.
        """
        rate = self.rate_table.at(self.phase, out=self._rate, work=self._rate_work)
        rate *= self._rot
        contacts = self.contacts
        # F = (Ft, -side Fn): F . r' = Ft r'x - side Fn r'y.
        np.multiply(contacts.tangential, rate.real, out=self._work)
        load = -(self._work @ self._ones)
        np.multiply(contacts.normal, rate.imag, out=self._work)
        load += self._work @ self._side
        omega = self.omega
        new, torque, friction = self.motor.step(omega, load)
        # Scenarios of the batch without a motor keep their constant speed (and have no motor
        # torque, current or friction to report).
        new = np.where(self.driven, new, self._constant_omega)
        torque = np.where(self.driven, torque, np.nan)
        friction = np.where(self.driven, friction, np.nan)
        self.motor_torque[:] = torque
        self.current[:] = torque / self.motor.k
        self.load_torque[:] = load
        self.friction_torque[:] = friction
        omega[:] = new
        if not (np.abs(new) <= self._runaway).all():
            i = int(np.argmax(~(np.abs(new) <= self._runaway)))
            raise DivergenceError(
                f'simulation diverged at t = {self.t:.3f} s (scenario {i}): the helix turned at '
                f'{new[i] / TWO_PI:.3g} Hz, far beyond the no-load speed of its motor, '
                f'{self.motor.ideal[i] / TWO_PI:.3g} Hz (load torque {load[i]:.3g} N m); '
                f'reduce integration.dt or soften the surfaces')

    @property
    def t(self) -> float:
        return self.steps * self.dt

    def placement_error(self) -> Optional[str]:
        """
        Say why the current state cannot go on under the current parameters, or return None.

        After a change of the gap (or of max_penetration) the tips are where they were: a
        narrower gap can put them deeper into a surface than the robot's start position may
        (PLACEMENT_SHARE of max_penetration), a depth the step cannot recover from.
        """
        body = self.table.at(self.phase) * np.exp(1j * self.q[2])[:, None]
        pen = (body.imag + self.q[1][:, None]) * self._side - self._level
        if self.walls is not None:
            pen = pen - self.walls.deflection       # as deep as the bent walls let them
        allowed = PLACEMENT_SHARE * self._max_penetration
        too_deep = pen - allowed[:, None]
        i, tip = np.unravel_index(np.argmax(too_deep), too_deep.shape)
        if too_deep[i, tip] <= 0:
            return None
        surface = 'top' if self._side[tip] > 0 else 'bottom'
        return (f'a tip would be {pen[i, tip] * 1000:.1f} mm deep in the {surface} surface '
                f'(scenario {i}), more than {PLACEMENT_SHARE:.0%} of surface.max_penetration = '
                f'{self._max_penetration[i] * 1000:.1f} mm')

    # -- stepping ------------------------------------------------------------------------------
    def step(self) -> None:
        """One semi-implicit Euler step of every scenario."""
        table, contacts, q = self.table, self.contacts, self.q
        body = table.at(self.phase, out=self._body, work=self._gathered)  # tips, body frame
        np.exp(1j * q[2], out=self._rot[:, 0])
        body *= self._rot                                        # rotated offsets from the COM
        bx, by = body.real, body.imag
        x = np.add(bx, q[0, :, None], out=self._x)
        pen = np.add(by, q[1, :, None], out=self.penetration)
        pen *= self._side
        pen -= self._level
        if self.walls is not None:
            # Bending walls (core.walls): the depth against the deflected surfaces.
            pen = self.walls.solve(pen, x, contacts, self.law)
        self.depth = pen
        fn, ft = contact_step(contacts, pen, x, self.law)
        forces = self._forces
        # Bottom tips push up (+y), top tips push down: Fy = -side Fn. Row sums as mat-vec
        # products: BLAS is several times faster than sum(axis=1) here.
        side, ones = self._side, self._ones
        np.matmul(fn, side, out=forces[1])
        np.matmul(ft, ones, out=forces[0])
        # Moment about the COM: rx Fy - ry Fx.
        np.multiply(bx, fn, out=self._work)
        m = self._work @ side
        np.multiply(by, ft, out=self._work)
        m += self._work @ ones
        np.negative(m, out=forces[2])
        forces[1] *= -1.0
        np.copyto(self.contact_wrench, forces)
        forces *= self._inv_inertia
        forces += self._bias_dt
        q[3:] += forces
        q[:3] += q[3:] * self.dt
        if self.motor_on:
            if self.profile is not None:
                self.motor.set_voltage(self.profile.voltage(self.phase))
            self._motor_step()
            self.phase += self.omega * self.dt
        else:
            self.phase += self._omega_dt
        np.remainder(self.phase, TWO_PI, out=self.phase)
        self.steps += 1
        # One dot product bounds every speed and catches NaN (the comparison is then False).
        speed = q[3:]
        if not np.vdot(speed, speed) <= MAX_SPEED ** 2 or \
                pen.max() > self._max_penetration_any or \
                (self.walls is not None and (self.walls.largest > self._gap).any()):
            self._check_divergence()

    @property
    def tip_positions(self) -> np.ndarray:
        """World (surface frame) tip positions of the last step, complex x + i y, (S, P)."""
        return cast(np.ndarray,
                    self._x + 1j * (self.penetration * self._side + self._level * self._side))

    def _check_divergence(self) -> None:
        t = self.t
        bad = ~np.isfinite(self.q).all(axis=0)
        if bad.any():
            i = int(np.argmax(bad))
            raise DivergenceError(
                f'simulation diverged at t = {t:.3f} s (scenario {i}): the state became '
                f'non-finite; reduce integration.dt or soften the surfaces')
        fast = np.abs(self.q[3:]).max(axis=0)
        if (fast > MAX_SPEED).any():
            i = int(np.argmax(fast))
            vx, vy, w = self.q[3:, i]
            raise DivergenceError(
                f'simulation diverged at t = {t:.3f} s (scenario {i}): the robot moved at '
                f'({vx:.3g} m/s, {vy:.3g} m/s, {w:.3g} rad/s), beyond {MAX_SPEED:g} m/s or '
                f'rad/s, far outside the model (check the resisting force and slope)')
        too_deep = self.depth - self._max_penetration[:, None]
        i, tip = (int(v) for v in np.unravel_index(np.argmax(too_deep), too_deep.shape))
        if too_deep[i, tip] > 0:
            n = self.table.count // 2
            surface = 'top' if tip >= n else 'bottom'
            raise DivergenceError(
                f'simulation diverged at t = {t:.3f} s (scenario {i}): a tip of link {tip % n} '
                f'pressed {self.depth[i, tip] * 1000:.1f} mm into the {surface} surface, '
                f'deeper than surface.max_penetration = '
                f'{self._max_penetration[i] * 1000:.1f} mm (the robot was pushed through the '
                f'surface: check the slope, resisting force and stiffness, or reduce '
                f'integration.dt)')
        if self.walls is not None:
            # A wall that gives way by more than the gap is no longer a wall of the channel
            # (nor a small deflection of a beam on its foundation): refused, not simulated.
            i = int(np.argmax(self.walls.largest - self._gap))
            if self.walls.largest[i] > self._gap[i]:
                wall = self.scenarios[i].surface
                raise DivergenceError(
                    f'simulation diverged at t = {t:.3f} s (scenario {i}): a wall gave way by '
                    f'{self.walls.largest[i] * 1000:.0f} mm, more than the gap of '
                    f'{self._gap[i] * 1000:.0f} mm: walls this soft do not hold the robot '
                    f'(surface.foundation_stiffness = {wall.foundation_stiffness:g} N/m^2, '
                    f'surface.bending_stiffness = {wall.bending_stiffness:g} N m^2)')

    def run(self, duration: float, record_every: int = 1,
            progress: Optional[Callable[[int], None]] = None,
            contacts: bool = False) -> Trajectory:
        """
        Step for ``duration`` seconds, recording the state every ``record_every`` steps.

        ``progress(n)`` is called with the number of steps done since the last call.
        """
        steps = int(round(duration / self.dt))
        n_rec = steps // record_every + 1
        t = np.empty(n_rec)
        q = np.empty((n_rec, self.count, 6))
        shape = (n_rec, self.count, self.table.count)
        # Any: None when not recorded, and the loop below indexes them only when they are not.
        fn: Any = np.zeros(shape) if contacts else None
        ft: Any = np.zeros(shape) if contacts else None
        omega = np.empty((n_rec, self.count))
        torque: Any = np.empty((n_rec, self.count)) if self.motor_on else None
        current: Any = np.empty((n_rec, self.count)) if self.motor_on else None
        t[0], q[0], omega[0] = self.t, self.q.T, self.omega
        if self.motor_on:
            torque[0], current[0] = self.motor_torque, self.current
        chunk = max(1, steps // 200)
        for k in range(1, steps + 1):
            self.step()
            if k % record_every == 0:
                j = k // record_every
                t[j] = self.t
                q[j] = self.q.T
                omega[j] = self.omega
                if self.motor_on:
                    torque[j], current[j] = self.motor_torque, self.current
                if contacts:
                    fn[j] = self.contacts.normal
                    ft[j] = self.contacts.tangential
            if progress is not None and k % chunk == 0:
                progress(chunk)
        if progress is not None and steps % chunk:
            progress(steps % chunk)
        return Trajectory(t, q, self.scenarios, fn, ft, omega, torque, current)


def _run_chunk(job: Tuple[Sequence[Scenario], float, int, bool]) -> Trajectory:
    scenarios, duration, record_every, contacts = job
    return Simulator(scenarios).run(duration, record_every, None, contacts)


def simulate(scenario: Union[Scenario, Sequence[Scenario]], duration: Optional[float] = None,
             record_every: int = 1, progress: Optional[Callable[[int], None]] = None,
             contacts: bool = False,
             workers: int = 1, pool: Optional[Pool] = None) -> Trajectory:
    """
    Run scenario(s) from the initial state for ``duration`` (default: integration.duration).

    A batch is cut into ``pool.workers`` parts (``core.pool.batches``) run by ``pool``: a
    ``LocalPool(workers)`` unless given, or any pool with the same interface (a Dask cluster).
    The scenarios are independent, so the numbers are those of one process; ``progress`` is then
    called per finished part. One part runs here, whatever the pool.
    """
    scenarios = [scenario] if isinstance(scenario, Scenario) else list(scenario)
    if duration is None:
        duration = scenarios[0].integration.duration
    pool = pool if pool is not None else LocalPool(workers)
    parts = batches(scenarios, pool.workers)
    if len(parts) == 1:
        return Simulator(scenarios).run(duration, record_every, progress, contacts)
    jobs = [(part, duration, record_every, contacts) for part in parts]
    steps = int(round(duration / scenarios[0].integration.dt))
    done = []
    for part in pool.map(_run_chunk, jobs):
        done.append(part)
        if progress is not None:
            progress(steps)

    def cat(name: str) -> Optional[np.ndarray]:
        got = [getattr(p, name) for p in done]
        if all(g is None for g in got):
            return None
        # A part without a motor recorded no torque or current: NaN, as in a mixed batch.
        rows = next(g for g in got if g is not None).shape[0]
        return np.concatenate([np.full((rows, len(p.scenarios)), np.nan) if g is None else g
                               for g, p in zip(got, done)], axis=1)
    return Trajectory(done[0].t, cast(np.ndarray, cat('q')), scenarios, cat('normal'),
                      cat('tangential'), cat('omega'), cat('torque'), cat('current'))
