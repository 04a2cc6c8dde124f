"""
Side-view renderer: what a level camera beside the track sees of the robot between its surfaces.

Drawn, back to front: a textured wall (static), the two rigid boards, the two silicone layers with
a dent wherever a link tip presses in (depth = the tip's penetration, width about a link), bent
along the walls' shape when the walls bend (``render(..., walls=)``, from /saw/walls), the
robot (spine, base link, wave links from down tip to up tip, each moved along body y by its
deflection on its flexure when ``RobotPose.deflection`` gives them, head, tail plate) and two pink
markers on the body's side: front on the head, back on the tail plate, both on the body axis and
symmetric about the COM by default, so that their midpoint is the COM.

Realism (``RenderOptions``): motion blur (average of ``blur_samples`` sub-frames spread over an
exposure CENTRED on the frame time, so a blurred marker's centroid is its position at the frame
time), brightness factor (saturating), Gaussian sensor noise (sigma in grey levels, from a
precomputed pool at random offsets: drawing 2.7 M normal numbers per frame would cost more than
the whole render), and a textured background.

Frames are BGR uint8 (OpenCV order). Everything drawn is anti-aliased with sub-pixel vertices;
the markers are drawn from their exact coverage so that their intensity centroid is where they
are (``marker_pixels`` gives it, for tests and benchmarks).

Footage that looks less like this (``scene.SceneOptions``): clutter on the wall or in front of the
robot, a lighting gradient and flicker, JPEG compression; and, with a camera that has a lens
distortion, the ideal image warped as the lens would (after blur and lighting, before the
sensor noise). Order: draw (blur) -> brightness and lighting -> lens -> noise -> JPEG.
"""
from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass
import math
from typing import Callable, Deque, Dict, Iterable, List, NamedTuple, Optional, Sequence, Tuple

import cv2
import numpy as np

from saw_ros.core import body
from saw_ros.core.kinematics import base_link_end, cycle_phases, hinge_x, link_geometry, PhaseTable
from saw_ros.core.params import check_fields, RobotParams, spec
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.scene import distortion_maps, draw_clutter, gradient_map, jpeg, SceneOptions

SHIFT = 4                       # fixed-point bits for cv2 sub-pixel vertices
ONE = 1 << SHIFT
POOL = 8                        # finished frames a renderer keeps to draw into again (recycle)
AA_ROWS = 3                     # rows an anti-aliased edge may reach beyond its vertices (2 do)

# Colours, BGR. Everything but the markers is neutral (R + B = 2 G), which the tracker's pinkness
# measure R + B - 2 G maps to zero.
PINK = (170, 60, 255)           # hot pink marker, RGB (255, 60, 170), OpenCV hue 163
BODY = (70, 70, 70)
SPINE = (45, 45, 45)
LINK = (205, 205, 205)
LINK_EDGE = (120, 120, 120)
BASE_LINK = (150, 150, 150)
SILICONE = (200, 205, 210)      # R 210, G 205, B 200: neutral
BOARD = (70, 110, 150)          # wood, R 150, G 110, B 70: neutral
WALL = 175                      # grey level of the wall behind


class RobotPose(NamedTuple):
    """
    Where the robot is: COM (x, y) in the surface frame (m), pitch theta (rad), wave phase.

    ``deflection``: each wave link's deflection on its flexure (m, one per link, head first:
    core ``Simulator.deflection``, the URDF's ``link_NN_flex``), drawn along body y as the URDF
    and /saw/markers move the link; None: rigid links, each at its kinematic target.
    """

    x: float
    y: float
    theta: float
    phase: float
    deflection: Optional[Tuple[float, ...]] = None


