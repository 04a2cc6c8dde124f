"""The renderer and camera model: pixels consistent with K, markers where the renderer says."""
import math

import cv2
import numpy as np
import pytest

from saw_ros.core import body, Scenario
from saw_ros.core.kinematics import link_geometry
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.frames import (LINK, PINK, pose_interpolator, Renderer, RenderOptions,
                                   RobotPose, StampedShapes,
                                   wall_shape)
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


# -- bending walls (issue 23): the surfaces drawn as /saw/walls says -----------------------------

FLAT = RenderOptions(texture=False)      # grey 175 behind the silicone (G 205): edges measurable


def edge_v(img, u: int, v_lo: int, v_hi: int) -> float:
    """
    Return the bottom silicone's top edge in column u (px, v of the edge).

    From the silicone's coverage (green: background 175, silicone 205) summed over rows
    [v_lo, v_hi), a window that starts above the edge and ends inside the silicone.
    """
    g = img[v_lo:v_hi, u, 1].astype(float)
    return v_hi - float(np.clip((g - 175.0) / (205.0 - 175.0), 0.0, 1.0).sum())


def plateau(along, centre, height, half=0.01, ramp=0.01):
    """Return ``height`` within ``half`` of ``centre``, falling linearly to 0 over ``ramp``."""
    return height * np.clip((half + ramp - np.abs(along - centre)) / ramp, 0.0, 1.0)


def test_walls_none_or_undeflected_draw_todays_frames_bit_for_bit():
    s = Scenario()
    along = np.linspace(-0.5, 1.0, 301)
    zeros = (along, np.zeros((2, len(along))))
    for options in (RenderOptions(), FLAT):
        r = Renderer(s.robot, s.conditions.gap, CameraModel(), options)
        for pose in (POSE, POSE._replace(phase=2.5, x=0.3)):
            today = r.render(pose)
            assert np.array_equal(r.render(pose, walls=None), today)
            assert np.array_equal(r.render(pose, walls=zeros), today)
    # Motion blur: every sub-frame takes the walls.
    blur = Renderer(s.robot, s.conditions.gap, CameraModel(), RenderOptions(exposure=1 / 60))
    moving = lambda t: POSE._replace(x=POSE.x + 0.06 * t)  # noqa: E731
    assert np.array_equal(blur.render(moving(0.0), (), moving, 0.0, walls=zeros),
                          blur.render(moving(0.0), (), moving, 0.0))
    with pytest.raises(ValueError):
        r.render(POSE, walls=(along, np.zeros(len(along))))          # one wall, not two
    with pytest.raises(ValueError):
        r.render(POSE, walls=(along[::-1], np.zeros((2, len(along)))))   # decreasing


