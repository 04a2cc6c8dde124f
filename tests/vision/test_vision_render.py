"""The renderer and camera model: pixels consistent with K, markers where the renderer says."""
import math

import numpy as np
import pytest

from saw_ros.core import Scenario
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.frames import PINK, Renderer, RenderOptions, RobotPose
from saw_ros.vision.tracker import detect

POSE = RobotPose(0.05, 0.0225, math.radians(1.5), 1.0)


def test_camera_round_trip_and_intrinsics():
    cam = CameraModel(slope=math.radians(20), center_x=0.1, mirror=False)
    pts = np.array([0.0 + 0.01j, 0.3 + 0.04j, -0.2 - 0.01j])
    assert np.allclose(cam.to_surface(cam.to_pixels(pts)), pts, atol=1e-12)
    # A level camera sees the surface x axis climb at the slope (image v decreases).
    d = cam.to_pixels(np.array([0.1j, 1.0 + 0.1j]))
    assert math.degrees(math.atan2(-(d[1] - d[0]).imag, (d[1] - d[0]).real)) == pytest.approx(20)
    K = cam.K
    assert K[0, 0] == K[1, 1] == pytest.approx(cam.scale * cam.distance)
    assert (K[0, 2], K[1, 2]) == ((1280 - 1) / 2, (720 - 1) / 2)
    again = CameraModel.from_intrinsics(K, 1280, 720, cam.distance, slope=cam.slope,
                                        center_x=0.1)
    assert np.allclose(again.to_pixels(pts), cam.to_pixels(pts))
    assert cam.with_fov(cam.horizontal_fov).scale == pytest.approx(cam.scale)
    mirrored = CameraModel(mirror=True)
    assert np.allclose(mirrored.to_surface(mirrored.to_pixels(pts)), pts)


def test_frame_shape_and_markers_drawn_where_reported():
    s = Scenario()
    r = Renderer(s.robot, s.conditions.gap, CameraModel())
    img = r.render(POSE)
    assert img.shape == (720, 1280, 3) and img.dtype == np.uint8
    front, back = r.marker_pixels(POSE)
    for p in (front, back):
        assert tuple(img[int(round(p.imag)), int(round(p.real))]) == PINK
    found = sorted(detect(img), key=lambda c: -c.u)
    assert len(found) == 2
    assert abs(found[0].p - front) < 0.05 and abs(found[1].p - back) < 0.05
    f_s, b_s = r.marker_surface(POSE)
    assert abs(0.5 * (f_s + b_s) - complex(POSE.x, POSE.y)) < 1e-12   # midpoint = COM


def test_hidden_marker_and_realism_options():
    s = Scenario()
    clean = Renderer(s.robot, s.conditions.gap, CameraModel()).render(POSE, hidden=('front',))
    assert len(detect(clean)) == 1
    dim = Renderer(s.robot, s.conditions.gap, CameraModel(),
                   RenderOptions(brightness=0.6, texture=False)).render(POSE)
    bright = Renderer(s.robot, s.conditions.gap, CameraModel(),
                      RenderOptions(brightness=1.4, texture=False)).render(POSE)
    assert dim.mean() < clean.mean() < bright.mean()
    base = Renderer(s.robot, s.conditions.gap, CameraModel(), RenderOptions(texture=False))
    noisy = Renderer(s.robot, s.conditions.gap, CameraModel(),
                     RenderOptions(noise=10, texture=False, seed=3))
    diff = noisy.render(POSE).astype(float) - base.render(POSE).astype(float)
    inside = (base.render(POSE) > 30) & (base.render(POSE) < 225)     # away from saturation
    assert np.std(diff[inside]) == pytest.approx(10, rel=0.1)
    # Motion blur: the exposure is centred on the frame time.
    moving = lambda t: POSE._replace(x=POSE.x + 0.06 * t)  # noqa: E731
    blur = Renderer(s.robot, s.conditions.gap, CameraModel(), RenderOptions(exposure=1 / 60))
    img = blur.render(moving(0.0), (), moving, 0.0)
    found = sorted(detect(img), key=lambda c: -c.u)
    front, _ = blur.marker_pixels(moving(0.0))
    assert abs(found[0].p - front) < 0.1


def test_render_is_fast_enough_smoke():
    """Not the benchmark (bench measures render_fps): a loose guard against regressions."""
    import time
    s = Scenario()
    r = Renderer(s.robot, s.conditions.gap, CameraModel())
    r.render(POSE)
    start = time.perf_counter()
    for k in range(30):
        r.render(POSE._replace(phase=0.1 * k))
    assert 30 / (time.perf_counter() - start) > 50
