"""
What a frame gave, in metres and seconds: the tracker's measurement.

6. Metric: ideal pixels -> surface frame. Robot position = midpoint of the markers plus
   ``com_offset`` (body frame: along the marker line, and normal to it), 0 when the markers are
   symmetric about the COM (as the renderer puts them); pitch = direction of the back->front line
   in the surface frame (the slope is removed by the camera model) minus ``marker_line_angle``.
   Without the slope (``slope_known`` False), the track's direction is the markers' own motion
   (least-squares over the kept history, once they travelled 40 px; ``slope_used``); with it, a
   motion more than 2 deg off the slope is a warning (speeds along it read cos(angle) low).
7. Speeds (surface frame, m/s): instantaneous = difference to the previous measured frame;
   smoothed = least-squares slope over the trailing ``smooth_window`` s; steady-state mean =
   least-squares slope of position over the trailing ``steady_window`` s, reported once the
   measured samples span at least ``steady_fill`` of it (and the direction is known).

The camera geometry itself (pixels <-> the surface frame, the lens, the plane of motion) is
``camera.CameraModel``'s; ``Measurement`` is the part of ``tracker.Tracker`` that turns its
ideal pixels into positions, pitch and speeds.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
import math
from typing import Deque, Dict, List, Optional, Tuple, TYPE_CHECKING

import numpy as np

from saw_ros.vision.camera import CameraModel

if TYPE_CHECKING:       # (for the declarations only: those modules import this one)
    from saw_ros.vision.association import _Track
    from saw_ros.vision.markers import TrackerConfig


class TrackStatus(StrEnum):
    """What a frame gave; the value is the text of messages and CSV files."""

    OK = 'ok'
    FRONT_LOST = 'front lost'
    BACK_LOST = 'back lost'
    BOTH_LOST = 'both lost'
    AMBIGUOUS = 'ambiguous'
    PARTIAL = 'partial'         # a marker partly hidden (or cut): its centre is not measured


MARKERS = ('front', 'back')
DIRECTION_PX = 40.0       # travel (px) before the track's direction is taken from the motion
LEARN = 0.1               # weight of each ok frame in the learned spacing, area and colour


@dataclass
class FrameResult:
    """What one frame gave. Surface-frame points are complex x + i y in metres."""

    t: float
    status: TrackStatus
    candidates: int = 0
    front_px: Optional[complex] = None        # image pixels (as detected, before undistortion)
    back_px: Optional[complex] = None
    front: Optional[complex] = None
    back: Optional[complex] = None
    spacing_px: Optional[float] = None        # ideal pixels between the markers (ok frames)
    position: Optional[complex] = None        # robot (COM) position
    pitch: Optional[float] = None             # rad
    velocity: Optional[complex] = None        # instantaneous, m/s (x along the surface, y normal)
    pitch_rate: Optional[float] = None        # instantaneous, rad/s
    velocity_smoothed: Optional[complex] = None
    pitch_rate_smoothed: Optional[float] = None
    steady_speed: Optional[float] = None      # m/s along x, over the steady window

    @property
    def ok(self) -> bool:
        return self.status is TrackStatus.OK


def _ls_slope(t: np.ndarray, y: np.ndarray) -> float:
    tc = t - t.mean()
    return float(np.dot(tc, y - y.mean()) / np.dot(tc, tc))


@dataclass
class Counters:
    frames: int = 0
    ok: int = 0
    front_lost: int = 0
    back_lost: int = 0
    ambiguous: int = 0
    partial: int = 0                  # frames with a marker partly hidden (not measured)
    consecutive_not_ok: int = 0
    longest_not_ok: int = 0
    acquisitions: int = 0             # times the pair was (re)acquired


def _learn(old: Optional[float], new: float) -> float:
    return new if old is None else old + LEARN * (new - old)


class TrackerState:
    """What the tracker's parts share: declared here, set by ``tracker.Tracker``."""

    camera: CameraModel
    config: 'TrackerConfig'
    slope_known: bool
    counters: Counters
    switched_at: Optional[float]
    _tracks: Dict[str, '_Track']
    # t, x, y, pitch: positions in the frame of the camera's slope, turned by _turn on output
    _history: Deque[Tuple[float, float, float, float]]
    _keep: float                    # s of history kept
    _turn: float                    # rad: track direction in that frame (0: the slope's)
    _direction: Optional[float]     # rad, the markers' motion in that frame
    _last_t: Optional[float]
    _switches: int
    _seen_moving: bool
    _spacing: Optional[float]       # px (ideal) between the markers
    _vector: Optional[complex]      # last back->front vector, px
    _area: Dict[str, Optional[float]]
    _colour: Dict[str, Optional[float]]
    _round: Dict[str, Optional[float]]
    _scatter: Dict[str, List[float]]
    _chains: List[Tuple[complex, Deque[complex]]]
    _confirmed: bool
    _locked_at: Optional[Tuple[complex, complex]]
    _given_area: Optional[float]

    def _forget(self) -> None:
        raise NotImplementedError


