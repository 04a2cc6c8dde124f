"""
Footage shot the way users shoot it, drawn by other means than the renderer (issue 21).

The renderer (``frames``) draws the paper's robot through the tracker's own camera model; a test
made only of its frames cannot find what the tracker assumes about them. ``Shot`` draws a scene
of its own, with a known answer:
- the background is a generated "room": multi-scale coloured noise, posters, shelves and cables
  in muted and in strong colours (reds and skin tones included, no pink), the two boards of the
  track across it, red objects (some in shadow) and, if asked, pink discs that are not markers;
- the robot is a kinematic model, not the simulation: a dark body with a travelling light wave
  and two pink discs (OpenCV's anti-aliased circles, not the renderer's colour) ``spacing``
  apart, moving along a track climbing at ``slope_deg`` at a mean ``speed`` with a ripple at the
  wave frequency, bobbing and pitching a little;
- the camera is handheld: it drifts by ``drift`` pixels over the clip, jitters (``jitter`` px
  RMS, frame to frame), and may zoom (``zoom``: relative scale change over the clip) and roll
  (``roll_deg``); the picture is a warp of the scene, so everything moves together but the robot;
- an ``occluder``: a dark bar sweeping across in front of the robot;
- sensor noise and JPEG compression;
- a camera that is not square to the robot's plane (issue 32): turned by ``yaw_deg`` (about the
  picture's vertical) and ``pitch_deg`` (about its horizontal) about the plane's point at the
  picture's centre, ``distance`` m from it, seen through a lens with ``dist_coeffs`` (OpenCV's
  model, barrel k1 < 0, pincushion k1 > 0). ``plane()`` is the true homography from ideal pixels
  to the plane, ``lens()`` the true lens; ``board_still`` is a picture of the scene with a
  calibration board lying in the plane, and ``BoardClip`` a clip of a board waved in front of a
  camera (the lens calibration's footage, with its known K and distortion).

The scene frame is the picture of a fixed camera (``camera()``: a ``CameraModel`` of the
picture's size and scale, level); ``truth(t)`` gives the markers' surface-frame centres and
``mean_speed`` the robot's true mean speed over whole wave cycles; ``track_shot`` tracks a shot
as ``saw-ros track`` does and holds the result against them. Pure numpy and OpenCV.
"""
from __future__ import annotations

from dataclasses import dataclass, replace as replace_camera
import math
from typing import Iterator, List, Optional, Sequence, Tuple

import cv2
import numpy as np

from saw_ros.vision.calibration import Board
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.scene import distortion_maps
from saw_ros.vision.tracker import FrameResult, Tracker, TrackerConfig

MARKER_BGR = (175, 70, 250)        # RGB (250, 70, 175): a pink that is not the renderer's
SHIFT = 4                          # fixed-point bits for sub-pixel drawing
ONE = 1 << SHIFT
MARGIN = 320                       # px of scene drawn around the picture (camera drift)


def _apply(h: np.ndarray, p):
    """Return the points p (complex px) through the homography h."""
    den = h[2, 0] * p.real + h[2, 1] * p.imag + h[2, 2]
    return (h[0, 0] * p.real + h[0, 1] * p.imag + h[0, 2]) / den + \
        1j * (h[1, 0] * p.real + h[1, 1] * p.imag + h[1, 2]) / den


def _local_scale(h: np.ndarray, p: complex) -> float:
    """Return the homography's length scale near p (square root of its area ratio)."""
    e = 0.5
    a, b, c = _apply(h, np.array([p, p + e, p + 1j * e]))
    return math.sqrt(abs(((b - a).conjugate() * (c - a)).imag)) / e


