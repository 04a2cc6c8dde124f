"""
Perspective along the track, from the markers' own spacing: noticed without a calibration.

A camera that is not square to the robot's plane sees it smaller where the plane is farther: one
scale (px per metre) for the whole picture is then wrong away from where it was measured (a
camera yawed 18 deg: +6 % on the speed, issue 32). The two markers are a ruler that travels with
the robot: their spacing in pixels changing with their place along the track says so.

Along a straight track the picture of the track is a line, and the map from the track (x, m) to
the line (a, measured in "apparent metres": pixels along it over the scale the tracker was
given, from the principal point's place on it) is projective: with the origins matched,

    x(a) = a / (g (1 - k a))

(g: the apparent scale over the true one at the origin; k: the perspective, 1/m; k = 0 for a
square camera). The markers, L apart on the robot, give in each frame a_front, a_back with
x(a_front) - x(a_back) = L cos(pitch) ~ L; ``fit`` finds k (the relative spread of the spacing
over frames is least at the right k: no L needed) and g (with L). ``AlongTrack.homography``
turns the fit into the plane's homography for ``CameraModel(plane=...)``: the scale then holds
where the robot is, frame by frame.

Noise, the robot's pitching and bobbing do not make the spacing follow its place along the track:
the change is taken as real when its slope is over SIGNIFICANT standard errors and the scale
changes by more than CHANGE_WARN over the track the robot travelled.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import List, Optional, Sequence, Tuple

import numpy as np

CHANGE_WARN = 0.01       # a scale changing by this much over the robot's travel is warned about
SIGNIFICANT = 4.0        # ... when the change is this many standard errors
MIN_FRAMES = 30          # fewer frames with both markers: no fit


@dataclass(frozen=True)
class AlongTrack:
    """What the markers' spacing says of the perspective along the track."""

    k: float                # 1/m (apparent): the perspective
    g: float                # apparent scale / true scale at the origin (1 without a spacing)
    a_range: tuple          # (first, last) apparent place of the markers' midpoint, m
    change: float           # the scale's relative change over a_range (signed)
    sigma: float            # standard error of ``change``
    frames: int

    @property
    def significant(self) -> bool:
        """Whether the scale changes along the track beyond noise and pitching."""
        return abs(self.change) > CHANGE_WARN and abs(self.change) > SIGNIFICANT * self.sigma

    def scale_at(self, a: float) -> float:
        """Return the true scale at apparent place a over the apparent scale (the ruler's)."""
        return self.g * (1.0 - self.k * a) ** 2

    def homography(self, scale: float, principal_point, direction: complex) -> np.ndarray:
        """
        Return the fit as the plane's 3x3 matrix (ideal pixels -> level plane, m).

        ``scale``: the apparent px/m the places were measured with; ``direction``: the track's
        unit direction in the level picture frame (x right, y up), from the principal point.
        """
        s = self.g * scale                       # true px/m at the principal point
        kappa = self.k / scale                   # per px
        cx, cy = principal_point
        dx, dy = direction.real, direction.imag
        # a_px = Re((u - cx - i (v - cy)) conj(direction)) = dx (u - cx) - dy (v - cy)
        return np.array([[1.0 / s, 0.0, -cx / s], [0.0, -1.0 / s, cy / s],
                         [-kappa * dx, kappa * dy, 1.0 + kappa * (dx * cx - dy * cy)]])


def _spread(k: float, af: np.ndarray, ab: np.ndarray) -> float:
    d = af / (1.0 - k * af) - ab / (1.0 - k * ab)
    return float(np.std(d) / abs(np.mean(d)))


