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

from collections import deque
from dataclasses import dataclass
import functools
import math
import os
import threading
from typing import Any, Callable, cast, Optional, Sequence, Tuple, TYPE_CHECKING, Union

import numba
import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core import stability
from saw_ros.core.contact import ContactLaw, ContactState, NORMAL, OFFSET_X, OFFSET_Y, Param
from saw_ros.core.contact import PENETRATION, press_tips, SEEN, TANGENTIAL, X
from saw_ros.core.drive import FREQUENCY_LIMIT, PhaseProfile, VOLTAGE_LIMIT
from saw_ros.core.dynamic_walls import dynamic, DynamicWalls, load_walls, ON, SETTINGS
from saw_ros.core.dynamic_walls import swing_walls, TABLE
from saw_ros.core.flexure import DEFLECTION as FLEX_DEFLECTION, flex_advance, flex_links
from saw_ros.core.flexure import FLEX_ON, flex_restore, FLEX_ROWS, flex_walls, FLEX_WORK_ROWS
from saw_ros.core.flexure import flexure_constants
from saw_ros.core.flexure import RATE as FLEX_RATE
from saw_ros.core.jit import CACHE
from saw_ros.core.kinematics import check_no_interference, TipRateTable, TipTable
from saw_ros.core.motor import MOTOR_FIELDS, MotorLaw, TORQUE_CONSTANT, turn_helix
from saw_ros.core.params import ParameterError, PLACEMENT_SHARE, RobotParams, Scenario
from saw_ros.core.pool import batches, LocalPool, Pool
from saw_ros.core.tips import place_tips, turned_table_value
from saw_ros.core.walls import ACTIVE, bend_walls, kernel, LARGEST, WALL_FIELDS, WALL_ROWS
from saw_ros.core.walls import Walls, WORK_ROWS

if TYPE_CHECKING:
    from concurrent.futures import ThreadPoolExecutor

GRAVITY = 9.81  # m/s^2
TWO_PI = 2.0 * math.pi
# Faster than this (m/s, or rad/s of pitch) the state left the model: the fastest wave allowed
# (5 Hz) drives the robot at 0.35 m/s, and a robot thrown by a tether force (external_force
# 1e9 N sent it to x = -4.8e10 m) or falling through a surface moves orders of magnitude faster.
MAX_SPEED = 100.0

# Columns of a scenario's state (Simulator.body[s]): the pose x, y, theta and its rates vx, vy,
# w (m, rad, m/s, rad/s), the helix phase (rad) and speed (rad/s), the net contact force and
# moment of the last step (surface axes, N, N m), the motor's torque at the helix, current,
# load torque and friction met (N m, A; NaN without a motor), the motor's voltage (V, the
# profile's at this phase when one feeds it), the state of the last kernel call (0 stepped on,
# DIVERGED, RUNAWAY) and the steps it made.
POSE_X, POSE_Y, THETA, VX, VY, W, PHASE, OMEGA = range(8)
FX, FY, MZ, MOTOR_TORQUE, CURRENT, LOAD_TORQUE, FRICTION_TORQUE, VOLTAGE = range(8, 16)
STATUS, DONE = 16, 17
BODY_FIELDS = 18
DIVERGED, RUNAWAY = 1, 2
# Columns of a scenario's constants (Simulator.constants[s]): surface.max_penetration and the
# gap (m), dt / mass and dt / inertia, the constant accelerations (gravity, tether) times dt
# along x and y (m/s), the constant helix's turn per step (rad), 1 where a motor drives the
# helix, the speed of a constant helix (rad/s), the runaway speed (rad/s), 1 where any scenario
# of the batch has a motor, 1 while a voltage profile feeds it.
MAX_PENETRATION, GAP, MASS_DT, INERTIA_DT, BIAS_X, BIAS_Y, OMEGA_DT = range(7)
DRIVEN, CONSTANT_OMEGA, RUNAWAY_SPEED, MOTOR_ON, PROFILED = range(7, 12)
CONSTANT_FIELDS = 12
# Columns of the recorded trace: the pose and its rates, helix speed, motor torque, current.
TRACE_FIELDS = 9
# Scenario-steps in one call from which a batch spread over threads is faster (bench/core.py).
PARALLEL_WORK = 2048
# Parts of a batch a thread (``spread``): enough for the threads to even out, few calls.
PARTS_PER_THREAD = 4


