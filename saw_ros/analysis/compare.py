"""
Simulation against tracking (paper Section 6.4.2): AR of both, and their relative error.

Pure numpy, no rclpy: the comparison node, the campaign and the tests share it.

Steady state is detected on the simulator's ground-truth forward velocity with the core's CCI
(under 2 % from then on, for at least one cycle). The velocity is a 10 ms centred difference of the
position resampled on a regular grid: a subscriber that lost a few of the 1 kHz samples then
still sees the same signal, where differences across a gap would average the ~25 Hz ripple and
keep the CCI above 2 %. Both mean speeds are then measured over the same
window, from the steady-state start over a whole number of wave cycles (the ripple cancels), the
tracked one by interpolating its 60 Hz positions at the window's ends.

When a motor turns the helix (docs/motor.md) its speed is an outcome and ripples within a
cycle: given the helix's angle (``add_helix``: the simulator's /saw/joint_states, or a
trajectory's recorded speed), a cycle is one helix turn, and v_theory takes the mean helix
frequency over the window (core.metrics).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
import math
from pathlib import Path
from typing import List, Optional

import numpy as np

from saw_ros.core.kinematics import v_theory
from saw_ros.core.metrics import STEADY_CCI, steady_state_start, TURN
from saw_ros.core.params import RobotParams


class _GrowingColumns:
    """A growing (t, value...) record, amortised O(1) appends."""

    def __init__(self, columns: int):
        self._data = np.empty((1024, columns))
        self.size = 0

    def append(self, *row: float) -> None:
        if self.size == len(self._data):
            self._data = np.concatenate([self._data, np.empty_like(self._data)])
        self._data[self.size] = row
        self.size += 1

    def column(self, i: int) -> np.ndarray:
        return self._data[:self.size, i]

    def clear(self) -> None:
        self.size = 0

    def drop_before(self, t: float) -> None:
        """Forget the rows older than ``t`` (column 0), keeping the rest in order."""
        first = int(np.searchsorted(self.column(0), t))
        if first:
            self._data[:self.size - first] = self._data[first:self.size]
            self.size -= first


@dataclass
class Comparison:
    """One report. While not steady only ``status`` and the counts mean something."""

    status: str                       # 'waiting for data' | 'not steady yet' | 'steady'
    frequency: float = float('nan')   # Hz
    v_theory: float = float('nan')    # m/s
    steady_from: float = float('nan')  # s of simulated time
    window_s: float = float('nan')    # length of the measuring window, s
    v_sim: float = float('nan')       # m/s
    v_tracked: float = float('nan')   # m/s
    ar_sim: float = float('nan')
    ar_tracked: float = float('nan')
    relative_error: float = float('nan')   # |AR_tracked - AR_sim| / AR_sim
    truth_samples: int = 0
    tracked_samples: int = 0

    @property
    def steady(self) -> bool:
        return self.status == 'steady'

    def why_not(self, simulated_s: float) -> str:
        """
        Return why there is no comparison after ``simulated_s`` s, in words ('' when steady).

        A report reads this instead of printing the nan its speeds then hold.
        """
        if self.steady:
            return ''
        if not self.frequency > 0:
            return 'the helix did not turn (0 Hz): there is no wave cycle to measure over'
        if not math.isfinite(self.steady_from):
            return (f'the simulated speed did not settle (cycle-to-cycle change of vx under '
                    f'{100 * STEADY_CCI:g} %) within the {simulated_s:g} s simulated at '
                    f'{self.frequency:.2f} Hz')
        return (f'the simulated speed settled at {self.steady_from:.2f} s, less than one whole '
                f'wave cycle with tracked frames before the end of the {simulated_s:g} s '
                f'simulated')


VELOCITY_WINDOW = 0.010   # s


def velocity_on_grid(t: np.ndarray, x: np.ndarray, window: float = VELOCITY_WINDOW):
    """
    Return (grid, v) of a sampled position: x resampled every median sample interval.

    v is the centred difference of the resampled x over ``window``.
    """
    step = float(np.median(np.diff(t)))
    grid = np.arange(t[0] + window / 2, t[-1] - window / 2 + 1e-12, step)
    v = (np.interp(grid + window / 2, t, x) - np.interp(grid - window / 2, t, x)) / window
    return grid, v


# Simulated seconds of samples a RunComparator keeps: the comparison needs a steady window of
# whole cycles, not the run's history. A node left running would otherwise grow by 16 bytes per
# pose (1 kHz) and helix sample (measured: 87 -> 104 MB over 300 s) and redo each report over all
# of it. 60 s is 60 wave cycles at the default 1 Hz, and about 2 MB at 1 kHz.
KEEP_S = 60.0


class RunComparator:
    """
    Collects ground truth and tracked positions, and compares them on demand.

    Ground truth is x and vx at the simulator's rate, tracking x at the camera's rate, both
    against simulated time. Only the last ``keep_s`` simulated seconds are kept (trimmed once
    the record is half as long again): the steady window is then found within them, so on a
    longer run the comparison is over its last ``keep_s`` seconds at most.
    """

    def __init__(self, robot: RobotParams, frequency: float = float('nan'),
                 threshold: float = STEADY_CCI, min_cycles: float = 1.0,
                 keep_s: float = KEEP_S):
        self.robot = robot
        self.frequency = frequency
        self.threshold = threshold
        self.min_cycles = min_cycles
        self.keep_s = keep_s
        self.truth = _GrowingColumns(2)
        self.tracked = _GrowingColumns(2)
        self.helix = _GrowingColumns(2)          # t, unwrapped helix angle (rad)

    def reset(self) -> None:
        self.truth.clear()
        self.tracked.clear()
        self.helix.clear()

    def add_helix(self, t: float, angle: float) -> None:
        """
        Take the helix angle (rad) at simulated time ``t``: wrapped to [0, 2 pi) or not.

        It is unwrapped here (the helix turns less than half a turn between two samples).
        """
        if self.helix.size:
            last_t, last = self.helix.column(0)[-1], self.helix.column(1)[-1]
            if t <= last_t:
                if t < last_t:
                    self.helix.clear()             # a reset of the simulation
                    self.helix.append(t, angle)
                return
            angle = last + (angle - last + math.pi) % TURN - math.pi
        self.helix.append(t, angle)

    def add_truth(self, t: float, x: float) -> None:
        if self.truth.size and t <= self.truth.column(0)[-1]:
            if t < self.truth.column(0)[-1]:      # time went back: a reset of the simulation
                self.reset()
            else:
                return
        self.truth.append(t, x)
        if t - self.truth.column(0)[0] > 1.5 * self.keep_s:
            cutoff = t - self.keep_s
            self.truth.drop_before(cutoff)
            # Tracking and helix a second longer: the window's start is interpolated in them.
            self.tracked.drop_before(cutoff - 1.0)
            self.helix.drop_before(cutoff - 1.0)

    def add_tracked(self, t: float, x: float) -> None:
        if not math.isfinite(x):
            return                                 # a frame without a position: skip it
        if self.tracked.size and t <= self.tracked.column(0)[-1]:
            if t < self.tracked.column(0)[-1]:
                self.tracked.clear()
            return
        self.tracked.append(t, x)

    def result(self) -> Comparison:
        n_truth, n_tracked = self.truth.size, self.tracked.size
        counts = {'truth_samples': n_truth, 'tracked_samples': n_tracked}
        f = self.frequency
        if not (f > 0) or n_truth < 10:
            return Comparison('waiting for data', frequency=f, **counts)
        t, x = self.truth.column(0), self.truth.column(1)
        grid, v = velocity_on_grid(t, x)
        turns = None
        if self.helix.size >= 2:
            ht, angle = self.helix.column(0), self.helix.column(1)
            # (a subscriber may have started following the helix after the pose)
            followed = grid >= ht[0]
            grid, v = grid[followed], v[followed]
            if len(grid) < 10:
                return Comparison('not steady yet', **counts)
            half = self.helix.size // 2
            f = float((angle[-1] - angle[half]) / (TURN * (ht[-1] - ht[half])))
            turns = np.interp(grid, ht, angle)
            if not (f > 0):
                return Comparison('not steady yet', frequency=f, **counts)
        start = steady_state_start(grid, v, f, self.threshold, self.min_cycles, turns)
        vth = v_theory(self.robot, f)
        if start is None:
            return Comparison('not steady yet', frequency=f, v_theory=vth, **counts)
        tt, xt = self.tracked.column(0), self.tracked.column(1)
        end = min(t[-1], tt[-1]) if n_tracked >= 2 else start
        if turns is None:
            cycles = math.floor((end - start) * f + 1e-9)
        else:
            first, last = np.interp([start, end], ht, angle)
            cycles = math.floor((last - first) / TURN + 1e-9)
        if cycles < 1 or tt[0] > start:
            return Comparison('not steady yet', frequency=f, v_theory=vth, steady_from=start,
                              **counts)
        if turns is None:
            end = start + cycles / f
        else:
            # Whole helix turns, at the helix's mean frequency over them.
            end = float(np.interp(first + cycles * TURN, angle, ht))
            f = cycles / (end - start)
            vth = v_theory(self.robot, f)
        v_sim = float(np.diff(np.interp([start, end], t, x))[0] / (end - start))
        v_tracked = float(np.diff(np.interp([start, end], tt, xt))[0] / (end - start))
        ar_sim, ar_tracked = v_sim / vth, v_tracked / vth
        return Comparison('steady', f, vth, start, end - start, v_sim, v_tracked, ar_sim,
                          ar_tracked, abs(ar_tracked - ar_sim) / abs(ar_sim), **counts)


# -- measured reference data ------------------------------------------------------------------
@dataclass
class ReferencePoint:
    """A measured result: slope (deg) and voltage (V) with a speed (m/s) and/or an AR."""

    slope_deg: float
    voltage: float
    speed: Optional[float]
    advance_ratio: Optional[float]
    source: str


def load_reference(path: Path) -> List[ReferencePoint]:
    """
    Return the points of a reference CSV of measured speeds or advance ratios.

    Columns slope_deg, voltage_V, and speed_cm_s and/or advance_ratio (either may be empty),
    plus an optional source; lines starting with # are comments.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f'reference file {path} does not exist')
    with open(path, newline='') as f:
        rows = [line for line in f if line.strip() and not line.lstrip().startswith('#')]
    reader = csv.DictReader(rows)
    needed = {'slope_deg', 'voltage_V'}
    if not reader.fieldnames or not needed <= set(reader.fieldnames) or not (
            {'speed_cm_s', 'advance_ratio'} & set(reader.fieldnames)):
        raise ValueError(f'{path}: needs columns slope_deg, voltage_V and speed_cm_s and/or '
                         f'advance_ratio; found {reader.fieldnames}')

    def number(text):
        text = (text or '').strip()
        return float(text) if text else None

    points = []
    for i, row in enumerate(reader, start=2):
        try:
            speed = number(row.get('speed_cm_s'))
            ar = number(row.get('advance_ratio'))
            if speed is None and ar is None:
                raise ValueError('it has neither speed_cm_s nor advance_ratio')
            points.append(ReferencePoint(float(row['slope_deg']), float(row['voltage_V']),
                                         None if speed is None else speed / 100.0, ar,
                                         (row.get('source') or '').strip()))
        except (TypeError, ValueError) as exc:
            raise ValueError(f'{path}: row {i} is not valid: {exc}') from None
    return points


def find_reference(points: List[ReferencePoint], slope_deg: float,
                   voltage: float) -> Optional[ReferencePoint]:
    for p in points:
        if abs(p.slope_deg - slope_deg) < 0.5 and abs(p.voltage - voltage) < 0.05:
            return p
    return None


def reference_error(point: ReferencePoint, v_sim: float, vth: float) -> float:
    """Relative error of the simulation against a measurement, on AR (or speed: the same)."""
    if point.advance_ratio is not None:
        measured_ar = point.advance_ratio
    elif point.speed is not None:
        measured_ar = point.speed / vth
    else:
        raise ValueError(f'reference point {point.source}: neither a speed nor an AR')
    return abs(v_sim / vth - measured_ar) / abs(measured_ar)
