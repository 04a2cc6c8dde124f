"""
Hold a speed through the camera (issue 22): the speed controller closed around the tracker.

What a lab would do with the real robot: a camera films it, the two-marker tracker measures its
speed, a PI controller (core.drive.SpeedPI, the one the ``speed_controller`` node runs) sets the
motor voltage. Here the camera is the renderer and the robot the core, stepped together offline:
60 frames a second rendered from the simulated state, tracked, and the tracker's smoothed speed
fed back, while the slope steps (0 -> 20 -> -20 degrees by default). The same run at a fixed
voltage (the one that gives the target on the level) is the open-loop comparison.

The error counted is the robot's true speed averaged over each helix turn (the speed ripples
within a turn at the link-passing rate, which no drive of this motor follows: docs/drive.md),
against the target, over each slope's window after ``settle`` seconds.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Dict, List, Optional, Sequence

import numpy as np

from saw_ros.core.drive import SpeedPI
from saw_ros.core.dynamics import Simulator
from saw_ros.core.params import Scenario
from saw_ros.vision.camera import CameraModel, FPS
from saw_ros.vision.frames import Renderer, RobotPose
from saw_ros.vision.tracker import Tracker

TARGET = 0.05                      # m/s
SLOPES_DEG = (0.0, 20.0, -20.0)
SEGMENT_S = 4.0                    # each slope lasts this long
SETTLE_S = 2.0                     # error counted after this much of each segment
KP, KI = 40.0, 80.0                # V per m/s, V per m: docs/drive.md (loop gain ~0.5)
VOLTAGE_LIMITS = (0.0, 12.0)


@dataclass
class HoldResult:
    """Per-slope and overall mean absolute error (% of the target) of the turn-mean speed."""

    feedback: str
    error_pct: float
    per_slope: Dict[float, float]
    t: np.ndarray                  # every step
    speed_turn: np.ndarray         # turn-mean true speed at each turn's end, m/s
    t_turn: np.ndarray
    voltage: np.ndarray            # per step, V
    ok_frames_pct: Optional[float] = None


def voltage_for(scenario: Scenario, target: float) -> float:
    """Return the constant voltage that gives ``target`` on ``scenario``'s slope (secant, core)."""
    def speed(v: float) -> float:
        sim = Simulator(scenario.with_values({'motor.voltage': v}))
        x0 = None
        for k in range(int(5.0 / sim.dt)):
            sim.step()
            if k == int(2.0 / sim.dt):
                x0 = sim.q[0, 0]
        return float((sim.q[0, 0] - x0) / (3.0 - sim.dt))
    v0, v1 = 4.0, 6.0
    s0, s1 = speed(v0), speed(v1)
    for _ in range(4):
        v2 = v1 + (target - s1) * (v1 - v0) / (s1 - s0)
        v0, s0, v1, s1 = v1, s1, v2, speed(v2)
        if abs(s1 / target - 1.0) < 2e-3:
            break
    return v1


def _turn_means(t, x, turns):
    """Mean speed over each whole helix turn: (end times, speeds)."""
    ends = np.searchsorted(turns, np.arange(1, int(turns[-1] / (2 * math.pi)) + 1) * 2 * math.pi)
    ends = ends[ends < len(t)]
    if len(ends) < 2:
        return t[:0], x[:0]
    return t[ends[1:]], np.diff(x[ends]) / np.diff(t[ends])


def hold(feedback: str = 'tracking', target: float = TARGET,
         slopes_deg: Sequence[float] = SLOPES_DEG, segment: float = SEGMENT_S,
         settle: float = SETTLE_S, voltage: Optional[float] = None,
         base: Scenario = Scenario()) -> HoldResult:
    """
    Run the slope steps with ``feedback``: 'tracking' (the camera), 'ground_truth' or 'open_loop'.

    ``voltage``: the feed-forward (and the open loop's fixed) voltage; default: the one that
    gives ``target`` on the first slope.
    """
    first = base.with_values({'conditions.slope': math.radians(slopes_deg[0])})
    if voltage is None:
        voltage = voltage_for(first, target)
    scenario = first.with_values({'motor.voltage': voltage})
    sim = Simulator(scenario)
    pi = SpeedPI(KP, KI, *VOLTAGE_LIMITS, u_ff=voltage)
    camera = CameraModel()
    renderer = renderer_tracker = None
    if feedback == 'tracking':
        renderer = Renderer(scenario.robot, scenario.conditions.gap, camera)
        renderer_tracker = Tracker(camera)
    steps_per_segment = int(round(segment / sim.dt))
    total = steps_per_segment * len(slopes_deg)
    frame_every = 1.0 / FPS
    next_frame = frame_every
    t = np.empty(total)
    x = np.empty(total)
    turns = np.empty(total)
    volts = np.empty(total)
    unwrapped = 0.0
    ok = frames = 0
    last_feedback = None
    for k in range(total):
        if k and k % steps_per_segment == 0:
            slope = math.radians(slopes_deg[k // steps_per_segment])
            sim.set_scenarios([scenario.with_values({'conditions.slope': slope})])
        before = sim.phase[0]
        sim.step()
        unwrapped += (sim.phase[0] - before) % (2 * math.pi)
        t[k], x[k], turns[k] = sim.t, sim.q[0, 0], unwrapped
        volts[k] = sim.motor.voltage[0]
        if feedback == 'open_loop' or sim.t + 1e-9 < next_frame:
            continue
        next_frame += frame_every
        if feedback == 'ground_truth':
            speed = float(sim.q[3, 0])
        else:
            frames += 1
            # A compliant robot's links drawn deflected on their flexures (0 for rigid links).
            pose = RobotPose(float(sim.q[0, 0]), float(sim.q[1, 0]), float(sim.q[2, 0]),
                             float(sim.phase[0]), tuple(sim.deflection[0].tolist()))
            assert renderer is not None and renderer_tracker is not None  # made for 'tracking'
            result = renderer_tracker.update(renderer.render(pose), sim.t)
            ok += result.ok
            if result.velocity_smoothed is None:
                continue            # no speed yet: the command stays (feed-forward)
            speed = float(result.velocity_smoothed.real)
        dt = frame_every if last_feedback is None else sim.t - last_feedback
        last_feedback = sim.t
        sim.command_voltage(pi.update(target, speed, dt))
    t_turn, speed_turn = _turn_means(t, x, turns)
    per_slope = {}
    errors: List[np.ndarray] = []
    for i, slope in enumerate(slopes_deg):
        window = (t_turn > i * segment + settle) & (t_turn <= (i + 1) * segment)
        error = np.abs(speed_turn[window] / target - 1.0) * 100.0
        errors.append(error)
        per_slope[float(slope)] = float(error.mean()) if len(error) else math.nan
    every = np.concatenate(errors)
    return HoldResult(feedback, float(every.mean()) if len(every) else math.nan, per_slope, t,
                      speed_turn, t_turn, volts,
                      100.0 * ok / frames if frames else None)
