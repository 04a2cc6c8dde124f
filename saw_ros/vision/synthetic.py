"""
Rendered runs with known answers: the simulation, its frames and the ground truth.

Used by the tests and the benchmark to hold the tracker against the simulator. (The tracker
itself never imports this module or the core.) ``cluttered_scene`` and ``hard_footage`` make the
footage that does not look like the renderer's: clutter including third pink markers, lighting,
noise, blur, lens distortion and compression.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
import os
import tempfile
from typing import Callable, cast, Iterable, Iterator, List, Optional, Tuple

import numpy as np

from saw_ros.core import Scenario, simulate, Simulator, Trajectory
from saw_ros.core.metrics import run_turns, TURN
from saw_ros.vision import compressed
from saw_ros.vision.camera import CameraModel, FPS
from saw_ros.vision.frames import pose_interpolator, Renderer, RenderOptions, RobotPose
from saw_ros.vision.scene import Clutter, HOT_PINK, MAGENTA, ORANGE, ORANGE_RED, RED, SceneOptions
from saw_ros.vision.tracker import FrameResult, Tracker, TrackerConfig
from saw_ros.vision.video import read_frames, VideoWriter


@dataclass
class Run:
    scenario: Scenario
    t: np.ndarray            # simulation times, s (every dt)
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    phase: np.ndarray
    pose_at: Callable[[float], RobotPose]
    trajectory: Optional[Trajectory] = None     # the simulation itself
    # A compliant robot's links on their flexures (Simulator.deflection): times (s) and the
    # deflections (N, n links), m; None for rigid links.
    deflection_t: Optional[np.ndarray] = None
    deflection: Optional[np.ndarray] = None

    def frame_times(self, fps: float = FPS, start: float = 0.0) -> np.ndarray:
        n = int(math.floor((self.t[-1] - start) * fps + 1e-9))
        return start + np.arange(1, n) / fps

    def mean_speed(self, t_end: float, window: float) -> float:
        """Return True mean speed over whole wave cycles ending at t_end (the ripple cancels)."""
        f = self.scenario.frequency
        span = math.floor(window * f + 1e-9) / f if f > 0 else window
        return float((np.interp(t_end, self.t, self.x) - np.interp(t_end - span, self.t, self.x))
                     / span)


DEFLECTION_PERIOD = 1e-3    # s between two samples of a compliant robot's link deflections


def simulate_run(scenario: Scenario, duration: float) -> Run:
    """
    Simulate ``scenario`` for ``duration`` s: the run and its ``pose_at`` for the renderer.

    A compliant robot (flexure.stiffness > 0) is run in pieces of DEFLECTION_PERIOD, its links'
    deflections taken after each (the same steps, so the same trajectory as one run), and its
    frames draw them.
    """
    if scenario.flexure.stiffness > 0:
        traj, deflection_t, deflection = _flexing_run(scenario, duration)
    else:
        traj, deflection_t, deflection = simulate(scenario, duration), None, None
    q = traj.q[:, 0]
    # The helix's own angle: a motor (motor.voltage > 0) turns it slower, and unevenly.
    phase = np.remainder(run_turns(traj), TURN)
    pose_at = pose_interpolator(traj.t, q[:, 0], q[:, 1], q[:, 2], phase, deflection_t,
                                deflection)
    return Run(scenario, traj.t, q[:, 0], q[:, 1], q[:, 2], phase, pose_at, traj,
               deflection_t, deflection)


def _flexing_run(scenario: Scenario, duration: float) \
        -> Tuple[Trajectory, np.ndarray, np.ndarray]:
    """Return the trajectory, and the links' deflections every DEFLECTION_PERIOD with times."""
    sim = Simulator(scenario)
    steps = int(round(duration / sim.dt))
    every = max(1, int(round(DEFLECTION_PERIOD / sim.dt)))
    pieces: List[Trajectory] = []
    times, deflections = [0.0], [sim.deflection[0].copy()]
    done = 0
    while done < steps:
        n = min(every, steps - done)
        piece = sim.run(n * sim.dt)
        # Each piece starts with the state the last one ended in: that row once.
        pieces.append(piece if not pieces else _after_first(piece))
        done += n
        times.append(float(piece.t[-1]))
        deflections.append(sim.deflection[0].copy())

    def joined(name: str) -> Optional[np.ndarray]:
        parts = [getattr(p, name) for p in pieces]
        return None if parts[0] is None else np.concatenate(parts)
    traj = Trajectory(joined('t'), joined('q'), pieces[0].scenarios, None, None, joined('omega'),
                      joined('torque'), joined('current'))
    return traj, np.array(times), np.array(deflections)


