"""Two-pink-marker tracker: robot position, pitch and speed from images alone.

It knows nothing of the simulation: only a camera model (``CameraModel``: pixels per metre or K
and the distance to the plane of motion, the slope of the surfaces as a level camera sees them,
the surface-frame point at the principal point) and what the markers look like.

Per frame:
1. Detection (coarse): the image is shrunk by ``downscale`` (bilinear: 8x cheaper than
   INTER_AREA at 1280x720 and enough to find a 14 px disc), converted to HSV and
   thresholded for pink (hue window that may wrap through 0, minimum saturation and value) and
   for a least pinkness R + B - 2 G (noise on dark grey passes the HSV test, not this one);
   connected components above a minimum area are candidates.
2. Refinement (full resolution, sub-pixel): around each candidate, the pinkness
   P = R + B - 2 G (zero for any grey, white or black, and for the neutral colours of the scene)
   minus its local background (median of the window), over the pixels above 30 % of the peak and
   a one-pixel rim: the P-weighted centroid. Linear in each pixel's coverage, so partly covered
   edge pixels count for what they hold. Candidates closer than a marker diameter are merged.
3. Assignment: front and back keep their identity through the run by prediction (last position +
   pixel velocity x elapsed time) and the cheapest assignment of candidates within ``gate``
   pixels; never by "rightmost". Only at the start (or after both have been lost for
   ``reacquire_after`` frames) does the order along the direction of travel decide, and only when
   exactly two candidates are seen. A marker with a second unexplained candidate inside its gate
   is ambiguous: it is not measured.
4. Metric: pixels -> surface frame. Robot position = midpoint of the markers plus ``com_offset``
   (body frame: along the marker line, and normal to it), 0 when the markers are symmetric about
   the COM (as the renderer puts them); pitch = direction of the back->front line in the surface
   frame (the slope is removed by the camera model) minus ``marker_line_angle``.
5. Speeds (surface frame, m/s): instantaneous = difference to the previous measured frame;
   smoothed = least-squares slope over the trailing ``smooth_window`` s; steady-state mean =
   least-squares slope of position over the trailing ``steady_window`` s, reported once the
   measured samples span at least ``steady_fill`` of it.

A frame gets status 'ok', 'front lost', 'back lost', 'both lost' or 'ambiguous'. Position, pitch
and speeds exist only for 'ok' frames: nothing is made up on the others.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Deque, List, Optional, Tuple

import cv2
import numpy as np

from .camera import CameraModel

OK = 'ok'
AMBIGUOUS = 'ambiguous'
MARKERS = ('front', 'back')


@dataclass(frozen=True)
class TrackerConfig:
    hue_min: int = 145            # OpenCV hue (0-179); a window with min > max wraps through 0
    hue_max: int = 5
    sat_min: int = 70             # 0-255
    val_min: int = 60             # 0-255
    pink_min: float = 60.0        # grey levels, least pinkness R + B - 2 G of a detection pixel
    min_area: float = 20.0        # px (full resolution), smallest marker blob
    downscale: int = 4            # detection runs on the image shrunk by this factor
    min_contrast: float = 60.0    # pinkness above background for a real marker
    merge_distance: float = 10.0  # px, candidates closer than this are one marker
    gate: float = 40.0            # px, how far a marker may be from its prediction
    reacquire_after: int = 30     # frames with both markers lost before re-initialising
    com_offset_x: float = 0.0     # m, COM minus marker midpoint, along the back->front line
    com_offset_y: float = 0.0     # m, ... and normal to it (towards the top surface)
    marker_line_angle: float = 0.0  # rad, angle of the back->front line in the body frame
    smooth_window: float = 0.25   # s, smoothed speed: LS slope over this trailing window
    steady_window: float = 4.0    # s, steady-state mean speed: LS slope over this window
    steady_fill: float = 0.9      # fraction of steady_window the samples must span
    max_step_gap: float = 0.25    # s, longest gap for an instantaneous speed

    def __post_init__(self):
        if not (0 <= self.hue_min <= 179 and 0 <= self.hue_max <= 179):
            raise ValueError('tracker hue_min/hue_max must be in [0, 179] (OpenCV hue)')
        if self.downscale < 1:
            raise ValueError('tracker downscale must be >= 1')
        for name in ('gate', 'smooth_window', 'steady_window', 'merge_distance'):
            if not getattr(self, name) > 0:
                raise ValueError(f'tracker {name} = {getattr(self, name)!r} must be > 0')
        if not 0 < self.steady_fill <= 1:
            raise ValueError('tracker steady_fill must be in (0, 1]')


@dataclass
class Candidate:
    u: float          # px, sub-pixel centroid
    v: float
    weight: float     # summed pinkness

    @property
    def p(self) -> complex:
        return complex(self.u, self.v)


@dataclass
class FrameResult:
    """What one frame gave. Surface-frame points are complex x + i y in metres."""

    t: float
    status: str
    candidates: int = 0
    front_px: Optional[complex] = None
    back_px: Optional[complex] = None
    front: Optional[complex] = None
    back: Optional[complex] = None
    position: Optional[complex] = None        # robot (COM) position
    pitch: Optional[float] = None             # rad
    velocity: Optional[complex] = None        # instantaneous, m/s (x along the surface, y normal)
    pitch_rate: Optional[float] = None        # instantaneous, rad/s
    velocity_smoothed: Optional[complex] = None
    pitch_rate_smoothed: Optional[float] = None
    steady_speed: Optional[float] = None      # m/s along x, over the steady window

    @property
    def ok(self) -> bool:
        return self.status == OK


def _ls_slope(t: np.ndarray, y: np.ndarray) -> float:
    tc = t - t.mean()
    return float(np.dot(tc, y - y.mean()) / np.dot(tc, tc))


def detect(image: np.ndarray, config: TrackerConfig = TrackerConfig(),
           encoding: str = 'bgr8') -> List[Candidate]:
    """Pink blobs in a BGR (or RGB) uint8 image with sub-pixel centroids."""
    if image is None or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError('detect needs an HxWx3 colour image')
    if encoding not in ('bgr8', 'rgb8'):
        raise ValueError(f'unsupported encoding {encoding!r}: use bgr8 or rgb8')
    s = config.downscale
    h, w = image.shape[:2]
    small = cv2.resize(image, (w // s, h // s), interpolation=cv2.INTER_LINEAR) if s > 1 \
        else image
    hsv = cv2.cvtColor(small, cv2.COLOR_BGR2HSV if encoding == 'bgr8' else cv2.COLOR_RGB2HSV)
    lo, hi = config.hue_min, config.hue_max
    if lo <= hi:
        mask = cv2.inRange(hsv, (lo, config.sat_min, config.val_min), (hi, 255, 255))
    else:
        mask = cv2.inRange(hsv, (lo, config.sat_min, config.val_min), (179, 255, 255))
        mask |= cv2.inRange(hsv, (0, config.sat_min, config.val_min), (hi, 255, 255))
    red, blue = (2, 0) if encoding == 'bgr8' else (0, 2)
    # Dark or grey pixels made colourful by sensor noise pass the HSV test; their pinkness is
    # near zero: ask for both.
    chans = small.astype(np.int16)
    pinkness = chans[..., red] + chans[..., blue] - 2 * chans[..., 1]
    mask[pinkness < config.pink_min] = 0
    count, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    found: List[Candidate] = []
    min_area = max(1.0, config.min_area / (s * s) * 0.5)
    margin = 2 * s + 2
    for label in range(1, count):
        x, y, bw, bh, area = stats[label]
        if area < min_area:
            continue
        u0, v0 = max(0, x * s - margin), max(0, y * s - margin)
        u1, v1 = min(w, (x + bw) * s + margin), min(h, (y + bh) * s + margin)
        roi = image[v0:v1, u0:u1].astype(np.float32)
        pink = roi[..., red] + roi[..., blue] - 2.0 * roi[..., 1]
        pink -= float(np.median(pink))
        peak = float(pink.max())
        if peak < config.min_contrast:
            continue
        core = (pink > 0.3 * peak).astype(np.uint8)
        if core.sum() < config.min_area * 0.3:
            continue
        core = cv2.dilate(core, np.ones((3, 3), np.uint8))
        weight = np.where(core > 0, np.maximum(pink, 0.0), 0.0)
        total = float(weight.sum())
        if total <= 0:
            continue
        uu = np.arange(u0, u1, dtype=np.float64)
        vv = np.arange(v0, v1, dtype=np.float64)
        u = float(weight.sum(axis=0) @ uu) / total
        v = float(weight.sum(axis=1) @ vv) / total
        found.append(Candidate(u, v, total))
    # Merge fragments of one marker: keep the heaviest.
    found.sort(key=lambda c: -c.weight)
    merged: List[Candidate] = []
    for c in found:
        if all(abs(c.p - m.p) >= config.merge_distance for m in merged):
            merged.append(c)
    return merged


@dataclass
class _Track:
    p: Optional[complex] = None       # last measured pixel position
    t: float = 0.0                    # when
    v: complex = 0j                   # px/s

    def predict(self, t: float) -> complex:
        return self.p + self.v * (t - self.t)

    def update(self, p: complex, t: float) -> None:
        if self.p is not None and t > self.t:
            v = (p - self.p) / (t - self.t)
            self.v = v if self.v == 0 else 0.5 * (self.v + v)
        self.p, self.t = p, t


@dataclass
class Counters:
    frames: int = 0
    ok: int = 0
    front_lost: int = 0
    back_lost: int = 0
    ambiguous: int = 0
    consecutive_not_ok: int = 0
    longest_not_ok: int = 0


class Tracker:
    """Feed frames in time order with ``update(image, t)``; read ``FrameResult``s back."""

    def __init__(self, camera: CameraModel, config: TrackerConfig = TrackerConfig(),
                 encoding: str = 'bgr8'):
        self.camera, self.config, self.encoding = camera, config, encoding
        self.counters = Counters()
        self._tracks = {'front': _Track(), 'back': _Track()}
        self._both_lost = 0
        keep = max(config.steady_window, config.smooth_window) + 1.0
        self._keep = keep
        self._history: Deque[Tuple[float, float, float, float]] = deque()   # t, x, y, pitch
        self._last_t: Optional[float] = None

    @property
    def last_time(self) -> Optional[float]:
        """Time of the last frame given to ``update`` (None before the first): the next must be
        later."""
        return self._last_t

    @property
    def initialised(self) -> bool:
        return self._tracks['front'].p is not None and self._tracks['back'].p is not None

    def reset(self) -> None:
        self.__init__(self.camera, self.config, self.encoding)

    # -- assignment ----------------------------------------------------------------------------
    def _assign(self, cands: List[Candidate], t: float):
        """{'front': Candidate or None, 'back': ...} and whether it was ambiguous."""
        gate = self.config.gate
        if not self.initialised:
            # Candidates come heaviest first: a third one much lighter than the second is noise.
            if len(cands) > 2 and cands[2].weight < 0.25 * cands[1].weight:
                cands = cands[:2]
            if len(cands) != 2:
                return {'front': None, 'back': None}, len(cands) > 2
            a, b = cands
            ax, bx = self.camera.to_surface(np.array([a.p, b.p])).real
            return ({'front': a, 'back': b} if ax >= bx else {'front': b, 'back': a}), False
        pred = {name: tr.predict(t) for name, tr in self._tracks.items()}
        options = list(range(len(cands))) + [None]
        best, best_cost = {'front': None, 'back': None}, 2 * gate
        for i in options:
            for j in options:
                if i is not None and i == j:
                    continue
                cost = 0.0
                for name, k in (('front', i), ('back', j)):
                    if k is None:
                        cost += gate
                    else:
                        d = abs(cands[k].p - pred[name])
                        cost += d if d <= gate else math.inf
                if cost < best_cost:
                    best_cost = cost
                    best = {'front': None if i is None else cands[i],
                            'back': None if j is None else cands[j]}
        ambiguous = False
        used = [c for c in best.values() if c is not None]
        for name, c in list(best.items()):
            if c is None:
                continue
            rivals = [o for o in cands if o not in used and abs(o.p - pred[name]) <= gate]
            if rivals:
                best[name] = None
                ambiguous = True
        return best, ambiguous

    # -- per frame -----------------------------------------------------------------------------
    def update(self, image: Optional[np.ndarray], t: float) -> FrameResult:
        cfg = self.config
        if self._last_t is not None and t <= self._last_t:
            raise ValueError(f'frame time {t} is not after the previous one {self._last_t}')
        self._last_t = t
        cands = detect(image, cfg, self.encoding) if image is not None else []
        found, ambiguous = self._assign(cands, t)
        c = self.counters
        c.frames += 1
        res = FrameResult(t=t, status=OK, candidates=len(cands))
        for name in MARKERS:
            cand = found[name]
            if cand is None:
                continue
            self._tracks[name].update(cand.p, t)
            setattr(res, f'{name}_px', cand.p)
            setattr(res, name, complex(self.camera.to_surface(cand.p)))
        lost = [name for name in MARKERS if found[name] is None]
        if ambiguous:
            res.status = AMBIGUOUS
            c.ambiguous += 1
        elif lost:
            res.status = 'both lost' if len(lost) == 2 else f'{lost[0]} lost'
        c.front_lost += 'front' in lost
        c.back_lost += 'back' in lost
        if len(lost) == 2:
            self._both_lost += 1
            if self._both_lost >= cfg.reacquire_after:
                self._tracks = {'front': _Track(), 'back': _Track()}
        else:
            self._both_lost = 0
        if res.status != OK:
            c.consecutive_not_ok += 1
            c.longest_not_ok = max(c.longest_not_ok, c.consecutive_not_ok)
            return res
        c.consecutive_not_ok = 0
        c.ok += 1
        line = res.front - res.back
        pitch = math.atan2(line.imag, line.real) - cfg.marker_line_angle
        res.pitch = pitch
        res.position = 0.5 * (res.front + res.back) + complex(math.cos(pitch), math.sin(pitch)) \
            * complex(cfg.com_offset_x, cfg.com_offset_y)
        self._speeds(res)
        return res

    def _speeds(self, res: FrameResult) -> None:
        cfg = self.config
        hist = self._history
        if hist and res.t - hist[-1][0] <= cfg.max_step_gap:
            t0, x0, y0, p0 = hist[-1]
            dt = res.t - t0
            res.velocity = complex((res.position.real - x0) / dt, (res.position.imag - y0) / dt)
            res.pitch_rate = (res.pitch - p0) / dt
        hist.append((res.t, res.position.real, res.position.imag, res.pitch))
        while hist and hist[0][0] < res.t - self._keep:
            hist.popleft()
        arr = np.array(hist)
        t = arr[:, 0] - res.t
        recent = t >= -cfg.smooth_window - 1e-9
        if recent.sum() >= 3:
            tt = t[recent]
            res.velocity_smoothed = complex(_ls_slope(tt, arr[recent, 1]),
                                            _ls_slope(tt, arr[recent, 2]))
            res.pitch_rate_smoothed = _ls_slope(tt, arr[recent, 3])
        window = t >= -cfg.steady_window - 1e-9
        if window.sum() >= 3 and -t[window][0] >= cfg.steady_fill * cfg.steady_window - 1e-9:
            res.steady_speed = _ls_slope(t[window], arr[window, 1])


def steady_speed(times, x, window: float) -> Optional[float]:
    """Least-squares mean speed of x over the last ``window`` seconds of (times, x)."""
    times, x = np.asarray(times, float), np.asarray(x, float)
    keep = times >= times[-1] - window - 1e-9
    if keep.sum() < 3:
        return None
    return _ls_slope(times[keep] - times[-1], x[keep])
