"""
Calibrating a camera: its lens from a board waved in front of it, and the plane of motion.

The lens: OpenCV's pinhole model with the plumb-bob distortion (k1, k2, p1, p2, k3), fitted by
``cv2.calibrateCamera`` to the corners of a calibration board seen in many views. Boards:
- ``chessboard:COLSxROWS:SQUARE_M``: COLS x ROWS INNER corners (as OpenCV's patternSize and the
  ROS camera_calibration tool's ``--size``), squares SQUARE_M metres; found whole or not at all
  (``cv2.findChessboardCorners``, refined by ``cornerSubPix``);
- ``charuco:COLSxROWS:SQUARE_M:MARKER_M[:DICT]``: COLS x ROWS SQUARES with ArUco markers of
  MARKER_M in the white ones (dictionary DICT, default DICT_4X4_50, as anipose's boards); found
  in part (``cv2.aruco.CharucoDetector``), each corner by its id.
A chessboard view counts when the whole board is found (one cut by the picture's edge or hidden
in part is not), a ChArUco view when it has at least MIN_CORNERS corners; and when it is sharp
(a chessboard's edges rise over at most MAX_EDGE_PX px: ``cv2.estimateChessboardSharpness``).
Refused (``CalibrationError``, one line saying why): fewer than MIN_VIEWS views, views that all
hold the board at nearly the same angle (the focal length is then not measured: it trades
against the distance), a fit whose RMS reprojection error is over MAX_RMS_PX.

The result is written in the ROS camera calibration YAML (what camera_info_manager and
camera_calibration read and write: image_width, image_height, camera_name, camera_matrix,
distortion_model plumb_bob, distortion_coefficients, rectification_matrix identity,
projection_matrix [K | 0]), with the RMS error and the views used as comments.

The plane of motion: the homography from ideal (undistorted) pixels to metres in the robot's
plane, from a board lying in it (one picture) or from four or more image points whose plane
coordinates are known. The plane's axes: x along the board's rows, pointing to the right of the
picture, y up (a board's corners are numbered so; the axes are turned by quarter turns to make
it so whichever way the board lies). Written as a YAML of its own (``plane_homography``, rows,
cols, data), read by ``saw-ros track --plane``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path
from typing import Iterable, List, Optional, Sequence, Tuple

import cv2
import numpy as np
import yaml

MIN_VIEWS = 8             # views with the board found needed for a calibration
MIN_CORNERS = 8           # corners a view needs (a ChArUco board seen in part)
MAX_EDGE_PX = 4.0         # a sharper chessboard: its edges rise over at most this many px
MIN_TILT = math.radians(10.0)     # views must hold the board at angles this far apart
MAX_RMS_PX = 1.0          # a worse fit is refused: a wrong detection or a lens not of this model
MAX_VIEWS = 60            # frames of a clip looked at, evenly spread
DICTIONARIES = ('DICT_4X4_50', 'DICT_4X4_100', 'DICT_4X4_250', 'DICT_5X5_50', 'DICT_5X5_100',
                'DICT_5X5_250', 'DICT_6X6_50', 'DICT_6X6_250', 'DICT_ARUCO_ORIGINAL')


class CalibrationError(ValueError):
    """A calibration that cannot be trusted, or bad input to one: the message says why."""


@dataclass(frozen=True)
class Board:
    """A calibration board: its kind, its size (inner corners or squares) and its lengths."""

    kind: str                       # 'chessboard' or 'charuco'
    cols: int                       # chessboard: inner corners; charuco: squares
    rows: int
    square: float                   # m
    marker: float = 0.0             # m, charuco only
    dictionary: str = 'DICT_4X4_50'

    @classmethod
    def parse(cls, text: str) -> 'Board':
        """Return the board of 'chessboard:COLSxROWS:SQUARE_M' or 'charuco:...:MARKER_M[:DICT]'."""
        parts = text.split(':')
        kind = parts[0].lower()
        form = 'chessboard:COLSxROWS:SQUARE_M (inner corners) or ' \
            'charuco:COLSxROWS:SQUARE_M:MARKER_M[:DICT] (squares)'
        if kind not in ('chessboard', 'charuco') or \
                len(parts) not in ((3,) if kind == 'chessboard' else (4, 5)):
            raise CalibrationError(f'--board {text!r}: give {form}')
        try:
            cols, rows = (int(v) for v in parts[1].lower().split('x'))
            square = float(parts[2])
            marker = float(parts[3]) if kind == 'charuco' else 0.0
        except ValueError:
            raise CalibrationError(f'--board {text!r}: give {form}') from None
        least = 2 if kind == 'chessboard' else 3
        if cols < least or rows < least or cols * rows < 6:
            raise CalibrationError(f'--board {text!r}: at least {least}x{least} and 6 '
                                   f"{'inner corners' if kind == 'chessboard' else 'squares'}")
        if not (0 < square < 1 and math.isfinite(square)):
            raise CalibrationError(f'--board {text!r}: the square is {square!r} m (0 < it < 1)')
        dictionary = parts[4].upper() if len(parts) == 5 else 'DICT_4X4_50'
        if kind == 'charuco':
            if not 0 < marker < square:
                raise CalibrationError(f'--board {text!r}: the marker ({marker!r} m) must be '
                                       f'smaller than the square ({square!r} m)')
            if dictionary not in DICTIONARIES:
                raise CalibrationError(f'--board {text!r}: dictionary {dictionary!r}: one of '
                                       f'{", ".join(DICTIONARIES)}')
        return cls(kind, cols, rows, square, marker, dictionary)

    @property
    def corners(self) -> int:
        """Return the number of corners of the whole board."""
        return self.cols * self.rows if self.kind == 'chessboard' else \
            (self.cols - 1) * (self.rows - 1)

    def object_points(self) -> np.ndarray:
        """Return every corner on the board, (n, 3) m, in the order detection numbers them."""
        if self.kind == 'charuco':
            return np.asarray(self.charuco().getChessboardCorners(), np.float64).reshape(-1, 3)
        c, r = np.meshgrid(np.arange(self.cols), np.arange(self.rows))
        return np.stack([c.ravel() * self.square, r.ravel() * self.square,
                         np.zeros(c.size)], -1)

    def charuco(self):
        """Return OpenCV's CharucoBoard of this board."""
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.cols, self.rows), self.square, self.marker, d)

    def image(self, px_per_square: int) -> np.ndarray:
        """
        Return the board's picture (grey, uint8), one square = ``px_per_square`` px.

        With one white square of margin; the board point (0, 0) of ``object_points`` at pixel
        ``origin_px`` (pixel centres at integers).
        """
        s = px_per_square
        if self.kind == 'charuco':
            w, h = self.cols * s, self.rows * s
            img = self.charuco().generateImage((w, h), marginSize=0)
            return cv2.copyMakeBorder(img, s, s, s, s, cv2.BORDER_CONSTANT, value=255)
        squares = np.indices((self.rows + 1, self.cols + 1)).sum(0) % 2
        img = np.kron(1 - squares, np.ones((s, s))) * 255
        return cv2.copyMakeBorder(img.astype(np.uint8), s, s, s, s, cv2.BORDER_CONSTANT,
                                  value=255)

    def origin_px(self, px_per_square: int) -> float:
        """Return where ``image`` puts the board point (0, 0) (x and y alike), px."""
        return (2 if self.kind == 'chessboard' else 1) * px_per_square - 0.5