@dataclass(frozen=True)
class Shot:
    """One clip: the robot, the scene and the camera (lengths in m, angles in degrees)."""

    duration: float = 8.0
    fps: float = 60.0
    width: int = 1280
    height: int = 720
    scale: float = 1200.0          # px/m in the robot's plane, for the fixed camera
    slope_deg: float = 0.0         # the track's climb as the level camera sees it
    speed: float = 0.07            # m/s, mean
    ripple: float = 0.25           # speed oscillation, fraction of speed, at wave_hz
    wave_hz: float = 1.5
    start_x: float = -0.2          # m, robot centre on the track at t = 0 (track x = 0 at the
    track_y: float = 0.0           # ... picture's centre, shifted by track_y across the track)
    spacing: float = 0.32          # m between the marker centres
    marker_diameter: float = 0.012
    drift: Tuple[float, float] = (0.0, 0.0)     # px over the clip (picture moves by minus it)
    jitter: float = 0.0            # px RMS per frame
    zoom: float = 0.0              # relative scale change over the clip
    roll_deg: float = 0.0          # camera roll over the clip
    red_clutter: bool = True       # red objects (and shadowed red) in view
    pink_clutter: int = 0          # static pink discs of a marker's size in view, not markers
    occluder: bool = False         # a dark bar sweeps across the robot
    noise: float = 3.0             # grey levels RMS
    quality: int = 85              # JPEG quality; 0: none
    seed: int = 1
    yaw_deg: float = 0.0           # camera turned about the picture's vertical, to the plane
    pitch_deg: float = 0.0         # ... about its horizontal
    distance: float = 1.0          # m, camera to the plane's point at the picture's centre
    dist_coeffs: Tuple[float, ...] = ()       # the lens (OpenCV's k1, k2, p1, p2[, k3])

    def __post_init__(self):
        if not (self.duration > 0 and self.fps > 0 and self.scale > 0 and self.spacing > 0
                and self.distance > 0):
            raise ValueError('shot duration, fps, scale, spacing and distance must be > 0')
        if not 0 <= self.quality <= 100:
            raise ValueError(f'shot quality = {self.quality!r}: 0 (none) or 1-100')
        if not (abs(self.yaw_deg) < 60 and abs(self.pitch_deg) < 60):
            raise ValueError('shot yaw_deg and pitch_deg must be within 60 deg')

    # -- the camera that films it --------------------------------------------------------------
    @property
    def square(self) -> bool:
        """Whether the camera looks square at the plane through a perfect lens."""
        return self.yaw_deg == 0 and self.pitch_deg == 0 and not any(self.dist_coeffs)

    def view(self) -> np.ndarray:
        """
        Return the homography from the level square camera's pixels to this camera's ideal ones.

        A plane point (X, Y) (m, right and up from the point at the picture's centre) is at
        R (X, -Y, 0) + (0, 0, distance) in this camera's frame (x right, y down, z forward); R
        turns by the pitch about x, then the yaw about y; K has f = scale * distance.
        """
        cx, cy = (self.width - 1) / 2.0, (self.height - 1) / 2.0
        a, b = math.radians(self.yaw_deg), math.radians(self.pitch_deg)
        ry = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
        rx = np.array([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]])
        r = ry @ rx
        f = self.scale * self.distance
        k = np.array([[f, 0, cx], [0, f, cy], [0, 0, 1.0]])
        m = k @ np.stack([r[:, 0], -r[:, 1], [0.0, 0.0, self.distance]], -1)
        to_plane = np.array([[1 / self.scale, 0, -cx / self.scale],
                             [0, -1 / self.scale, cy / self.scale], [0, 0, 1.0]])
        h = m @ to_plane
        return h / h[2, 2]

    def plane(self) -> np.ndarray:
        """Return the truth: the 3x3 map from this camera's ideal pixels to metres on the plane."""
        to_plane = np.array([[1 / self.scale, 0, -(self.width - 1) / 2.0 / self.scale],
                             [0, -1 / self.scale, (self.height - 1) / 2.0 / self.scale],
                             [0, 0, 1.0]])
        h = to_plane @ np.linalg.inv(self.view())
        return h / h[2, 2]

    def lens(self) -> CameraModel:
        """Return the true lens as a camera model (K of f = scale * distance, the distortion)."""
        return CameraModel(width=self.width, height=self.height, scale=self.scale,
                           distance=self.distance, dist_coeffs=self.dist_coeffs)

    def calibrated_camera(self, slope_known: bool = True) -> CameraModel:
        """Return the camera a tracker gets from a perfect lens and plane calibration."""
        lens = self.lens()
        return replace_camera(self.camera(slope_known), plane=tuple(self.plane().ravel()),
                              dist_coeffs=lens.dist_coeffs,
                              dist_matrix=tuple(lens._dist_K()[[0, 1, 0, 1], [0, 1, 2, 2]]))

    def ruler_scale(self) -> float:
        """
        Return the px per metre a ruler along the track at the picture's centre measures.

        The scale a user gives without a calibration: right there, wrong away from there when
        the camera is not square to the plane.
        """
        to_image = np.linalg.inv(self.plane())
        slope = math.radians(self.slope_deg)
        c = complex(_apply(self.plane(), np.array(complex((self.width - 1) / 2.0,
                                                          (self.height - 1) / 2.0))))
        half = 0.005 * complex(math.cos(slope), math.sin(slope))
        a, b = _apply(to_image, np.array([c - half, c + half]))
        return float(abs(b - a) / 0.01)

    def picture_of(self, scene_px) -> np.ndarray:
        """Return where the scene frame's pixels are in this camera's picture (lens included)."""
        p = _apply(self.view(), np.asarray(scene_px))
        return self.lens().distort(p)

    # -- geometry ------------------------------------------------------------------------------
    def camera(self, slope_known: bool = True) -> CameraModel:
        """Return the fixed camera: the scene frame (slope 0 unless ``slope_known``)."""
        return CameraModel(width=self.width, height=self.height, scale=self.scale,
                           slope=math.radians(self.slope_deg) if slope_known else 0.0,
                           center_x=0.0, center_y=self.track_y)

    @property
    def times(self) -> np.ndarray:
        return np.arange(int(round(self.duration * self.fps))) / self.fps

    def pose(self, t: float) -> Tuple[float, float, float]:
        """Robot centre (track x, y normal to it, m) and pitch (rad) at time t."""
        w = 2.0 * math.pi * self.wave_hz
        x = self.start_x + self.speed * t + self.ripple * self.speed / w * math.sin(w * t)
        y = self.track_y + 0.0225 + 0.0004 * math.sin(w * t + 0.7)     # mid-gap
        return x, y, math.radians(0.4) * math.sin(w * t + 1.9)

    def truth(self, t: float) -> Tuple[complex, complex]:
        """(front, back) marker centres in the surface frame (complex, m)."""
        x, y, pitch = self.pose(t)
        half = 0.5 * self.spacing * complex(math.cos(pitch), math.sin(pitch))
        return complex(x, y) + half, complex(x, y) - half

    def mean_speed(self) -> float:
        """Return the true mean speed (whole wave cycles: the ripple cancels), m/s."""
        return self.speed

    def _camera_motion(self) -> np.ndarray:
        """Per frame 2x3 similarity: scene pixel -> picture pixel."""
        rng = np.random.default_rng(self.seed + 7)
        n = len(self.times)
        s = np.linspace(0.0, 1.0, n)
        # The drift starts and stops gently (a hand), the jitter is white frame to frame.
        ease = 0.5 - 0.5 * np.cos(np.pi * s)
        shake = rng.normal(0.0, self.jitter / math.sqrt(2.0), (n, 2)) if self.jitter else \
            np.zeros((n, 2))
        c = np.array([(self.width - 1) / 2.0, (self.height - 1) / 2.0])
        out = np.empty((n, 2, 3))
        for k in range(n):
            zoom = 1.0 + self.zoom * ease[k]
            a = math.radians(self.roll_deg) * ease[k]
            r = zoom * np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
            shift = -np.array(self.drift) * ease[k] + shake[k]
            out[k, :, :2] = r
            out[k, :, 2] = c - r @ c + shift
        return out

    # -- drawing -------------------------------------------------------------------------------
    def _background(self) -> np.ndarray:
        """Return the static scene, MARGIN px larger than the picture on every side."""
        rng = np.random.default_rng(self.seed)
        h, w = self.height + 2 * MARGIN, self.width + 2 * MARGIN
        img = np.zeros((h, w, 3), np.float32)
        for cell, weight in ((240, 45.0), (60, 25.0), (12, 14.0), (3, 7.0)):
            # Mostly brightness, a little colour: plaster, wood, fabric.
            field = rng.normal(0.0, 1.0, (h // cell + 2, w // cell + 2, 1)) * [1.0, 1.0, 1.0] \
                + rng.normal(0.0, 0.2, (h // cell + 2, w // cell + 2, 3))
            img += weight * cv2.resize(field.astype(np.float32), (w, h),
                                       interpolation=cv2.INTER_CUBIC)
        img += np.array([120.0, 135.0, 145.0], np.float32)        # a warm grey wall
        palette = [(40, 40, 160), (30, 60, 200), (60, 110, 200), (90, 140, 220),   # reds, skin
                   (150, 100, 60), (60, 120, 60), (200, 200, 190), (30, 30, 30),
                   (80, 160, 200), (120, 90, 70), (170, 170, 60), (20, 90, 140)]
        for _ in range(70):                                          # posters, boxes, shelves
            colour = palette[rng.integers(len(palette))]
            x0, y0 = rng.integers(0, w), rng.integers(0, h)
            bw, bh = rng.integers(20, 260), rng.integers(10, 200)
            if rng.random() < 0.5:
                cv2.rectangle(img, (int(x0), int(y0)), (int(x0 + bw), int(y0 + bh)), colour, -1,
                              cv2.LINE_AA)
            else:
                cv2.ellipse(img, (int(x0), int(y0)), (int(bw // 2), int(bh // 2)),
                            float(rng.uniform(0, 180)), 0, 360, colour, -1, cv2.LINE_AA)
        for _ in range(25):                                          # cables, edges, text
            p0 = (int(rng.integers(0, w)), int(rng.integers(0, h)))
            p1 = (int(p0[0] + rng.integers(-300, 300)), int(p0[1] + rng.integers(-300, 300)))
            cv2.line(img, p0, p1, palette[rng.integers(len(palette))], int(rng.integers(1, 5)),
                     cv2.LINE_AA)
        cam = self.camera()
        half = 1.5 * (self.width + 2 * MARGIN) / self.scale
        for low, high, colour in ((-0.035, -0.008, (60, 100, 140)), (0.053, 0.080, (60, 100, 140)),
                                  (-0.008, 0.0, (190, 200, 205)), (0.045, 0.053, (190, 200, 205))):
            corners = np.array([-half + 1j * low, half + 1j * low, half + 1j * high,
                                -half + 1j * high])
            self._poly(img, cam.to_pixels(corners + 1j * self.track_y) + MARGIN * (1 + 1j),
                       colour)
        if self.red_clutter:
            for x, y, r, colour in ((0.05, 0.17, 0.03, (35, 30, 200)),
                                    (-0.30, 0.15, 0.012, (25, 20, 110)),      # red in shadow
                                    (-0.22, 0.15, 0.012, (25, 20, 110)),
                                    (0.35, -0.14, 0.02, (40, 25, 215)),
                                    (-0.40, -0.12, 0.04, (30, 45, 170))):
                self._disc(img, cam.to_pixels(complex(x, y + self.track_y)) + MARGIN * (1 + 1j),
                           r * self.scale, colour)
        for k in range(self.pink_clutter):
            p = complex(-0.35 + 0.25 * k, 0.13 + 0.02 * k + self.track_y)
            self._disc(img, cam.to_pixels(p) + MARGIN * (1 + 1j),
                       0.5 * self.marker_diameter * self.scale, MARKER_BGR)
        return np.clip(cv2.GaussianBlur(img, (0, 0), 0.7), 0, 255).astype(np.uint8)

    @staticmethod
    def _poly(img, points, colour) -> None:
        pts = np.stack([np.rint(points.real * ONE), np.rint(points.imag * ONE)], -1)
        cv2.fillPoly(img, [pts.astype(np.int32)], colour, cv2.LINE_AA, SHIFT)

    @staticmethod
    def _disc(img, centre: complex, radius: float, colour) -> None:
        cv2.circle(img, (int(round(centre.real * ONE)), int(round(centre.imag * ONE))),
                   int(round(radius * ONE)), colour, -1, cv2.LINE_AA, SHIFT)

    def _robot(self, img, t: float, to_picture, zoom: float) -> None:
        """Draw the robot (body, wave, markers) at time t into the picture."""
        x, y, pitch = self.pose(t)
        cam = self.camera()
        rot = complex(math.cos(pitch), math.sin(pitch))
        centre = complex(x, y)

        def px(points):
            return to_picture(cam.to_pixels(centre + rot * np.asarray(points)))
        self._poly(img, px(np.array([-0.21 - 0.02j, 0.21 - 0.02j, 0.21 + 0.02j, -0.21 + 0.02j])),
                   (55, 60, 62))
        s = np.linspace(-0.19, 0.19, 60)
        phase = 2.0 * math.pi * self.wave_hz * t
        wave = s + 1j * (0.014 * np.sin(2.0 * math.pi * s / 0.1 - phase))
        pts = px(wave)
        cv2.polylines(img, [np.stack([np.rint(pts.real * ONE), np.rint(pts.imag * ONE)], -1)
                            .astype(np.int32)], False, (185, 190, 190),
                      max(1, int(round(0.006 * self.scale * zoom))), cv2.LINE_AA, SHIFT)
        for m in (0.5 * self.spacing, -0.5 * self.spacing):
            self._disc(img, complex(px(m)),
                       0.5 * self.marker_diameter * self.scale * zoom, MARKER_BGR)

    def frames(self) -> Iterator[Tuple[int, float, np.ndarray]]:
        """Yield (index, t, BGR frame): a frame source (saw_ros.vision.offline)."""
        return self._frames(self._background(), robot=True)

    def board_still(self, board: Board, at: complex = 0j, px_per_square: int = 48) -> \
            np.ndarray:
        """
        Return one picture of the scene (no robot) with ``board`` lying in the robot's plane.

        The board's point (0, 0) at the surface point ``at`` (m, track frame), its rows along
        the plane's x (level), its columns down: the plane it gives is the true one moved.
        """
        background = self._background()
        img = board.image(px_per_square)
        o, per_m = board.origin_px(px_per_square), px_per_square / board.square
        cam = self.camera(False)
        origin = complex(cam.to_pixels(at + 1j * self.track_y)) + MARGIN * (1 + 1j)
        k = self.scale / per_m
        to_bg = np.array([[k, 0, origin.real - k * o], [0, k, origin.imag - k * o]])
        size = (background.shape[1], background.shape[0])
        warped = cv2.warpAffine(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR), to_bg, size,
                                flags=cv2.INTER_AREA)
        mask = cv2.warpAffine(np.full(img.shape, 255, np.uint8), to_bg, size,
                              flags=cv2.INTER_AREA)[..., None] / 255.0
        background = (background * (1 - mask) + warped * mask).astype(np.uint8)
        return next(self._frames(background, robot=False))[2]

    def _frames(self, background: np.ndarray, robot: bool) -> \
            Iterator[Tuple[int, float, np.ndarray]]:
        motion = self._camera_motion()
        view = self.view()
        lens = self.lens()
        lens_maps = distortion_maps(lens) if lens.distorted else None
        rng = np.random.default_rng(self.seed + 3)
        noise = np.rint(rng.normal(0.0, self.noise, (self.height + 16, self.width + 16, 3))) \
            .astype(np.int16) if self.noise > 0 else None
        cam = self.camera()
        for k, t in enumerate(self.times):
            m = motion[k]
            if self.square:
                into_bg = m.copy()
                into_bg[:, 2] -= m[:, :2] @ np.array([MARGIN, MARGIN])
                frame = cv2.warpAffine(background, into_bg, (self.width, self.height),
                                       flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)

                def to_picture(p, m=m):
                    p = np.asarray(p)
                    return (m[0, 0] * p.real + m[0, 1] * p.imag + m[0, 2]) + \
                        1j * (m[1, 0] * p.real + m[1, 1] * p.imag + m[1, 2])
                zoom = math.hypot(m[0, 0], m[1, 0])
            else:
                # The handheld motion acts on this camera's picture, after the view.
                g = np.vstack([m, [0.0, 0.0, 1.0]]) @ view
                shift = np.array([[1.0, 0, -MARGIN], [0, 1.0, -MARGIN], [0, 0, 1.0]])
                frame = cv2.warpPerspective(background, g @ shift, (self.width, self.height),
                                            flags=cv2.INTER_LINEAR,
                                            borderMode=cv2.BORDER_REFLECT)

                def to_picture(p, g=g):
                    return _apply(g, np.asarray(p))
                # (discs drawn with the local scale at the picture's centre: a 14 px marker's
                # ellipse has the same centroid as its circle to 0.01 px)
                zoom = _local_scale(g, complex((self.width - 1) / 2.0, (self.height - 1) / 2.0))
            if robot:
                self._robot(frame, float(t), to_picture, zoom)
            if self.occluder:
                # A bar 3 cm wide sweeping right to left across the robot every 2 s.
                u = (1.0 - ((t * 0.5) % 1.0)) * (self.width + 200) - 100
                x_track = cam.to_surface(complex(u, self.height / 2)).real
                bar = np.array([x_track - 0.015 - 0.12j, x_track + 0.015 - 0.12j,
                                x_track + 0.015 + 0.17j, x_track - 0.015 + 0.17j]) + \
                    1j * self.track_y
                self._poly(frame, to_picture(cam.to_pixels(bar)), (40, 35, 30))
            if lens_maps is not None:
                frame = cv2.remap(frame, lens_maps[0], lens_maps[1], cv2.INTER_LINEAR,
                                  borderMode=cv2.BORDER_REFLECT)
            if noise is not None:
                dy, dx = rng.integers(0, 16, 2)
                frame = np.clip(frame + noise[dy:dy + self.height, dx:dx + self.width], 0, 255) \
                    .astype(np.uint8)
            if self.quality:
                ok, buf = cv2.imencode('.jpg', frame, [cv2.IMWRITE_JPEG_QUALITY, self.quality])
                frame = np.asarray(cv2.imdecode(buf, cv2.IMREAD_COLOR))
            yield k, float(t), frame

    def occluded(self, t: float, name: str) -> bool:
        """Whether the occluder covers any of marker ``name`` ('front', 'back') at time t."""
        if not self.occluder:
            return False
        cam = self.camera()
        u = (1.0 - ((t * 0.5) % 1.0)) * (self.width + 200) - 100
        x_track = cam.to_surface(complex(u, self.height / 2)).real
        front, back = self.truth(t)
        p = front if name == 'front' else back
        return abs(p.real - x_track) <= 0.015 + 0.5 * self.marker_diameter + 0.001

    def visible(self, t: float, name: str) -> bool:
        """Whether marker ``name`` is fully in the picture of the fixed camera and not hidden."""
        front, back = self.truth(t)
        p = complex(self.camera(True).to_pixels(front if name == 'front' else back))
        if not self.square:
            p = complex(self.picture_of(p))
        r = 0.5 * self.marker_diameter * self.scale + 12.0     # room for drift of a few px
        return r <= p.real <= self.width - 1 - r and r <= p.imag <= self.height - 1 - r and \
            not self.occluded(t, name)

    @property
    def size(self) -> Tuple[int, int]:
        return self.width, self.height


@dataclass
class ShotResult:
    """What the tracker made of a shot, against the truth."""

    speed: Optional[float]          # the speed it would print: steady speed of its last pair, m/s
    speed_error_pct: float          # against the true mean speed (inf without a speed)
    visible_frames: int             # both markers fully in view
    ok_visible_frames: int          # ... and both measured on the marker (within its radius)
    wrong_frames: int               # ok frames with a marker off by more than its radius
    warnings: List[str]
    notes: List[str]
    tracker: Tracker
    results: List[FrameResult]

    @property
    def ok_frames_pct(self) -> float:
        return 100.0 * self.ok_visible_frames / self.visible_frames if self.visible_frames \
            else 0.0

    @property
    def silent_wrong(self) -> bool:
        """Whether a speed more than 2 % wrong would be printed without a warning."""
        return self.speed is not None and self.speed_error_pct > 2.0 and not self.warnings


def track_shot(shot: Shot, slope_known: bool = False, config: TrackerConfig = TrackerConfig(),
               camera: Optional[CameraModel] = None) -> ShotResult:
    """
    Track a shot as ``saw-ros track`` does (the scale given), and hold it against the truth.

    ``slope_known``: the track's slope given (True) or taken from the motion (the default of the
    command); ``camera``: the camera the tracker is given, if not the shot's fixed camera.
    """
    return track_shot_ways(shot, [(slope_known, config, camera)])[0]


def track_shot_ways(shot: Shot, ways: Sequence[Tuple[bool, TrackerConfig,
                                                     Optional[CameraModel]]]) -> List[ShotResult]:
    """
    Track one rendering of a shot with several trackers: ``track_shot`` for each of ``ways``.

    Each way is (slope_known, config, camera); the frames are drawn once for all of them.
    """
    trackers = [Tracker(camera or shot.camera(slope_known), config, slope_known=slope_known)
                for slope_known, config, camera in ways]
    visible = 0
    ok_visible = [0] * len(trackers)
    wrong = [0] * len(trackers)
    results: List[List[FrameResult]] = [[] for _ in trackers]
    for _, t, frame in shot.frames():
        seen = shot.visible(t, 'front') and shot.visible(t, 'back')
        visible += seen
        for i, tracker in enumerate(trackers):
            res = tracker.update(frame, t)
            results[i].append(res)
            if res.ok and res.front is not None and res.back is not None:
                # The truth in the tracker's surface frame: the track's when the slope is used.
                front, back = shot.truth(t)
                right = max(abs(res.front - front), abs(res.back - back)) <= \
                    0.5 * shot.marker_diameter
                wrong[i] += not right
                ok_visible[i] += seen and right
    out = []
    for i, tracker in enumerate(trackers):
        since = tracker.switched_at if tracker.switched_at is not None else -math.inf
        speed = next((r.steady_speed for r in reversed(results[i])
                      if r.steady_speed is not None and r.t > since), None)
        error = math.inf if speed is None else \
            100.0 * abs(speed - shot.mean_speed()) / shot.mean_speed()
        out.append(ShotResult(speed, error, visible, ok_visible[i], wrong[i], tracker.warnings,
                              tracker.notes, tracker, results[i]))
    return out


@dataclass(frozen=True)
class BoardClip:
    """
    A calibration board waved in front of a camera: the lens calibration's footage.

    ``views`` pictures of ``board`` held ``near``-``far`` m away, tilted by up to ``tilt_deg``
    towards and away from the camera, left and right (``tilt_deg`` 0: every view parallel to the
    picture), turned a little in the picture, somewhere in view; drawn through the pinhole camera
    of focal length ``focal`` px and the lens ``dist_coeffs``. ``blur`` px of Gaussian blur
    (sigma), ``noise`` grey levels; ``cut`` views pushed half out of the picture. A frame source
    (``size``, ``frames()``); ``lens()`` is the truth.
    """

    board: Board
    width: int = 640
    height: int = 360
    focal: float = 600.0
    dist_coeffs: Tuple[float, ...] = ()
    views: int = 16
    near: float = 0.35
    far: float = 0.6
    tilt_deg: float = 35.0
    blur: float = 0.0
    noise: float = 2.0
    cut: int = 0
    fps: float = 10.0
    seed: int = 3

    @property
    def size(self) -> Tuple[int, int]:
        return self.width, self.height

    def lens(self) -> CameraModel:
        """Return the true camera: K (f = ``focal``, centre) and the distortion."""
        return CameraModel(width=self.width, height=self.height, scale=self.focal, distance=1.0,
                           dist_coeffs=self.dist_coeffs)

    def _pose(self, rng, k: int) -> Tuple[np.ndarray, np.ndarray]:
        """Return the board's rotation and the camera-frame position of its centre."""
        a = math.radians(self.tilt_deg)
        # Tilts spread over the clip: about x and y in turn, both signs (a hand waving it).
        ax = a * math.sin(2.4 * k + 0.3) * rng.uniform(0.6, 1.0)
        ay = a * math.cos(1.7 * k) * rng.uniform(0.6, 1.0)
        az = math.radians(rng.uniform(-15.0, 15.0))
        r = cv2.Rodrigues(np.array([ax, ay, az]))[0]
        z = rng.uniform(self.near, self.far)
        half_w, half_h = 0.5 * self.width / self.focal * z, 0.5 * self.height / self.focal * z
        b = self.board
        extent = 0.5 * (b.cols + 1) * b.square
        room = np.array([max(half_w - extent, 0.0), max(half_h - 0.7 * extent, 0.0)])
        xy = rng.uniform(-1.0, 1.0, 2) * room * 0.8
        if k < self.cut:
            xy[0] = half_w * (1.0 if k % 2 else -1.0)        # half out of the picture
        return r, np.array([xy[0], xy[1], z])

    def frames(self) -> Iterator[Tuple[int, float, np.ndarray]]:
        """Yield (index, t, BGR frame)."""
        rng = np.random.default_rng(self.seed)
        s = 48
        img = self.board.image(s)
        o, per_m = self.board.origin_px(s), s / self.board.square
        centre = self.board.object_points()[:, :2].mean(0) if self.board.kind == 'chessboard' \
            else 0.5 * np.array([self.board.cols, self.board.rows]) * self.board.square
        from_img = np.array([[1 / per_m, 0, -o / per_m], [0, 1 / per_m, -o / per_m], [0, 0, 1]])
        lens = self.lens()
        maps = distortion_maps(lens) if lens.distorted else None
        k_mat = lens.K
        for k in range(self.views):
            r, t = self._pose(rng, k)
            t = t - r @ np.array([centre[0], centre[1], 0.0])
            h = k_mat @ np.stack([r[:, 0], r[:, 1], t], -1) @ from_img
            frame = cv2.warpPerspective(img, h, (self.width, self.height), flags=cv2.INTER_LINEAR,
                                        borderMode=cv2.BORDER_CONSTANT, borderValue=110)
            if maps is not None:
                frame = cv2.remap(frame, maps[0], maps[1], cv2.INTER_LINEAR,
                                  borderMode=cv2.BORDER_CONSTANT, borderValue=110)
            if self.blur > 0:
                frame = cv2.GaussianBlur(frame, (0, 0), self.blur)
            if self.noise > 0:
                frame = np.clip(frame + rng.normal(0.0, self.noise, frame.shape), 0, 255)
            yield k, k / self.fps, cv2.cvtColor(frame.astype(np.uint8), cv2.COLOR_GRAY2BGR)
