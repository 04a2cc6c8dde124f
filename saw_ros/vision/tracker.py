"""
Two-pink-marker tracker: robot position, pitch and speed from images alone.

It knows nothing of the simulation: only a camera model (``CameraModel``: pixels per metre or K
and the distance to the plane of motion, the slope of the surfaces as a level camera sees them,
the surface-frame point at the principal point, optionally the lens distortion) and what the
markers look like (``TrackerConfig``: colour window, optionally their spacing on the robot, their
size and a region of interest).

Per frame:
1. Detection (coarse): the image (or its region of interest) is shrunk by ``downscale``
   (bilinear: 8x cheaper than INTER_AREA at 1280x720 and enough to find a 14 px disc), converted
   to HSV and thresholded for pink (hue window that may wrap through 0, minimum saturation and
   value) and for a least pinkness R + B - 2 G (noise on dark grey passes the HSV test, not this
   one); connected components above a minimum area are candidates, except those cut by the edge
   of the picture (their centroid would be biased).
2. Refinement (full resolution, sub-pixel): around each candidate, the pinkness
   P = R + B - 2 G (zero for any grey, white or black, and for the neutral colours of the scene)
   minus its local background (median of the window), over the pixels above 30 % of the peak and
   a one-pixel rim: the P-weighted centroid. Linear in each pixel's coverage, so partly covered
   edge pixels count for what they hold. Also measured: the blob's area (pixels above 30 % of
   the peak) and its colour (B - G) / (R - G) (0 for red, 0.56 for the renderer's hot pink, 1 for
   magenta; unchanged by brightness and by blending with grey). Candidates closer than
   ``merge_distance`` are merged; blobs that the coarse step joined but that are apart at full
   resolution are measured apart. Centres are then undistorted (camera's lens model).
3. Acquisition (no marker tracked yet, or both lost for ``reacquire_after`` frames): every pair
   of candidates is tested as (front, back): the back->front line within ``max_pitch`` of the
   track's direction (the surfaces' slope, plus ``marker_line_angle``); the two blobs of similar
   size (area ratio <= 2.5) and colour (within ``colour_tolerance``); their distance within
   ``spacing_tolerance`` of ``marker_spacing`` (m, times the scale) when it is given, or of the
   spacing measured while tracking before; each blob's area near that of a
   ``marker_diameter`` disc when given. The pair that passes with the lowest cost (sum of the
   squared deviations in units of their tolerances) is taken when no other passing pair comes
   within 0.25 of it; otherwise motion decides: each candidate is followed from frame to frame
   (nearest of the previous frame's within ``gate``) and the pair whose two blobs have moved by
   the same distance along their line (a rigid body: pitching does not change it), at least
   4 px, since both were first seen, is taken if it is the only such pair. Otherwise the frame
   is ``ambiguous`` and acquisition goes on with the next. So an orange-red object, a magenta
   sticker, a third pink marker on the wall ahead or behind, do not stop the start.
4. Tracking: front and back keep their identity by prediction (last position + pixel velocity
   x elapsed time; a marker lost meanwhile is predicted from the other through the last
   back->front vector, the robot being rigid) and the cheapest assignment of candidates within
   ``gate`` pixels whose colour matches the marker's; a pair must keep the marker spacing
   measured so far (within 3 px or 2 %). A blob much larger than the marker (1.5x: something
   pink touching it) is not measured; a much smaller one (0.5x: mostly hidden) is not the marker.
   A marker for which another assignment fits within ``merge_distance`` / 2 px of the best is
   ambiguous: it is not measured. A third pink thing passing near the robot is thus ignored
   unless it is where the marker should be.
5. Metric: ideal pixels -> surface frame. Robot position = midpoint of the markers plus
   ``com_offset`` (body frame: along the marker line, and normal to it), 0 when the markers are
   symmetric about the COM (as the renderer puts them); pitch = direction of the back->front line
   in the surface frame (the slope is removed by the camera model) minus ``marker_line_angle``.
6. Speeds (surface frame, m/s): instantaneous = difference to the previous measured frame;
   smoothed = least-squares slope over the trailing ``smooth_window`` s; steady-state mean =
   least-squares slope of position over the trailing ``steady_window`` s, reported once the
   measured samples span at least ``steady_fill`` of it.

A frame gets status 'ok', 'front lost', 'back lost', 'both lost' or 'ambiguous'. Position, pitch
and speeds exist only for 'ok' frames: nothing is made up on the others.

The default colour window, hue 140..172 (OpenCV 0-179), S >= 70, V >= 60, is pink, not red: it
takes magenta (150), neon and shocking pink (152-158), hot and deep pink (163-165, the renderer's
is 163) and fluorescent pink under warm light (170-172); it refuses crimson (174), red (175-179
and 0-4), orange-red and tomato (5-8), orange (16-19) and violet (< 140). Magenta passes: size,
colour, spacing and the robot's line tell it from a marker.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from enum import StrEnum
import math
from typing import Deque, Dict, List, Optional, Tuple

import cv2
import numpy as np

from saw_ros.core.params import spec
from saw_ros.vision.camera import CameraModel


class TrackStatus(StrEnum):
    """What a frame gave; the value is the text of messages and CSV files."""

    OK = 'ok'
    FRONT_LOST = 'front lost'
    BACK_LOST = 'back lost'
    BOTH_LOST = 'both lost'
    AMBIGUOUS = 'ambiguous'


MARKERS = ('front', 'back')

SIZE_RATIO = 2.5          # largest area ratio of the two markers (or of a marker to its size)
MERGED = 1.5              # a blob this much larger than the tracked marker holds something else
PARTIAL = 0.5             # ... this much smaller: the marker is mostly hidden
CLEAR_MARGIN = 0.25       # acquisition: the best pair's cost must beat the next by this much
MOTION_FRAMES = 600       # acquisition: longest history over which candidates' motion counts
MIN_MOTION = 4.0          # px along the marker line to count as moving
SPACING_PX = 3.0          # tracking: the marker spacing may change by max(this, ...)
SPACING_FRACTION = 0.02   # ... this fraction of it from frame to frame
LEARN = 0.1               # weight of each ok frame in the learned spacing, area and colour
MAX_PAIR_CANDIDATES = 12  # acquisition looks at the heaviest candidates only
_KERNEL = np.ones((3, 3), np.uint8)


@dataclass(frozen=True)
class TrackerConfig:
    """
    What the markers look like and how the tracker follows them.

    Each field carries its unit, range and description (``core.params.spec``): the vision node's
    parameters, its msg_config/vision.yaml and ``saw-ros track``'s options are made from them. The
    ranges are those ``__post_init__`` checks (open bounds and the checks between fields stay
    there).
    """

    hue_min: int = spec(140, '', 'pink hue window lower end, OpenCV hue 0-179 (a window with '
                                 'min > max wraps through 0)', 0, 179)
    hue_max: int = spec(172, '', 'pink hue window upper end, OpenCV hue 0-179', 0, 179)
    sat_min: int = spec(70, '', 'least saturation of a marker pixel, 0-255', 0, 255)
    val_min: int = spec(60, '', 'least value (brightness) of a marker pixel, 0-255', 0, 255)
    pink_min: float = spec(60.0, 'grey levels', 'least pinkness R + B - 2G of a marker pixel')
    min_area: float = spec(20.0, 'px', 'smallest marker blob (full resolution)')
    downscale: int = spec(4, '', 'detection runs on the image shrunk by this factor', 1, None)
    min_contrast: float = spec(60.0, 'grey levels',
                               'least pinkness of a marker above its surroundings')
    merge_distance: float = spec(10.0, 'px', 'candidates closer than this are one marker', 0.0,
                                 None, low_open=True)
    gate: float = spec(40.0, 'px', 'largest marker motion from its prediction between frames',
                       0.0, None, low_open=True)
    reacquire_after: int = spec(30, '', 'frames with both markers lost before acquiring again',
                                1, None)
    roi: Optional[Tuple[int, int, int, int]] = spec(
        None, 'px', 'region of interest x0,y0,x1,y1 (x1 and y1 excluded): markers are looked '
                    'for only there')
    # (metadata 'flag': the command-line flag when it is not --<name>)
    marker_spacing: Optional[float] = spec(
        None, 'm', "distance between the two markers' centres on the robot (the renderer's: "
                   '0.32); picks the pair among pink things, and without --px-per-m sets the '
                   'scale', 0.0, None, low_open=True, flag='--marker-spacing-m')
    marker_diameter: Optional[float] = spec(
        None, 'm', "diameter of a marker (the renderer's: 0.012): blobs of another size are not "
                   'markers', 0.0, None, low_open=True, flag='--marker-diameter-m')
    spacing_tolerance: float = spec(0.1, '', 'acquisition: relative tolerance on the marker '
                                             'spacing', 0.0, 0.5, low_open=True, high_open=True)
    max_pitch: float = spec(math.radians(15.0), 'rad', 'acquisition: largest angle of the marker '
                            'line to the track', 0.0, math.pi / 2, low_open=True, high_open=True)
    colour_tolerance: float = spec(0.2, '', 'largest difference of colour (B - G) / (R - G) '
                                            'between the markers and from frame to frame', 0.0,
                                   None, low_open=True)
    com_offset_x: float = spec(0.0, 'm', 'COM minus marker midpoint along the back->front line')
    com_offset_y: float = spec(0.0, 'm', 'COM minus marker midpoint normal to that line')
    marker_line_angle: float = spec(0.0, 'rad', 'angle of the back->front line in the body frame')
    smooth_window: float = spec(0.25, 's', 'smoothed speed: least-squares window', 0.0, None,
                                low_open=True)
    steady_window: float = spec(4.0, 's', 'steady-state mean speed: least-squares window', 0.0,
                                None, low_open=True)
    steady_fill: float = spec(0.9, '', 'fraction of the steady window the samples must span',
                              0.0, 1.0, low_open=True)
    max_step_gap: float = spec(0.25, 's', 'longest gap for an instantaneous speed', 0.0, None,
                               low_open=True)

    def __post_init__(self):
        for name in ('hue_min', 'hue_max', 'sat_min', 'val_min', 'downscale', 'reacquire_after'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ValueError(f'tracker {name} = {value!r} must be an integer')
        if not (0 <= self.hue_min <= 179 and 0 <= self.hue_max <= 179):
            raise ValueError('tracker hue_min/hue_max must be in [0, 179] (OpenCV hue)')
        for name in ('sat_min', 'val_min'):
            if not 0 <= getattr(self, name) <= 255:
                raise ValueError(f'tracker {name} = {getattr(self, name)!r} must be in [0, 255]')
        if self.downscale < 1:
            raise ValueError('tracker downscale must be >= 1')
        if self.reacquire_after < 1:
            raise ValueError('tracker reacquire_after must be >= 1')
        for name in ('gate', 'smooth_window', 'steady_window', 'merge_distance',
                     'spacing_tolerance', 'colour_tolerance', 'max_step_gap'):
            if not getattr(self, name) > 0:
                raise ValueError(f'tracker {name} = {getattr(self, name)!r} must be > 0')
        if not 0 < self.steady_fill <= 1:
            raise ValueError('tracker steady_fill must be in (0, 1]')
        if not 0 < self.spacing_tolerance < 0.5:
            raise ValueError(f'tracker spacing_tolerance = {self.spacing_tolerance!r} must be in '
                             f'(0, 0.5)')
        if not 0 < self.max_pitch < math.pi / 2:
            raise ValueError(f'tracker max_pitch = {self.max_pitch!r} rad must be in (0, pi/2)')
        for name in ('marker_spacing', 'marker_diameter'):
            value = getattr(self, name)
            if value is not None and not (value > 0 and math.isfinite(value)):
                raise ValueError(f'tracker {name} = {value!r} must be > 0 m (or None: unknown)')
        if self.marker_spacing is not None and self.marker_diameter is not None and \
                self.marker_diameter >= self.marker_spacing:
            raise ValueError('tracker marker_diameter must be smaller than marker_spacing')
        if self.roi is not None:
            roi = tuple(self.roi)
            if len(roi) != 4 or not all(isinstance(v, (int, np.integer)) for v in roi):
                raise ValueError(f'tracker roi = {self.roi!r}: give four integers x0, y0, x1, y1')
            x0, y0, x1, y1 = roi
            if not (0 <= x0 < x1 and 0 <= y0 < y1):
                raise ValueError(f'tracker roi = {self.roi!r}: needs 0 <= x0 < x1 and '
                                 f'0 <= y0 < y1 (px)')
            object.__setattr__(self, 'roi', tuple(int(v) for v in roi))


@dataclass
class Candidate:
    u: float          # px, sub-pixel centroid in the image
    v: float
    weight: float     # summed pinkness
    area: float = 0.0       # px above 30 % of the peak
    colour: float = 0.0     # (B - G) / (R - G) over those pixels
    q: Optional[complex] = None   # ideal (undistorted) pixel position, set by the tracker

    @property
    def p(self) -> complex:
        return complex(self.u, self.v)


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


def detect(image: np.ndarray, config: TrackerConfig = TrackerConfig(),
           encoding: str = 'bgr8') -> List[Candidate]:
    """
    Pink blobs in a BGR (or RGB) uint8 image with sub-pixel centroids.

    (image pixels), area and colour; heaviest first.
    """
    if image is None or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError('detect needs an HxWx3 colour image')
    if encoding not in ('bgr8', 'rgb8'):
        raise ValueError(f'unsupported encoding {encoding!r}: use bgr8 or rgb8')
    ox = oy = 0
    if config.roi is not None:
        x0, y0, x1, y1 = config.roi
        x1, y1 = min(x1, image.shape[1]), min(y1, image.shape[0])
        if x0 >= x1 or y0 >= y1:
            return []
        image, ox, oy = image[y0:y1, x0:x1], x0, y0
    s = config.downscale
    h, w = image.shape[:2]
    if w // s < 3 or h // s < 3:
        return []
    small = cv2.resize(image, (w // s, h // s), interpolation=cv2.INTER_LINEAR) if s > 1 \
        else image
    sh, sw = small.shape[:2]
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
        if x == 0 or y == 0 or x + bw >= sw or y + bh >= sh:
            continue            # cut by the edge of the picture (or of the region of interest)
        u0, v0 = max(0, x * s - margin), max(0, y * s - margin)
        u1, v1 = min(w, (x + bw) * s + margin), min(h, (y + bh) * s + margin)
        roi = image[v0:v1, u0:u1].astype(np.float32)
        green = roi[..., 1]
        rg = roi[..., red] - green
        bg = roi[..., blue] - green
        pink = rg + bg
        pink -= float(np.median(pink))
        peak = float(pink.max())
        if peak < config.min_contrast:
            continue
        core = (pink > 0.3 * peak).view(np.uint8)
        parts, labels = cv2.connectedComponents(core, connectivity=8)
        # Two blobs merged by the coarse step (a pink thing touching a marker) but apart at full
        # resolution are measured apart.
        masks = [core] if parts == 2 else [(labels == k).view(np.uint8)
                                           for k in range(1, parts)]
        pink_pos = np.maximum(pink, 0.0)
        for blob in masks:
            in_blob = blob > 0
            n_core = int(np.count_nonzero(in_blob))
            if n_core < config.min_area * 0.3:
                continue
            rim = cv2.dilate(blob, _KERNEL)
            weight = np.where(rim > 0, pink_pos, 0.0)
            total = float(weight.sum())
            if total <= 0:
                continue
            uu = np.arange(u0 + ox, u1 + ox, dtype=np.float64)
            vv = np.arange(v0 + oy, v1 + oy, dtype=np.float64)
            u = float(weight.sum(axis=0) @ uu) / total
            v = float(weight.sum(axis=1) @ vv) / total
            rg_sum = float(rg[in_blob].sum())
            colour = float(bg[in_blob].sum()) / rg_sum if rg_sum > 0 else math.inf
            found.append(Candidate(u, v, total, float(n_core), colour))
    # Merge fragments of one marker: keep the heaviest.
    found.sort(key=lambda c: -c.weight)
    merged: List[Candidate] = []
    for c in found:
        if all(abs(c.p - m.p) >= config.merge_distance for m in merged):
            merged.append(c)
    return merged


@dataclass
class _Track:
    p: Optional[complex] = None       # last measured (ideal) pixel position
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
    acquisitions: int = 0             # times the pair was (re)acquired


def _learn(old: Optional[float], new: float) -> float:
    return new if old is None else old + LEARN * (new - old)


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
        # What is known of the markers: given, or learned on ok frames.
        self._spacing: Optional[float] = None           # px (ideal) between the markers
        self._vector: Optional[complex] = None          # last back->front vector, px
        self._area: Dict[str, Optional[float]] = {'front': None, 'back': None}
        self._colour: Dict[str, Optional[float]] = {'front': None, 'back': None}
        self._chains: List[Tuple[complex, Deque[complex]]] = []     # acquisition: motion
        self._given_area = None if config.marker_diameter is None else \
            math.pi * (0.5 * config.marker_diameter * camera.scale) ** 2

    @property
    def last_time(self) -> Optional[float]:
        """
        Return the time of the last frame given to ``update`` (None before the first).

        The next frame must be later.
        """
        return self._last_t

    @property
    def initialised(self) -> bool:
        return self._tracks['front'].p is not None and self._tracks['back'].p is not None

    @property
    def spacing_px(self) -> Optional[float]:
        """Return the marker spacing in ideal pixels tracked so far (None before acquisition)."""
        return self._spacing

    def move_camera(self, camera: CameraModel) -> None:
        """
        Return the camera moved parallel to the plane of motion.

        (same size, scale and lens: a camera on a rail following the robot): tracking goes on, what
        is known in ideal pixels moves with the picture; positions and speeds stay continuous in
        the surface frame.
        """
        delta = complex(camera.to_pixels(0j)) - complex(self.camera.to_pixels(0j))
        for track in self._tracks.values():
            if track.p is not None:
                track.p += delta
        self._chains = [(q + delta, deque((h + delta for h in hist), maxlen=hist.maxlen))
                        for q, hist in self._chains]
        self.camera = camera

    def reset(self) -> None:
        self.__init__(self.camera, self.config, self.encoding)

    # -- acquisition ---------------------------------------------------------------------------
    def _expected_spacing(self) -> Optional[float]:
        if self.config.marker_spacing is not None:
            return self.config.marker_spacing * self.camera.scale
        return self._spacing

    def _motions(self, cands: List[Candidate]) -> List[Optional[complex]]:
        """
        Each candidate's displacement since it was first seen.

        (up to MOTION_FRAMES frames back; None when new): candidates are chained to the nearest of
        the previous frame's.
        """
        free = list(range(len(self._chains)))
        chains, motions = [], []
        for c in cands:
            best, best_d = None, self.config.gate
            for k in free:
                d = abs(c.q - self._chains[k][0])
                if d < best_d:
                    best, best_d = k, d
            if best is None:
                hist: Deque[complex] = deque(maxlen=MOTION_FRAMES + 1)
            else:
                free.remove(best)
                hist = self._chains[best][1]
            hist.append(c.q)
            chains.append((c.q, hist))
            motions.append(hist[-1] - hist[0] if len(hist) > 1 else None)
        self._chains = chains
        return motions

    def _acquire(self, cands: List[Candidate]):
        """{'front': Candidate or None, 'back': ...} and whether it was ambiguous."""
        cfg = self.config
        none = {'front': None, 'back': None}
        cands = cands[:MAX_PAIR_CANDIDATES]
        motions = self._motions(cands)
        if len(cands) < 2:
            return none, False
        q = np.array([c.q for c in cands])
        surface = self.camera.to_surface(q) * complex(math.cos(cfg.marker_line_angle),
                                                      -math.sin(cfg.marker_line_angle))
        spacing = self._expected_spacing()
        log_ratio = math.log(SIZE_RATIO)
        single = []
        for c in cands:
            cost = 0.0
            if self._given_area is not None:
                cost = (math.log(max(c.area, 1.0) / self._given_area) / log_ratio) ** 2
            single.append(cost)
        pairs = []
        for a, ca in enumerate(cands):
            if single[a] > 1.0:
                continue
            for b, cb in enumerate(cands):
                if a == b or single[b] > 1.0:
                    continue
                line = surface[a] - surface[b]
                angle = math.atan2(line.imag, line.real) / cfg.max_pitch
                if abs(angle) > 1.0:        # also refuses the pair in the wrong order
                    continue
                d = abs(q[a] - q[b])
                if d < 2.0 * cfg.merge_distance:
                    continue
                size = math.log(max(ca.area, 1.0) / max(cb.area, 1.0)) / log_ratio
                colour = (ca.colour - cb.colour) / cfg.colour_tolerance
                if abs(size) > 1.0 or not abs(colour) <= 1.0:
                    continue
                cost = angle ** 2 + size ** 2 + colour ** 2 + single[a] + single[b]
                if spacing is not None:
                    dev = (d - spacing) / (cfg.spacing_tolerance * spacing)
                    if abs(dev) > 1.0:
                        continue
                    cost += dev ** 2
                pairs.append((cost, a, b))
        if not pairs:
            return none, False
        pairs.sort()
        close = [p for p in pairs if p[0] < pairs[0][0] + CLEAR_MARGIN]
        if len(close) > 1:
            close = [p for p in close if self._rigid_moving(q, motions, p[1], p[2])]
            if len(close) != 1:
                return none, True
        _, a, b = close[0]
        self._chains = []
        self.counters.acquisitions += 1
        return {'front': cands[a], 'back': cands[b]}, False

    @staticmethod
    def _rigid_moving(q, motions, a: int, b: int) -> bool:
        """Whether candidates a and b moved together along their line (a rigid body moving)."""
        ma, mb = motions[a], motions[b]
        if ma is None or mb is None:
            return False
        # (Both chains may not reach equally far back; a rigid pair seen since different frames
        # then differs by the motion in between, and is taken a little later.)
        line = (q[a] - q[b]) / abs(q[a] - q[b])
        along_a = (ma * line.conjugate()).real
        along_b = (mb * line.conjugate()).real
        moved = min(abs(along_a), abs(along_b))
        return moved >= MIN_MOTION and abs(along_a - along_b) <= 1.5 + 0.1 * moved

    # -- tracking ------------------------------------------------------------------------------
    def _predict(self, t: float) -> Dict[str, complex]:
        front, back = self._tracks['front'], self._tracks['back']
        pf, pb = front.predict(t), back.predict(t)
        if self._vector is not None:           # a marker lost meanwhile follows the other
            if front.t < back.t:
                pf = pb + self._vector
            elif back.t < front.t:
                pb = pf - self._vector
        return {'front': pf, 'back': pb}

    def _track(self, cands: List[Candidate], t: float):
        """{'front': Candidate or None, 'back': ...} and whether it was ambiguous."""
        cfg = self.config
        gate = cfg.gate
        pred = self._predict(t)
        near: Dict[str, List[Tuple[int, float]]] = {}
        for name in MARKERS:
            colour, area = self._colour[name], self._area[name]
            near[name] = []
            for k, c in enumerate(cands):
                d = abs(c.q - pred[name])
                if d > gate:
                    continue
                if colour is not None and not abs(c.colour - colour) <= cfg.colour_tolerance:
                    continue
                if area is not None and c.area < PARTIAL * area:
                    continue
                near[name].append((k, d))
        spacing = self._spacing
        tol = max(SPACING_PX, SPACING_FRACTION * spacing) if spacing else math.inf
        options = []
        for i, df in near['front'] + [(None, gate)]:
            for j, db in near['back'] + [(None, gate)]:
                if i is not None and i == j:
                    continue
                if i is not None and j is not None and spacing is not None and \
                        abs(abs(cands[i].q - cands[j].q) - spacing) > tol:
                    continue
                options.append((df + db, i, j))
        options.sort(key=lambda o: o[0])
        cost, i, j = options[0]
        found = {'front': None if i is None else cands[i],
                 'back': None if j is None else cands[j]}
        ambiguous = False
        margin = 0.5 * cfg.merge_distance
        for slot, name in ((1, 'front'), (2, 'back')):
            chosen = options[0][slot]
            if chosen is None:
                continue
            area = self._area[name]
            rival = any(o[slot] is not None and o[slot] != chosen and o[0] <= cost + margin
                        for o in options[1:])
            if rival or (area is not None and cands[chosen].area > MERGED * area):
                found[name] = None
                ambiguous = True
        return found, ambiguous

    # -- per frame -----------------------------------------------------------------------------
    def update(self, image: Optional[np.ndarray], t: float) -> FrameResult:
        cfg = self.config
        if self._last_t is not None and t <= self._last_t:
            raise ValueError(f'frame time {t} is not after the previous one {self._last_t}')
        self._last_t = t
        cands = detect(image, cfg, self.encoding) if image is not None else []
        if cands:
            ideal = self.camera.undistort(np.array([c.p for c in cands]))
            for c, q in zip(cands, ideal):
                c.q = complex(q)
        if self.initialised:
            found, ambiguous = self._track(cands, t)
        else:
            found, ambiguous = self._acquire(cands)
        c = self.counters
        c.frames += 1
        res = FrameResult(t=t, status=TrackStatus.OK, candidates=len(cands))
        for name in MARKERS:
            cand = found[name]
            if cand is None:
                continue
            self._tracks[name].update(cand.q, t)
            self._area[name] = _learn(self._area[name], cand.area)
            self._colour[name] = _learn(self._colour[name], cand.colour)
            setattr(res, f'{name}_px', cand.p)
            setattr(res, name, complex(self.camera.to_surface(cand.q)))
        if found['front'] is not None and found['back'] is not None:
            self._vector = found['front'].q - found['back'].q
            res.spacing_px = abs(self._vector)
            self._spacing = _learn(self._spacing, res.spacing_px)
        lost = [name for name in MARKERS if found[name] is None]
        if ambiguous:
            res.status = TrackStatus.AMBIGUOUS
            c.ambiguous += 1
        elif lost:
            res.status = (TrackStatus.BOTH_LOST if len(lost) == 2 else
                          TrackStatus.FRONT_LOST if lost == ['front'] else TrackStatus.BACK_LOST)
        c.front_lost += 'front' in lost
        c.back_lost += 'back' in lost
        if len(lost) == 2:
            self._both_lost += 1
            if self._both_lost >= cfg.reacquire_after and self.initialised:
                self._tracks = {'front': _Track(), 'back': _Track()}
                self._vector = None
        else:
            self._both_lost = 0
        if res.status is not TrackStatus.OK:
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