def test_bent_walls_move_their_edges_by_the_deflection_in_pixels():
    """
    A bump of the bottom wall away from the robot: its edge lower by the bump, there only.

    OpenCV draws a horizontal polygon edge on whole rows (its anti-aliasing is along the edges'
    slope: an edge at v = n + f, f < 0.5, covers the same rows as at v = n), so the camera sits
    with the flat edge on a row (v integer) and the expected shift is the one of the rows the
    moved edge falls on: 2.5 mm = 3 px at 1200 px/m, 3 mm = 3.6 px -> 4 rows.
    """
    s = Scenario()
    cam = CameraModel(center_y=CameraModel().center_y - 0.5 / CameraModel().scale)
    r = Renderer(s.robot, s.conditions.gap, cam, FLAT)
    along = np.linspace(0.3, 0.9, 121)                     # 5 mm apart, as /saw/walls
    xb = 0.6                                               # right of the robot (x 0.05)
    v0 = cam.to_pixels(np.array([xb + 0j]))[0].imag        # the flat edge (y = 0)
    assert v0 == pytest.approx(round(v0))
    v_lo, v_hi = int(v0) - 8, int(v0) + 9                  # silicone at v_hi in both frames
    u_b = int(round(cam.to_pixels(np.array([xb + 0j]))[0].real))
    flat = r.render(POSE)
    for height in (2.5e-3, 3e-3):
        deflection = np.zeros((2, len(along)))
        deflection[0] = plateau(along, xb, height)
        bent = r.render(POSE, walls=(along, deflection))
        # On the plateau (x within 1 cm of the bump's centre): moved by the rows to_pixels says.
        for x in (xb - 0.008, xb - 0.003, xb, xb + 0.005, xb + 0.009):
            u = int(round(cam.to_pixels(np.array([x + 0j]))[0].real))
            x_col = cam.to_surface(np.array([u + v0 * 1j]))[0].real       # the column's x
            v = cam.to_pixels(np.array([x_col - 1j * height]))[0].imag
            moved = edge_v(bent, u, v_lo, v_hi) - edge_v(flat, u, v_lo, v_hi)
            assert moved == pytest.approx(round(v) - round(v0), abs=0.05), (height, x, moved)
        # On the ramps (1 cm each side): between flat and the plateau, rising towards it.
        ramp = [edge_v(bent, u, v_lo, v_hi) - edge_v(flat, u, v_lo, v_hi)
                for u in range(u_b - 22, u_b - 11)]
        assert 0.0 <= min(ramp) and max(ramp) <= height * cam.scale + 0.5
        assert ramp[-1] - ramp[0] > 0.6 * height * cam.scale
        # Far from the bump (and beyond the samples) the edge stays where it was.
        for x in (0.2, 0.4, 0.5, 0.7, 0.85):
            u = int(round(cam.to_pixels(np.array([x + 0j]))[0].real))
            far = edge_v(flat, u, v_lo, v_hi)
            assert edge_v(bent, u, v_lo, v_hi) == pytest.approx(far, abs=0.05), x
        # Only the bottom silicone changed: the top wall and the robot are the same pixels.
        rows = np.flatnonzero((bent != flat).any(axis=(1, 2)))
        t = r.options.silicone_thickness
        assert rows.min() >= v0 - 2 and rows.max() <= v0 + (t + height) * cam.scale + 2, rows
        columns = np.flatnonzero((bent != flat).any(axis=(0, 2)))
        assert len(columns) < cam.width / 2
    # The top wall bends the other way: its edge (y = gap) goes up by the deflection.
    top = np.zeros((2, len(along)))
    top[1] = plateau(along, xb, 2.5e-3)
    up = r.render(POSE, walls=(along, top))
    vt = int(round(cam.to_pixels(np.array([xb + 1j * s.conditions.gap]))[0].imag))

    def cover(img):                 # silicone rows above the top wall's edge
        return np.clip((img[vt - 12:vt + 8, u_b, 1] - 175.0) / 30.0, 0.0, 1.0).sum()
    assert cover(flat) - cover(up) == pytest.approx(2.5e-3 * cam.scale, abs=0.1)


