"""
What /saw/markers draws is what the camera shows.

The shapes of saw_ros.interface.scene_markers are projected through the camera model onto an
ideal rendered frame of the same instant: every wave link plate, head, spine and tail lands on
the renderer's colour for that part, and the true markers on the pink discs.
"""
import math

import numpy as np
import pytest
from saw_ros.analysis.figures.markers_view import snapshot
from saw_ros.interface import scene_markers
from saw_ros.vision import frames
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.frames import Renderer, RenderOptions, RobotPose


@pytest.fixture(scope='module')
def instant():
    scenario, pose, phase, contacts = snapshot(1.3)
    shapes = scene_markers.scene(scenario.robot, scenario.conditions.gap, pose, phase, contacts)
    camera = CameraModel(center_x=pose[0], center_y=scenario.conditions.gap / 2)
    renderer = Renderer(scenario.robot, scenario.conditions.gap, camera,
                        RenderOptions(texture=False))
    image = renderer.draw(RobotPose(*pose, phase), np.empty((camera.height, camera.width, 3),
                                                            np.uint8))
    return scenario, pose, shapes, camera, renderer, image


def colour_at(image, camera, point):
    p = complex(camera.to_pixels(np.array([complex(point[0], point[1])]))[0])
    return tuple(int(c) for c in image[int(round(p.imag)), int(round(p.real))])


def by_namespace(shapes, namespace):
    return [s for s in shapes if s.namespace == namespace]


def covered(shapes, point) -> bool:
    """Whether ``point`` is under the head or the tail plate (drawn over the links)."""
    for part in by_namespace(shapes, 'body'):
        rel = (complex(*point[:2]) - complex(*part.position[:2])) * np.exp(-1j * part.yaw)
        if abs(rel.real) <= part.scale[0] / 2 and abs(rel.imag) <= part.scale[1] / 2 and \
                part.id != 1:                                    # 1: the spine, under them
            return True
    return False


def test_link_plates_lie_on_the_rendered_links(instant):
    scenario, _, shapes, camera, _, image = instant
    plates, = by_namespace(shapes, 'wave_links')
    assert plates.kind == 'triangle_list'
    triangles = np.array(plates.points).reshape(-1, 6, 3)        # two triangles per link
    assert len(triangles) == scenario.robot.wave_links
    seen = 0
    for corners in triangles:
        centre = corners[[0, 1, 2, 5]].mean(axis=0)              # the plate's four corners
        if not covered(shapes, centre):
            assert colour_at(image, camera, centre) == frames.LINK
            seen += 1
    assert seen >= scenario.robot.wave_links - 2


def test_links_on_flexures_are_drawn_deflected_normal_to_the_backbone(instant):
    """Each plate and its two tips move by the link's deflection along the body's normal."""
    scenario, pose, _, _, _, _ = instant
    n = scenario.robot.wave_links
    e = np.linspace(-3e-3, 3e-3, n)
    shapes, bent = (scene_markers.scene(scenario.robot, scenario.conditions.gap, pose, 1.3,
                                        deflection=d) for d in (None, e))
    normal = 1j * np.exp(1j * pose[2])                      # the body's y in the surface frame
    for namespace, rows in (('wave_links', 6), ('tips', 1)):
        (before,), (after,) = by_namespace(shapes, namespace), by_namespace(bent, namespace)
        moved = (after.points - before.points)[:, :2] @ [1.0, 1j]
        shift = np.repeat(e, rows) if namespace == 'wave_links' else np.tile(e, 2)
        np.testing.assert_allclose(moved, shift * normal, atol=1e-15)


def test_body_parts_and_true_markers_lie_where_the_camera_draws_them(instant):
    _, pose, shapes, camera, renderer, image = instant
    head, spine, tail = by_namespace(shapes, 'body')
    assert (head.kind, head.yaw) == ('cube', pytest.approx(pose[2]))
    # Head and tail plate are BODY grey away from the markers (the spine is under the links).
    axis = complex(math.cos(pose[2]), math.sin(pose[2]))
    for part, along in ((head, -0.3), (tail, 0.3)):
        point = complex(*part.position[:2]) + along * part.scale[0] * axis
        assert colour_at(image, camera, (point.real, point.imag)) == frames.BODY, part
    assert spine.position[0] < head.position[0] and spine.scale[1] == pytest.approx(0.006)
    truth = by_namespace(shapes, 'markers_truth')
    for shape, expected in zip(truth, renderer.marker_surface(RobotPose(*pose, 0.0))):
        assert shape.position[:2] == pytest.approx((expected.real, expected.imag), abs=1e-12)
        assert colour_at(image, camera, shape.position) == frames.PINK


def test_force_arrows_and_tracking_estimate():
    forces = scene_markers.force_arrows([0.01, 0.05], [0.0, 0.045], [2.0, 3.0], [0.5, -1.0],
                                        [0, 1], [0, 1], scale=0.01)
    (s0, e0), (s1, e1) = (a.points for a in forces)
    assert (e0[0] - s0[0], e0[1] - s0[1]) == pytest.approx((0.005, 0.02))     # up, from bottom
    assert (e1[0] - s1[0], e1[1] - s1[1]) == pytest.approx((-0.01, -0.03))    # down, from top
    assert [a.colour for a in forces] == [scene_markers.STICK_COLOUR, scene_markers.SLIP_COLOUR]
    estimate = scene_markers.tracking((0.28, 0.02, 0.0), None, (0.11, 0.02, 0.1))
    sphere, arrow = estimate
    assert sphere.position[:2] == (0.28, 0.02) and sphere.position[2] > scene_markers.DEPTH / 2
    (x0, y0, _), (x1, y1, _) = arrow.points
    assert math.atan2(y1 - y0, x1 - x0) == pytest.approx(0.1)
    assert scene_markers.tracking(None, None, None) == []


def test_squeezed_bands_are_as_deep_and_wide_as_the_dents():
    """Each touching tip's band: its penetration deep under the tip, the camera's dent width."""
    from saw_ros.core import body
    scenario, pose, phase, contacts = snapshot(1.3)
    gap = scenario.conditions.gap
    shapes = scene_markers.scene(scenario.robot, gap, pose, phase, contacts)
    bands = {s.id: np.array(s.points).reshape(-1, 3) for s in by_namespace(shapes, 'squeezed')}
    half = body.dent_half_width(scenario.robot)
    pressed = 0
    for c in contacts:
        level, sign = (0.0, 1.0) if c['surface'] == 0 else (gap, -1.0)
        depth = sign * (level - c['y'])
        if depth <= 0:
            continue
        pressed += 1
        points = bands[int(c['surface'])]
        near = points[np.abs(points[:, 0] - c['x']) <= half + 1e-12]
        # The deepest point of the band right under the tip is the tip itself.
        assert np.max(sign * (level - near[:, 1])) == pytest.approx(depth, abs=1e-12)
        assert np.all(sign * (level - points[:, 1]) >= -1e-12)       # never above the surface
    assert pressed >= 2 and sum(len(p) for p in bands.values()) == pressed * 8 * 6
