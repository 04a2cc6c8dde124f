"""
Outputs of a run (paper Section 5): v_theory, mean velocity, AR, CCI and steady state.

Pure functions of sampled signals, so that the simulator's 1 kHz ground truth and the tracker's
60 fps estimates go through the same code.

CCI(t) = |v(t) - v(t + T)| / |v_avg|, T = 1/f: how much a velocity differs from itself one wave
cycle later (the paper's "cyclic convergence index"). When a motor turns the helix its speed
ripples within a cycle, and "one cycle later" is one helix turn later: given the helix's turns
(its unwrapped angle per sample, ``helix_turns``), the CCI, the steady state and the averaging
window follow the helix instead of the clock. (At 4 V, climbing, the clock's T = 1 / mean f lands
a few ms off the next turn, and the ~25 Hz ripple then keeps the CCI near 10 %.)

For the forward velocity v_avg is its steady mean. The normal and pitch velocities average to
about zero, which would make the index meaningless, so they are scaled by their RMS over the
steady part instead (our choice; the paper does not say).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Dict, List, Optional, Tuple, TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core.kinematics import v_theory
from saw_ros.core.params import RobotParams

if TYPE_CHECKING:     # dynamics imports this module
    from saw_ros.core.dynamics import Trajectory

STEADY_CCI = 0.02   # the paper's first convergence threshold (2 %)
TURN = 2.0 * math.pi


def cci(t: ArrayLike, v: ArrayLike, frequency: float, scale: Optional[float] = None,
        turns: Optional[ArrayLike] = None) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return (times, CCI) for every sample with a full cycle after it.

    ``scale`` defaults to |mean v| over the last two cycles (the steady part of a run that
    converged). ``turns``: the helix angle (rad, unwrapped) per sample; a cycle is then one turn
    of it, else 1 / ``frequency``.

    v(t + T) is interpolated in time, so samples may be irregular or missing (a subscriber that
    lost messages, a tracker that lost a frame).
    """
    t = np.asarray(t, float)
    v = np.asarray(v, float)
    if frequency <= 0:
        raise ValueError('CCI needs a wave frequency above 0')
    period = 1.0 / frequency
    if turns is None:
        usable = t <= t[-1] - period + 1e-9 if len(t) else t.astype(bool)
    else:
        turns = np.asarray(turns, float)
        usable = turns <= turns[-1] - TURN + 1e-9 if len(t) else t.astype(bool)
    if not usable.any():
        return t[:0], v[:0]
    if scale is None:
        scale = abs(float(np.mean(v[t >= t[-1] - 2 * period])))
    if turns is None:
        later = np.interp(t[usable] + period, t, v)
    else:
        later = np.interp(np.interp(turns[usable] + TURN, turns, t), t, v)
    return t[usable], np.abs(later - v[usable]) / max(scale, 1e-12)


def rms_scale(v: ArrayLike, t: ArrayLike, frequency: float) -> float:
    """Return the RMS of ``v`` over the last two cycles (the scale of a ripple around 0)."""
    t = np.asarray(t, float)
    tail = np.asarray(v, float)[t >= t[-1] - 2.0 / frequency]
    return float(np.sqrt(np.mean(tail ** 2)))


def velocity_cci(t: ArrayLike, q: np.ndarray, frequency: float,
                 turns: Optional[ArrayLike] = None) -> Tuple[np.ndarray, Dict[str, np.ndarray]]:
    """
    Return (times, {'vx', 'vy', 'w': CCI}) of the velocities of q (n, 6) = x, y, theta, vx, vy, w.

    Vx scaled by its steady mean, vy and w by their steady RMS (module docstring).
    """
    indices: Dict[str, np.ndarray] = {}
    for name, col in (('vx', 3), ('vy', 4), ('w', 5)):
        scale = None if col == 3 else rms_scale(q[:, col], t, frequency)
        tc, indices[name] = cci(t, q[:, col], frequency, scale, turns)
    return tc, indices