@numba.njit(cache=CACHE)
def profile_voltage(phase: float, harmonics: np.ndarray, drive: np.ndarray) -> float:
    """
    Return a voltage profile's V at the helix phase (core.drive.PhaseProfile.voltage; kernel).

    ``drive``: the mean voltage, the top of the range, then the relative cos and sin
    coefficients of the ``harmonics``.
    """
    k = len(harmonics)
    shape = 1.0
    for h in range(k):
        angle = phase * harmonics[h]
        shape += math.cos(angle) * drive[2 + h] + math.sin(angle) * drive[2 + k + h]
    return float(min(max(drive[0] * shape, 0.0), drive[1]))


# Compiled as the wall kernels are (core.walls.kernel: without numba's reference counts): it
# allocates nothing, and its calls kept numba from pruning the counts of its eight arrays, an
# atomic increment and decrement of six of them at every step (one thread's batch 3.6 -> 4.3 M
# scenario-steps per CPU second without them).
@kernel
def move_body(dt: float, side: np.ndarray, rates: np.ndarray, scale: float,
              harmonics: np.ndarray, drive: np.ndarray, motor: np.ndarray, constants: np.ndarray,
              body: np.ndarray, tips: np.ndarray) -> int:
    """
    Finish one scenario's step from its tips' contact forces (compiled kernel).

    The net force and moment about the COM, semi-implicit Euler of the body, then the helix:
    the motor against the load torque of the contacts, or its constant speed. Returns 0, or
    DIVERGED / RUNAWAY (the step left the model: the caller says why).
    """
    fx = fy = moment = 0.0
    for p in range(tips.shape[1]):
        # Bottom tips push up (+y), top tips push down: Fy = -side Fn. Moment: rx Fy - ry Fx.
        fn, ft = tips[NORMAL, p] * side[p], tips[TANGENTIAL, p]
        fx += ft
        fy -= fn
        moment -= tips[OFFSET_X, p] * fn + tips[OFFSET_Y, p] * ft
    body[FX], body[FY], body[MZ] = fx, fy, moment
    phase = body[PHASE]
    motor_on = constants[MOTOR_ON] > 0.0
    load = 0.0
    if motor_on:
        # tau_load = -sum F . dr/dphase, F = (Ft, -side Fn) on the tip, dr/dphase the tip's
        # rate (body frame, from the table) turned by the pitch the forces were found at.
        cos, sin = math.cos(body[THETA]), math.sin(body[THETA])
        for p in range(tips.shape[1]):
            rx, ry = turned_table_value(rates, scale, phase, p, cos, sin)
            load += tips[NORMAL, p] * ry * side[p] - tips[TANGENTIAL, p] * rx
    body[VX] += fx * constants[MASS_DT] + constants[BIAS_X]
    body[VY] += fy * constants[MASS_DT] + constants[BIAS_Y]
    body[W] += moment * constants[INERTIA_DT]
    body[POSE_X] += body[VX] * dt
    body[POSE_Y] += body[VY] * dt
    body[THETA] += body[W] * dt
    if motor_on:
        if constants[PROFILED] > 0.0:
            body[VOLTAGE] = profile_voltage(phase, harmonics, drive)
        if constants[DRIVEN] > 0.0:
            omega, torque, friction = turn_helix(body[OMEGA], load, body[VOLTAGE], motor)
        else:
            omega, torque, friction = constants[CONSTANT_OMEGA], math.nan, math.nan
        body[MOTOR_TORQUE], body[CURRENT] = torque, torque / motor[TORQUE_CONSTANT]
        body[LOAD_TORQUE], body[FRICTION_TORQUE] = load, friction
        body[OMEGA] = omega
        runaway = not abs(omega) <= constants[RUNAWAY_SPEED]
        phase += omega * dt
    else:
        runaway = False
        phase += constants[OMEGA_DT]
    if not runaway:
        body[PHASE] = phase % (2.0 * math.pi)
    # Non-finite states fail every comparison. One return, after every check: an early one
    # keeps numba from dropping the reference counts of the arrays (atomic operations).
    deepest = constants[MAX_PENETRATION]
    inside = True
    for p in range(tips.shape[1]):
        inside &= tips[SEEN, p] <= deepest
    for i in range(VX, W + 1):
        inside &= abs(body[i]) <= MAX_SPEED
    for i in range(POSE_X, THETA + 1):
        inside &= math.isfinite(body[i])
    return RUNAWAY if runaway else 0 if inside else DIVERGED


