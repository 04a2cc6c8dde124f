"""
The camera model of the renderer and the tracker: a level pinhole camera beside the track.

The camera looks square at the plane in which the robot moves (its side), from ``distance``
metres. In that plane one metre is ``scale`` pixels (f = scale * distance is the focal length
in pixels that goes into CameraInfo's K). The camera is level, so the surfaces appear inclined
at the slope alpha; the point of the surface frame seen at the principal point is
(``center_x``, ``center_y``).

Pixel convention (OpenCV and ROS CameraInfo): pixel (u, v) has its centre at integer (u, v), u to
the right, v down; the principal point defaults to the image centre ((W - 1) / 2, (H - 1) / 2).

Surface frame (docs/model.md section 1): x along the surfaces in the direction of travel, y
normal to them away from the bottom surface. With ``mirror`` False the robot travels to the
right of the image (up to the right when climbing); ``mirror`` True is for videos in which it
travels to the left.

Mapping, with points as complex numbers x + i y:
    w = (s - c) e^(i alpha)           surface -> level world (horizontal, up), m
    w = -conj(w) if mirror
    u = cx + scale Re(w),  v = cy - scale Im(w)

Lens distortion (optional, OpenCV's model): ``dist_coeffs`` (k1, k2, p1, p2[, k3[, k4, k5, k6]])
with the camera matrix they were calibrated with, ``dist_matrix`` (fx, fy, cx, cy; default: this
model's K). The mapping above is then between the surface and the IDEAL (undistorted) pixels;
``distort`` takes ideal pixels to where a real lens puts them in the image, ``undistort`` back.
The renderer draws the ideal image and warps it; the tracker undistorts its marker centres only.

The plane of motion (optional, ``plane``): a camera that is not square to the robot's plane sees
it through a perspective. ``plane`` is then the homography (3x3, row-major) from ideal pixels to
the plane's own coordinates in metres (x along its first axis, y up; from a calibration board
lying in the plane or from points measured in it: ``saw_ros.vision.calibration``), and
    w = H(u, v)                        ideal pixels -> plane, m
takes the place of the scale above (``w`` then as above: mirror, slope, centre). ``scale`` is
set to the plane's scale at the principal point (what the tracker's pixel tolerances use).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
import math
from typing import Optional, Tuple

import cv2
import numpy as np

from saw_ros.core.params import check_fields, spec

# The paper's experiment was filmed at 60 fps (Sec. 6: nearly 60 measurements per wave cycle):
# the virtual camera's frame rate unless told otherwise.
FPS = 60.0


@dataclass(frozen=True)
class CameraModel:
    # spec(): unit, range and description, for the camera node's parameters, its
    # msg_config/camera.yaml and saw-ros render's options; __post_init__ checks these ranges
    width: int = spec(1280, 'px', 'image width', 16, None)
    height: int = spec(720, 'px', 'image height', 16, None)
    scale: float = spec(1200.0, 'px/m', 'pixels per metre in the plane of motion', 0.0, None,
                        low_open=True)
    slope: float = spec(0.0, 'rad', 'slope of the surfaces as the level camera sees them (their '
                        'angle to the image horizontal, + climbs)', -math.pi / 2, math.pi / 2)
    center_x: float = spec(0.33, 'm', 'surface-frame x seen at the principal point')
    center_y: float = spec(0.0225, 'm', 'surface-frame y seen at the principal point')
    distance: float = spec(1.0, 'm', 'optical centre to the plane of motion: focal length '
                           'f = scale * distance', 0.0, None, low_open=True)
    mirror: bool = spec(False, '', 'true when the robot travels towards the left of the image '
                        "(surface +x points to the image's left)")
    cx: Optional[float] = None   # px, principal point; None = image centre
    cy: Optional[float] = None   # px
    dist_coeffs: Tuple[float, ...] = ()           # OpenCV (k1, k2, p1, p2[, k3[, k4, k5, k6]])
    # (fx, fy, cx, cy) of the calibration; None = K
    dist_matrix: Optional[Tuple[float, ...]] = None
    # ideal pixels -> plane of motion (m), 3x3 row-major; None = square to the plane at ``scale``
    plane: Optional[Tuple[float, ...]] = None

    def __post_init__(self):
        check_fields(self)          # the spec() ranges; ParameterError is a ValueError
        object.__setattr__(self, 'dist_coeffs', tuple(float(k) for k in self.dist_coeffs))
        if len(self.dist_coeffs) not in (0, 4, 5, 8) or not all(
                math.isfinite(k) for k in self.dist_coeffs):
            raise ValueError(f'camera dist_coeffs = {self.dist_coeffs!r}: give 4, 5 or 8 finite '
                             f'numbers (k1, k2, p1, p2[, k3[, k4, k5, k6]], OpenCV order)')
        if self.dist_matrix is not None:
            m = tuple(float(v) for v in self.dist_matrix)
            if len(m) != 4 or not (m[0] > 0 and m[1] > 0) or not all(map(math.isfinite, m)):
                raise ValueError(f'camera dist_matrix = {self.dist_matrix!r}: give (fx, fy, cx, '
                                 f'cy) with fx, fy > 0')
            object.__setattr__(self, 'dist_matrix', m)
        if self.plane is not None:
            h = np.asarray(self.plane, dtype=float).ravel()
            if h.size != 9 or not np.all(np.isfinite(h)) or \
                    abs(np.linalg.det(h.reshape(3, 3))) < 1e-300:
                raise ValueError('camera plane: give the 9 finite numbers of an invertible '
                                 'homography (ideal pixels -> plane, m)')
            object.__setattr__(self, 'plane', tuple(float(v) for v in h))
            object.__setattr__(self, 'scale', self._plane_scale())

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
    def distorted(self) -> bool:
        """Return True when a lens distortion is set (any coefficient non-zero)."""
        return any(k != 0.0 for k in self.dist_coeffs)

    def _dist_K(self) -> np.ndarray:
        if self.dist_matrix is None:
            return self.K
        fx, fy, cx, cy = self.dist_matrix
        return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])

    def distort(self, pixels):
        """
        Return where the lens puts ideal pixels (complex u + i v) in the image.

        OpenCV's distortion model; the identity without a distortion.
        """
        p = np.asarray(pixels)
        if not self.distorted:
            return p
        K = self._dist_K()
        d = np.zeros(8)
        d[:len(self.dist_coeffs)] = self.dist_coeffs
        k1, k2, p1, p2, k3, k4, k5, k6 = d
        x = (p.real - K[0, 2]) / K[0, 0]
        y = (p.imag - K[1, 2]) / K[1, 1]
        r2 = x * x + y * y
        radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        return (K[0, 0] * xd + K[0, 2]) + 1j * (K[1, 1] * yd + K[1, 2])

    def undistort(self, pixels):
        """
        Return the ideal pixels of image pixels (complex), the inverse of ``distort``.

        OpenCV's iterative undistortPoints, in the calibration's pixel grid; the identity without
        a distortion.
        """
        p = np.asarray(pixels)
        if not self.distorted:
            return p
        flat = np.ascontiguousarray(np.stack([p.real.ravel(), p.imag.ravel()], axis=-1)
                                    .reshape(-1, 1, 2), dtype=np.float64)
        if flat.shape[0] == 0:
            return p.astype(complex)
        K = self._dist_K()
        out = cv2.undistortPoints(flat, K, np.asarray(self.dist_coeffs), None, K).reshape(-1, 2)
        return (out[:, 0] + 1j * out[:, 1]).reshape(p.shape)

    @property
    def horizontal_fov(self) -> float:
        """Full horizontal field of view, rad."""
        return 2.0 * math.atan(self.width / 2.0 / self.focal)

    @classmethod
    def from_intrinsics(cls, K, width: int, height: int, distance: float, **pose) -> \
            'CameraModel':
        """Return a model from a K matrix (CameraInfo) and the distance to the plane of motion."""
        K = np.asarray(K, dtype=float).reshape(3, 3)
        fx, fy = K[0, 0], K[1, 1]
        if not (fx > 0 and fy > 0):
            raise ValueError(f'camera intrinsics have no focal length (K = {K.ravel().tolist()})')
        if abs(fx - fy) > 1e-6 * fx:
            raise ValueError(f'non-square pixels (fx = {fx}, fy = {fy}) are not supported')
        return cls(width=int(width), height=int(height), scale=fx / distance, distance=distance,
                   cx=float(K[0, 2]), cy=float(K[1, 2]), **pose)

    def with_fov(self, horizontal_fov: float) -> 'CameraModel':
        """Return the same camera with the scale set by a horizontal field of view (rad)."""
        focal = self.width / 2.0 / math.tan(horizontal_fov / 2.0)
        return replace(self, scale=focal / self.distance)

    def replace(self, **changes) -> 'CameraModel':
        return replace(self, **changes)

    # -- the plane of motion --------------------------------------------------------------------
    @property
    def homography(self) -> Optional[np.ndarray]:
        """Return the plane's 3x3 matrix (ideal pixels -> plane, m), or None without one."""
        return None if self.plane is None else np.array(self.plane).reshape(3, 3)

    def _plane_scale(self) -> float:
        """Return the plane's px per metre at the principal point (root of the area ratio)."""
        h = np.array(self.plane).reshape(3, 3)
        cx, cy = self.principal_point
        x, y, w = h @ np.array([cx, cy, 1.0])
        # The Jacobian of (u, v) -> (x / w, y / w) at the principal point, m per px
        jac = (h[:2, :2] * w - np.outer([x, y], h[2, :2])) / (w * w)
        return float(1.0 / math.sqrt(abs(np.linalg.det(jac))))

    @staticmethod
    def _apply(h: np.ndarray, p):
        p = np.asarray(p)
        den = h[2, 0] * p.real + h[2, 1] * p.imag + h[2, 2]
        return (h[0, 0] * p.real + h[0, 1] * p.imag + h[0, 2]) / den + \
            1j * (h[1, 0] * p.real + h[1, 1] * p.imag + h[1, 2]) / den

    # -- mapping -------------------------------------------------------------------------------
    def to_pixels(self, points):
        """Surface-frame points (complex x + i y, m) -> ideal pixels (complex u + i v)."""
        w = (np.asarray(points) - complex(self.center_x, self.center_y)) * np.exp(1j * self.slope)
        if self.mirror:
            w = -np.conj(w)
        if self.plane is not None:
            return self._apply(np.linalg.inv(self.homography), w)
        cx, cy = self.principal_point
        return (cx + self.scale * w.real) + 1j * (cy - self.scale * w.imag)

    def to_surface(self, pixels):
        """Ideal pixels (complex u + i v) -> surface-frame points (complex x + i y, m)."""
        p = np.asarray(pixels)
        cx, cy = self.principal_point
        if self.plane is not None:
            w = self._apply(self.homography, p)
        else:
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