@dataclass
class View:
    """One picture's corners: board points (n, 3) m and image points (n, 2) px."""

    index: int
    object_points: np.ndarray
    image_points: np.ndarray


@dataclass
class Detections:
    """What a clip gave: the views found and why the other frames were not used."""

    size: Tuple[int, int]           # (width, height)
    views: List[View] = field(default_factory=list)
    frames: int = 0
    no_board: int = 0
    blurred: int = 0
    partial: int = 0

    def summary(self) -> str:
        """Return the views found and the frames left out, and why (one line)."""
        return (f'{len(self.views)} views with the board of {self.frames} frames looked at '
                f'({self.no_board} without the whole board found, {self.partial} with fewer '
                f'than {MIN_CORNERS} corners, {self.blurred} blurred)')


def _grey(frame: np.ndarray) -> np.ndarray:
    return frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)


class Detector:
    """Finds a board's corners in pictures (one detector for a whole clip)."""

    def __init__(self, board: Board):
        self.board = board
        if board.kind == 'charuco':
            self._charuco = cv2.aruco.CharucoDetector(board.charuco())

    def find(self, frame: np.ndarray, index: int = 0) -> Tuple[Optional[View], str]:
        """Return the view (or None) and '' or why not: 'no board', 'partial', 'blurred'."""
        grey = _grey(frame)
        b = self.board
        if b.kind == 'charuco':
            corners, ids, _, _ = self._charuco.detectBoard(grey)
            if corners is None or ids is None or len(ids) == 0:
                return None, 'no board'
            if len(ids) < MIN_CORNERS:
                return None, 'partial'
            obj, img = b.charuco().matchImagePoints(corners, ids)
            return View(index, obj.reshape(-1, 3).astype(np.float64),
                        img.reshape(-1, 2).astype(np.float64)), ''
        size = (b.cols, b.rows)
        found, corners = cv2.findChessboardCorners(
            grey, size, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
        if not found:
            # (A chessboard cut by the picture's edge or hidden in part is not found at all.)
            return None, 'no board'
        sharp = float(np.ravel(cv2.estimateChessboardSharpness(grey, size, corners)[0])[0])
        if not sharp <= MAX_EDGE_PX:
            return None, 'blurred'
        corners = cv2.cornerSubPix(grey, corners, (5, 5), (-1, -1),
                                   (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 40, 0.001))
        return View(index, b.object_points(), corners.reshape(-1, 2).astype(np.float64)), ''


def detect_views(frames: Iterable[Tuple[int, float, np.ndarray]], board: Board,
                 size: Tuple[int, int]) -> Detections:
    """Return the views of a frame source's frames (index, t, picture) with the board found."""
    det = Detector(board)
    out = Detections(size=size)
    for index, _, frame in frames:
        if (frame.shape[1], frame.shape[0]) != tuple(size):
            raise CalibrationError(f'frame {index} is {frame.shape[1]}x{frame.shape[0]}, the '
                                   f'clip {size[0]}x{size[1]}: one camera, one size')
        out.frames += 1
        view, why = det.find(frame, index)
        if view is not None:
            out.views.append(view)
        elif why == 'blurred':
            out.blurred += 1
        elif why == 'partial':
            out.partial += 1
        else:
            out.no_board += 1
    return out


@dataclass
class Lens:
    """A calibrated camera: K (3x3), plumb-bob distortion (k1, k2, p1, p2, k3), picture size."""

    width: int
    height: int
    K: np.ndarray
    dist: np.ndarray
    rms_px: float = math.nan        # RMS reprojection error of the calibration
    views: int = 0                  # views it was fitted to
    frames: Tuple[int, ...] = ()    # their frame indices
    camera_name: str = 'camera'

    @property
    def focal(self) -> float:
        """Return the mean focal length (fx + fy) / 2, px."""
        return 0.5 * (self.K[0, 0] + self.K[1, 1])

    def camera_kw(self) -> dict:
        """Return the ``CameraModel`` arguments of this lens (its distortion and matrix)."""
        return {'dist_coeffs': tuple(float(v) for v in self.dist),
                'dist_matrix': (float(self.K[0, 0]), float(self.K[1, 1]),
                                float(self.K[0, 2]), float(self.K[1, 2]))}


def _tilt_spread(rvecs: Sequence[np.ndarray]) -> float:
    """Return the largest angle between two views' board normals, rad."""
    normals = np.array([cv2.Rodrigues(np.asarray(r, float))[0][:, 2] for r in rvecs])
    cos = np.clip(np.abs(normals @ normals.T), -1.0, 1.0)
    return float(np.arccos(cos.min()))


def _spread_views(views: List[View], most: int) -> List[View]:
    """Return at most ``most`` views, evenly spread over the clip."""
    if len(views) <= most:
        return views
    keep = np.unique(np.linspace(0, len(views) - 1, most).round().astype(int))
    return [views[k] for k in keep]


def calibrate(detections: Detections, camera_name: str = 'camera',
              most_views: int = 40) -> Lens:
    """
    Return the lens fitted to the views (CalibrationError when it cannot be trusted).

    At most ``most_views`` views, evenly spread over the clip, go into the fit.
    """
    views = _spread_views(detections.views, most_views)
    if len(views) < MIN_VIEWS:
        raise CalibrationError(f'too few views of the board: {detections.summary()}; at least '
                               f'{MIN_VIEWS} needed (wave the board slowly, whole and in focus, '
                               'at several angles)')
    width, height = detections.size
    obj = [v.object_points.astype(np.float32).reshape(-1, 1, 3) for v in views]
    img = [v.image_points.astype(np.float32).reshape(-1, 1, 2) for v in views]
    try:
        rms, K, dist, rvecs, _ = cv2.calibrateCamera(obj, img, (width, height), None, None)
    except cv2.error as exc:
        raise CalibrationError(f'the calibration failed ({str(exc).strip().splitlines()[-1]}): '
                               f'{detections.summary()}') from None
    # Views that all hold the board at one angle fit any focal length (it trades against the
    # distance): refused, whatever the fit's error.
    spread = _tilt_spread(rvecs)
    if spread < MIN_TILT:
        raise CalibrationError(f'the {len(views)} views hold the board at nearly the same angle '
                               f'(the most tilted pair {math.degrees(spread):.1f} deg apart, '
                               f'{math.degrees(MIN_TILT):g} needed): the focal length cannot be '
                               'told from the distance; tilt the board towards and away from '
                               'the camera, left and right')
    if not (math.isfinite(rms) and rms <= MAX_RMS_PX):
        raise CalibrationError(f'the fit is poor: RMS reprojection error {rms:.2f} px (at most '
                               f'{MAX_RMS_PX:g}): a wrong board size, motion blur, or a lens '
                               "that the plumb-bob model does not fit (a fisheye's)")
    return Lens(width, height, K, dist.ravel()[:5], float(rms), len(views),
                tuple(v.index for v in views), camera_name)


# -- ROS camera calibration YAML ------------------------------------------------------------
def _matrix(rows: int, cols: int, values) -> dict:
    return {'rows': rows, 'cols': cols, 'data': [float(v) for v in np.ravel(values)]}


def write_lens(path: Path, lens: Lens, source: str) -> None:
    """Write the lens in the ROS camera calibration YAML (camera_info_manager's)."""
    doc = {'image_width': int(lens.width), 'image_height': int(lens.height),
           'camera_name': lens.camera_name,
           'camera_matrix': _matrix(3, 3, lens.K),
           'distortion_model': 'plumb_bob',
           'distortion_coefficients': _matrix(1, 5, lens.dist),
           'rectification_matrix': _matrix(3, 3, np.eye(3)),
           'projection_matrix': _matrix(3, 4, np.hstack([lens.K, np.zeros((3, 1))]))}
    text = yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=1000)
    head = (f'# saw-ros calibrate-camera {source}\n'
            f'# RMS reprojection error {lens.rms_px:.4f} px over {lens.views} views '
            f'(frames {" ".join(map(str, lens.frames))})\n')
    Path(path).write_text(head + text)


