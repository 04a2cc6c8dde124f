"""
Camera calibration (issue 32): the lens from a board waved in front of it, the plane of motion.

Footage from our own generator drawn through a known camera (``footage.BoardClip``, ``Shot``
with yaw, pitch and a lens): the calibration recovers it, the same clip is measured right with
the calibration, and without it the perspective is a warning, never a silent wrong speed.
"""
import math

import cv2
import numpy as np
import pytest
from saw_ros.cli.main import main
from saw_ros.vision import calibration, perspective
from saw_ros.vision.calibration import Board, CalibrationError
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.footage import BoardClip, Shot
from saw_ros.vision.offline import measure_plane, track_video
from saw_ros.vision.tracker import TrackerConfig
import yaml

BARREL = (-0.12, 0.0, 0.0, 0.0)
CHESS = Board.parse('chessboard:9x6:0.02')
CHARUCO = Board.parse('charuco:7x5:0.04:0.03')
CONFIG = TrackerConfig(steady_window=2.0)


class Frames:
    """A shot's frames drawn once, as a frame source for several trackings."""

    def __init__(self, shot):
        self.size = shot.size
        self._frames = list(shot.frames())

    def frames(self):
        return iter(self._frames)


# A tripod not quite square (yaw 18 deg, pitch 10 deg) and a phone's barrel lens; the robot
# starts left of the centre, where a ruler at the centre is most wrong. 960 px wide: the camera
# motion's corners need it (at 640 px too few are found).
PERSPECTIVE = {'duration': 3.0, 'fps': 30.0, 'width': 960, 'height': 540, 'scale': 900.0,
               'yaw_deg': 18.0, 'pitch_deg': 10.0, 'dist_coeffs': BARREL, 'start_x': -0.12,
               'quality': 90}


@pytest.fixture(scope='module')
def tilted():
    """Return (shot, its frames, the same robot filmed square)."""
    shot = Shot(**PERSPECTIVE)
    square = Shot(**{**PERSPECTIVE, 'yaw_deg': 0.0, 'pitch_deg': 0.0, 'dist_coeffs': ()})
    return shot, Frames(shot), Frames(square)


def steady(results):
    return next(r.steady_speed for r in reversed(results) if r.steady_speed is not None)


# -- the lens ---------------------------------------------------------------------------------
@pytest.mark.parametrize('board, dist', [(CHESS, BARREL), (CHESS, (0.1, 0.0, 0.0, 0.0)),
                                         (CHARUCO, BARREL)])
def test_the_lens_is_recovered(board, dist):
    """Barrel and pincushion, chessboard and ChArUco: f within 0.5 %, the distortion's k1 too."""
    clip = BoardClip(board, dist_coeffs=dist, views=12)
    found = calibration.detect_views(clip.frames(), board, clip.size)
    lens = calibration.calibrate(found)
    assert lens.views == 12 and lens.rms_px <= 0.3
    assert lens.focal == pytest.approx(clip.focal, rel=0.005)
    assert lens.K[0, 2] == pytest.approx((clip.width - 1) / 2, abs=3.0)
    # The distortion where the board went: how far the lens moves a pixel (6 px), within 1 px
    # (the principal point, 1-3 px off, takes a part of it).
    truth = clip.lens()
    fitted = CameraModel(width=clip.width, height=clip.height, **lens.camera_kw())
    pixels = np.array([80.0 + 50.0j, 560.0 + 60.0j, 100.0 + 310.0j, 540 + 300j])
    moved = fitted.undistort(pixels) - pixels
    assert np.abs(moved - (truth.undistort(pixels) - pixels)).max() < 1.0
    assert np.abs(moved).max() > 5.0          # (a lens that moves them, to be found)


