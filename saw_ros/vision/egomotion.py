"""
The camera's own motion, from the background: where a handheld camera's picture went.

A handheld or vibrating camera moves the whole picture; the markers' motion in it is the robot's
plus the camera's. ``CameraMotion.update`` finds the similarity (shift, roll, zoom) that takes the
current picture back to the scene frame (the first picture): corners of the background
(``goodFeaturesToTrack``, the robot masked out) are picked on a key picture and followed into each
new one by pyramidal Lucas-Kanade, and a similarity is fitted by RANSAC (the robot, the occluders
and anything else moving are outliers). All of it on the picture shrunk by ``downscale`` (the
cost is ~0.5 ms a frame at 1280x720), against the key picture rather than the previous frame, so
that the errors do not add up from frame to frame; a new key picture (and new corners) is taken
when too few corners remain or the picture moved far from it.

A fixed camera stays exactly fixed: until the picture has moved by ``FIXED_PX`` at full
resolution, no correction is applied at all (noise, flicker and the robot itself move the fit by
hundredths of a pixel).
"""
from __future__ import annotations

import math
from typing import Optional, Sequence, Tuple

import cv2
import numpy as np

from saw_ros.vision.markers import median

GRID = (64, 45)         # small px: cells of the key picture, two corners taken in each
MIN_FEATURES = 12       # fewest corners for a fit
AGREE = 0.3             # fraction of the key's corners that must agree on the fit
AWAY_FRAMES = 3         # frames in a row away by FIXED_PX before the camera counts as moving
FIXED_PX = 0.5          # full-resolution px the picture must move (see AWAY_FRAMES)
KEY_SHIFT = 0.15        # fraction of the picture's width: beyond this shift, a new key picture
INLIER_PX = 0.5         # small px: a corner further than this from the fit is not background
# Lucas-Kanade optical flow: its window (small px), pyramid levels and when it stops iterating.
LK_WINDOW = (11, 11)
LK_LEVELS = 2
LK_STOP = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 0.03)


def _h(a: np.ndarray) -> np.ndarray:
    """Return a 2x3 affine as 3x3."""
    return np.vstack([a, [0.0, 0.0, 1.0]])


def _similarity(src: np.ndarray, dst: np.ndarray):
    """
    Return (2x3 similarity src -> dst, inliers) fitted to the corners that move together.

    Robust without RANSAC's cost (0.3 ms): the median shift picks the background (the largest
    group), then two least-squares fits, each on the corners within INLIER_PX of the last. (None,
    0) when too few corners agree.
    """
    z = src.reshape(-1, 2) @ [1.0, 1j]
    w = dst.reshape(-1, 2) @ [1.0, 1j]
    if z.size < MIN_FEATURES:
        return None, 0
    shift = w - z
    m = complex(median(shift.real), median(shift.imag))
    keep = np.abs(shift - m) < 2.0 * INLIER_PX
    k, t = 1.0 + 0j, m
    for _ in range(2):
        if keep.sum() < MIN_FEATURES:
            return None, 0
        zm, wm = z[keep].mean(), w[keep].mean()
        zc = z[keep] - zm
        k = complex(np.vdot(zc, w[keep] - wm) / np.vdot(zc, zc).real)
        t = wm - k * zm
        keep = np.abs(k * z + t - w) < INLIER_PX
    n = int(keep.sum())
    if n < MIN_FEATURES:
        return None, 0
    return np.array([[k.real, -k.imag, t.real], [k.imag, k.real, t.imag]]), n


