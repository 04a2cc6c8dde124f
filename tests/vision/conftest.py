"""Runs and trackers the vision tests share."""
import pytest

from saw_ros.core import Scenario
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.frames import Renderer
from saw_ros.vision.synthetic import simulate_run
from saw_ros.vision.tracker import Tracker


@pytest.fixture(scope='session')
def level_run():
    """Return 6.1 s of the default level run (simulated once for every vision test)."""
    return simulate_run(Scenario(), 6.1)


@pytest.fixture
def mirrored_tracking(level_run):
    """
    Return (renderer, tracker) after 20 frames of the level run seen by a mirrored camera.

    Every frame of the warm-up is checked: both markers measured within 0.3 mm.
    """
    s = Scenario()
    cam = CameraModel(mirror=True, center_x=0.1)
    r = Renderer(s.robot, s.conditions.gap, cam)
    tracker = Tracker(cam)
    for k in range(20):
        t = 2.0 + k / 60
        pose = level_run.pose_at(t)
        res = tracker.update(r.render(pose), t)
        front, back = r.marker_surface(pose)
        assert res.ok and abs(res.front - front) < 3e-4 and abs(res.back - back) < 3e-4
    return r, tracker