@numba.njit(cache=CACHE)
def advance_scenario(s: int, steps: int, first: int, every: int, dt: float, scale: float,
                     side: np.ndarray, table: np.ndarray, rates: np.ndarray,
                     harmonics: np.ndarray, drive: np.ndarray, law: np.ndarray,
                     motor: np.ndarray, constants: np.ndarray, walls: np.ndarray,
                     wall_state: np.ndarray, wall_modes: np.ndarray, flex: np.ndarray,
                     flex_state: np.ndarray, body: np.ndarray, tips: np.ndarray,
                     trace: np.ndarray, trace_tips: np.ndarray) -> None:
    """
    Advance scenario ``s`` by ``steps`` steps: tips, walls, contact law, body, helix (kernel).

    Walls with mass or damping (core.dynamic_walls, ``wall_modes[s]`` on) are solved by
    ``swing_walls`` and stepped under the law's forces by ``load_walls``, quasi-static ones
    solved by ``bend_walls``.

    With link flexures (core.flexure, ``flex[s]`` on): the links' deflections enter the depths
    the law sees, and the body gets the flexures' reactions; with bending walls too (either
    kind), ``flex_walls`` solves the walls and the links together.

    Records the state into ``trace`` (and the tips' forces into ``trace_tips`` when it has
    rows) after every step whose number since the run's start (``first`` + k) is a multiple of
    ``every``; stops at a step that leaves the model, with body[s, STATUS] saying why and
    body[s, DONE] the steps made.
    """
    # The scenario's rows, taken once: a row taken inside the loop costs two atomic reference
    # counts a step each (numba's NRT), some 12 % of a rigid step for three of them.
    b, c, t, wc = body[s], constants[s], tips[s], walls[s]
    ls, ds, ms, ws, wm = law[s], drive[s], motor[s], wall_state[s], wall_modes[s]
    bending = wc[ACTIVE] > 0.0
    swinging = bending and wall_modes[s, SETTINGS, ON] > 0.0
    fc, fs = flex[s], flex_state[s]
    flexing = fc[FLEX_ON] > 0.0
    n = tips.shape[2] // 2
    work = np.empty((0, 0))
    if bending:
        work = (np.empty((FLEX_WORK_ROWS + 4 * n, 2 * n)) if flexing else
                np.empty((WORK_ROWS + 2 * n, n)))
    b[STATUS] = 0.0
    for k in range(1, steps + 1):
        place_tips(table, scale, side, b, b[PHASE], c[GAP], t)
        if bending and flexing:
            flex_walls(ls, wc, ws, wm, swinging, fc, fs, t, work)
        elif swinging:
            swing_walls(ls, wc, ws, wm, t, work)
        elif bending:
            bend_walls(ls, wc, ws, t, work)
        elif flexing:
            flex_links(ls, fc, fs, t)
        press_tips(ls, t)
        if swinging:
            load_walls(wc, ws, wm, t)
        if flexing:
            flex_advance(fc, fs, t)
        status = move_body(dt, side, rates, scale, harmonics, ds, ms, c, b, t)
        if flexing:
            flex_restore(fs, t)
        # A wall that gives way by more than the gap is no longer a wall of the channel.
        if status == 0 and bending and wc[LARGEST] > c[GAP]:
            status = DIVERGED
        if status != 0:
            b[STATUS] = status
            b[DONE] = k - 1 if status == RUNAWAY else k
            return
        n = first + k
        if n % every == 0:
            j = n // every
            for i in range(W + 1):
                trace[j, s, i] = b[i]
            trace[j, s, 6] = b[OMEGA]
            trace[j, s, 7] = b[MOTOR_TORQUE]
            trace[j, s, 8] = b[CURRENT]
            if trace_tips.shape[0] > 0:
                # Element by element: an assignment of rows compiles numba's shape checks with
                # their messages, 1.8 s of the cold start.
                for p in range(t.shape[1]):
                    trace_tips[j, 0, s, p] = t[NORMAL, p]
                    trace_tips[j, 1, s, p] = t[TANGENTIAL, p]
    b[DONE] = steps