def _read_matrix(doc: dict, key: str, shape: Tuple[int, int], where: str) -> np.ndarray:
    m = doc.get(key)
    if not isinstance(m, dict) or not isinstance(m.get('data'), list):
        raise CalibrationError(f'{where}: no {key} {{rows, cols, data}}')
    try:
        data = np.array(m['data'], dtype=float)
    except (TypeError, ValueError):
        raise CalibrationError(f'{where}: {key} data is not a list of numbers') from None
    if (m.get('rows'), m.get('cols')) != shape or data.size != shape[0] * shape[1] or \
            not np.all(np.isfinite(data)):
        raise CalibrationError(f'{where}: {key} must be {shape[0]}x{shape[1]} finite numbers')
    return data.reshape(shape)


def _load(path: Path, what: str) -> dict:
    where = f'{what} {path}'
    try:
        text = Path(path).read_text()
    except UnicodeDecodeError:
        raise CalibrationError(f'{where}: not a text file') from None
    except OSError as exc:
        raise CalibrationError(f'{where}: {exc.strerror or exc}') from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        at = f' at line {mark.line + 1}' if mark is not None else ''
        raise CalibrationError(f'{where}: not YAML{at}') from None
    if not isinstance(doc, dict):
        raise CalibrationError(f'{where}: not a YAML mapping')
    return doc


