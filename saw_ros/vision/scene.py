"""
Footage that does not look like the renderer's: clutter, lighting, lens and codec.

``SceneOptions`` adds to a rendered run what real footage has and the tracker must survive:
- ``clutter``: coloured things in view (``Clutter``: disc or box, RGB colour, surface-frame
  position and velocity, on the wall behind the robot or in front of it, between robot and camera):
  red, orange, magenta objects, a third pink marker, static or moving;
- lighting: a brightness ``gradient`` across the picture (gain 1 - g .. 1 + g along
  ``gradient_angle``) and ``flicker`` (gain 1 + a sin(2 pi ``flicker_hz`` t): mains light at 100 Hz
  seen at 60 fps beats at 20 Hz);
- ``compression``: every frame through JPEG ('jpeg', at ``quality``) or the whole run through the
  .mp4 writer ('mp4', codec mp4v, which takes no quality setting) and back.
Sensor noise and motion blur are ``RenderOptions`` (noise, exposure); lens distortion is the
camera's (``CameraModel.dist_coeffs``): the renderer draws the ideal image and warps it.

``synthetic.cluttered_scene`` builds the hard case of the tests and the benchmark from these.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Iterable, Tuple

import cv2
import numpy as np

from saw_ros.vision.camera import CameraModel

# RGB
HOT_PINK = (255, 60, 170)        # the renderer's marker colour (render.PINK is its BGR)
RED = (210, 25, 30)
ORANGE_RED = (255, 69, 0)
ORANGE = (255, 150, 20)
MAGENTA = (230, 20, 230)

LAYERS = ('wall', 'front')
SHAPES = ('disc', 'box')
COMPRESSION = ('', 'jpeg', 'mp4')


@dataclass(frozen=True)
class Clutter:
    """One thing in view that is not the robot. Positions in the surface frame (m)."""

    colour: Tuple[int, int, int]             # RGB
    x: float                                 # m, centre at t = 0
    y: float
    size: Tuple[float, float] = (0.012, 0.012)   # m: disc diameter (first), box width x height
    shape: str = 'disc'
    velocity: Tuple[float, float] = (0.0, 0.0)   # m/s, surface frame
    layer: str = 'wall'                      # 'wall': behind the robot; 'front': occludes it

    def __post_init__(self):
        if self.shape not in SHAPES:
            raise ValueError(f'clutter shape {self.shape!r}: one of {SHAPES}')
        if self.layer not in LAYERS:
            raise ValueError(f'clutter layer {self.layer!r}: one of {LAYERS}')
        if not (len(self.colour) == 3 and all(0 <= c <= 255 for c in self.colour)):
            raise ValueError(f'clutter colour {self.colour!r}: RGB, 0-255')
        if not (len(self.size) == 2 and self.size[0] > 0 and self.size[1] > 0):
            raise ValueError(f'clutter size {self.size!r}: two lengths > 0, m')

    def centre(self, t: float) -> complex:
        return complex(self.x + self.velocity[0] * t, self.y + self.velocity[1] * t)

    def covers(self, point: complex, t: float, margin: float = 0.0) -> bool:
        """Whether the thing covers a surface-frame point at time t (within margin, m)."""
        d = point - self.centre(t)
        if self.shape == 'disc':
            return abs(d) <= self.size[0] / 2.0 + margin
        return abs(d.real) <= self.size[0] / 2.0 + margin and \
            abs(d.imag) <= self.size[1] / 2.0 + margin


@dataclass(frozen=True)
class SceneOptions:
    clutter: Tuple[Clutter, ...] = ()
    gradient: float = 0.0            # gain varies 1 - g .. 1 + g across the picture
    gradient_angle: float = 0.0      # rad, direction of increasing gain (0: to the right)
    flicker: float = 0.0             # amplitude of the gain's flicker
    flicker_hz: float = 100.0        # Hz (sampled at the frame times)
    compression: str = ''            # '', 'jpeg' (per frame) or 'mp4' (the whole run)
    quality: int = 75                # JPEG quality 1-100

    def __post_init__(self):
        object.__setattr__(self, 'clutter', tuple(self.clutter))
        if not 0 <= self.gradient < 1:
            raise ValueError(f'scene gradient = {self.gradient!r}: allowed [0, 1)')
        if not 0 <= self.flicker < 1:
            raise ValueError(f'scene flicker = {self.flicker!r}: allowed [0, 1)')
        if self.compression not in COMPRESSION:
            raise ValueError(f'scene compression {self.compression!r}: one of {COMPRESSION}')
        if not 1 <= self.quality <= 100:
            raise ValueError(f'scene quality = {self.quality!r}: allowed 1-100')

    @property
    def lighting(self) -> bool:
        return self.gradient > 0 or self.flicker > 0

    def gain(self, t: float) -> float:
        """Return the flicker's factor at time t."""
        return 1.0 + self.flicker * math.sin(2.0 * math.pi * self.flicker_hz * t)

    def occluded(self, point: complex, t: float, radius: float) -> bool:
        """Whether something in front covers any of a disc of ``radius`` m at ``point``."""
        return any(c.layer == 'front' and c.covers(point, t, radius + 0.001)
                   for c in self.clutter)