class CameraMotion:
    """Feed every picture with ``update``; read the picture -> scene transform back."""

    def __init__(self, downscale: int = 4):
        self.d = int(downscale)
        self.moving = False           # the camera has moved (corrections applied)
        self.failed = 0               # frames on which the motion could not be measured
        self.largest_shift = 0.0      # px (full resolution) from the scene frame, largest
        self.zoom_range = [1.0, 1.0]  # smallest, largest scale of the picture to the scene
        self.roll_range = [0.0, 0.0]  # rad
        # (grey picture, corners) of the key picture, and the corners where they were last seen
        self._key: Optional[Tuple[np.ndarray, np.ndarray, np.ndarray]] = None
        self._key_to_scene = np.eye(3)      # small px
        self._to_scene = np.eye(3)    # current small px -> scene small px
        self._away = 0                # consecutive frames the fit says the camera moved
        d = float(self.d)
        # Full-resolution pixel centres: u_full = d u_small + (d - 1) / 2 (cv2.resize).
        self._up = np.array([[d, 0.0, (d - 1) / 2], [0.0, d, (d - 1) / 2], [0.0, 0.0, 1.0]])
        self._down = np.linalg.inv(self._up)

    def _new_key(self, gray: np.ndarray, masks) -> bool:
        """
        Take a key picture: corners spread over it (a grid of cells, the best two of each).

        The strongest corners of a picture are often all on the robot, on the boards' long edges
        or on one poster; spread out, most are on the static background.
        """
        mask = np.full(gray.shape, 255, np.uint8)
        for a, b, r in masks:                # the robot: a thick segment (full-res px)
            a, b, r = a / self.d, b / self.d, r / self.d
            cv2.line(mask, (int(a.real), int(a.imag)), (int(b.real), int(b.imag)), 0,
                     max(1, int(2 * r)))
        h, w = gray.shape
        found = []
        for y0 in range(0, h - GRID[1] // 2, GRID[1]):
            for x0 in range(0, w - GRID[0] // 2, GRID[0]):
                cell = (slice(y0, min(y0 + GRID[1], h)), slice(x0, min(x0 + GRID[0], w)))
                pts = cv2.goodFeaturesToTrack(gray[cell], 2, 0.05, 6, mask=mask[cell],
                                              blockSize=5)
                if pts is not None:
                    found.append(pts.reshape(-1, 2) + [x0, y0])
        if sum(len(f) for f in found) < 2 * MIN_FEATURES:
            self._key = None
            return False
        corners = np.concatenate(found).astype(np.float32).reshape(-1, 1, 2)
        self._key = (gray, corners, corners.copy())
        self._key_mean = cv2.mean(gray)[0]
        self._key_to_scene = self._to_scene.copy()
        return True

    def update(self, small: np.ndarray, width: int, height: int,
               masks: Sequence[Tuple[complex, complex, float]] = ()) -> Optional[np.ndarray]:
        """
        Return the 3x3 transform full-resolution picture px -> scene px (identity while fixed).

        ``small``: the picture (``width`` x ``height``) shrunk by ``downscale`` (the tracker's
        ``shrink``, shared with detection). ``masks``: segments (a, b, radius), full-resolution
        px, that are not background (the robot). None when the motion could not be measured on
        this picture (too little texture): the last transform stays.
        """
        gray = cv2.cvtColor(small, cv2.COLOR_BGR2GRAY)   # (R and B order does not matter)
        if self._key is None:
            if not self._new_key(gray, masks):
                self.failed += 1
                return None
            return self.transform
        key, pts, guess = self._key
        # Lighting that flickers changes the picture's gain, which Lucas-Kanade would take for
        # motion: the picture is brought to the key's mean brightness first.
        mean = cv2.mean(gray)[0]
        if mean > 0:
            gray = cv2.convertScaleAbs(gray, alpha=self._key_mean / mean)
        nxt, status, _ = cv2.calcOpticalFlowPyrLK(key, gray, pts, guess.copy(),
                                                  winSize=LK_WINDOW, maxLevel=LK_LEVELS,
                                                  criteria=LK_STOP,
                                                  flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
        good = status.ravel() == 1
        fit, inliers = _similarity(pts[good], nxt[good])
        if fit is None or inliers < AGREE * len(pts):
            self.failed += 1
            self._new_key(gray, masks)
            return None
        guess[good] = nxt[good]
        to_scene = self._key_to_scene @ np.linalg.inv(_h(fit))
        full = self._up @ to_scene @ self._down
        corners = np.array([[0.0, 0.0, 1.0], [width, height, 1.0]]).T
        shift = float(np.abs(full @ corners - corners).max())
        if not self.moving:
            # Fixed until the picture has been away for a few frames in a row (a single fit
            # off by a pixel is not a camera that moved).
            self._away = self._away + 1 if shift >= FIXED_PX else 0
            self.moving = self._away >= AWAY_FRAMES
        self._to_scene = to_scene
        if self.moving:
            self.largest_shift = max(self.largest_shift, shift)
            zoom = math.hypot(full[0, 0], full[1, 0])
            roll = math.atan2(full[1, 0], full[0, 0])
            self.zoom_range = [min(self.zoom_range[0], zoom), max(self.zoom_range[1], zoom)]
            self.roll_range = [min(self.roll_range[0], roll), max(self.roll_range[1], roll)]
        if inliers < 0.6 * len(pts) or \
                abs(fit[0, 2]) + abs(fit[1, 2]) > KEY_SHIFT * gray.shape[1]:
            self._new_key(gray, masks)
        return self.transform

    @property
    def transform(self) -> np.ndarray:
        """Picture -> scene now: 3x3, full-resolution px (identity while the camera is fixed)."""
        if not self.moving:
            return np.eye(3)
        return self._up @ self._to_scene @ self._down


def apply(transform: np.ndarray, points):
    """Apply a 3x3 affine to complex points."""
    p = np.asarray(points)
    return (transform[0, 0] * p.real + transform[0, 1] * p.imag + transform[0, 2]) + \
        1j * (transform[1, 0] * p.real + transform[1, 1] * p.imag + transform[1, 2])