def read_lens(path: Path) -> Lens:
    """Return the lens of a ROS camera calibration YAML (plumb_bob; square pixels not needed)."""
    where = f'camera calibration {path}'
    doc = _load(path, 'camera calibration')
    width, height = doc.get('image_width'), doc.get('image_height')
    if not (isinstance(width, int) and isinstance(height, int) and width > 0 and height > 0):
        raise CalibrationError(f'{where}: image_width and image_height must be positive '
                               'integers')
    K = _read_matrix(doc, 'camera_matrix', (3, 3), where)
    if not (K[0, 0] > 0 and K[1, 1] > 0):
        raise CalibrationError(f'{where}: camera_matrix has no focal length')
    model = doc.get('distortion_model', 'plumb_bob')
    if model not in ('plumb_bob', 'rational_polynomial'):
        raise CalibrationError(f'{where}: distortion_model {model!r}: plumb_bob or '
                               'rational_polynomial (OpenCV pinhole)')
    d = doc.get('distortion_coefficients', {})
    n = d.get('cols') if isinstance(d, dict) else None
    dist = _read_matrix(doc, 'distortion_coefficients', (1, n if n in (4, 5, 8) else 5),
                        where).ravel()
    return Lens(width, height, K, dist, camera_name=str(doc.get('camera_name', 'camera')))