@dataclass(frozen=True)
class RenderOptions:
    # spec(): unit, range and description, for the camera node's parameters, its
    # msg_config/camera.yaml and saw-ros render's options; __post_init__ checks these ranges
    noise: float = spec(0.0, 'grey levels', 'sensor noise, standard deviation; 0 = none', 0.0,
                        None)
    exposure: float = spec(0.0, 's', 'exposure time for motion blur; 0 = none', 0.0, None)
    blur_samples: int = spec(5, '', 'sub-frames averaged over the exposure', 1, None)
    brightness: float = spec(1.0, '', "brightness factor on the scene's intensity (1 = nominal; "
                             'saturates at 255)', 0.0, None, low_open=True)
    texture: bool = spec(True, '', 'textured wall behind the track (false: flat grey)')
    seed: int = spec(0, '', 'random seed of texture and noise')
    marker_radius: float = spec(0.006, 'm', 'radius of a pink marker', 0.0, None, low_open=True)
    front_marker: float = spec(body.FRONT_MARKER_X, 'm',
                               'body x of the front marker (on the body axis, y = 0)')
    back_marker: float = spec(body.BACK_MARKER_X, 'm', 'body x of the back marker')
    silicone_thickness: float = spec(0.012, 'm', 'thickness of the silicone on each surface')
    board_thickness: float = spec(0.018, 'm', 'thickness of the board behind each surface')

    def __post_init__(self):
        check_fields(self)          # the spec() ranges; ParameterError is a ValueError


class WallShape(NamedTuple):
    """Bending walls: abscissae (m, increasing) and deflections (2, m: bottom, top; > 0 away)."""

    along: np.ndarray
    deflection: np.ndarray


def wall_shape(along, deflection) -> WallShape:
    """
    Return a checked ``WallShape``: float arrays, (m,) and (2, m), m >= 2, increasing, finite.

    Raises ValueError otherwise.
    """
    a = np.asarray(along, float)
    w = np.asarray(deflection, float)
    if a.ndim != 1 or len(a) < 2 or w.shape != (2, len(a)):
        raise ValueError(f'walls: along (m,) and deflection (2, m) with m >= 2, not {a.shape} '
                         f'and {w.shape}')
    if not (np.isfinite(a).all() and np.isfinite(w).all()) or not (np.diff(a) > 0).all():
        raise ValueError('walls: abscissae must increase and every value be finite')
    return WallShape(a, w)


class _GeometryTable(PhaseTable):
    """
    Body-frame link geometry over one wave cycle.

    Centres, directions, base-link end, up and down tips side by side in one complex table.
    """

    def __init__(self, robot: RobotParams, samples: int = 1024):
        geo = link_geometry(robot, cycle_phases(samples))
        self.n = robot.wave_links
        super().__init__(np.concatenate(
            [geo.centres, np.exp(1j * geo.angles), base_link_end(robot, geo.base_angle)[:, None],
             geo.up_tips, geo.down_tips], axis=1), samples)

    def geometry(self, phase: float):
        """(centres, unit directions, base-link end, up tips, down tips) at ``phase``."""
        row = self.at(phase % (2.0 * np.pi))
        n = self.n
        d = row[n:2 * n]
        return row[:n], d / np.abs(d), row[2 * n], row[2 * n + 1:3 * n + 1], row[3 * n + 1:]


