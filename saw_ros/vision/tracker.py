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
3. Camera motion (``egomotion.CameraMotion``, on the shrunk image detection made): the
   background's corners, the robot masked out, give the similarity that takes each picture back
   to the first one (the scene's frame); marker centres are measured in that frame, so a
   handheld camera's drift and jitter do not add to the robot's motion. A fixed camera is left
   exactly as it is (no correction until the picture has moved by 0.5 px three frames in a
   row); a scale (zoom) or roll that changes during the clip is a warning.
4. Acquisition (no marker tracked yet, or both lost for ``reacquire_after`` frames, which also
   forgets what was learned of the pair: spacing, vector, size, colour, unless given): a marker
   is pink in absolute terms (colour (B - G) / (R - G) >= ``colour_min``: red and shadowed red
   are 0-0.2), round, of a ``marker_diameter`` disc's area when that is given. A pair is two of
   them of similar size (area ratio <= 2.5) and colour (within ``colour_tolerance``), their
   distance within ``spacing_tolerance`` of ``marker_spacing`` (times the scale) when given.
   First choice: a pair that has moved together as one rigid body along its own line for
   ACQUIRE_FRAMES frames or more (each candidate followed from frame to frame, nearest within
   ``gate``; spacing constant within 1.5 px + 1 %, at least 4 px travelled, within 25 deg of
   the line): the robot. While no candidate moves, and only with the slope known and before
   anything was seen moving, the old rule: the cheapest pair on the track's line (within
   ``max_pitch``) when no other comes within 0.25 of its cost. Such a static pair is dropped
   (with what was learned of it) as soon as another pair moves as the robot does, and its
   frames are then not the robot's (``switched_at``); while it is held, a warning says so.
   Otherwise the frame is ``ambiguous`` (or 'both lost' with fewer than two marker-like blobs).
5. Tracking: front and back keep their identity by prediction (last position + pixel velocity
   x elapsed time; a marker lost meanwhile is predicted from the other through the last
   back->front vector, the robot being rigid) and the cheapest assignment of candidates within
   ``gate`` pixels whose colour matches the marker's; a pair must keep the marker spacing
   measured so far (within 3 px or 2 %). A blob much larger than the marker (1.5x: something
   pink touching it) is not measured; a much smaller one (0.5x: mostly hidden) is not the marker;
   one smaller by 15 % or less round by 0.13 than it usually is (or by 6 times its usual
   scatter, for small markers) is partly hidden: its centroid is not its centre, the frame is
   'partial'. A marker for which another assignment fits within ``merge_distance`` / 2 px of
   the best is ambiguous: it is not measured. A third pink thing passing near the robot is thus
   ignored unless it is where the marker should be.
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

``Tracker.warnings`` says what makes the numbers doubtful, ``Tracker.notes`` what was done
(camera motion taken out, the slope from the motion, a static pair dropped).

A frame gets status 'ok', 'front lost', 'back lost', 'both lost', 'ambiguous' or 'partial'.
Position, pitch and speeds exist only for 'ok' frames: nothing is made up on the others.

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
from saw_ros.vision.egomotion import apply, CameraMotion


class TrackStatus(StrEnum):
    """What a frame gave; the value is the text of messages and CSV files."""

    OK = 'ok'
    FRONT_LOST = 'front lost'
    BACK_LOST = 'back lost'
    BOTH_LOST = 'both lost'
    AMBIGUOUS = 'ambiguous'
    PARTIAL = 'partial'         # a marker partly hidden (or cut): its centre is not measured


MARKERS = ('front', 'back')