# -- the plane of motion ----------------------------------------------------------------------
def _orient(plane: np.ndarray, image: np.ndarray) -> np.ndarray:
    """
    Return plane points turned so that x points to the picture's right and y up.

    ``plane`` (n, 2) m and their ``image`` (n, 2) ideal pixels: of the eight ways to lay the
    axes on the board, the one whose x goes most to the right and y most upwards.
    """
    h, _ = cv2.findHomography(plane, image)          # plane -> image
    c = plane.mean(0)
    best, best_score = plane, -math.inf
    for swap in (False, True):
        for sx in (1.0, -1.0):
            for sy in (1.0, -1.0):
                turn = (np.array([[0.0, 1.0], [1.0, 0.0]]) if swap else np.eye(2)) * [[sx], [sy]]
                inv = np.linalg.inv(turn)
                # the image directions of the turned axes at the board's centre
                pts = np.array([c, c + inv @ [0.01, 0.0], c + inv @ [0.0, 0.01]])
                img = cv2.perspectiveTransform(pts.reshape(-1, 1, 2), h).reshape(-1, 2)
                ex, ey = img[1] - img[0], img[2] - img[0]
                if ex[0] * ey[1] - ex[1] * ey[0] > 0:   # y down in the picture: mirrored axes
                    continue
                score = ex[0] / np.hypot(*ex) - ey[1] / np.hypot(*ey)
                if score > best_score:
                    best, best_score = plane @ turn.T, score
    return best