def settling_time(t: np.ndarray, index: ArrayLike, threshold: float) -> Optional[float]:
    """Return the first time after which the index stays below ``threshold`` (None: never)."""
    index = np.asarray(index)
    if len(index) == 0:
        return None
    above = np.nonzero(index >= threshold)[0]
    if len(above) == 0:
        return float(t[0])
    last = above[-1]
    if last + 1 >= len(index):
        return None
    return float(t[last + 1])


def steady_state_start(t: ArrayLike, v: ArrayLike, frequency: float, threshold: float = STEADY_CCI,
                       min_cycles: float = 1.0,
                       turns: Optional[ArrayLike] = None) -> Optional[float]:
    """
    Return the start of steady state: the CCI of the forward velocity stays low from there on.

    Low is under ``threshold``, with at least ``min_cycles`` cycles of evidence after it. None
    while not steady. ``turns``: as ``cci``.
    """
    tc, index = cci(t, v, frequency, turns=turns)
    start = settling_time(tc, index, threshold)
    if start is None or len(tc) == 0 or tc[-1] - start < min_cycles / frequency - 1e-9:
        return None
    return start


def cycle_window(t: ArrayLike, start: float, frequency: float,
                 turns: Optional[ArrayLike] = None) -> Tuple[int, int]:
    """
    Return the first and last sample (i0, i1) of the whole wave cycles from ``start``.

    The cycles run to the end of the record, or the window is all of it when it is shorter than
    a cycle. ``turns``: the helix angle per sample, whose whole turns are then the cycles.
    """
    t = np.asarray(t, float)
    span = t[-1] - start
    if turns is not None:
        turns = np.asarray(turns, float)
        first = float(np.interp(start, t, turns))
        whole = math.floor((turns[-1] - first) / TURN + 1e-9)
        if whole >= 1:
            span = float(np.interp(first + whole * TURN, turns, t)) - start
    elif frequency > 0 and span * frequency >= 1.0:
        span = math.floor(span * frequency + 1e-9) / frequency
    i0 = int(np.searchsorted(t, start - 1e-12))
    i1 = int(np.searchsorted(t, start + span - 1e-9))
    i1 = min(i1, len(t) - 1)
    if i1 <= i0:
        raise ValueError('need at least two samples after the start to measure a velocity')
    return i0, i1


def mean_velocity(t: ArrayLike, x: ArrayLike, start: float, frequency: float) -> float:
    """Return the mean velocity from ``start`` over whole wave cycles (the ripple cancels)."""
    t = np.asarray(t, float)
    x = np.asarray(x, float)
    i0, i1 = cycle_window(t, start, frequency)
    return float((x[i1] - x[i0]) / (t[i1] - t[i0]))


def helix_turns(t: ArrayLike, omega: ArrayLike) -> np.ndarray:
    """
    Return the helix angle (rad, unwrapped, 0 at the first sample) from its speed (rad/s).

    Sample k holds the speed of the step that ended there (``Trajectory.omega``), so the angle
    is exact when every step is recorded.
    """
    t = np.asarray(t, float)
    omega = np.asarray(omega, float)
    return np.concatenate([[0.0], np.cumsum(omega[1:] * np.diff(t))])


def helix_frequency(t: np.ndarray, turns: np.ndarray, i0: int, i1: int) -> float:
    """Return the mean helix frequency (Hz) between samples i0 and i1 of helix angle ``turns``."""
    return float((turns[i1] - turns[i0]) / (TURN * (t[i1] - t[i0])))


@dataclass
class RunMetrics:
    """What a run measured; SI units (m/s, s)."""

    frequency: float
    v_theory: float
    v_mean: float
    advance_ratio: float
    steady_from: Optional[float]        # s, CCI of vx under 2 % from here on
    cci_2pct_after: Optional[float]     # s, every velocity's CCI under 2 %
    cci_02pct_after: Optional[float]    # s, every velocity's CCI under 0.2 %


