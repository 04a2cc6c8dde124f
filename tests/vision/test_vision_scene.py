"""
Footage that does not look like the renderer's (saw_ros.vision.scene).

Clutter, lighting, lens distortion and compression are drawn as asked, and the camera's lens model
round-trips.
"""
import math

import numpy as np
import pytest

from saw_ros.core import Scenario
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.frames import PINK, Renderer, RenderOptions, RobotPose
from saw_ros.vision.scene import Clutter, HOT_PINK, ORANGE_RED, SceneOptions
from saw_ros.vision.tracker import detect

POSE = RobotPose(0.05, 0.0225, math.radians(1.5), 1.0)
LENS = (-0.12, 0.02, 0.0005, -0.0008, 0.0)


def renderer(camera=CameraModel(), options=RenderOptions(texture=False), scene=SceneOptions()):
    s = Scenario()
    return Renderer(s.robot, s.conditions.gap, camera, options, scene)


def test_lens_model_round_trip_and_opencv_agreement():
    import cv2
    cam = CameraModel(dist_coeffs=LENS)
    u, v = np.meshgrid(np.arange(0, 1280, 37.0), np.arange(0, 720, 29.0))
    image = u + 1j * v
    ideal = cam.undistort(image)
    assert np.abs(cam.distort(ideal) - image).max() < 0.01        # px
    assert np.abs(ideal - image).max() > 20                       # it does distort
    # distort() is OpenCV's model: projectPoints of the normalised ideal points.
    K = cam.K
    pts = np.stack([(ideal.real.ravel() - K[0, 2]) / K[0, 0],
                    (ideal.imag.ravel() - K[1, 2]) / K[1, 1], np.ones(ideal.size)], -1)
    proj, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, np.array(LENS))
    ours = cam.distort(ideal).ravel()
    assert np.abs(proj[:, 0, 0] + 1j * proj[:, 0, 1] - ours).max() < 1e-6
    assert not CameraModel().distorted and CameraModel().undistort(3 + 4j) == 3 + 4j
    for bad in ((0.1,), (0.1, 0.0, 0.0), (math.nan, 0, 0, 0)):
        with pytest.raises(ValueError):
            CameraModel(dist_coeffs=bad)
    with pytest.raises(ValueError):
        CameraModel(dist_coeffs=LENS, dist_matrix=(1200, 0, 640, 360))


def test_distorted_frame_puts_the_markers_where_the_lens_does():
    cam = CameraModel(dist_coeffs=LENS)
    r = renderer(cam)
    pose = POSE._replace(x=0.55)               # the front marker 460 px right of the centre
    img = r.render(pose)
    front, back = r.marker_pixels(pose)
    ideal = renderer().marker_pixels(pose)
    assert abs(front - ideal[0]) > 5                               # moved by the lens
    found = sorted(detect(img), key=lambda c: -c.u)
    assert len(found) == 2
    assert abs(found[0].p - front) < 0.1 and abs(found[1].p - back) < 0.1
    # Undistorted, they are where the ideal camera sees them.
    assert abs(complex(cam.undistort(found[0].p)) - ideal[0]) < 0.1
    assert abs(complex(cam.undistort(found[1].p)) - ideal[1]) < 0.1


def test_clutter_layers_lighting_and_jpeg():
    gap = Scenario().conditions.gap
    head = complex(POSE.x + 0.15, gap / 2)                     # on the robot's head
    scene = SceneOptions(clutter=(
        Clutter(ORANGE_RED, head.real, head.imag + 0.002, (0.008, 0.008)),          # hidden
        Clutter(HOT_PINK, 0.3, 0.15, (0.012, 0.012), velocity=(0.1, 0.0)),        # moving
        Clutter(ORANGE_RED, head.real - 0.05, head.imag, (0.01, 0.01), 'box',
                layer='front')))
    r = renderer(scene=scene)
    cam = r.camera
    img = r.render(POSE, t=0.0)
    behind = complex(cam.to_pixels(head + 0.002j))
    in_front = complex(cam.to_pixels(head - 0.05))
    bgr = (ORANGE_RED[2], ORANGE_RED[1], ORANGE_RED[0])
    assert tuple(img[int(round(behind.imag)), int(round(behind.real))]) != bgr
    assert tuple(img[int(round(in_front.imag)), int(round(in_front.real))]) == bgr
    pink = [c for c in detect(img) if abs(c.p - complex(cam.to_pixels(0.3 + 0.15j))) < 1]
    assert len(pink) == 1
    later = r.render(POSE, t=0.5)                              # moved 5 cm = 60 px
    assert any(abs(c.p - complex(cam.to_pixels(0.35 + 0.15j))) < 1 for c in detect(later))
    # A lighting gradient darkens the left and brightens the right; flicker scales it all.
    lit = renderer(scene=SceneOptions(gradient=0.3)).render(POSE)
    plain = renderer().render(POSE)
    left, right = np.s_[:, :100], np.s_[:, -100:]
    assert lit[left].mean() < 0.8 * plain[left].mean()
    assert lit[right].mean() > 1.1 * plain[right].mean()
    flick = renderer(scene=SceneOptions(flicker=0.2, flicker_hz=15.0))
    assert flick.render(POSE, t=1 / 60).mean() > 1.1 * flick.render(POSE, t=3 / 60).mean()
    # JPEG: changed, not much.
    q = renderer(scene=SceneOptions(compression='jpeg', quality=50)).render(POSE)
    diff = np.abs(q.astype(int) - plain.astype(int))
    assert diff.max() > 0 and diff.mean() < 3
    assert tuple(plain[int(round(r.marker_pixels(POSE)[0].imag)),
                       int(round(r.marker_pixels(POSE)[0].real))]) == PINK


def test_scene_options_are_validated():
    for bad in ({'gradient': 1.0}, {'flicker': -0.1}, {'compression': 'h264'},
                {'quality': 0}):
        with pytest.raises(ValueError):
            SceneOptions(**bad)
    for bad in ({'shape': 'star'}, {'layer': 'ceiling'}, {'colour': (300, 0, 0)},
                {'size': (0.0, 0.01)}):
        with pytest.raises(ValueError):
            Clutter(**dict({'colour': HOT_PINK, 'x': 0.0, 'y': 0.0}, **bad))


def test_vision_imports_no_rclpy():
    """The vision layer (and the track command) stays numpy + OpenCV."""
    import subprocess
    import sys
    code = ('import sys, importlib, pkgutil, saw_ros.vision\n'
            'for m in pkgutil.iter_modules(saw_ros.vision.__path__):\n'
            '    importlib.import_module("saw_ros.vision." + m.name)\n'
            'import saw_ros.cli.commands.track, saw_ros.bench.vision\n'
            'print(sorted(m for m in sys.modules if m.split(".")[0] in ("rclpy", "rcl")))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == '[]', out.stdout + out.stderr