def plane_from_points(image: np.ndarray, plane: np.ndarray) -> Tuple[np.ndarray, float]:
    """
    Return the homography ideal pixels -> plane (m) through 4+ point pairs, and its RMS error (m).

    CalibrationError for fewer than 4 points, three of them on a line, or a map that folds.
    """
    image, plane = np.asarray(image, float).reshape(-1, 2), np.asarray(plane, float).reshape(-1, 2)
    n = len(image)
    if n < 4 or len(plane) != n:
        raise CalibrationError(f'the plane needs 4 or more points with their plane coordinates '
                               f'({n} given)')
    if not (np.all(np.isfinite(image)) and np.all(np.isfinite(plane))):
        raise CalibrationError('the plane points must be finite numbers')
    for pts, what in ((image, 'image'), (plane, 'plane')):
        centred = pts - pts.mean(0)
        sv = np.linalg.svd(centred, compute_uv=False)
        if sv[1] < 1e-3 * max(sv[0], 1e-12):
            raise CalibrationError(f'the plane points lie on one line in the {what}: the plane '
                                   'needs points spread in both directions')
    h, _ = cv2.findHomography(image, plane, 0)
    if h is None or not np.all(np.isfinite(h)):
        raise CalibrationError('no homography fits the plane points (three of them on a line?)')
    mapped = cv2.perspectiveTransform(image.reshape(-1, 1, 2), h).reshape(-1, 2)
    # A map that folds (the horizon between the points) is no camera's view of a plane.
    den = h[2, 0] * image[:, 0] + h[2, 1] * image[:, 1] + h[2, 2]
    if not (np.all(den > 0) or np.all(den < 0)):
        raise CalibrationError('the plane points are not a camera view of a plane (the map '
                               'folds between them): check their order')
    rms = float(np.sqrt(np.mean(np.sum((mapped - plane) ** 2, 1))))
    return h / h[2, 2], rms


def plane_from_view(view: View, undistort) -> Tuple[np.ndarray, float]:
    """
    Return the plane's homography from a board lying in it, and its RMS error (m).

    ``undistort``: image pixels (complex) -> ideal pixels (the lens's; identity without one).
    The board's first corner is the plane's origin; its axes are turned so that x points to the
    picture's right and y up.
    """
    pix = view.image_points
    ideal = np.asarray(undistort(pix[:, 0] + 1j * pix[:, 1]))
    image = np.stack([ideal.real, ideal.imag], -1)
    plane = _orient(view.object_points[:, :2].copy(), image)
    return plane_from_points(image, plane - plane[0])


def write_plane(path: Path, h: np.ndarray, rms_m: float, source: str, lens_file: str = '') -> None:
    """Write the plane's homography (ideal pixels -> plane, m) as YAML."""
    doc = {'plane_homography': _matrix(3, 3, h), 'rms_m': float(rms_m)}
    head = (f'# saw-ros calibrate-camera: the plane of motion from {source}\n'
            f'# ideal (undistorted{" by " + lens_file if lens_file else ""}) pixels -> plane '
            f'metres, x to the right, y up; RMS {1000 * rms_m:.3f} mm at the points\n')
    Path(path).write_text(head + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None,
                                                width=1000))


def read_plane(path: Path) -> np.ndarray:
    """Return the homography of a plane file written by ``write_plane``."""
    where = f'plane {path}'
    h = _read_matrix(_load(path, 'plane'), 'plane_homography', (3, 3), where)
    if abs(np.linalg.det(h)) < 1e-300:
        raise CalibrationError(f'{where}: plane_homography is singular')
    return h


def parse_plane_points(text: str) -> Tuple[np.ndarray, np.ndarray]:
    """Return (image (n, 2) px, plane (n, 2) m) of 'u,v,x,y;u,v,x,y;...'."""
    image, plane = [], []
    for item in text.replace(' ', '').split(';'):
        if not item:
            continue
        try:
            u, v, x, y = (float(s) for s in item.split(','))
        except ValueError:
            raise CalibrationError(f'--plane-points {text!r}: give u,v,x,y;u,v,x,y;... (pixels, '
                                   'then metres in the plane), 4 points or more') from None
        image.append((u, v))
        plane.append((x, y))
    return np.array(image).reshape(-1, 2), np.array(plane).reshape(-1, 2)