def _after_first(piece: Trajectory) -> Trajectory:
    """Return ``piece`` without its first sample (the one the piece before ended with)."""
    def cut(a: Optional[np.ndarray]) -> Optional[np.ndarray]:
        return None if a is None else a[1:]
    return Trajectory(cut(piece.t), cut(piece.q), piece.scenarios, None, None, cut(piece.omega),
                      cut(piece.torque), cut(piece.current))


def frames(run: Run, renderer: Renderer, times: Iterable[float],
           hidden: Callable[[int], Tuple[str, ...]] = lambda k: ()) \
        -> Iterator[Tuple[int, float, RobotPose, np.ndarray]]:
    """
    (index, time, true pose, frame) of each frame time.

    With the scene's compression 'mp4' the whole run goes through an .mp4 file (codec mp4v) and
    back first.
    """
    times = list(times)
    if renderer.scene.compression != 'mp4':
        for k, t in enumerate(times):
            pose = run.pose_at(t)
            yield k, t, pose, renderer.render(pose, hidden(k), run.pose_at, t)
        return
    cam = renderer.camera
    fd, path = tempfile.mkstemp(suffix='.mp4')
    os.close(fd)
    try:
        with VideoWriter(path, FPS, (cam.width, cam.height)) as writer:
            for k, t in enumerate(times):
                writer.write(renderer.render(run.pose_at(t), hidden(k), run.pose_at, t))
        for (k, _, frame), t in zip(read_frames(path), times):
            yield k, t, run.pose_at(t), frame
    finally:
        os.unlink(path)


def cluttered_scene(run: Run, camera: CameraModel = CameraModel(), compression: str = 'jpeg',
                    quality: int = 70, cross_at: float = 3.0) -> SceneOptions:
    """
    Return the hard case for a run of the default scenario, seen by ``camera``.

    The robot goes from x = 0 towards +x at about 5 cm/s. Red, orange-red and orange objects are
    in the corners (the orange one moving, in front of everything), two magenta discs of a
    marker's size (one on the wall above the track, one drifting against the robot on the top
    board, 42 px above the marker line), and three more hot-pink markers: one behind the robot on
    its line, one ahead of it on its line (out of the robot's reach in 6.5 s) and one moving up
    through the picture in front of the robot that crosses the marker line 25 px behind the back
    marker at ``cross_at`` s (inside the back marker's gate for about 35 frames). Lighting gradient
    +-35 % and 10 % flicker at 100 Hz; compression as given.
    """
    x0, x1 = camera.visible_x_range(0.0)
    gap = run.scenario.conditions.gap
    mid = gap / 2.0
    marker = (0.012, 0.012)
    pose = run.pose_at(cross_at)
    back = pose.x - 0.16 * math.cos(pose.theta)
    lift = 0.09                                    # m/s, the crossing marker's speed up
    things = (
        Clutter(RED, x0 + 0.09, mid + 0.19, (0.09, 0.09)),
        Clutter(ORANGE_RED, x1 - 0.10, mid + 0.19, (0.12, 0.07), 'box'),
        Clutter(ORANGE_RED, x1 - 0.12, mid - 0.20, (0.05, 0.05)),
        Clutter(ORANGE, x0 + 0.10, mid - 0.19, (0.06, 0.06), velocity=(0.04, 0.0),
                layer='front'),
        Clutter(MAGENTA, 0.10, gap + 0.07, marker),
        Clutter(MAGENTA, 0.45, mid + 0.035, marker, velocity=(-0.03, 0.0)),
        Clutter(HOT_PINK, x0 + 0.018, mid, marker),
        Clutter(HOT_PINK, 0.16 + 0.50, mid, marker),
        Clutter(HOT_PINK, back - 0.021, mid - lift * cross_at, marker,
                velocity=(0.0, lift), layer='front'),
    )
    return SceneOptions(clutter=things, gradient=0.35, gradient_angle=math.radians(30),
                        flicker=0.10, compression=compression, quality=quality)


