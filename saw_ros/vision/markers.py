"""
Where the pink markers are in a picture: the tracker's detection (its first two steps).

What the markers look like is ``TrackerConfig`` (also the tracker's other settings: the vision
node's parameters and ``saw-ros track``'s options are made from its fields); ``detect`` finds
them in one picture, as ``Candidate`` blobs:

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

The default colour window, hue 140..172 (OpenCV 0-179), S >= 70, V >= 60, is pink, not red: it
takes magenta (150), neon and shocking pink (152-158), hot and deep pink (163-165, the renderer's
is 163) and fluorescent pink under warm light (170-172); it refuses crimson (174), red (175-179
and 0-4), orange-red and tomato (5-8), orange (16-19) and violet (< 140). Magenta passes: size,
colour, spacing and the robot's line tell it from a marker.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import List, Optional, Tuple

import cv2
import numpy as np

from saw_ros.core.params import spec

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
    q: complex = 0j               # ideal (undistorted) pixel position, set by the tracker

    @property
    def p(self) -> complex:
        return complex(self.u, self.v)


def median(values: np.ndarray) -> float:
    """
    Return np.median of a finite array, to the bit, without its overhead.

    np.median costs 8-16 us on the few hundred values of a marker's window or the camera
    motion's corners, its partition 2.
    """
    flat = values.ravel()
    k = flat.size // 2
    if flat.size % 2:
        return float(np.partition(flat, k)[k])
    part = np.partition(flat, (k - 1, k))
    return float((part[k - 1] + part[k]) / 2)


def check_reduced(reduced: int, downscale: int) -> int:
    """Return ``reduced`` if detection can take a picture reduced by it; ValueError otherwise."""
    if isinstance(reduced, bool) or not isinstance(reduced, (int, np.integer)) or reduced < 1 \
            or downscale % reduced:
        raise ValueError(f'a picture reduced by {reduced!r}: needs a positive integer that '
                         f'divides the downscale {downscale}')
    return int(reduced)


def shrink(image: np.ndarray, factor: int) -> np.ndarray:
    """Return the image shrunk by ``factor`` as detection does it (bilinear)."""
    h, w = image.shape[:2]
    return cv2.resize(image, (w // factor, h // factor), interpolation=cv2.INTER_LINEAR) \
        if factor > 1 else image


def detect(image: np.ndarray, config: TrackerConfig = TrackerConfig(),
           encoding: str = 'bgr8', small: Optional[np.ndarray] = None,
           reduced: int = 1) -> List[Candidate]:
    """
    Return the pink blobs in a BGR (or RGB) uint8 image, heaviest first.

    Each with its sub-pixel centroid (image pixels), area, colour and roundness. ``small``: the
    whole image already shrunk (``shrink``), when there is no region of interest.

    ``reduced``: the image is the picture at 1 / ``reduced`` of its size, as a JPEG decoder's
    DCT scaling gives it (``compressed.decode(..., reduced=2)``; ``config.downscale`` a multiple
    of it); centres, areas and the region of interest stay in the picture's own pixels.
    Pinkness R + B - 2 G is chroma alone (Y cancels), which a 4:2:0 JPEG holds at half
    resolution: the half-size decode keeps all of it.
    """
    if image is None or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError('detect needs an HxWx3 colour image')
    if encoding not in ('bgr8', 'rgb8'):
        raise ValueError(f'unsupported encoding {encoding!r}: use bgr8 or rgb8')
    r = check_reduced(reduced, config.downscale)
    ox = oy = 0
    if config.roi is not None:
        # The reduced pixels wholly inside the region.
        x0, y0 = (-(-v // r) for v in config.roi[:2])
        x1, y1 = (v // r for v in config.roi[2:])
        x1, y1 = min(x1, image.shape[1]), min(y1, image.shape[0])
        if x0 >= x1 or y0 >= y1:
            return []
        image, ox, oy = image[y0:y1, x0:x1], x0, y0
    s = config.downscale // r
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
        mask = cv2.bitwise_or(mask, cv2.inRange(hsv, (0, config.sat_min, config.val_min),
                                                (hi, 255, 255)))
    red, blue = (2, 0) if encoding == 'bgr8' else (0, 2)
    # Dark or grey pixels made colourful by sensor noise pass the HSV test; their pinkness is
    # near zero: ask for both.
    chans = small.astype(np.int16)
    pinkness = chans[..., red] + chans[..., blue] - 2 * chans[..., 1]
    mask[pinkness < config.pink_min] = 0
    # Grana's block-based labelling: 0.09 ms on a 320x180 mask against 0.33 for OpenCV's
    # default (Spaghetti, whose decision forest pays off on larger, busier masks).
    count, _, stats, _ = cv2.connectedComponentsWithStatsWithAlgorithm(mask, 8, cv2.CV_32S,
                                                                       cv2.CCL_GRANA)
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
        pink -= median(pink)
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
            n_core = int(np.count_nonzero(in_blob)) * r * r
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
            # Reduced pixel j covers the picture's r j .. r j + r - 1: centre r j + (r - 1) / 2.
            found.append(Candidate(r * u + 0.5 * (r - 1), r * v + 0.5 * (r - 1), total * r * r,
                                   float(n_core), colour,
                                   max(low, 0.0) / big if big > 0 else 0.0))
    # Merge fragments of one marker: keep the heaviest.
    found.sort(key=lambda c: -c.weight)
    merged: List[Candidate] = []
    for c in found:
        if all(abs(c.p - m.p) >= config.merge_distance for m in merged):
            merged.append(c)
    return merged