class Measurement(TrackerState):
    """The tracker's measurement: ideal pixels to the surface frame, positions, speeds."""

    def _to_surface(self, q) -> complex:
        """Scene-frame ideal pixels -> surface frame (the slope turned by what the motion says)."""
        p = complex(self.camera.to_surface(q))
        if self._turn:
            c = complex(self.camera.center_x, self.camera.center_y)
            p = c + (p - c) * complex(math.cos(self._turn), -math.sin(self._turn))
        return p

    def _speeds(self, res: FrameResult, position0: complex, pitch0: float) -> None:
        cfg = self.config
        hist = self._history
        prev = hist[-1] if hist and res.t - hist[-1][0] <= cfg.max_step_gap else None
        hist.append((res.t, position0.real, position0.imag, pitch0))
        while hist and hist[0][0] < res.t - self._keep:
            hist.popleft()
        arr = np.array(hist)
        t = arr[:, 0] - res.t
        if len(hist) >= 3:
            # The markers' own direction of motion, over the history (the wave's ripple and the
            # pitching average out): the track's direction when the slope is not given.
            v = complex(_ls_slope(t, arr[:, 1]), _ls_slope(t, arr[:, 2]))
            if abs(v) * (t[-1] - t[0]) * self.camera.scale >= DIRECTION_PX:
                self._direction = math.atan2(v.imag, v.real)
                if not self.slope_known:
                    self._turn = self._direction
        turn = complex(math.cos(self._turn), -math.sin(self._turn))
        c = complex(self.camera.center_x, self.camera.center_y)
        res.pitch = pitch0 - self._turn
        res.position = c + (position0 - c) * turn
        if prev is not None:
            t0, x0, y0, p0 = prev
            dt = res.t - t0
            res.velocity = complex((position0.real - x0) / dt,
                                   (position0.imag - y0) / dt) * turn
            res.pitch_rate = (pitch0 - p0) / dt
        recent = t >= -cfg.smooth_window - 1e-9
        if recent.sum() >= 3:
            tt = t[recent]
            res.velocity_smoothed = complex(_ls_slope(tt, arr[recent, 1]),
                                            _ls_slope(tt, arr[recent, 2])) * turn
            res.pitch_rate_smoothed = _ls_slope(tt, arr[recent, 3])
        window = t >= -cfg.steady_window - 1e-9
        if window.sum() >= 3 and -t[window][0] >= cfg.steady_fill * cfg.steady_window - 1e-9 \
                and (self.slope_known or self._direction is not None):
            res.steady_speed = (complex(_ls_slope(t[window], arr[window, 1]),
                                        _ls_slope(t[window], arr[window, 2])) * turn).real


def steady_speed(times, x, window: float) -> Optional[float]:
    """Least-squares mean speed of x over the last ``window`` seconds of (times, x)."""
    times, x = np.asarray(times, float), np.asarray(x, float)
    keep = times >= times[-1] - window - 1e-9
    if keep.sum() < 3:
        return None
    return _ls_slope(times[keep] - times[-1], x[keep])


def scale_from_spacing(results, spacing: float) -> Optional[Tuple[float, int, float]]:
    """
    Return the scale (px per metre) that makes the markers ``spacing`` m apart.

    The median of the measured ``spacing_px`` of the ok frames over it, with the number of frames
    and the spread (half the 16-84 % range, px). None without an ok frame.
    """
    d = np.array([r.spacing_px for r in results if r.ok and r.spacing_px is not None])
    if d.size == 0:
        return None
    lo, mid, hi = np.percentile(d, [16, 50, 84])
    return float(mid / spacing), int(d.size), float((hi - lo) / 2)