def test_charuco_boards_count_seen_in_part():
    """Views half out of the picture: a ChArUco board still gives its corners, a chessboard not."""
    clip = BoardClip(CHARUCO, dist_coeffs=BARREL, views=12, cut=4)
    found = calibration.detect_views(clip.frames(), CHARUCO, clip.size)
    assert len(found.views) >= 11
    assert any(len(v.image_points) < CHARUCO.corners for v in found.views[:4])
    chess = BoardClip(CHESS, dist_coeffs=BARREL, views=12, cut=4)
    found = calibration.detect_views(chess.frames(), CHESS, chess.size)
    assert len(found.views) <= 9 and found.no_board >= 3


@pytest.mark.parametrize('kw, why', [
    ({'views': 5}, 'too few views of the board: 5 views'),
    ({'blur': 3.0}, '12 blurred'),
    ({'tilt_deg': 0.0}, 'nearly the same angle'),
])
def test_a_lens_that_cannot_be_trusted_is_refused(kw, why):
    """Too few views, blurred ones, all parallel: refused with the reason, no file."""
    clip = BoardClip(CHESS, dist_coeffs=BARREL, **dict({'views': 12}, **kw))
    found = calibration.detect_views(clip.frames(), CHESS, clip.size)
    with pytest.raises(CalibrationError, match=why):
        calibration.calibrate(found)


def test_the_ros_camera_calibration_yaml(tmp_path):
    """The file has the ROS format's keys and shapes, and reads back to the same lens."""
    clip = BoardClip(CHESS, dist_coeffs=BARREL, views=10)
    lens = calibration.calibrate(calibration.detect_views(clip.frames(), CHESS, clip.size),
                                 camera_name='bench_cam')
    path = tmp_path / 'camera.yaml'
    calibration.write_lens(path, lens, 'test')
    doc = yaml.safe_load(path.read_text())
    assert list(doc) == ['image_width', 'image_height', 'camera_name', 'camera_matrix',
                         'distortion_model', 'distortion_coefficients', 'rectification_matrix',
                         'projection_matrix']
    assert (doc['image_width'], doc['image_height'], doc['camera_name']) == (640, 360,
                                                                             'bench_cam')
    assert doc['distortion_model'] == 'plumb_bob'
    for key, shape in (('camera_matrix', (3, 3)), ('distortion_coefficients', (1, 5)),
                       ('rectification_matrix', (3, 3)), ('projection_matrix', (3, 4))):
        assert (doc[key]['rows'], doc[key]['cols']) == shape
        assert len(doc[key]['data']) == shape[0] * shape[1]
    back = calibration.read_lens(path)
    np.testing.assert_allclose(back.K, lens.K)
    np.testing.assert_allclose(back.dist, lens.dist)
    assert 'RMS reprojection error' in path.read_text().splitlines()[1]


@pytest.mark.parametrize('text, why', [
    ('', 'not a YAML mapping'),
    ('image_width: [', 'not YAML'),
    ('image_width: 640\nimage_height: 360\n', 'no camera_matrix'),
    ('image_width: 640\nimage_height: 360\ncamera_matrix: {rows: 3, cols: 3, data: [1, 2]}\n',
     'must be 3x3'),
    ('image_width: -1\nimage_height: 360\n', 'positive integers'),
])
def test_bad_calibration_files_are_refused(tmp_path, text, why):
    path = tmp_path / 'camera.yaml'
    path.write_text(text)
    with pytest.raises(CalibrationError, match=why):
        calibration.read_lens(path)


