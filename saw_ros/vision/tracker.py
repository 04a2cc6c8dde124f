"""
Two-pink-marker tracker: robot position, pitch and speed from images alone.

It knows nothing of the simulation: only a camera model (``CameraModel``: pixels per metre or K
and the distance to the plane of motion, the slope of the surfaces as a level camera sees them,
the surface-frame point at the principal point, optionally the lens distortion) and what the
markers look like (``TrackerConfig``: colour window, optionally their spacing on the robot, their
size and a region of interest).

Per frame, each step in a module of its own:
1.-2. Detection (``markers``): pink blobs in the picture, their sub-pixel centres, area, colour
   and roundness; centres undistorted by the camera's lens.
3. Camera motion (``egomotion.CameraMotion``, on the shrunk image detection made): the
   background's corners, the robot masked out, give the similarity that takes each picture back
   to the first one (the scene's frame); marker centres are measured in that frame, so a
   handheld camera's drift and jitter do not add to the robot's motion. A fixed camera is left
   exactly as it is (no correction until the picture has moved by 0.5 px three frames in a
   row); a scale (zoom) or roll that changes during the clip is a warning.
4. Acquisition (``acquisition``): which two blobs are the robot's markers.
5. Association (``association``): which blob is which marker from frame to frame; a marker
   lost, ambiguous or partly hidden is not measured.
6.-7. Measurement (``measurement``): ideal pixels -> surface frame through the camera model
   (``camera``: scale or the plane of motion, slope, lens), position, pitch and speeds.

``Tracker.warnings`` says what makes the numbers doubtful, ``Tracker.notes`` what was done
(camera motion taken out, the slope from the motion, a static pair dropped).

A frame gets status 'ok', 'front lost', 'back lost', 'both lost', 'ambiguous' or 'partial'.
Position, pitch and speeds exist only for 'ok' frames: nothing is made up on the others.
"""
from __future__ import annotations

from collections import deque
import math
from typing import Deque, Dict, List, Optional, Tuple

import numpy as np

from saw_ros.vision import perspective
from saw_ros.vision.acquisition import Acquisition
from saw_ros.vision.association import _Track, Association
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.egomotion import apply, CameraMotion
from saw_ros.vision.markers import Candidate, check_reduced, detect, shrink, TrackerConfig
from saw_ros.vision.measurement import (_learn, Counters, DIRECTION_PX, FrameResult, LEARN,
                                        MARKERS, Measurement, scale_from_spacing, steady_speed,
                                        TrackStatus)

__all__ = ['Candidate', 'Counters', 'detect', 'FrameResult', 'scale_from_spacing', 'shrink',
           'steady_speed', 'Tracker', 'TrackerConfig', 'TrackStatus']

SLOPE_WARN = math.radians(2.0)     # a given slope this far from the motion is warned about
ZOOM_WARN = 0.01          # the picture's scale changing by this much is warned about
ROLL_WARN = math.radians(0.5)      # ... its roll by this much
PLACES = 3600             # ok frames whose marker places the perspective check keeps (1 min)
PLACES_EVERY = 30         # ... checked again after this many more


class Tracker(Acquisition, Association, Measurement):
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
        # ok frames' marker places (scene-frame ideal px): the perspective along the track
        self._places: Deque[Tuple[complex, complex]] = deque(maxlen=PLACES)
        self._placed = 0                # places kept so far, all told
        self._along: Tuple[int, Optional[perspective.AlongTrack]] = (0, None)
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
        along = self.perspective()
        if along is not None and along.significant:
            out.append(perspective.warning(along, f'{self.camera.scale:.1f} px/m'))
        if not self.slope_known and self._direction is None and self.counters.ok:
            out.append(f'the track direction is not known: the markers did not move '
                       f'{DIRECTION_PX:g} px (no steady speed without --slope-deg)')
        return out

    def perspective(self) -> Optional[perspective.AlongTrack]:
        """
        Return what the markers' spacing says of a perspective along the track (None: unknown).

        Only for a camera without a plane (a plane takes the perspective out); from the ok
        frames' marker places, along the track's direction, refitted every PLACES_EVERY frames.
        """
        slope = self.slope_used
        if self.camera.plane is not None or slope is None:
            return None
        count, along = self._along
        if self._placed >= count + PLACES_EVERY:
            direction = complex(math.cos(slope), math.sin(slope))
            if self.camera.mirror:
                direction = -direction.conjugate()
            cx, cy = self.camera.principal_point
            places = np.array(self._places)
            z = (places.real - cx) - 1j * (places.imag - cy)       # level picture frame, y up
            a = (z * direction.conjugate()).real / self.camera.scale
            along = perspective.fit(a[:, 0], a[:, 1])
            self._along = (self._placed, along)
        return along

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
        self._places = deque(((f + delta, b + delta) for f, b in self._places), maxlen=PLACES)
        self.camera = camera

    def reset(self) -> None:
        Tracker.__init__(self, self.camera, self.config, self.encoding, self.slope_known)

    # -- per frame -----------------------------------------------------------------------------
    def _camera_motion(self, image: np.ndarray, small: np.ndarray, reduced: int) -> np.ndarray:
        masks = []
        if self._last_px is not None:
            f, b = self._last_px
            along = f - b
            masks.append((b - 0.2 * along, f + 0.2 * along, 0.2 * abs(along) + 10.0))
        transform = self.motion.update(small, image.shape[1] * reduced,
                                       image.shape[0] * reduced, masks)
        return self.motion.transform if transform is None else transform

    def update(self, image: Optional[np.ndarray], t: float, reduced: int = 1) -> FrameResult:
        """
        Track one frame taken at ``t`` (s, later than the last); None: no picture this time.

        ``reduced``: the image is the picture at 1 / ``reduced`` of its size (a JPEG decoded at
        half size, ``compressed.decode``), ``config.downscale`` a multiple of it: detection and
        the camera's motion see the same shrunk picture, and everything comes back in the
        picture's own pixels.
        """
        cfg = self.config
        if self._last_t is not None and t <= self._last_t:
            raise ValueError(f'frame time {t} is not after the previous one {self._last_t}')
        check_reduced(reduced, cfg.downscale)
        self._last_t = t
        cands: List[Candidate] = []
        if image is not None:
            if image.ndim != 3 or image.shape[2] != 3:
                raise ValueError('detect needs an HxWx3 colour image')
            small = shrink(image, cfg.downscale // reduced)
            cands = detect(image, cfg, self.encoding, small, reduced)
            to_scene = self._camera_motion(image, small, reduced)
            if cands:
                ideal = self.camera.undistort(np.array([c.p for c in cands]))
                if self.motion.moving:
                    ideal = apply(to_scene, ideal)
                for blob, q in zip(cands, ideal):
                    blob.q = complex(q)
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
            if not ambiguous and not partial:
                self._places.append((found['front'].q, found['back'].q))
                self._placed += 1
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