def fit(front: Sequence[float], back: Sequence[float],
        spacing: Optional[float] = None) -> Optional[AlongTrack]:
    """
    Return the perspective along the track from the markers' apparent places (m), or None.

    ``front``, ``back``: each ok frame's markers along the track (apparent m, from the
    principal point's place); ``spacing``: the markers' true distance (m) for g (else g = 1).
    None with fewer than MIN_FRAMES frames or a robot that did not move.
    """
    af, ab = np.asarray(front, float), np.asarray(back, float)
    if af.size < MIN_FRAMES:
        return None
    mid, dist = 0.5 * (af + ab), af - ab
    lo, hi = float(mid.min()), float(mid.max())
    if not hi - lo > 0.05 * abs(float(np.mean(dist))):
        return None
    # Significance from the straight line through spacing against place (ordinary least squares)
    mc = mid - mid.mean()
    beta = float(np.dot(mc, dist - dist.mean()) / np.dot(mc, mc))
    resid = dist - dist.mean() - beta * mc
    sigma_beta = float(np.sqrt(np.dot(resid, resid) / max(af.size - 2, 1) / np.dot(mc, mc)))
    first, last = float(mid[0]), float(mid[-1])
    # The exact projective k: least relative spread of the true spacings (golden section).
    reach = float(max(np.abs(af).max(), np.abs(ab).max()))
    lo_k, hi_k = -0.8 / reach, 0.8 / reach
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = hi_k - ratio * (hi_k - lo_k), lo_k + ratio * (hi_k - lo_k)
    f1, f2 = _spread(x1, af, ab), _spread(x2, af, ab)
    for _ in range(80):
        if f1 < f2:
            hi_k, x2, f2 = x2, x1, f1
            x1 = hi_k - ratio * (hi_k - lo_k)
            f1 = _spread(x1, af, ab)
        else:
            lo_k, x1, f1 = x1, x2, f2
            x2 = lo_k + ratio * (hi_k - lo_k)
            f2 = _spread(x2, af, ab)
    k = 0.5 * (lo_k + hi_k)
    d = af / (1.0 - k * af) - ab / (1.0 - k * ab)
    g = float(np.mean(d) / spacing) if spacing else 1.0
    # The scale change over the travel: (1 - k a)^2 from first to last; its error from beta's.
    change = ((1.0 - k * last) / (1.0 - k * first)) ** 2 - 1.0
    sigma = sigma_beta * abs(last - first) / abs(float(np.mean(dist)))
    return AlongTrack(k, g, (first, last), change, sigma, int(af.size))


def along_track(results, camera, slope: float) -> Tuple[List[float], List[float]]:
    """
    Return the ok frames' (front, back) places along the track, apparent m from the centre.

    From the markers' pixels (undistorted by ``camera``'s lens), along the track's direction in
    the picture (``slope``, rad; the tracker's ``slope_used``) at ``camera.scale``: the same
    frame for every frame of the clip (the tracker's own positions are turned once the track's
    direction is known, and its estimate improves as the robot goes).
    """
    ok = [r for r in results if r.ok and r.front_px is not None and r.back_px is not None]
    if not ok:
        return [], []
    direction = complex(math.cos(slope), math.sin(slope))
    if camera.mirror:
        direction = -direction.conjugate()
    cx, cy = camera.principal_point
    out = []
    for name in ('front_px', 'back_px'):
        p = camera.undistort(np.array([getattr(r, name) for r in ok]))
        z = (p.real - cx) - 1j * (p.imag - cy)             # level picture frame, y up
        out.append(list((z * direction.conjugate()).real / camera.scale))
    return out[0], out[1]


def warning(fit_: AlongTrack, how: str) -> str:
    """Return the warning for a significant perspective (``how``: where the scale came from)."""
    first, last = fit_.a_range
    return (f"perspective: the markers' spacing in pixels changes by {100 * fit_.change:+.1f} % "
            f'(+-{100 * fit_.sigma:.1f}) as the robot moves from {100 * first:.1f} to '
            f'{100 * last:.1f} cm along the track: the camera is not square to the plane, so one '
            f'scale ({how}) is not right everywhere and speeds are off by up to about '
            f'{100 * abs(fit_.change):.0f} %; calibrate the plane (saw-ros calibrate-camera ... '
            '--plane-image, then --plane; or --plane-points), or give --marker-spacing-m alone '
            'to measure the scale where the robot is')