def test_frames_drawn_into_recycled_frames_are_the_frames_drawn_afresh():
    """
    Draw into frames handed back, as the camera node does: the frames of one that never does.

    Only the rows drawn on are restored; bit for bit all the same through jumps across the
    picture, a 20 deg slope, bent walls that come and go, deflected links, and three frames in
    flight.
    """
    s = Scenario()
    along = np.linspace(-0.5, 1.0, 301)
    bent = np.zeros((2, len(along)))
    bent[0], bent[1] = plateau(along, 0.1, 4e-3), plateau(along, 0.0, 3e-3)
    poses = [POSE._replace(x=x, theta=th, phase=ph) for x, th, ph in
             ((0.0, 0.0, 0.3), (0.45, 0.02, 2.0), (-0.3, -0.03, 4.0), (0.05, 0.0, 1.0),
              (0.6, 0.01, 5.5), (0.0, 0.0, 0.3), (0.2, -0.02, 3.3), (0.21, -0.02, 3.4))]
    # (and links moved on their flexures, 3 mm at most)
    poses[6] = poses[6]._replace(deflection=tuple(
        0.003 * math.sin(k) for k in range(s.robot.wave_links)))
    walls = [None, (along, bent), None, (along, bent), (along, bent), None, None, None]
    for cam in (CameraModel(), CameraModel(slope=math.radians(20))):
        recycled = Renderer(s.robot, s.conditions.gap, cam)
        afresh = Renderer(s.robot, s.conditions.gap, cam)
        in_flight = []
        for k in range(24):
            pose, shape = poses[k % len(poses)], walls[(k // 2) % len(walls)]
            frame = recycled.render(pose, walls=shape)
            drawn = afresh.render(pose, walls=shape)
            assert np.array_equal(frame, drawn), k
            in_flight.append(frame)
            if len(in_flight) > 3:
                recycled.recycle(in_flight.pop(0))
        assert recycled._free and recycled._drawn   # frames were drawn into again
    # A noisy picture changes everywhere: its frames are not taken back.
    noisy = Renderer(s.robot, s.conditions.gap, CameraModel(), RenderOptions(noise=3.0))
    frame = noisy.render(POSE)
    noisy.recycle(frame)
    assert not noisy._free and noisy.render(POSE) is not frame


def test_tips_dent_the_deflected_wall_not_the_flat_one():
    """
    The contact law's depth is against the deflected wall (docs/walls.md).

    Walls pushed away further than any tip reaches (9 mm; the tips press up to 7.6 mm into the
    flat silicone at POSE) show no dent: in every column of the bottom edge the robot does not
    cover, the edge is where it is with the robot out of view. Flat, the dents show.
    """
    s = Scenario()
    cam = CameraModel(center_y=CameraModel().center_y - 0.5 / CameraModel().scale)
    r = Renderer(s.robot, s.conditions.gap, cam, FLAT)
    along = np.linspace(-0.4, 1.0, 281)
    pushed = (along, np.full((2, len(along)), 9e-3))
    away = POSE._replace(x=5.0)                      # the robot out of view
    flat, bent = r.render(POSE), r.render(POSE, walls=pushed)
    flat_alone, bent_alone = r.render(away), r.render(away, walls=pushed)
    v0 = int(round(cam.to_pixels(np.array([0j]))[0].imag))
    win = {'flat': (v0 - 4, v0 + 10), 'bent': (v0 + 5, v0 + 20)}   # around each edge

    def silicone_only(img, u, lo, hi):
        """Only background and silicone in the window: a blend c of (175,) * 3 and SILICONE."""
        bgr = img[lo:hi, u].astype(float)
        c = (bgr[:, 1] - 175.0) / 30.0
        return bool(np.all(np.abs(bgr[:, 0] - 175.0 - 25.0 * c) <= 1.5)
                    and np.all(np.abs(bgr[:, 2] - 175.0 - 35.0 * c) <= 1.5))

    columns = [u for u in range(cam.width)
               if silicone_only(flat, u, *win['flat']) and silicone_only(bent, u, *win['bent'])]
    assert len(columns) > cam.width * 0.8
    dented = [u for u in columns if abs(edge_v(flat, u, *win['flat'])
                                        - edge_v(flat_alone, u, *win['flat'])) > 0.3]
    assert len(dented) >= 5                           # flat: dents beside the links
    moved = [edge_v(bent, u, *win['bent']) - edge_v(bent_alone, u, *win['bent'])
             for u in columns]
    assert np.abs(moved).max() < 0.05                 # bent 9 mm: none
    u = columns[0]
    assert edge_v(bent_alone, u, *win['bent']) - edge_v(flat_alone, u, *win['flat']) == \
        pytest.approx(round(9e-3 * cam.scale), abs=0.05)


def test_rigid_links_draw_todays_frames_bit_for_bit():
    s = Scenario()
    r = Renderer(s.robot, s.conditions.gap, CameraModel())
    zeros = POSE._replace(deflection=(0.0,) * s.robot.wave_links)
    assert np.array_equal(r.render(zeros), r.render(POSE))


def test_a_deflected_link_is_drawn_where_its_deflected_plate_is():
    """
    Link k moved 4 mm down its body y (12 px at 3000 px/m, level): the rows its plate gained.

    Are the link's colour, those it left are not, and nothing else changes but its tip's dent
    in the silicone; the other links stay where they were.
    """
    s = Scenario()
    gap, n = s.conditions.gap, s.robot.wave_links
    cam = CameraModel(scale=3000.0, center_x=0.0, center_y=gap / 2)
    r = Renderer(s.robot, gap, cam, RenderOptions(texture=False))
    pose = RobotPose(0.0, gap / 2, 0.0, 1.0)
    k, e = n // 2, -0.004
    deflection = np.zeros(n)
    deflection[k] = e
    rigid = r.render(pose, ('front', 'back'))
    bent = r.render(pose._replace(deflection=tuple(deflection)), ('front', 'back'))
    g = link_geometry(s.robot, pose.phase)

    def plate(shift):
        corners = cam.to_pixels(complex(pose.x, pose.y) + body.link_plates(
            s.robot, g.centres[k] + 1j * shift, np.exp(1j * g.angles[k])))
        mask = np.zeros(rigid.shape[:2], np.uint8)
        cv2.fillConvexPoly(mask, np.rint(np.stack([corners.real, corners.imag], -1))
                           .astype(np.int32), 1)
        return mask
    before, after = plate(0.0), plate(e)
    square = np.ones((5, 5), np.uint8)
    gained = cv2.erode(after & (1 - before), square).astype(bool)
    left = cv2.erode(before & (1 - after), square).astype(bool)
    assert gained.sum() > 50 and left.sum() > 50
    is_link = (bent == LINK).all(axis=2)
    assert is_link[gained].all() and not (rigid == LINK).all(axis=2)[gained].any()
    assert not is_link[left].any()
    # Elsewhere only the down tip's dent (it pressed deeper): within a dent's half-width of the
    # tip, in the bottom silicone's rows.
    changed = (rigid != bent).any(axis=2) & \
        ~cv2.dilate(before | after, square).astype(bool)
    v, u = np.nonzero(changed)
    tip = complex(cam.to_pixels(complex(pose.x, pose.y) + g.down_tips[k] + 1j * e))
    half = body.dent_half_width(s.robot) * cam.scale
    assert len(u) and np.abs(u - tip.real).max() <= half + 2
    bottom = complex(cam.to_pixels(complex(pose.x, 0.0))).imag
    assert v.min() >= bottom - 2 and v.max() <= bottom + 3 + abs(e) * cam.scale


def test_pose_interpolator_interpolates_the_deflections():
    t = np.array([0.0, 1.0, 2.0])
    at = pose_interpolator(t, t, t, 0 * t, t, np.array([0.0, 2.0]),
                           np.array([[0.0, 1e-3], [2e-3, -1e-3]]))
    assert at(0.5).deflection == pytest.approx((5e-4, 5e-4))
    assert at(3.0).deflection == pytest.approx((2e-3, -1e-3))       # clamped at the end
    assert pose_interpolator(t, t, t, 0 * t, t)(0.5).deflection is None


def test_a_compliant_run_renders_its_links_deflected_as_the_core_has_them():
    """
    simulate_run of a compliant robot: the core's trajectory bit for bit, its deflections.

    (Simulator.deflection after each millisecond) in the frames, which are not the rigid ones.
    """
    from saw_ros.core import simulate, Simulator
    from saw_ros.vision.synthetic import simulate_run
    s = Scenario().with_values({'flexure.stiffness': 863.0, 'flexure.damping': 2.6})
    run = simulate_run(s, 0.3)
    whole = simulate(s, 0.3)
    for name in ('t', 'q', 'omega'):
        assert np.array_equal(getattr(run.trajectory, name), getattr(whole, name)), name
    sim = Simulator(s)
    sim.run(0.25)
    k = int(np.argmin(np.abs(run.deflection_t - 0.25)))
    assert run.deflection_t[k] == pytest.approx(0.25, abs=1e-9)
    assert np.array_equal(run.deflection[k], sim.deflection[0])
    assert np.abs(sim.deflection).max() > 1e-4
    pose = run.pose_at(0.25)
    assert np.array_equal(pose.deflection, sim.deflection[0])
    r = Renderer(s.robot, s.conditions.gap, CameraModel(center_x=0.0))
    assert not np.array_equal(r.render(pose), r.render(pose._replace(deflection=None)))
    assert simulate_run(Scenario(), 0.05).pose_at(0.02).deflection is None


def test_stamped_shapes_give_the_last_recent_shape_at_or_before_a_time():
    ms = 1_000_000
    shapes = StampedShapes(keep_ns=2000 * ms, stale_ns=250 * ms)
    assert shapes.before(0) is None                       # none yet: flat
    a = wall_shape([0.0, 1.0], [[0.0, 0.0], [0.0, 0.0]])
    b = wall_shape([0.0, 1.0], [[1e-3, 0.0], [0.0, 1e-3]])
    shapes.add(100 * ms, a)
    shapes.add(116 * ms, b)
    assert shapes.before(99 * ms) is None                 # before the first one: flat
    assert shapes.before(100 * ms) is a and shapes.before(115 * ms) is a
    assert shapes.before(116 * ms) is b and shapes.before(300 * ms) is b
    assert shapes.before(400 * ms) is None                # no shape for 0.28 s: stale, flat
    for k in range(200):                                  # 60 Hz for 3.3 s: 2 s kept
        shapes.add(200 * ms + k * 16 * ms, a)
    assert shapes.t[-1] - shapes.t[0] <= 2000 * ms
    shapes.add(50 * ms, b)                                # time went back: a restart
    assert shapes.t == [50 * ms] and shapes.before(60 * ms) is b