# -- the plane --------------------------------------------------------------------------------
def test_the_plane_from_a_board_lying_in_it():
    """A board in the robot's plane, seen at yaw 18 deg and pitch 10 deg: metres on the plane."""
    shot = Shot(**PERSPECTIVE)
    view, why = calibration.Detector(CHESS).find(shot.board_still(CHESS, at=-0.1 + 0.03j))
    assert why == ''
    h, rms = calibration.plane_from_view(view, shot.lens().undistort)
    assert rms < 2e-4
    truth = CameraModel(width=shot.width, height=shot.height, plane=tuple(shot.plane().ravel()))
    found = CameraModel(width=shot.width, height=shot.height, plane=tuple(h.ravel()))
    # Across the picture: the same lengths and directions (the origin is the board's first
    # corner), within 0.3 % over 76 cm: a 16 cm board's plane, carried 4 times its size.
    p = np.array([150 + 200j, 800 + 230j, 480 + 400j])
    a, b = truth.to_surface(p), found.to_surface(p)
    np.testing.assert_allclose(np.abs(np.diff(a)), np.abs(np.diff(b)), rtol=0.003)
    np.testing.assert_allclose(np.angle(np.diff(a)), np.angle(np.diff(b)), atol=2e-3)


def test_the_plane_points_are_checked():
    image = np.array([[100, 100], [500, 110], [520, 300], [90, 310]], float)
    plane = np.array([[0, 0.2], [0.4, 0.2], [0.4, 0], [0, 0]], float)
    h, rms = calibration.plane_from_points(image, plane)
    assert rms < 1e-7             # (4 points: the homography through them exactly)
    with pytest.raises(CalibrationError, match='4 or more points'):
        calibration.plane_from_points(image[:3], plane[:3])
    line = np.array([[0, 0], [1, 1], [2, 2], [3, 3]], float)
    with pytest.raises(CalibrationError, match='on one line in the image'):
        calibration.plane_from_points(line, plane)
    with pytest.raises(CalibrationError, match='u,v,x,y'):
        calibration.parse_plane_points('1,2,3;4,5,6,7')


def test_a_camera_on_a_plane_maps_both_ways():
    shot = Shot(**PERSPECTIVE)
    cam = shot.calibrated_camera()
    s = np.array([0.1 + 0.02j, -0.2 + 0.05j])
    np.testing.assert_allclose(cam.to_surface(cam.to_pixels(s)), s, atol=1e-12)
    assert cam.scale == pytest.approx(shot.ruler_scale(), rel=0.1)


# -- the same clip with and without the calibration -------------------------------------------
def test_the_calibrated_clip_measures_the_square_clips_speed(tilted):
    """Lens and plane calibrated: the speed the square camera measures, and the positions."""
    shot, frames, square = tilted
    kw = {'center_x': 0.0, 'center_y': shot.track_y}
    results, tracker = track_video(square, dict(kw, scale=shot.scale), CONFIG, slope_known=False)
    reference = steady(results)
    cam = shot.calibrated_camera(False)
    results, tracker = track_video(frames, {k: getattr(cam, k) for k in (
        'center_x', 'center_y', 'plane', 'dist_coeffs', 'dist_matrix')}, CONFIG,
        slope_known=False)
    assert steady(results) == pytest.approx(reference, rel=0.003)
    assert tracker.warnings == []
    ok = [r for r in results if r.ok]
    assert len(ok) >= 0.9 * len(results)
    for r in ok:
        # metres on the plane: the markers 0.32 m apart wherever they are (within 0.5 mm);
        # where they are, within 3 mm (the track's direction from the motion: a turn of
        # a few mrad about the centre)
        assert abs(r.front - r.back) == pytest.approx(shot.spacing, abs=5e-4)
        front, back = shot.truth(r.t)
        assert max(abs(r.front - front), abs(r.back - back)) < 3e-3


def test_a_ruler_scale_alone_is_warned_about(tilted):
    """The ruler at the picture's centre: several % off where the robot is, and said so."""
    shot, frames, square = tilted
    kw = {'center_x': 0.0, 'center_y': shot.track_y, 'scale': shot.ruler_scale()}
    results, tracker = track_video(frames, kw, CONFIG, slope_known=False)
    error = steady(results) / shot.mean_speed() - 1.0
    assert abs(error) > 0.01             # what the warning is about
    along = perspective.fit(*perspective.along_track(results, tracker.camera,
                                                     tracker.slope_used))
    assert along.significant and abs(along.change) > 0.05
    assert 'calibrate the plane' in perspective.warning(along, '--px-per-m')