@numba.njit(cache=CACHE, nogil=True)
def advance(start: int, stop: int, steps: int, first: int, every: int, dt: float, scale: float,
            side: np.ndarray, table: np.ndarray, rates: np.ndarray, harmonics: np.ndarray,
            drive: np.ndarray, law: np.ndarray, motor: np.ndarray, constants: np.ndarray,
            walls: np.ndarray, wall_state: np.ndarray, wall_modes: np.ndarray, flex: np.ndarray,
            flex_state: np.ndarray, body: np.ndarray, tips: np.ndarray, trace: np.ndarray,
            trace_tips: np.ndarray) -> None:
    """
    Advance scenarios ``start`` to ``stop`` - 1 by ``steps`` each, one after the other (kernel).

    Without the GIL: the threads of ``spread`` run parts of one batch at once (the scenarios
    write no state they share).
    """
    for s in range(start, stop):
        advance_scenario(s, steps, first, every, dt, scale, side, table, rates, harmonics,
                         drive, law, motor, constants, walls, wall_state, wall_modes, flex,
                         flex_state, body, tips, trace, trace_tips)


# The helper threads of ``spread``, made at the first batch a process spreads; a forked child
# (LocalPool) makes its own, threads do not survive a fork: (process id, threads, executor).
_helpers: Optional[Tuple[int, int, ThreadPoolExecutor]] = None
_helpers_lock = threading.Lock()


def helper_threads(count: int) -> ThreadPoolExecutor:
    """Return this process's pool of at least ``count`` helper threads."""
    global _helpers
    # Imported here: 6 ms of every start of the simulator node, which never spreads a batch.
    from concurrent.futures import ThreadPoolExecutor
    with _helpers_lock:
        if _helpers is None or _helpers[0] != os.getpid() or _helpers[1] < count:
            _helpers = (os.getpid(), count,
                        ThreadPoolExecutor(count, thread_name_prefix='saw_ros_core'))
        return _helpers[2]


