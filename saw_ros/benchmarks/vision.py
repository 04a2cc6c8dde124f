"""Issue 4 figures: tracker and renderer frames per second at 1280x720, and the tracker's
accuracy on clean rendered frames at the defaults against the simulation's ground truth."""
import time

from ..core import Scenario
from ..vision.camera import CameraModel
from ..vision.render import Renderer
from ..vision.synthetic import evaluate, simulate_run
from ..vision.tracker import Tracker

KEYS = ('tracker_fps', 'render_fps', 'tracker_position_rms_mm', 'tracker_speed_error_pct',
        'tracker_pitch_error_deg')


def run(quick: bool = False) -> dict:
    scenario = Scenario()
    sim_run = simulate_run(scenario, 6.1)
    camera = CameraModel()
    renderer = Renderer(scenario.robot, scenario.scenario.gap, camera)
    n = 60 if quick else 240
    times = [2.0 + k / 60 for k in range(n)]
    poses = [sim_run.pose_at(t) for t in times]
    renderer.render(poses[0])
    start = time.perf_counter()
    frames = [renderer.render(p) for p in poses]
    render_fps = n / (time.perf_counter() - start)
    tracker = Tracker(camera)
    start = time.perf_counter()
    for t, f in zip(times, frames):
        tracker.update(f, t)
    tracker_fps = n / (time.perf_counter() - start)
    ev = evaluate(sim_run, camera, start=2.0)
    return {'tracker_fps': round(tracker_fps, 1), 'render_fps': round(render_fps, 1),
            'tracker_position_rms_mm': round(ev.position_rms_mm, 4),
            'tracker_speed_error_pct': round(ev.speed_error_pct, 4),
            'tracker_pitch_error_deg': round(ev.pitch_error_deg, 4)}