def test_the_marker_spacing_alone_measures_the_scale_where_the_robot_is(tilted):
    """No ruler, no calibration: the spacing's change along the track is the perspective."""
    shot, frames, square = tilted
    kw = {'center_x': 0.0, 'center_y': shot.track_y}
    reference = steady(track_video(square, dict(kw, scale=shot.scale), CONFIG,
                                   slope_known=False)[0])
    measured = measure_plane(frames, kw, CONFIG, shot.spacing, slope_known=False)
    assert measured.plane is not None and measured.along.change > 0.05
    results, _ = track_video(frames, measured.camera_kw(kw), CONFIG, slope_known=False)
    assert steady(results) == pytest.approx(reference, rel=0.01)


def test_a_square_camera_gives_no_perspective_warning(tilted):
    shot, frames, square = tilted
    results, tracker = track_video(square, {'center_x': 0.0, 'center_y': shot.track_y,
                                            'scale': shot.scale}, CONFIG, slope_known=False)
    along = perspective.fit(*perspective.along_track(results, tracker.camera,
                                                     tracker.slope_used))
    assert along is not None and not along.significant and abs(along.change) < 0.002


# -- the command ------------------------------------------------------------------------------
@pytest.fixture(scope='module')
def board_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp('board')
    for k, _, frame in BoardClip(CHESS, dist_coeffs=BARREL, views=10).frames():
        cv2.imwrite(str(folder / f'{k:03d}.png'), frame)
    return folder


def test_calibrate_camera_writes_the_lens_and_the_plane(board_folder, tmp_path, capsys):
    shot = Shot(**dict(PERSPECTIVE, width=640, height=360, scale=600.0))
    still = tmp_path / 'still.png'
    cv2.imwrite(str(still), shot.board_still(CHESS, at=-0.1 + 0.03j))
    code = main(['calibrate-camera', str(board_folder), '--board', 'chessboard:9x6:0.02',
                 '-o', str(tmp_path / 'camera.yaml'), '--plane-image', str(still),
                 '--plane-output', str(tmp_path / 'plane.yaml')])
    out = capsys.readouterr().out
    assert code == 0, out
    assert 'RMS reprojection error' in out and '10 views' in out
    lens = calibration.read_lens(tmp_path / 'camera.yaml')
    assert lens.focal == pytest.approx(600.0, rel=0.005)
    h = calibration.read_plane(tmp_path / 'plane.yaml')
    found = CameraModel(width=640, height=360, plane=tuple(h.ravel()))
    assert found.scale == pytest.approx(shot.calibrated_camera().scale, rel=0.01)


@pytest.mark.parametrize('args, why', [
    (['--board', 'chessboard:9x6'], 'give chessboard:COLSxROWS:SQUARE_M'),
    (['--board', 'charuco:7x5:0.04:0.05'], 'must be smaller than the square'),
    (['--board', 'chessboard:9x6:0.02', '--plane-frame', '-1'], 'frames count from 0'),
    (['--board', 'chessboard:9x6:0.02', '--lens', 'x.yaml', '--plane-image', 'x.png'],
     'give the lens once'),
])
def test_calibrate_camera_refuses_in_one_line(board_folder, args, why, capsys):
    code = main(['calibrate-camera', str(board_folder), *args])
    err = capsys.readouterr().err
    assert code == 2 and why in err and len(err.strip().splitlines()) == 1


def test_calibrate_camera_refuses_a_parallel_set(tmp_path, capsys):
    folder = tmp_path / 'flat'
    folder.mkdir()
    for k, _, frame in BoardClip(CHESS, dist_coeffs=BARREL, views=10, tilt_deg=0.0).frames():
        cv2.imwrite(str(folder / f'{k:03d}.png'), frame)
    code = main(['calibrate-camera', str(folder), '--board', 'chessboard:9x6:0.02',
                 '-o', str(tmp_path / 'camera.yaml')])
    err = capsys.readouterr().err
    assert code == 2 and 'nearly the same angle' in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / 'camera.yaml').exists()


