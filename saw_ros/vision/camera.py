"""The camera model of the renderer and the tracker: a level pinhole camera beside the track.

The camera looks square at the plane in which the robot moves (its side), from ``distance``
metres. In that plane one metre is ``scale`` pixels (f = scale * distance is the focal length
in pixels that goes into CameraInfo's K). The camera is level, so the surfaces appear inclined
at the slope alpha; the point of the surface frame seen at the principal point is
(``center_x``, ``center_y``).

Pixel convention (OpenCV and ROS CameraInfo): pixel (u, v) has its centre at integer (u, v), u to
the right, v down; the principal point defaults to the image centre ((W - 1) / 2, (H - 1) / 2).

Surface frame (model.md): x along the surfaces in the direction of travel, y normal to them away
from the bottom surface. With ``mirror`` False the robot travels to the right of the image (up to
the right when climbing); ``mirror`` True is for videos in which it travels to the left.

Mapping, with points as complex numbers x + i y:
    w = (s - c) e^(i alpha)           surface -> level world (horizontal, up), m
    w = -conj(w) if mirror
    u = cx + scale Re(w),  v = cy - scale Im(w)
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np


@dataclass(frozen=True)
class CameraModel:
    width: int = 1280            # px
    height: int = 720            # px
    scale: float = 1200.0        # px per metre in the plane of motion
    slope: float = 0.0           # rad, the surfaces' angle to the image horizontal (+ climbs)
    center_x: float = 0.33       # m, surface-frame x seen at the principal point
    center_y: float = 0.0225     # m, surface-frame y seen at the principal point
    distance: float = 1.0        # m, optical centre to the plane of motion (f = scale * distance)
    mirror: bool = False         # True: surface +x points to the image's left
    cx: Optional[float] = None   # px, principal point; None = image centre
    cy: Optional[float] = None   # px

    def __post_init__(self):
        if self.width < 16 or self.height < 16:
            raise ValueError(f'camera size {self.width}x{self.height} is too small (>= 16x16)')
        if not (self.scale > 0 and math.isfinite(self.scale)):
            raise ValueError(f'camera scale = {self.scale!r} px/m is invalid: must be > 0')
        if not (self.distance > 0 and math.isfinite(self.distance)):
            raise ValueError(f'camera distance = {self.distance!r} m is invalid: must be > 0')
        if not abs(self.slope) <= math.pi / 2:
            raise ValueError(f'camera slope = {self.slope!r} rad is invalid: allowed '
                             f'[-pi/2, pi/2]')

    # -- intrinsics ----------------------------------------------------------------------------
    @property
    def principal_point(self):
        cx = (self.width - 1) / 2.0 if self.cx is None else float(self.cx)
        cy = (self.height - 1) / 2.0 if self.cy is None else float(self.cy)
        return cx, cy

    @property
    def focal(self) -> float:
        """Focal length in pixels (square pixels)."""
        return self.scale * self.distance

    @property
    def K(self) -> np.ndarray:
        cx, cy = self.principal_point
        f = self.focal
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])

    @property
    def P(self) -> np.ndarray:
        return np.hstack([self.K, np.zeros((3, 1))])

    @property
    def horizontal_fov(self) -> float:
        """Full horizontal field of view, rad."""
        return 2.0 * math.atan(self.width / 2.0 / self.focal)

    @classmethod
    def from_intrinsics(cls, K, width: int, height: int, distance: float, **pose) -> \
            'CameraModel':
        """A model from a K matrix (CameraInfo) and the distance to the plane of motion."""
        K = np.asarray(K, dtype=float).reshape(3, 3)
        fx, fy = K[0, 0], K[1, 1]
        if not (fx > 0 and fy > 0):
            raise ValueError(f'camera intrinsics have no focal length (K = {K.ravel().tolist()})')
        if abs(fx - fy) > 1e-6 * fx:
            raise ValueError(f'non-square pixels (fx = {fx}, fy = {fy}) are not supported')
        return cls(width=int(width), height=int(height), scale=fx / distance, distance=distance,
                   cx=float(K[0, 2]), cy=float(K[1, 2]), **pose)

    def with_fov(self, horizontal_fov: float) -> 'CameraModel':
        """The same camera with the scale set by a horizontal field of view (rad)."""
        focal = self.width / 2.0 / math.tan(horizontal_fov / 2.0)
        return replace(self, scale=focal / self.distance)

    def replace(self, **changes) -> 'CameraModel':
        return replace(self, **changes)

    # -- mapping -------------------------------------------------------------------------------
    def to_pixels(self, points):
        """Surface-frame points (complex x + i y, m) -> pixels (complex u + i v)."""
        w = (np.asarray(points) - complex(self.center_x, self.center_y)) * np.exp(1j * self.slope)
        if self.mirror:
            w = -np.conj(w)
        cx, cy = self.principal_point
        return (cx + self.scale * w.real) + 1j * (cy - self.scale * w.imag)

    def to_surface(self, pixels):
        """Pixels (complex u + i v) -> surface-frame points (complex x + i y, m)."""
        p = np.asarray(pixels)
        cx, cy = self.principal_point
        w = ((p.real - cx) - 1j * (p.imag - cy)) / self.scale
        if self.mirror:
            w = -np.conj(w)
        return w * np.exp(-1j * self.slope) + complex(self.center_x, self.center_y)

    def visible_x_range(self, margin: float = 0.05):
        """Surface-frame x range (m) that can appear in the image (corners), plus a margin."""
        corners = np.array([0, self.width - 1, (self.height - 1) * 1j,
                            self.width - 1 + (self.height - 1) * 1j])
        xs = self.to_surface(corners).real
        return float(xs.min() - margin), float(xs.max() + margin)