def gradient_map(camera: CameraModel, scene: SceneOptions) -> np.ndarray:
    """H x W x 3 float32 gain of the lighting gradient (1 - g .. 1 + g)."""
    h, w = camera.height, camera.width
    u = (np.arange(w, dtype=np.float32) - (w - 1) / 2) / ((w - 1) / 2)
    v = (np.arange(h, dtype=np.float32) - (h - 1) / 2) / ((h - 1) / 2)
    c, s = math.cos(scene.gradient_angle), math.sin(scene.gradient_angle)
    ramp = c * u[None, :] - s * v[:, None]          # image v is down
    ramp /= max(float(np.abs(ramp).max()), 1e-9)
    gain = 1.0 + scene.gradient * ramp
    return np.repeat(gain[..., None], 3, axis=2).astype(np.float32)


def distortion_maps(camera: CameraModel):
    """
    cv2.remap maps that warp the ideal image into the distorted one.

    For every image pixel, the ideal pixel the lens brought there.
    """
    u, v = np.meshgrid(np.arange(camera.width, dtype=np.float64),
                       np.arange(camera.height, dtype=np.float64))
    ideal = camera.undistort(u + 1j * v)
    return ideal.real.astype(np.float32), ideal.imag.astype(np.float32)


def jpeg(frame: np.ndarray, quality: int) -> np.ndarray:
    ok, buf = cv2.imencode('.jpg', frame, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError('JPEG encoding failed')
    return np.asarray(cv2.imdecode(buf, cv2.IMREAD_COLOR))


def draw_clutter(img: np.ndarray, camera: CameraModel, things: Iterable[Clutter], t: float,
                 layer: str, disc) -> None:
    """
    Draw the things of one layer into an ideal (undistorted) frame.

    ``disc(img, centre_px, radius_px, bgr)`` draws an anti-aliased disc.
    """
    for c in things:
        if c.layer != layer:
            continue
        bgr = (c.colour[2], c.colour[1], c.colour[0])
        centre = complex(camera.to_pixels(c.centre(t)))
        if c.shape == 'disc':
            disc(img, centre, c.size[0] / 2.0 * camera.scale, bgr)
        else:
            hw, hh = c.size[0] / 2.0, c.size[1] / 2.0
            corners = c.centre(t) + np.array([-hw - hh * 1j, hw - hh * 1j, hw + hh * 1j,
                                              -hw + hh * 1j])
            p = camera.to_pixels(corners)
            pts = np.stack([np.rint(p.real * 16), np.rint(p.imag * 16)], -1).astype(np.int32)
            cv2.fillConvexPoly(img, pts, bgr, cv2.LINE_AA, 4)