SIZE_RATIO = 2.5          # largest area ratio of the two markers (or of a marker to its size)
MERGED = 1.5              # a blob this much larger than the tracked marker holds something else
PARTIAL = 0.5             # ... this much smaller: the marker is mostly hidden
CLEAR_MARGIN = 0.25       # acquisition: the best pair's cost must beat the next by this much
MOTION_FRAMES = 30        # acquisition: frames over which candidates' motion counts
ACQUIRE_FRAMES = 6        # ... a moving pair must have been seen together this many frames
MIN_MOTION = 4.0          # px along the marker line to count as moving
RIGID_PX = 1.5            # ... and keep its spacing within this (plus 1 %) meanwhile
MOTION_ANGLE = math.radians(25.0)   # ... moving along its own line within this
# Tracking: a marker whose area falls below this fraction of its own (or by 6 times its usual
# scatter, for small markers whose area and roundness jump from frame to frame) is partly hidden
PARTIAL_AREA = 0.85
# ... or less round than it was by this much (a 14 px disc: 0.92-1; with noise, blur, lens and
# JPEG 70, down by 0.11 at worst; cut by an edge so that its centroid moves 0.6 px: 0.74-0.8
# instead of 0.96; a 7 px disc through mp4: 0.70-0.99)
PARTIAL_ROUND = 0.13
SCATTER = 6.0
SCATTER_FRAMES = 10       # measurements of a marker before it can be judged partly hidden
ROUND_MIN = 0.6           # acquisition: least roundness (smaller / larger second moment)
DIRECTION_PX = 40.0       # travel (px) before the track's direction is taken from the motion
SLOPE_WARN = math.radians(2.0)     # a given slope this far from the motion is warned about
ZOOM_WARN = 0.01          # the picture's scale changing by this much is warned about
ROLL_WARN = math.radians(0.5)      # ... its roll by this much
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
    colour_min: float = spec(0.25, '', 'acquisition: least colour (B - G) / (R - G) of a marker '
                                       '(red and shadowed red 0-0.2, crimson 0.2, pinks 0.3-0.8, '
                                       'magenta 1)', 0.0, None)
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
    roundness: float = 1.0  # smaller / larger principal second moment: 1 for a disc
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


