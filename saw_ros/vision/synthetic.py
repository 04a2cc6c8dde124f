"""Rendered runs with known answers: the simulation, its frames and the ground truth.

Used by the tests and the benchmark to hold the tracker against the simulator. (The tracker
itself never imports this module or the core.)
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Iterable, Iterator, List, Optional, Tuple

import numpy as np

from ..core import Scenario, simulate
from .camera import CameraModel
from .render import Renderer, RenderOptions, RobotPose, pose_interpolator
from .tracker import FrameResult, Tracker, TrackerConfig


@dataclass
class Run:
    scenario: Scenario
    t: np.ndarray            # simulation times, s (every dt)
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    phase: np.ndarray
    pose_at: Callable[[float], RobotPose]

    def frame_times(self, fps: float = 60.0, start: float = 0.0) -> np.ndarray:
        n = int(math.floor((self.t[-1] - start) * fps + 1e-9))
        return start + np.arange(1, n) / fps

    def mean_speed(self, t_end: float, window: float) -> float:
        """True mean speed over whole wave cycles ending at t_end (the ripple cancels)."""
        f = self.scenario.frequency
        span = math.floor(window * f + 1e-9) / f if f > 0 else window
        return float((np.interp(t_end, self.t, self.x) - np.interp(t_end - span, self.t, self.x))
                     / span)


def simulate_run(scenario: Scenario, duration: float) -> Run:
    traj = simulate(scenario, duration)
    q = traj.q[:, 0]
    f = scenario.frequency
    phase = (2.0 * math.pi * f * traj.t) % (2.0 * math.pi)
    pose_at = pose_interpolator(traj.t, q[:, 0], q[:, 1], q[:, 2], phase)
    return Run(scenario, traj.t, q[:, 0], q[:, 1], q[:, 2], phase, pose_at)


def frames(run: Run, renderer: Renderer, times: Iterable[float],
           hidden: Callable[[int], Tuple[str, ...]] = lambda k: ()) \
        -> Iterator[Tuple[int, float, RobotPose, np.ndarray]]:
    for k, t in enumerate(times):
        pose = run.pose_at(t)
        yield k, t, pose, renderer.render(pose, hidden(k), run.pose_at, t)


@dataclass
class Evaluation:
    results: List[FrameResult]
    position_rms_mm: float      # marker positions, both markers, ok frames
    pitch_error_deg: float      # largest |pitch error| on ok frames
    speed: Optional[float]      # tracker's steady-state speed at the end, m/s
    true_speed: float           # whole-cycle mean speed over the same window, m/s
    speed_error_pct: float
    lost_frames: int
    not_ok_frames: int


def evaluate(run: Run, camera: CameraModel = CameraModel(),
             options: RenderOptions = RenderOptions(), config: TrackerConfig = TrackerConfig(),
             start: float = 0.0, hidden=lambda k: ()) -> Evaluation:
    renderer = Renderer(run.scenario.robot, run.scenario.scenario.gap, camera, options)
    tracker = Tracker(camera, config)
    results, err2, pitch_err = [], [], 0.0
    for k, t, pose, image in frames(run, renderer, run.frame_times(start=start), hidden):
        res = tracker.update(image, t)
        results.append(res)
        if res.ok:
            front, back = renderer.marker_surface(pose)
            err2 += [abs(res.front - front) ** 2, abs(res.back - back) ** 2]
            pitch_err = max(pitch_err, abs(res.pitch - pose.theta))
    last = results[-1]
    true_speed = run.mean_speed(last.t, config.steady_window)
    speed = last.steady_speed
    err = abs(speed - true_speed) / abs(true_speed) * 100.0 if speed is not None else math.inf
    return Evaluation(results, 1000.0 * math.sqrt(np.mean(err2)) if err2 else math.inf,
                      math.degrees(pitch_err), speed, true_speed, err,
                      tracker.counters.front_lost + tracker.counters.back_lost,
                      tracker.counters.frames - tracker.counters.ok)