def hard_footage(run: Run, compression: str = 'jpeg', quality: int = 70, cross_at: float = 3.0):
    """
    (camera, render options, scene) of the hard case.

    ``cluttered_scene``, sensor noise 6, motion blur over 1/60 s and a barrel lens distortion (k1 =
    -0.12: 30 px at the corners), whose calibration the tracker is given (it is the camera's).
    """
    camera = CameraModel(dist_coeffs=(-0.12, 0.02, 0.0005, -0.0008, 0.0))
    options = RenderOptions(noise=6.0, exposure=1 / 60, seed=11)
    return camera, options, cluttered_scene(run, camera, compression, quality, cross_at)


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
    visible_frames: int = 0     # frames on which both markers are in full view (ground truth)
    ok_visible_frames: int = 0  # ... and the tracker measured both
    wrong_frames: int = 0       # ok frames with a marker more than 2 mm from the truth

    @property
    def ok_frames_pct(self) -> float:
        """Frames with both markers measured, % of those where both are in full view."""
        return 100.0 * self.ok_visible_frames / self.visible_frames if self.visible_frames \
            else 0.0


def evaluate(run: Run, camera: CameraModel = CameraModel(),
             options: RenderOptions = RenderOptions(), config: TrackerConfig = TrackerConfig(),
             start: float = 0.0, hidden=lambda k: (), scene: SceneOptions = SceneOptions(),
             tracker_camera: Optional[CameraModel] = None, end: Optional[float] = None,
             jpeg_quality: Optional[int] = None, reduced: int = 1) -> Evaluation:
    """
    Render the run from ``start`` (to ``end``, default the run's end) and track it.

    The tracker sees ``tracker_camera`` (default: the rendering camera, so it knows the lens).
    ``jpeg_quality``: each frame goes through a JPEG of that quality first, decoded at
    1 / ``reduced`` of its size, as the vision node takes the camera's compressed stream.
    """
    renderer = Renderer(run.scenario.robot, run.scenario.conditions.gap, camera, options, scene)
    tracker = Tracker(tracker_camera or camera, config)
    radius = options.marker_radius
    margin = (radius + 0.002) * camera.scale
    results, err2, pitch_err = [], [], 0.0
    visible = ok_visible = wrong = 0
    times = run.frame_times(start=start)
    if end is not None:
        times = times[times <= end + 1e-9]
    for k, t, pose, image in frames(run, renderer, times, hidden):
        if jpeg_quality is not None:
            image = compressed.decode(compressed.JPEG_FORMAT,
                                      compressed.encode_jpeg(image, jpeg_quality), reduced)[0]
        res = tracker.update(image, t, 1 if jpeg_quality is None else reduced)
        results.append(res)
        truth = renderer.marker_surface(pose)
        pixels = renderer.marker_pixels(pose)
        seen = all(name not in hidden(k) and margin <= p.real <= camera.width - 1 - margin
                   and margin <= p.imag <= camera.height - 1 - margin
                   and not scene.occluded(m, t, radius)
                   for name, p, m in zip(('front', 'back'), pixels, truth))
        visible += seen
        if res.ok:
            ok_visible += seen
            front, back = truth
            e = (abs(res.front - front), abs(res.back - back))
            wrong += max(e) > 0.002
            err2 += [e[0] ** 2, e[1] ** 2]
            pitch_err = max(pitch_err, abs(cast(float, res.pitch) - pose.theta))   # ok: measured
    last = results[-1]
    true_speed = run.mean_speed(last.t, config.steady_window)
    speed = last.steady_speed
    err = abs(speed - true_speed) / abs(true_speed) * 100.0 if speed is not None else math.inf
    return Evaluation(results, 1000.0 * math.sqrt(np.mean(err2)) if err2 else math.inf,
                      math.degrees(pitch_err), speed, true_speed, err,
                      tracker.counters.front_lost + tracker.counters.back_lost,
                      tracker.counters.frames - tracker.counters.ok, visible, ok_visible, wrong)