class Renderer:
    """Renders frames of one robot between its surfaces, seen by ``camera``."""

    def __init__(self, robot: RobotParams, gap: float, camera: CameraModel,
                 options: RenderOptions = RenderOptions(), scene: SceneOptions = SceneOptions()):
        self.robot, self.gap, self.camera, self.options = robot, float(gap), camera, options
        self.scene = scene
        self._table = _GeometryTable(robot)
        self._rng = np.random.default_rng(options.seed)
        self._hinge = hinge_x(robot)
        outline = body.outline(robot, gap)
        self._head, self._spine, self._tail = outline.head, outline.spine, outline.tail
        self._rows = [0, 0]             # rows drawn on since the last draw began
        self._background = self._make_background()
        self._frame = np.empty_like(self._background)
        # Frames handed back by ``recycle``: (frame, (first, last + 1) rows drawn over the
        # background). Only the picture's plain form (the robot over the background, nothing
        # over the whole picture) is drawn into them.
        self._free: Deque[Tuple[np.ndarray, Tuple[int, int]]] = deque()
        self._drawn: Dict[int, Tuple[int, int]] = {}       # id(frame) -> its rows drawn
        self._reuses = not (scene.clutter or camera.distorted or options.noise > 0
                            or scene.compression == 'jpeg')
        self._noise = self._make_noise() if options.noise > 0 else None
        self._accum: Optional[np.ndarray] = None    # the motion blur's sum of sub-frames
        self._gradient = gradient_map(camera, scene) if scene.gradient > 0 else None
        self._lens = distortion_maps(camera) if camera.distorted else None

    # -- static parts --------------------------------------------------------------------------
    def _make_background(self) -> np.ndarray:
        cam, opt = self.camera, self.options
        h, w = cam.height, cam.width
        if opt.texture:
            rng = np.random.default_rng(opt.seed + 1)
            coarse = cv2.resize(
                rng.normal(0.0, 1.0, (h // 32 + 2, w // 32 + 2)).astype(np.float32), (w, h),
                interpolation=cv2.INTER_CUBIC)
            fine = cv2.GaussianBlur(rng.normal(0.0, 1.0, (h, w)).astype(np.float32), (0, 0), 1.5)
            grey = WALL + 18.0 * coarse + 10.0 * fine
            grey = np.clip(grey, 0, 255).astype(np.uint8)
        else:
            grey = np.full((h, w), WALL, np.uint8)
        img = cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)
        x0, x1 = cam.visible_x_range(0.1)
        t, b = opt.silicone_thickness, opt.board_thickness
        g = self.gap
        for y0, y1 in ((-t - b, -t), (g + t, g + t + b)):
            self._fill(img, [body.rectangle(x0, x1, y0, y1)], BOARD)
        return img

    def _make_noise(self) -> Tuple[np.ndarray, np.ndarray]:
        """Return a pool of noise, split into positive and negative parts for saturating adds."""
        cam = self.camera
        pad = 32
        n = self._rng.normal(0.0, self.options.noise, (cam.height + pad, cam.width + pad, 3))
        n = np.rint(n)
        return (np.clip(n, 0, 255).astype(np.uint8), np.clip(-n, 0, 255).astype(np.uint8))

    # -- drawing helpers -----------------------------------------------------------------------
    def _fixed(self, surface_points) -> np.ndarray:
        # (u, v) pairs straight from the complex pixels' memory: a stack of their real and
        # imaginary parts cost 10 us a polygon, 7 polygons a frame.
        p = np.ascontiguousarray(self.camera.to_pixels(surface_points), np.complex128)
        fixed = np.rint(p.view(np.float64).reshape(p.shape + (2,)) * ONE).astype(np.int32)
        v = fixed[..., 1]
        self._touch(int(v.min()) >> SHIFT, (int(v.max()) >> SHIFT) + 1)
        return fixed

    def _touch(self, first: int, end: int) -> None:
        """Note rows first .. end - 1 drawn on (and AA_ROWS more each side)."""
        rows = self._rows
        rows[0] = min(rows[0], max(first - AA_ROWS, 0))
        rows[1] = max(rows[1], min(end + AA_ROWS, self.camera.height))

    def _fill(self, img, polygons: Sequence[np.ndarray], colour) -> None:
        for poly in polygons:
            cv2.fillConvexPoly(img, self._fixed(poly), colour, cv2.LINE_AA, SHIFT) \
                if len(poly) <= 4 else \
                cv2.fillPoly(img, [self._fixed(poly)], colour, cv2.LINE_AA, SHIFT)

    def _silicone(self, img, x0, x1, down_tips, up_tips, walls=None) -> None:
        """
        Both silicone layers, dented where tips press in (penetration > 0).

        ``walls``: (along, deflection (2, m)) of bending walls, or None. A wall deflected
        nowhere (all zeros) is drawn flat, by the flat code: the same pixels as without walls.
        """
        t = self.options.silicone_thickness
        width = body.dent_half_width(self.robot)   # half-width of a dent, m
        for surface, (tips, level, sign) in enumerate(((down_tips, 0.0, 1.0),
                                                       (up_tips, self.gap, -1.0))):
            if walls is not None and walls[1][surface].any():
                self._bent_silicone(img, x0, x1, tips, level, sign, walls[0],
                                    walls[1][surface])
                continue
            pen = sign * (level - tips.imag)     # > 0 inside the surface
            pressed = pen > 0
            edge = [x0 + 1j * level]
            if pressed.any():
                tx, depth = tips.real[pressed], pen[pressed]
                xs = np.sort(np.linspace(tx - width, tx + width, 9, axis=1).ravel())
                d = (xs[:, None] - tx[None, :]) / width
                bump = np.where(np.abs(d) < 1.0, np.cos(0.5 * np.pi * d) ** 2, 0.0)
                profile = (bump * depth[None, :]).max(axis=1)
                edge.extend(xs + 1j * (level - sign * profile))
            edge.append(x1 + 1j * level)
            back = level - sign * t
            poly = np.array(edge + [x1 + 1j * back, x0 + 1j * back])
            self._fill(img, [poly], SILICONE)

    def _bent_silicone(self, img, x0, x1, tips, level, sign, along, w) -> None:
        """
        One silicone layer on a bending wall: deflected by ``w`` at ``along`` (> 0 away).

        Its face follows the wall, y = level - sign w(x) (linear between the samples, w = 0
        beyond them), dented where tips press into the DEFLECTED wall (the contact law's depth,
        d - w); its back is t behind the face where the wall is pushed away, and stays at the
        board where it lifts (w < 0), so that no gap opens. One polygon: the face through the
        samples in view and the dents' vertices, the back through the samples; samples within
        1/100 px of the flat wall, between two others as flat, are left out (the drawn edge
        moves by less than that): the cost is in the polygon's edges, and the walls bend only
        around the robot.
        """
        t = self.options.silicone_thickness
        width = body.dent_half_width(self.robot)
        pen = sign * (level - tips.imag) - np.interp(tips.real, along, w, left=0.0, right=0.0)
        pressed = pen > 0
        inside = (along > x0) & (along < x1)
        bent = np.abs(w) > 0.01 / self.camera.scale
        bent[1:] |= bent[:-1].copy()
        bent[:-1] |= bent[1:].copy()
        samples = np.concatenate(([x0], along[inside & bent], [x1]))
        ws = np.interp(samples, along, w, left=0.0, right=0.0)
        back = samples + 1j * (level - sign * (t + np.maximum(ws, 0.0)))
        if pressed.any():
            tx, depth = tips.real[pressed], pen[pressed]
            dents = (tx[:, None] + width * np.linspace(-1.0, 1.0, 9)[None, :]).ravel()
            xs = np.sort(np.concatenate([samples, dents]))
            d = (xs[:, None] - tx[None, :]) / width
            bump = np.where(np.abs(d) < 1.0, np.cos(0.5 * np.pi * d) ** 2, 0.0)
            face = xs + 1j * (level - sign * (np.interp(xs, along, w, left=0.0, right=0.0)
                                              + (bump * depth[None, :]).max(axis=1)))
        else:
            face = samples + 1j * (level - sign * ws)
        self._fill(img, [np.concatenate([face, back[::-1]])], SILICONE)

    def _marker(self, img, centre: complex) -> None:
        """Return a pink disc drawn from its exact (1-pixel ramp) coverage."""
        radius = self.options.marker_radius * self.camera.scale
        self._touch(int(math.floor(centre.imag - radius - 1)),
                    int(math.ceil(centre.imag + radius + 2)))
        self._disc(img, centre, radius, PINK)

    @staticmethod
    def _disc(img, centre: complex, radius: float, colour) -> None:
        """Return a disc (radius px, BGR colour) drawn from its exact (1-pixel ramp) coverage."""
        h, w = img.shape[:2]
        u0 = int(math.floor(centre.real - radius - 1))
        u1 = int(math.ceil(centre.real + radius + 2))
        v0 = int(math.floor(centre.imag - radius - 1))
        v1 = int(math.ceil(centre.imag + radius + 2))
        u0c, u1c, v0c, v1c = max(u0, 0), min(u1, w), max(v0, 0), min(v1, h)
        if u0c >= u1c or v0c >= v1c:
            return
        uu = np.arange(u0c, u1c) - centre.real
        vv = np.arange(v0c, v1c) - centre.imag
        dist = np.sqrt(uu[None, :] ** 2 + vv[:, None] ** 2)
        a = np.clip(radius + 0.5 - dist, 0.0, 1.0)[..., None].astype(np.float32)
        patch = img[v0c:v1c, u0c:u1c]
        patch[...] = (patch * (1.0 - a) + np.array(colour, np.float32) * a + 0.5).astype(np.uint8)

    # -- public --------------------------------------------------------------------------------
    def marker_surface(self, pose: RobotPose):
        """(front, back) marker centres in the surface frame (complex, m): the ground truth."""
        com = complex(pose.x, pose.y)
        rot = complex(math.cos(pose.theta), math.sin(pose.theta))
        return com + rot * self.options.front_marker, com + rot * self.options.back_marker

    def _ideal_pixels(self, pose: RobotPose):
        front, back = self.marker_surface(pose)
        p = self.camera.to_pixels(np.array([front, back]))
        return complex(p[0]), complex(p[1])

    def marker_pixels(self, pose: RobotPose):
        """
        (front, back) marker centres in the image, pixels (complex u + i v).

        Through the lens distortion when the camera has one.
        """
        p = self.camera.distort(np.array(self._ideal_pixels(pose)))
        return complex(p[0]), complex(p[1])

    def draw(self, pose: RobotPose, out: np.ndarray, hidden: Iterable[str] = (),
             t: float = 0.0, walls: Optional[WallShape] = None) -> np.ndarray:
        """
        Draw the scene at one instant (time t for moving clutter) into ``out``.

        The ideal picture: no lens, no blur, brightness or noise. ``walls``: the bending walls'
        shape (``wall_shape``), or None for flat ones.
        """
        np.copyto(out, self._background)
        return self._draw_over(pose, out, hidden, t, walls)

    def _draw_over(self, pose: RobotPose, out: np.ndarray, hidden: Iterable[str], t: float,
                   walls: Optional[WallShape]) -> np.ndarray:
        """
        Draw what ``draw`` draws over the background, noting the rows drawn.

        Whatever is drawn here must note its rows (``_touch``; ``_fixed`` and ``_marker`` do it):
        a frame handed back is restored, and the camera's JPEG encoded, only in those rows
        (test_frames_drawn_into_recycled_frames_are_the_frames_drawn_afresh).
        """
        self._rows = [self.camera.height, 0]
        clutter = self.scene.clutter
        if clutter:
            draw_clutter(out, self.camera, clutter, t, 'wall', self._disc)
        centres, direction, base_end, up, down = self._table.geometry(pose.phase)
        if pose.deflection is not None and any(pose.deflection):
            # Each link, both its tips with it, moved along body y (scene_markers.robot's shift):
            # the silicone is dented where the deflected tips press.
            shift = 1j * np.asarray(pose.deflection, float)
            if shift.shape != centres.shape:
                raise ValueError(f'{len(shift)} deflections for {len(centres)} wave links')
            centres, up, down = centres + shift, up + shift, down + shift
        com = complex(pose.x, pose.y)
        rot = complex(math.cos(pose.theta), math.sin(pose.theta))
        x0, x1 = self.camera.visible_x_range(0.1)
        self._silicone(out, x0, x1, com + rot * down, com + rot * up, walls)

        def world(points):
            return com + rot * points
        self._fill(out, [world(self._spine)], SPINE)
        hinge = complex(self._hinge, 0.0)
        bar = 0.002j * (hinge - base_end) / abs(hinge - base_end)
        self._fill(out, [world(np.array([hinge + bar, base_end + bar, base_end - bar,
                                         hinge - bar]))], BASE_LINK)
        pix = self._fixed(world(body.link_plates(self.robot, centres, direction)))
        for poly in pix:
            cv2.fillConvexPoly(out, poly, LINK, cv2.LINE_AA, SHIFT)
        cv2.polylines(out, list(pix), True, LINK_EDGE, 1, cv2.LINE_AA, SHIFT)
        self._fill(out, [world(self._head), world(self._tail)], BODY)
        hidden = set(hidden)
        front, back = self._ideal_pixels(pose)
        if 'front' not in hidden:
            self._marker(out, front)
        if 'back' not in hidden:
            self._marker(out, back)
        if clutter:
            draw_clutter(out, self.camera, clutter, t, 'front', self._disc)
        return out

    def render(self, pose: RobotPose, hidden: Iterable[str] = (),
               pose_at: Optional[Callable[[float], RobotPose]] = None,
               t: Optional[float] = None, walls=None) -> np.ndarray:
        """
        One finished frame (a new array).

        With motion blur (options.exposure > 0) give ``pose_at(time)`` and the frame time ``t``:
        sub-frames are drawn over [t - exposure / 2, t + exposure / 2].

        ``walls``: the shape of bending walls at the frame time, (along (m,), deflection (2, m))
        in the surface frame: abscissae (m, increasing) and each wall's deflection there (m,
        bottom then top, > 0 away from the robot), as /saw/walls carries it. Each surface is
        drawn following it (the bottom's edge at y = -w(x), the top's at gap + w(x)), linear
        between the samples and flat beyond them. None (the default), or all zeros: flat
        surfaces, the same pixels as ever.
        """
        # A WallShape has been checked already (the camera node checks each cloud once).
        shape = walls if walls is None or isinstance(walls, WallShape) else \
            wall_shape(*walls)
        opt, scene = self.options, self.scene
        cam = self.camera
        t_frame = 0.0 if t is None else t
        brightness = opt.brightness * scene.gain(t_frame)
        if opt.exposure > 0 and opt.blur_samples > 1 and pose_at is not None and t is not None:
            accum = self._accum
            if accum is None:
                accum = self._accum = np.zeros((cam.height, cam.width, 3), np.float32)
            accum[...] = 0.0
            n = opt.blur_samples
            for k in range(n):
                tk = t + opt.exposure * ((k + 0.5) / n - 0.5)
                cv2.accumulate(self.draw(pose_at(tk), self._frame, hidden, tk, shape),
                               accum)
            if self._gradient is not None:
                frame = cv2.multiply(accum, self._gradient, scale=brightness / n,
                                     dtype=cv2.CV_8U)
            else:
                frame = cv2.convertScaleAbs(accum, alpha=brightness / n)
        elif self._gradient is None and brightness == 1.0 and self._reuses:
            # Drawn straight into a frame handed back (``recycle``): only the rows drawn on
            # there are the background's again, a tenth of the picture. A whole 1280x720
            # copy cost the camera node 0.3-0.5 ms a frame, from memory other processes' work
            # had taken out of the caches.
            frame = self._draw_over(pose, self._reused(), hidden, t_frame, shape)
            if len(self._drawn) > 4 * POOL + 256:
                self._drawn.clear()     # frames never handed back: drawn into no more
            self._drawn[id(frame)] = (self._rows[0], self._rows[1])
        elif self._gradient is None and brightness == 1.0:
            # Drawn straight into the new frame: a 1280x720 copy less per frame.
            frame = self.draw(pose, np.empty_like(self._frame), hidden, t_frame, shape)
        else:
            self.draw(pose, self._frame, hidden, t_frame, shape)
            if self._gradient is not None:
                frame = cv2.multiply(self._frame, self._gradient, scale=brightness,
                                     dtype=cv2.CV_8U)
            else:
                frame = cv2.convertScaleAbs(self._frame, alpha=brightness)
        if self._lens is not None:
            frame = cv2.remap(frame, self._lens[0], self._lens[1], cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
        if self._noise is not None:
            pos, neg = self._noise
            dy, dx = self._rng.integers(0, 32, 2)
            h, w = cam.height, cam.width
            cv2.add(frame, pos[dy:dy + h, dx:dx + w], dst=frame)
            # Same offset for both halves: pos - neg is the Gaussian sample itself.
            cv2.subtract(frame, neg[dy:dy + h, dx:dx + w], dst=frame)
        if scene.compression == 'jpeg':
            frame = jpeg(frame, scene.quality)
        return frame

    def _reused(self) -> np.ndarray:
        """Return a frame handed back, the background again where it was drawn (or a new one)."""
        try:
            frame, (first, end) = self._free.popleft()
        except IndexError:
            return self._background.copy()
        np.copyto(frame[first:end], self._background[first:end])
        return frame

    @property
    def background(self) -> np.ndarray:
        """Return the static picture the robot is drawn over (not to be written to)."""
        return self._background

    def rows_drawn(self, frame: np.ndarray) -> Optional[Tuple[int, int]]:
        """
        Return (first, end) of the rows ``render`` drew on in ``frame`` (not yet recycled).

        The frame is the background everywhere else. None: not known (any other picture).
        """
        return self._drawn.get(id(frame))

    def recycle(self, frame: np.ndarray) -> None:
        """
        Hand back a frame ``render`` returned, once nothing reads it: a later one is drawn in it.

        It must not have been written to. Frames of another renderer, of a picture drawn over
        as a whole (noise, lens, clutter, lighting) and frames beyond POOL are left alone.
        """
        rows = self._drawn.pop(id(frame), None)
        if rows is not None and len(self._free) < POOL:
            self._free.append((frame, rows))


class StampedSeries:
    """
    Time-stamped samples arriving in order (stamps increasing), linearly interpolated.

    Stamps are ns in the camera node. Keeps the last ``keep_ns`` (at least 4096 samples; None:
    all).
    """

    def __init__(self, keep_ns: Optional[int] = None):
        self.keep_ns = None if keep_ns is None else int(keep_ns)
        self.t: List[float] = []
        self.v: List[tuple] = []

    @classmethod
    def of(cls, t: Iterable[float], *columns: Iterable[float]) -> 'StampedSeries':
        """Return a whole record at once: stamps ``t`` and one sequence per value column."""
        series = cls()
        series.t = [float(s) for s in t]
        series.v = list(zip(*(np.asarray(c, float).tolist() for c in columns)))
        return series

    def add(self, t: float, values: tuple) -> bool:
        """Append; False (and cleared) when time went backwards (a replay restarted)."""
        if self.t and t <= self.t[-1]:
            if t == self.t[-1]:
                return True
            self.t.clear()
            self.v.clear()
            self.t.append(t)
            self.v.append(values)
            return False
        self.t.append(t)
        self.v.append(values)
        if (self.keep_ns is not None and len(self.t) > 4096
                and self.t[-1] - self.t[0] > self.keep_ns):
            cut = bisect.bisect_left(self.t, self.t[-1] - self.keep_ns)
            del self.t[:cut]
            del self.v[:cut]
        return True

    @property
    def last(self) -> float:
        return self.t[-1]

    def at(self, t: float, wrap: bool = False):
        """Values at time t (ns, float); clamped to the ends. ``wrap``: angles modulo 2 pi."""
        i = bisect.bisect_left(self.t, t)
        if i <= 0:
            return self.v[0]
        if i >= len(self.t):
            return self.v[-1]
        t0, t1 = self.t[i - 1], self.t[i]
        a, b = self.v[i - 1], self.v[i]
        w = (t - t0) / (t1 - t0)
        if wrap:
            return tuple(x + w * ((y - x + math.pi) % (2 * math.pi) - math.pi)
                         for x, y in zip(a, b))
        return tuple(x + w * (y - x) for x, y in zip(a, b))


class StampedShapes:
    """
    Stamped wall shapes (``WallShape``) arriving in order; ``before(t)`` gives the one at t.

    That is the last one stamped at or before t, while it is recent: no older than ``stale_ns``
    or three times the spacing of the last two, whichever is longer (walls that stop bending,
    surface.foundation_stiffness set to 0 while the simulator runs, stop publishing their
    shape: flat again). Keeps the last ``keep_ns`` of them; a stamp that goes back (a replay
    restarted) clears them. Stamps are ns in the camera node.
    """

    def __init__(self, keep_ns: int, stale_ns: int):
        self.keep_ns, self.stale_ns = int(keep_ns), int(stale_ns)
        self.t: List[int] = []
        self.v: List[WallShape] = []

    def add(self, t: int, shape: WallShape) -> None:
        """Keep ``shape`` stamped ``t``; it replaces one of the same stamp."""
        if self.t and t <= self.t[-1]:
            if t < self.t[-1]:
                self.t.clear()
                self.v.clear()
            else:
                self.t.pop()
                self.v.pop()
        self.t.append(t)
        self.v.append(shape)
        if self.t[-1] - self.t[0] > self.keep_ns:
            cut = bisect.bisect_left(self.t, self.t[-1] - self.keep_ns)
            del self.t[:cut]
            del self.v[:cut]

    def before(self, t: float) -> Optional[WallShape]:
        """Return the shape at ``t``: the last at or before it, if recent; else None (flat)."""
        i = bisect.bisect_right(self.t, t)
        if not i:
            return None
        spacing = self.t[-1] - self.t[-2] if len(self.t) > 1 else 0
        return self.v[i - 1] if t - self.t[i - 1] <= max(self.stale_ns, 3 * spacing) else None


def pose_between(poses: StampedSeries, phases: StampedSeries, t_ns: float,
                 deflections: Optional[StampedSeries] = None) -> RobotPose:
    """
    Return the pose at ``t_ns`` from streams of (x, y, theta) and (helix phase,) samples.

    ``deflections``: a stream of the links' deflections (one value a link), or None (or none
    yet): rigid links.
    """
    x, y, theta = poses.at(t_ns)
    (phase,) = phases.at(t_ns, wrap=True)
    deflection = deflections.at(t_ns) if deflections is not None and deflections.t else None
    return RobotPose(x, y, theta, phase % (2.0 * math.pi), deflection)


def pose_interpolator(t: np.ndarray, x: np.ndarray, y: np.ndarray, theta: np.ndarray,
                      phase: np.ndarray, deflection_t: Optional[np.ndarray] = None,
                      deflection: Optional[np.ndarray] = None) -> Callable[[float], RobotPose]:
    """
    pose_at(time) of a recorded run.

    The camera node's interpolation (``pose_between``) over the whole record. ``deflection``
    (N, n): the links' deflections at the times ``deflection_t`` (N,), or None: rigid links.
    """
    poses = StampedSeries.of(t, x, y, theta)
    phases = StampedSeries.of(t, phase)
    flexing = None
    if deflection is not None:
        if deflection_t is None:
            raise ValueError('deflections without their times (deflection_t)')
        flexing = StampedSeries.of(deflection_t, *np.asarray(deflection, float).T)
    return lambda time: pose_between(poses, phases, time, flexing)