def shrink(image: np.ndarray, factor: int) -> np.ndarray:
    """Return the image shrunk by ``factor`` as detection does it (bilinear)."""
    h, w = image.shape[:2]
    return cv2.resize(image, (w // factor, h // factor), interpolation=cv2.INTER_LINEAR) \
        if factor > 1 else image


def detect(image: np.ndarray, config: TrackerConfig = TrackerConfig(),
           encoding: str = 'bgr8', small: Optional[np.ndarray] = None) -> List[Candidate]:
    """
    Return the pink blobs in a BGR (or RGB) uint8 image, heaviest first.

    Each with its sub-pixel centroid (image pixels), area, colour and roundness. ``small``: the
    whole image already shrunk (``shrink``), when there is no region of interest.
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
    if small is None or config.roi is not None:
        small = shrink(image, s)
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
            wu, wv = weight.sum(axis=0), weight.sum(axis=1)
            u = float(wu @ uu) / total
            v = float(wv @ vv) / total
            # Second moments: a disc's are equal; a marker partly hidden is a cut disc.
            du, dv = uu - u, vv - v
            suu, svv = float(wu @ (du * du)) / total, float(wv @ (dv * dv)) / total
            suv = float(dv @ weight @ du) / total
            root = math.sqrt(max(0.25 * (suu - svv) ** 2 + suv * suv, 0.0))
            big, low = 0.5 * (suu + svv) + root, 0.5 * (suu + svv) - root
            rg_sum = float(rg[in_blob].sum())
            colour = float(bg[in_blob].sum()) / rg_sum if rg_sum > 0 else math.inf
            found.append(Candidate(u, v, total, float(n_core), colour,
                                   max(low, 0.0) / big if big > 0 else 0.0))
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
    partial: int = 0                  # frames with a marker partly hidden (not measured)
    consecutive_not_ok: int = 0
    longest_not_ok: int = 0
    acquisitions: int = 0             # times the pair was (re)acquired


def _learn(old: Optional[float], new: float) -> float:
    return new if old is None else old + LEARN * (new - old)


class Tracker:
    """
    Feed frames in time order with ``update(image, t)``; read ``FrameResult``s back.

    ``slope_known``: the camera's slope is the track's (given by the user); False: the track's
    direction is taken from the markers' own motion (``slope_used``), the camera's slope being a
    first guess only. ``warnings`` says what makes the numbers doubtful, ``notes`` what was done.
    """

    def __init__(self, camera: CameraModel, config: TrackerConfig = TrackerConfig(),
                 encoding: str = 'bgr8', slope_known: bool = True):
        self.camera, self.config, self.encoding = camera, config, encoding
        self.slope_known = slope_known
        self.counters = Counters()
        self.motion = CameraMotion(config.downscale)
        self._tracks = {'front': _Track(), 'back': _Track()}
        self._both_lost = 0
        keep = max(config.steady_window, config.smooth_window) + 1.0
        self._keep = keep
        # t, x, y, pitch: positions in the frame of the camera's slope (the surface frame when
        # the slope is known), turned by self._turn on output
        self._history: Deque[Tuple[float, float, float, float]] = deque()
        self._turn = 0.0                # rad: track direction in that frame (0: the slope's)
        self._direction: Optional[float] = None     # rad, the markers' motion in that frame
        self._last_t: Optional[float] = None
        self._last_px: Optional[Tuple[complex, complex]] = None    # last ok frame's markers
        self._switches = 0              # static pairs dropped for a moving one
        self._seen_moving = False       # a pair has been seen moving: no static pair after it
        self.switched_at: Optional[float] = None    # when a static pair was last dropped
        self._forget()

    def _forget(self) -> None:
        """Forget what was learned of the markers (spacing, vector, size, colour, motion)."""
        self._spacing: Optional[float] = None           # px (ideal) between the markers
        self._vector: Optional[complex] = None          # last back->front vector, px
        self._area: Dict[str, Optional[float]] = {'front': None, 'back': None}
        self._colour: Dict[str, Optional[float]] = {'front': None, 'back': None}
        self._round: Dict[str, Optional[float]] = {'front': None, 'back': None}
        # mean absolute deviations of area and roundness from the learned values, and the
        # number of measurements they come from
        self._scatter: Dict[str, List[float]] = {'front': [0.0, 0.0, 0], 'back': [0.0, 0.0, 0]}
        self._chains: List[Tuple[complex, Deque[complex]]] = []     # acquisition: motion
        self._confirmed = False         # the tracked pair has been seen moving
        self._locked_at: Optional[Tuple[complex, complex]] = None
        self._given_area = None if self.config.marker_diameter is None else \
            math.pi * (0.5 * self.config.marker_diameter * self.camera.scale) ** 2

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

    @property
    def slope_used(self) -> Optional[float]:
        """Return the track's slope in the picture, rad (None: not known yet)."""
        if not self.slope_known and self._direction is None:
            return None
        return self.camera.slope + self._turn

    @property
    def motion_slope(self) -> Optional[float]:
        """Return the direction of the markers' motion in the picture, rad (None: too short)."""
        return None if self._direction is None else self.camera.slope + self._direction

    @property
    def warnings(self) -> List[str]:
        """Return what makes the positions or speeds doubtful, one line each (empty: nothing)."""
        out = []
        m = self.motion
        if m.moving:
            zoom = m.zoom_range[1] / m.zoom_range[0] - 1.0
            if zoom > ZOOM_WARN:
                out.append(f"the picture's scale changed by {100 * zoom:.1f} % during the clip "
                           '(zoom, or the camera moved towards the scene): positions and speeds '
                           'are off by up to as much')
            roll = m.roll_range[1] - m.roll_range[0]
            if roll > ROLL_WARN:
                out.append(f'the camera rolled by {math.degrees(roll):.1f} deg during the clip '
                           "(compensated; the slope is the first picture's)")
        if m.failed > 0.05 * max(self.counters.frames, 1):
            out.append(f"the camera's motion could not be measured on {m.failed} frames (too "
                       'little texture in the background): positions there may hold it')
        if self.slope_known and self._direction is not None and \
                abs(self._direction) > SLOPE_WARN:
            given = math.degrees(self.camera.slope)
            moved = math.degrees(self.camera.slope + self._direction)
            low = 100.0 * (1.0 - math.cos(self._direction))
            out.append(f'the markers move at {moved:.1f} deg in the picture, not along the given '
                       f'slope {given:.1f} deg: speeds along it read {low:.1f} % low (give the '
                       "right --slope-deg, or leave it out to take the motion's)")
        if self.initialised and not self._confirmed and self.counters.ok:
            out.append('the pair tracked has not moved: a robot at rest, or two pink things '
                       'that are not its markers (nothing else pink moved as a pair)')
        if not self.slope_known and self._direction is None and self.counters.ok:
            out.append(f'the track direction is not known: the markers did not move '
                       f'{DIRECTION_PX:g} px (no steady speed without --slope-deg)')
        return out

    @property
    def notes(self) -> List[str]:
        """Return what the tracker did that the numbers depend on, one line each."""
        out = []
        if self.motion.moving:
            out.append(f'camera motion: the picture moved up to {self.motion.largest_shift:.0f} '
                       "px; markers measured in the scene's frame")
        slope = self.slope_used
        if not self.slope_known and slope is not None:
            out.append(f"slope: {math.degrees(slope):.2f} deg, from the markers' motion")
        if self._switches:
            out.append(f'acquisition: a static pair was dropped for a moving one at '
                       f"t = {self.switched_at:.3f} s: the frames before are not the robot's")
        return out

    def move_camera(self, camera: CameraModel) -> None:
        """
        Take the camera moved parallel to the plane of motion, and track on.

        Same size, scale and lens: a camera on a rail following the robot. What is known in ideal
        pixels moves with the picture; positions and speeds stay continuous in
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
        self.__init__(self.camera, self.config, self.encoding, self.slope_known)

    # -- geometry ------------------------------------------------------------------------------
    def _to_surface(self, q) -> complex:
        """Scene-frame ideal pixels -> surface frame (the slope turned by what the motion says)."""
        p = complex(self.camera.to_surface(q))
        if self._turn:
            c = complex(self.camera.center_x, self.camera.center_y)
            p = c + (p - c) * complex(math.cos(self._turn), -math.sin(self._turn))
        return p

    # -- acquisition ---------------------------------------------------------------------------
    def _expected_spacing(self) -> Optional[float]:
        if self.config.marker_spacing is not None:
            return self.config.marker_spacing * self.camera.scale
        return self._spacing

    def _motions(self, cands: List[Candidate]) -> List[Deque[complex]]:
        """
        Each candidate's recent positions (scene frame), up to MOTION_FRAMES frames back.

        Candidates are chained to the nearest of the previous frame's.
        """
        free = list(range(len(self._chains)))
        chains, hists = [], []
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
            hists.append(hist)
        self._chains = chains
        return hists

    def _marker_like(self, c: Candidate) -> float:
        """Return the candidate's cost as a marker alone (> 1: not a marker)."""
        if not c.colour >= self.config.colour_min or c.roundness < ROUND_MIN:
            return math.inf
        if self._given_area is None:
            return 0.0
        return (math.log(max(c.area, 1.0) / self._given_area) / math.log(SIZE_RATIO)) ** 2

    def _pair_cost(self, ca: Candidate, cb: Candidate, d: float, spacing) -> Optional[float]:
        """Return the cost of two candidates as the two markers (None: they are not)."""
        size = math.log(max(ca.area, 1.0) / max(cb.area, 1.0)) / math.log(SIZE_RATIO)
        colour = (ca.colour - cb.colour) / self.config.colour_tolerance
        if abs(size) > 1.0 or not abs(colour) <= 1.0 or d < 2.0 * self.config.merge_distance:
            return None
        cost = size ** 2 + colour ** 2
        if spacing is not None:
            dev = (d - spacing) / (self.config.spacing_tolerance * spacing)
            if abs(dev) > 1.0:
                return None
            cost += dev ** 2
        return cost

    def _moving_pairs(self, cands, hists, single) -> List[Tuple[float, int, int]]:
        """
        Return the pairs (cost, front, back) that move together as one rigid body.

        Along their own line, for ACQUIRE_FRAMES frames or more: the robot. The front is the
        marker ahead along the track when its slope is known, else along the motion.
        """
        # (A spacing learned on a pair that never moved may be the wrong pair's.)
        spacing = self._expected_spacing() if self._confirmed or \
            self.config.marker_spacing is not None else None
        out = []
        track = complex(math.cos(self.camera.slope), -math.sin(self.camera.slope))
        if self.camera.mirror:
            track = -track.conjugate()
        for a in range(len(cands)):
            if single[a] > 1.0 or len(hists[a]) < ACQUIRE_FRAMES:
                continue
            for b in range(a + 1, len(cands)):
                if single[b] > 1.0 or len(hists[b]) < ACQUIRE_FRAMES:
                    continue
                n = min(len(hists[a]), len(hists[b]))
                pa = np.array(hists[a])[-n:]
                pb = np.array(hists[b])[-n:]
                dist = np.abs(pa - pb)
                if dist.max() - dist.min() > RIGID_PX + 0.01 * dist.mean():
                    continue
                move = 0.5 * (pa[-1] + pb[-1] - pa[0] - pb[0])
                line = pa[-1] - pb[-1]
                along = (move * line.conjugate()).real / abs(line)
                if abs(along) < MIN_MOTION or abs(along) < math.cos(MOTION_ANGLE) * abs(move):
                    continue
                cost = self._pair_cost(cands[a], cands[b], float(dist[-1]), spacing)
                if cost is None:
                    continue
                ahead = (line * track.conjugate()).real if self.slope_known else along
                front, back = (a, b) if ahead > 0 else (b, a)
                out.append((cost + single[a] + single[b], front, back))
        out.sort()
        return out

    def _static_pair(self, cands, single):
        """Return the old rule: the clearly cheapest pair on the track's line, or None."""
        cfg = self.config
        q = np.array([c.q for c in cands])
        surface = self.camera.to_surface(q) * complex(math.cos(cfg.marker_line_angle),
                                                      -math.sin(cfg.marker_line_angle))
        spacing = self._expected_spacing()
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
                cost = self._pair_cost(ca, cb, abs(q[a] - q[b]), spacing)
                if cost is not None:
                    pairs.append((cost + angle ** 2 + single[a] + single[b], a, b))
        if not pairs:
            return None, False
        pairs.sort()
        close = [p for p in pairs if p[0] < pairs[0][0] + CLEAR_MARGIN]
        return (close[0] if len(close) == 1 else None), len(close) > 1

    def _acquire(self, cands: List[Candidate], hists):
        """
        {'front': Candidate or None, 'back': ...} and whether it was ambiguous.

        A pair moving rigidly along its line is taken first; a static pair (the clearly cheapest
        on the track's line) only while no candidate moves, with the slope known, and before any
        pair was seen moving (once the robot moved, something static is not the robot).
        """
        none = {'front': None, 'back': None}
        if len(cands) < 2:
            return none, False
        single = [self._marker_like(c) for c in cands]
        moving = self._moving_pairs(cands, hists, single)
        if moving:
            close = [p for p in moving if p[0] < moving[0][0] + CLEAR_MARGIN]
            if len(close) > 1:
                return none, True
            _, a, b = moving[0]
            self._confirmed = self._seen_moving = True
        else:
            still = all(abs(h[-1] - h[0]) < MIN_MOTION for h in hists)
            if not (self.slope_known and still and not self._seen_moving):
                # Something pink moves (or the track's direction is unknown): wait for a pair
                # that moves as the robot does.
                return none, sum(cost <= 1.0 for cost in single) >= 2
            pair, ambiguous = self._static_pair(cands, single)
            if pair is None:
                return none, ambiguous
            _, a, b = pair
        self.counters.acquisitions += 1
        self._locked_at = (cands[a].q, cands[b].q)
        return {'front': cands[a], 'back': cands[b]}, False

    def _check_lock(self, cands, hists, found) -> Optional[dict]:
        """
        Confirm a pair locked while static once it moves, or drop it for a moving pair.

        Returns the moving pair to take instead, or None.
        """
        f, b = found['front'], found['back']
        if f is not None and b is not None and self._locked_at is not None and \
                min(abs(f.q - self._locked_at[0]), abs(b.q - self._locked_at[1])) >= MIN_MOTION:
            self._confirmed = self._seen_moving = True
            self._chains = []
            return None
        single = [self._marker_like(c) for c in cands]
        moving = [p for p in self._moving_pairs(cands, hists, single)
                  if cands[p[1]] is not f and cands[p[2]] is not b]
        if len(moving) != 1 and not (moving and moving[1][0] >= moving[0][0] + CLEAR_MARGIN):
            return None
        _, a, bb = moving[0]
        self._switches += 1
        self.switched_at = self._last_t
        self._forget()
        self._history.clear()
        self._tracks = {'front': _Track(), 'back': _Track()}
        self._confirmed = self._seen_moving = True
        self.counters.acquisitions += 1
        return {'front': cands[a], 'back': cands[bb]}

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
        """{'front': Candidate or None, 'back': ...}, whether it was ambiguous, partial markers."""
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
        partial = []
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
            elif area is not None and self._partial(name, cands[chosen]):
                # Partly hidden: the visible part's centroid is not the marker's centre.
                found[name] = None
                partial.append(name)
        return found, ambiguous, partial

    def _partial(self, name: str, c: Candidate) -> bool:
        """Whether a marker's blob is smaller or less round than it usually is: partly hidden."""
        area, roundness = self._area[name], self._round[name]
        d_area, d_round, n = self._scatter[name]
        if n < SCATTER_FRAMES:
            return False            # (too few measurements to know what is usual)
        return c.area < area - max((1.0 - PARTIAL_AREA) * area, SCATTER * d_area) or \
            c.roundness < roundness - max(PARTIAL_ROUND, SCATTER * d_round)

    # -- per frame -----------------------------------------------------------------------------
    def _camera_motion(self, image: np.ndarray, small: np.ndarray) -> np.ndarray:
        masks = []
        if self._last_px is not None:
            f, b = self._last_px
            along = f - b
            masks.append((b - 0.2 * along, f + 0.2 * along, 0.2 * abs(along) + 10.0))
        transform = self.motion.update(small, image.shape[1], image.shape[0], masks)
        return self.motion.transform if transform is None else transform

    def update(self, image: Optional[np.ndarray], t: float) -> FrameResult:
        cfg = self.config
        if self._last_t is not None and t <= self._last_t:
            raise ValueError(f'frame time {t} is not after the previous one {self._last_t}')
        self._last_t = t
        cands: List[Candidate] = []
        if image is not None:
            if image.ndim != 3 or image.shape[2] != 3:
                raise ValueError('detect needs an HxWx3 colour image')
            small = shrink(image, cfg.downscale)
            cands = detect(image, cfg, self.encoding, small)
            to_scene = self._camera_motion(image, small)
            if cands:
                ideal = self.camera.undistort(np.array([c.p for c in cands]))
                if self.motion.moving:
                    ideal = apply(to_scene, ideal)
                for c, q in zip(cands, ideal):
                    c.q = complex(q)
        partial: List[str] = []
        hists = self._motions(cands) if not (self.initialised and self._confirmed) else None
        if self.initialised:
            found, ambiguous, partial = self._track(cands, t)
            if not self._confirmed:
                switch = self._check_lock(cands, hists, found)
                if switch is not None:
                    found, ambiguous, partial = switch, False, []
                    self._locked_at = (switch['front'].q, switch['back'].q)
        else:
            found, ambiguous = self._acquire(cands, hists)
        c = self.counters
        c.frames += 1
        res = FrameResult(t=t, status=TrackStatus.OK, candidates=len(cands))
        for name in MARKERS:
            cand = found[name]
            if cand is None:
                continue
            self._tracks[name].update(cand.q, t)
            if self._area[name] is not None:
                scatter = self._scatter[name]
                scatter[2] += 1
                w = max(LEARN, 1.0 / scatter[2])      # a plain mean over the first ten
                scatter[0] += w * (abs(cand.area - self._area[name]) - scatter[0])
                scatter[1] += w * (abs(cand.roundness - self._round[name]) - scatter[1])
            self._area[name] = _learn(self._area[name], cand.area)
            self._colour[name] = _learn(self._colour[name], cand.colour)
            self._round[name] = _learn(self._round[name], cand.roundness)
            setattr(res, f'{name}_px', cand.p)
            setattr(res, name, self._to_surface(cand.q))
        if found['front'] is not None and found['back'] is not None:
            self._vector = found['front'].q - found['back'].q
            res.spacing_px = abs(self._vector)
            self._spacing = _learn(self._spacing, res.spacing_px)
            self._last_px = (found['front'].p, found['back'].p)
        lost = [name for name in MARKERS if found[name] is None]
        if ambiguous:
            res.status = TrackStatus.AMBIGUOUS
            c.ambiguous += 1
        elif partial:
            res.status = TrackStatus.PARTIAL
            c.partial += 1
        elif lost:
            res.status = (TrackStatus.BOTH_LOST if len(lost) == 2 else
                          TrackStatus.FRONT_LOST if lost == ['front'] else TrackStatus.BACK_LOST)
        c.front_lost += 'front' in lost
        c.back_lost += 'back' in lost
        if len(lost) == 2:
            self._both_lost += 1
            if self._both_lost >= cfg.reacquire_after and self.initialised:
                # The lock is lost: what was learned of that pair (perhaps the wrong one) goes.
                self._tracks = {'front': _Track(), 'back': _Track()}
                self._forget()
                self._last_px = None
        else:
            self._both_lost = 0
        if res.status is not TrackStatus.OK:
            c.consecutive_not_ok += 1
            c.longest_not_ok = max(c.longest_not_ok, c.consecutive_not_ok)
            return res
        c.consecutive_not_ok = 0
        c.ok += 1
        # In the frame of the camera's slope first (the history's), turned on output.
        front0 = complex(self.camera.to_surface(found['front'].q))
        back0 = complex(self.camera.to_surface(found['back'].q))
        line = front0 - back0
        pitch0 = math.atan2(line.imag, line.real) - cfg.marker_line_angle
        position0 = 0.5 * (front0 + back0) + complex(math.cos(pitch0), math.sin(pitch0)) \
            * complex(cfg.com_offset_x, cfg.com_offset_y)
        self._speeds(res, position0, pitch0)
        return res

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