def test_track_with_plane_points(tmp_path, capsys):
    """--plane-points: four picture points with their plane coordinates, as Tracker's users do."""
    shot = Shot(**dict(PERSPECTIVE, dist_coeffs=(), duration=2.2, width=640, height=360,
                       scale=600.0))
    folder = tmp_path / 'run'
    folder.mkdir()
    for k, _, frame in shot.frames():
        cv2.imwrite(str(folder / f'{k:04d}.jpg'), frame, [cv2.IMWRITE_JPEG_QUALITY, 95])
    cam = shot.calibrated_camera(False)
    plane = np.array([-0.3 + 0.1j, 0.3 + 0.1j, 0.3 - 0.05j, -0.3 - 0.05j]) + 1j * shot.track_y
    image = cam.to_pixels(plane)
    points = ';'.join(f'{p.real:.3f},{p.imag:.3f},{q.real:.4f},{q.imag:.4f}'
                      for p, q in zip(image, plane))
    code = main(['track', str(folder), '--fps', '30', '--plane-points', points, '--quiet',
                 '--steady-window', '1.8'])
    out = capsys.readouterr().out
    assert code == 0, out
    speed = float(out.split('steady-state speed (last 1.8 s): ')[1].split()[0]) / 100
    assert speed == pytest.approx(shot.mean_speed(), rel=0.015)
    assert math.isfinite(speed)


def test_the_plane_from_a_frame_of_a_clip(tmp_path, capsys):
    """--lens and --plane-video/--plane-frame: the board in frame 1 of a folder of pictures."""
    shot = Shot(**{**PERSPECTIVE, 'width': 640, 'height': 360, 'scale': 600.0})
    lens = shot.lens()
    calibration.write_lens(tmp_path / 'camera.yaml', calibration.Lens(
        640, 360, lens.K, np.array([*BARREL, 0.0])), 'the generator')
    clip = tmp_path / 'clip'
    clip.mkdir()
    cv2.imwrite(str(clip / '0.png'), next(shot.frames())[2])
    cv2.imwrite(str(clip / '1.png'), shot.board_still(CHESS, at=-0.1 + 0.03j))
    code = main(['calibrate-camera', '--lens', str(tmp_path / 'camera.yaml'), '--board',
                 'chessboard:9x6:0.02', '--plane-video', str(clip), '--plane-frame', '1',
                 '--plane-output', str(tmp_path / 'plane.yaml')])
    out = capsys.readouterr().out
    assert code == 0, out
    assert '54 corners' in out and 'clip frame 1' in out
    h = calibration.read_plane(tmp_path / 'plane.yaml')
    found = CameraModel(width=640, height=360, plane=tuple(h.ravel()))
    assert found.scale == pytest.approx(shot.calibrated_camera().scale, rel=0.005)
    code = main(['calibrate-camera', '--lens', str(tmp_path / 'camera.yaml'), '--board',
                 'chessboard:9x6:0.02', '--plane-video', str(clip), '--plane-frame', '0',
                 '--plane-output', str(tmp_path / 'plane0.yaml')])
    assert code == 2 and 'the board lying in the plane was not found' in capsys.readouterr().err


def test_no_perspective_warning_on_a_square_climb(capsys):
    """
    A 10 deg climb filmed square, slope not given: the spacing does not change, no warning.

    (Taken from the tracker's own positions, the frames before the track's direction was known
    read the spacing 1.5 % short, cos 10 deg: a perspective that was not there.)
    """
    from pathlib import Path
    clip = Path(__file__).resolve().parents[2] / 'samples' / 'footage' / 'climb_10deg_6V.mp4'
    assert main(['track', str(clip), '--px-per-m', '600', '--quiet']) in (0, 1)
    assert 'perspective' not in capsys.readouterr().err