def analyse(t: ArrayLike, q: ArrayLike, robot: RobotParams, frequency: float,
            min_cycles: float = 1.0, omega: Optional[ArrayLike] = None) -> RunMetrics:
    """
    Return the metrics of one recorded run: t (n,), q (n, 6) = x, y, theta, vx, vy, w.

    The mean velocity is taken from the steady-state start (or from the middle of the run if it
    never settled, flagged by steady_from = None) to the end over whole cycles.

    ``omega`` (n,): the helix speed (rad/s, ``Trajectory.omega``) of a run a motor drove, whose
    frequency is an outcome: ``frequency`` (the no-load one) is then ignored, the cycles are
    helix turns (module docstring), and v_theory and AR use the mean helix frequency over the
    averaging window (AR = v / (wavelength f_actual) in the paper's terms), which
    ``RunMetrics.frequency`` reports.
    """
    t = np.asarray(t, float)
    q = np.asarray(q, float)
    turns = None
    if omega is not None:
        turns = helix_turns(t, omega)
        frequency = helix_frequency(t, turns, len(t) // 2 - 1, len(t) - 1)
    if frequency <= 0:
        v = mean_velocity(t, q[:, 0], t[0], 0.0)
        return RunMetrics(frequency, v_theory(robot, frequency), v, float('nan'), None, None,
                          None)
    start = steady_state_start(t, q[:, 3], frequency, min_cycles=min_cycles, turns=turns)
    from_t = start if start is not None else t[len(t) // 2]
    i0, i1 = cycle_window(t, from_t, frequency, turns)
    v = float((q[i1, 0] - q[i0, 0]) / (t[i1] - t[i0]))
    if turns is not None:
        frequency = helix_frequency(t, turns, i0, i1)
    vth = v_theory(robot, frequency)
    tc, indices = velocity_cci(t, q, frequency, turns)
    settled: Dict[float, Optional[float]] = {}
    for threshold in (0.02, 0.002):
        times = [settling_time(tc, index, threshold) for index in indices.values()]
        known: List[float] = [x for x in times if x is not None]
        settled[threshold] = max(known) if len(known) == len(times) else None
    ar = v / vth if vth > 0 else float('nan')
    return RunMetrics(frequency, vth, v, ar, start, settled[0.02], settled[0.002])


def run_frequency(trajectory: 'Trajectory', i: int = 0) -> float:
    """
    Return the helix frequency (Hz) scenario ``i`` of a ``Trajectory`` ran at.

    That is conditions.frequency, or, where a motor drove the helix, its mean over the second
    half of the record (past the spin-up): what v_theory and AR of a motor run are taken against.
    """
    scenario = trajectory.scenarios[i]
    if scenario.motor.voltage <= 0.0 or trajectory.omega is None:
        return scenario.frequency
    n = len(trajectory.t)
    return helix_frequency(trajectory.t, run_turns(trajectory, i), n // 2 - 1, n - 1)


def run_turns(trajectory: 'Trajectory', i: int = 0) -> np.ndarray:
    """Return the helix angle (rad, unwrapped, 0 at start) of scenario ``i`` per sample."""
    if trajectory.omega is None:
        raise ValueError('the trajectory holds no helix speed (omega): simulate() records it')
    return helix_turns(trajectory.t, trajectory.omega[:, i])


def analyse_run(trajectory: 'Trajectory', i: int = 0, min_cycles: float = 1.0) -> RunMetrics:
    """Return the metrics of scenario ``i`` of a ``Trajectory``, against its helix's speed."""
    scenario = trajectory.scenarios[i]
    omega = trajectory.omega if scenario.motor.voltage > 0.0 else None
    return analyse(trajectory.t, trajectory.q[:, i], scenario.robot, scenario.frequency,
                   min_cycles, omega[:, i] if omega is not None else None)