def spread(count: int, threads: int, arguments: Tuple[Any, ...]) -> None:
    """
    Run ``advance`` over scenarios 0 to ``count`` - 1 on ``threads`` threads, this one among them.

    The batch is cut into PARTS_PER_THREAD parts a thread, each taken by whichever thread is
    free: scenarios differ in cost (bending walls take two to three rigid steps; a scenario
    that leaves the model stops), so a fixed share each would leave a thread waiting. Python
    threads, not numba's prange: a prange kernel compiles the whole step a second time (some
    10 of the cold start's 26 s of CPU), for no more scenario-steps (docs/core.md).
    """
    size = -(-count // (threads * PARTS_PER_THREAD))
    parts = deque((a, min(a + size, count)) for a in range(0, count, size))

    def work() -> None:
        while True:
            try:
                start, stop = parts.popleft()            # atomic: no lock needed
            except IndexError:
                return
            advance(start, stop, *arguments)

    helpers = [helper_threads(threads - 1).submit(work) for _ in range(threads - 1)]
    try:
        work()
    finally:
        parts.clear()                                   # an error here stops the helpers too
        for helper in helpers:
            helper.result()


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
        # The state the kernels advance, one row per scenario (module constants name the
        # columns; the attributes below are views of it).
        self.contacts = ContactState(self.count, tips)
        self.tips = self.contacts.tips
        self.body = np.zeros((self.count, BODY_FIELDS))
        self.constants = np.zeros((self.count, CONSTANT_FIELDS))
        self.q = self.body[:, POSE_X:W + 1].T            # x, y, theta, vx, vy, w: (6, S)
        self.phase = self.body[:, PHASE]
        self.omega = self.body[:, OMEGA]                 # helix speed, rad/s
        # The motor of the last step, per scenario (NaN where no motor drives the helix): torque
        # k i at the helix (N m), current (A), the load torque of the contacts and the friction
        # torque it met (N m).
        self.motor_torque = self.body[:, MOTOR_TORQUE]
        self.current = self.body[:, CURRENT]
        self.load_torque = self.body[:, LOAD_TORQUE]
        self.friction_torque = self.body[:, FRICTION_TORQUE]
        self.steps = 0
        # Net contact force (fx, fy, surface axes, N) and moment about the COM (N m) of the last
        # step, per scenario: what the step accelerated the body with.
        self.contact_wrench = self.body[:, FX:MZ + 1].T
        self._x = self.tips[:, X]                               # world tip abscissae, m
        self.penetration = self.tips[:, PENETRATION]            # > 0 inside a surface, m
        # What the contact law sees: the penetration, less the bending walls' deflection.
        self.depth = self.tips[:, SEEN]
        self._side = self.table.side
        self._no_trace = np.zeros((0, 2, self.count, tips))
        self._step_trace = np.zeros((2, self.count, TRACE_FIELDS))
        self._motor_rows = np.zeros((self.count, MOTOR_FIELDS))
        self._rates = np.zeros((2, 2, tips), complex)       # the rate table, with a motor
        self._harmonics = np.zeros(0)
        self._drive = np.zeros((self.count, 2))
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
        self._law_rows = self.law.rows(self.count)
        self._max_penetration = np.array([s.surface.max_penetration for s in scenarios])
        # Bending walls where any scenario has them (core.walls); None: rigid, as the paper's.
        # New parameters start the walls from the last forces' shape again at the next step
        # (walls with mass go on moving, or start at rest in that shape: DynamicWalls.carry).
        before = getattr(self, 'walls', None)
        self.walls = (Walls(scenarios, self.table.side)
                      if any(s.surface.foundation_stiffness > 0.0 for s in scenarios) else None)
        self._wall_modes = np.zeros((self.count, TABLE, 1))
        if any(dynamic(s) for s in scenarios):
            self.walls = DynamicWalls(scenarios, self.table.side, self.dt)
            self._wall_modes = self.walls.modes
        if self.walls is not None:
            self.walls.tip_x = self._x
        if isinstance(self.walls, DynamicWalls) and before is not None:
            self.walls.carry(before)
        if self.walls is not None:
            self._walls, self._wall_state = self.walls.constants, self.walls.state
        else:
            self._walls = np.zeros((self.count, WALL_FIELDS))
            self._wall_state = np.zeros((self.count, WALL_ROWS, 2, self.table.count // 2))
        # Link flexures (core.flexure, docs/compliant_robot.md); their state lives on across
        # new parameters, as the body's does, and starts at rest where they are switched on.
        flex = flexure_constants([s.flexure for s in scenarios], self.dt)
        if not hasattr(self, '_flex_state'):
            self._flex_state = np.zeros((self.count, FLEX_ROWS, self.table.count // 2))
        else:
            was_on: np.ndarray = self._flex[:, FLEX_ON] > 0.0
            self._flex_state[(flex[:, FLEX_ON] > 0.0) & ~was_on] = 0.0
        self._flex: np.ndarray = flex
        gap = np.array([[s.conditions.gap] for s in scenarios])
        self._gap = gap[:, 0]
        side = self.table.side
        # penetration = side * (y - level): top surface at y = gap, bottom at y = 0.
        self._level = np.where(side > 0, gap, 0.0) * side           # (S, P)
        self._omega_dt = np.array([TWO_PI * s.frequency * self.dt for s in scenarios])
        if self.commanded_frequency is not None:
            self._omega_dt = TWO_PI * self.commanded_frequency * self.dt
        mass = np.array([s.robot.mass for s in scenarios])
        inertia = np.array([s.robot.inertia for s in scenarios])
        slope = np.array([c.slope for c in cond])
        f_ext = np.array([c.external_force for c in cond])
        c = self.constants
        c[:, MAX_PENETRATION] = self._max_penetration
        c[:, GAP] = self._gap
        c[:, MASS_DT] = (1.0 / mass) * self.dt
        c[:, INERTIA_DT] = (1.0 / inertia) * self.dt
        # Constant accelerations (gravity, tether) times dt.
        c[:, BIAS_X] = (-GRAVITY * np.sin(slope) - f_ext / mass) * self.dt
        c[:, BIAS_Y] = -GRAVITY * np.cos(slope) * self.dt
        c[:, OMEGA_DT] = self._omega_dt
        self._set_motor(scenarios)

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
        self.body[:, FX:MZ + 1] = 0.0
        self.body[:, STATUS:] = 0.0
        self.contacts.reset()
        self._flex_state[:] = 0.0
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
        c = self.constants
        c[:, DRIVEN] = self.driven
        c[:, CONSTANT_OMEGA] = self._omega_dt / self.dt
        c[:, MOTOR_ON] = self.motor_on
        if not self.motor_on:
            c[:, PROFILED] = 0.0
            return
        self.rate_table = tip_rate_table(self.robot)
        self._rates = self.rate_table.stacked
        self.motor = MotorLaw([s.motor for s in scenarios], self.dt)
        # The kernels read and the profile writes the voltage here: MotorLaw's is a view.
        self.body[:, VOLTAGE] = self.motor.voltage
        self.motor.voltage = self.body[:, VOLTAGE]
        self._motor_rows = self.motor.rows()
        self._constant_omega = self._omega_dt / self.dt
        if self.commanded_voltage is not None:
            self.motor.set_voltage(self.commanded_voltage)
        self._set_profile_rows()
        self._set_runaway()

    def _set_runaway(self) -> None:
        # A helix faster than this was driven by something no surface can supply.
        ideal = np.abs(self.motor.ideal)
        if self.profile is not None:
            ideal = np.maximum(ideal, TWO_PI * self.motor.hz_per_volt * self.profile.peak)
        self._runaway = 5.0 * (ideal + self._constant_omega) + 1.0
        self.constants[:, RUNAWAY_SPEED] = self._runaway

    def _set_profile_rows(self) -> None:
        """Give the kernels the voltage profile: mean, top, cos and sin coefficients."""
        profile = self.profile
        self.constants[:, PROFILED] = profile is not None
        if profile is None:
            return
        self._harmonics = np.ascontiguousarray(profile.harmonics, dtype=float)
        self._drive = np.ascontiguousarray(np.column_stack(
            [profile.mean, np.full(self.count, profile.v_max), profile.cos, profile.sin]))

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
        self.constants[:, OMEGA_DT] = self._omega_dt
        self.constants[:, CONSTANT_OMEGA] = self._omega_dt / self.dt
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
        self._set_profile_rows()
        if profile is None:
            self.command_voltage(self.commanded_voltage)
        else:
            self._set_runaway()

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
    def _kernel_arguments(self) -> Tuple[Any, ...]:
        return (self.dt, self.table.scale, self._side, self.table.stacked, self._rates,
                self._harmonics, self._drive, self._law_rows, self._motor_rows, self.constants,
                self._walls, self._wall_state, self._wall_modes, self._flex, self._flex_state,
                self.body, self.tips)

    def step(self) -> None:
        """One semi-implicit Euler step of every scenario (one kernel call)."""
        self._advance(1, 0, 1, self._step_trace, self._no_trace)

    def _advance(self, steps: int, first: int, every: int, trace: np.ndarray,
                 trace_tips: np.ndarray) -> None:
        """Advance every scenario ``steps`` steps in one kernel call."""
        arguments = (steps, first, every, *self._kernel_arguments(), trace, trace_tips)
        # Spread over the cores when there is enough to share (waking a thread costs more than
        # one scenario's step), and from the main thread only: a thread of a pool (Dask's
        # workers) already has its share of the cores. numba.set_num_threads says how many.
        threads = 1
        if (self.count > 1 and self.count * steps >= PARALLEL_WORK
                and threading.current_thread() is threading.main_thread()):
            threads = min(numba.get_num_threads(), self.count)
        if threads > 1:
            spread(self.count, threads, arguments)
        else:
            advance(0, self.count, *arguments)
        self._finish(steps)

    def _finish(self, steps: int) -> None:
        """Count the steps made; raise DivergenceError where a scenario left the model."""
        status = self.body[:, STATUS]
        if not status.any():
            self.steps += steps
            return
        # The scenario that left first (the lowest index among equals), at the time it did.
        done = np.where(status != 0, self.body[:, DONE], np.inf)
        i = int(np.argmin(done))
        self.steps += int(done[i])
        if status[i] == RUNAWAY:
            raise DivergenceError(
                f'simulation diverged at t = {self.t:.3f} s (scenario {i}): the helix turned at '
                f'{self.omega[i] / TWO_PI:.3g} Hz, far beyond the no-load speed of its motor, '
                f'{self.motor.ideal[i] / TWO_PI:.3g} Hz (load torque '
                f'{self.load_torque[i]:.3g} N m); reduce integration.dt or soften the surfaces')
        self._check_divergence(i)

    @property
    def deflection(self) -> np.ndarray:
        """
        Each wave link's deflection from its kinematic target after the last step, m, (S, n).

        The link flexures' e (core.flexure, + up: away from the bottom wall); 0 for rigid links,
        also where a scenario's flexures were switched off (their state is kept, not stepped).
        """
        return self._flexing(FLEX_DEFLECTION)

    @property
    def deflection_rate(self) -> np.ndarray:
        """Return each wave link's deflection rate e' after the last step, m/s, (S, n)."""
        return self._flexing(FLEX_RATE)

    def _flexing(self, row: int) -> np.ndarray:
        on = self._flex[:, FLEX_ON, None] > 0.0
        return np.where(on, self._flex_state[:, row], 0.0)

    @property
    def tip_positions(self) -> np.ndarray:
        """
        World (surface frame) tip positions of the last step, complex x + i y, (S, P).

        Where the contact law pressed them: a link on a flexure moves both its tips by its
        deflection along the walls' normal (core.flexure: the depths the law sees).
        """
        y = self.penetration * self._side + self._level * self._side
        return cast(np.ndarray, self._x + 1j * (y + np.tile(self.deflection, 2)))

    def _check_divergence(self, i: int) -> None:
        """Raise DivergenceError saying how scenario ``i`` left the model."""
        t = self.t
        if not np.isfinite(self.q[:, i]).all():
            raise DivergenceError(
                f'simulation diverged at t = {t:.3f} s (scenario {i}): the state became '
                f'non-finite; reduce integration.dt or soften the surfaces')
        vx, vy, w = self.q[3:, i]
        if max(abs(vx), abs(vy), abs(w)) > MAX_SPEED:
            raise DivergenceError(
                f'simulation diverged at t = {t:.3f} s (scenario {i}): the robot moved at '
                f'({vx:.3g} m/s, {vy:.3g} m/s, {w:.3g} rad/s), beyond {MAX_SPEED:g} m/s or '
                f'rad/s, far outside the model (check the resisting force and slope)')
        tip = int(np.argmax(self.depth[i]))
        if self.depth[i, tip] > self._max_penetration[i]:
            n = self.table.count // 2
            surface = 'top' if tip >= n else 'bottom'
            raise DivergenceError(
                f'simulation diverged at t = {t:.3f} s (scenario {i}): a tip of link {tip % n} '
                f'pressed {self.depth[i, tip] * 1000:.1f} mm into the {surface} surface, '
                f'deeper than surface.max_penetration = '
                f'{self._max_penetration[i] * 1000:.1f} mm (the robot was pushed through the '
                f'surface: check the slope, resisting force and stiffness, or reduce '
                f'integration.dt)')
        if self.walls is not None and self.walls.largest[i] > self._gap[i]:
            # A wall that gives way by more than the gap is no longer a wall of the channel
            # (nor a small deflection of a beam on its foundation): refused, not simulated.
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

        ``progress(n)`` is called with the number of steps done since the last call. The steps
        run inside the kernel: one call a run, or about 200 with ``progress``.
        """
        steps = int(round(duration / self.dt))
        n_rec = steps // record_every + 1
        trace = np.full((n_rec, self.count, TRACE_FIELDS), np.nan)
        trace_tips = (np.zeros((n_rec, 2, self.count, self.table.count)) if contacts
                      else self._no_trace)
        start = self.steps
        self._record(trace, 0)
        chunk = max(1, steps // 200) if progress is not None else max(1, steps)
        done = 0
        while done < steps:
            n = min(chunk, steps - done)
            self._advance(n, done, record_every, trace, trace_tips)
            done += n
            if progress is not None:
                progress(n)
        t = (start + np.arange(n_rec) * record_every) * self.dt
        q = np.ascontiguousarray(trace[:, :, :6])
        omega = np.ascontiguousarray(trace[:, :, 6])
        torque = np.ascontiguousarray(trace[:, :, 7]) if self.motor_on else None
        current = np.ascontiguousarray(trace[:, :, 8]) if self.motor_on else None
        fn = np.ascontiguousarray(trace_tips[:, 0]) if contacts else None
        ft = np.ascontiguousarray(trace_tips[:, 1]) if contacts else None
        return Trajectory(t, q, self.scenarios, fn, ft, omega, torque, current)

    def _record(self, trace: np.ndarray, row: int) -> None:
        trace[row, :, :6] = self.q.T
        trace[row, :, 6] = self.omega
        trace[row, :, 7] = self.motor_torque
        trace[row, :, 8] = self.current


@functools.lru_cache(maxsize=1)
def warm_up() -> None:
    """
    Compile the step's kernels into the disk cache (core.jit), or load them: once a process.

    One scenario stepped once (``advance``: the simulator node's path) and a batch of two, one
    with bending walls and a motor, long enough to be spread over threads (the same kernel).
    scripts/bootstrap.sh calls it after installing, LocalPool before it forks.
    """
    Simulator(Scenario()).step()
    bending = Scenario().with_values({'surface.foundation_stiffness': 1.5e5,
                                      'motor.voltage': 6.0})
    Simulator([Scenario(), bending]).run(PARALLEL_WORK * Scenario().integration.dt)


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
