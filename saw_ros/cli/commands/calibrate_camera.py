r"""
Calibrate a camera: its lens from a board waved in front of it, and the robot's plane of motion.

The lens: a clip (or a folder of pictures) of a calibration board held whole and in focus,
moved around the picture and tilted towards and away from the camera, left and right, in at
least 8 views. Written in the ROS camera calibration YAML (-o), which camera_info_manager, ROS
camera drivers and `saw-ros track --camera-calibration` read; the RMS reprojection error and
the frames used are printed and kept in the file as comments. Refused, in one line saying why:
too few views of the whole board, blurred views, views that all hold the board at one angle,
a poor fit.

The plane: a board lying flat in the robot's plane of motion (against the wall it crawls along,
or on the track), in one picture taken with the camera where it films the robot
(--plane-image, or --plane-frame N of a clip: --plane-video). Written as --plane-output for
`saw-ros track --plane`. The plane's axes: x along the board's rows, to the picture's right; y
up; the origin at the board's first inner corner. The lens is the one calibrated here, or
--lens (a calibration made before); without either the picture is taken as undistorted (and
saw-ros track must then be given no lens either).

Boards: chessboard:COLSxROWS:SQUARE_M (inner corners, e.g. chessboard:9x6:0.025) or
charuco:COLSxROWS:SQUARE_M:MARKER_M[:DICT] (squares, e.g. charuco:7x5:0.04:0.03:DICT_4X4_50;
seen in part too).

Example: saw-ros calibrate-camera board.mp4 --board chessboard:9x6:0.025 -o camera.yaml
         saw-ros calibrate-camera --lens camera.yaml --board chessboard:9x6:0.025 \\
             --plane-image still.png --plane-output plane.yaml
         saw-ros track run.mp4 --camera-calibration camera.yaml --plane plane.yaml
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import cv2

from saw_ros.cli.checks import input_file, number, output_file, YAML_SUFFIXES
from saw_ros.cli.errors import UserError
from saw_ros.vision import calibration
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.video import VideoError

NAME = 'calibrate-camera'
HELP = 'calibrate a camera: the lens (ROS camera calibration YAML) and the plane of motion'


def add_arguments(p):
    p.add_argument('video', nargs='?', default=None, metavar='VIDEO|FOLDER',
                   help='a clip (or a folder of pictures) of the board waved in front of the '
                        'camera: the lens')
    p.add_argument('--board', required=True, metavar='KIND:COLSxROWS:SQUARE_M[:MARKER_M[:DICT]]',
                   help='the board: chessboard:COLSxROWS:SQUARE_M (inner corners) or '
                        'charuco:COLSxROWS:SQUARE_M:MARKER_M[:DICT] (squares)')
    p.add_argument('-o', '--output', type=Path, default=Path('camera.yaml'),
                   help='where the lens goes (ROS camera calibration YAML; default camera.yaml)')
    p.add_argument('--camera-name', default='camera', help='camera_name in the file')
    p.add_argument('--fps', type=float, default=0.0,
                   help='frame rate of a folder of pictures (its frames are numbered by it)')
    p.add_argument('--max-views', type=int, default=40,
                   help='views the fit uses at most, evenly spread over the clip (default 40)')
    g = p.add_argument_group('the plane of motion')
    g.add_argument('--lens', type=Path, default=None, metavar='CAMERA.yaml',
                   help='a lens calibrated before (instead of VIDEO)')
    g.add_argument('--plane-image', type=Path, default=None, metavar='STILL',
                   help="a picture with the board lying in the robot's plane")
    g.add_argument('--plane-video', type=Path, default=None, metavar='VIDEO',
                   help='... or a clip with it in frame --plane-frame (default: VIDEO)')
    g.add_argument('--plane-frame', type=int, default=None, metavar='N',
                   help='the frame (from 0) of the clip in which the board lies in the plane')
    g.add_argument('--plane-board', default=None, metavar='BOARD',
                   help='the board lying in the plane, when not --board')
    g.add_argument('--plane-output', type=Path, default=Path('plane.yaml'),
                   help='where the plane goes (default plane.yaml)')


def _frames(path, fps: float):
    """Return a frame source for a clip or a folder of pictures."""
    from saw_ros.cli.commands.track import _source
    p = Path(path)
    if p.is_dir():
        return _source(p, fps if fps > 0 else 1.0)
    return _source(p, fps)


def _plane_picture(args) -> tuple:
    """Return (picture, where it came from) of the board lying in the plane."""
    if args.plane_image is not None:
        input_file(args.plane_image, '--plane-image', 'picture')
        picture = cv2.imread(str(args.plane_image), cv2.IMREAD_COLOR)
        if picture is None:
            raise UserError(f'--plane-image {args.plane_image}: not a picture OpenCV can read '
                            '(.png, .jpg, ...)')
        return picture, str(args.plane_image)
    clip = args.plane_video or args.video
    if clip is None:
        raise UserError('--plane-frame needs the clip: VIDEO or --plane-video')
    for k, _, frame in _frames(clip, args.fps).frames():
        if k == args.plane_frame:
            return frame, f'{clip} frame {k}'
    raise UserError(f'--plane-frame {args.plane_frame}: {clip} has fewer frames')


def run(args):
    try:
        board = calibration.Board.parse(args.board)
        plane_board = calibration.Board.parse(args.plane_board) if args.plane_board else board
    except calibration.CalibrationError as exc:
        raise UserError(str(exc)) from None
    number(args.fps, '--fps', 'Hz (0: the rate the file says)', 0.0, None)
    number(args.max_views, '--max-views', '', calibration.MIN_VIEWS, 1000)
    plane_wanted = args.plane_image is not None or args.plane_frame is not None
    if args.plane_image is not None and args.plane_frame is not None:
        raise UserError("give the plane's picture once: --plane-image or --plane-frame")
    if args.plane_video is not None and args.plane_frame is None:
        raise UserError('--plane-video needs --plane-frame (the frame with the board in the '
                        'plane)')
    if args.plane_frame is not None and args.plane_frame < 0:
        raise UserError(f'--plane-frame {args.plane_frame}: frames count from 0')
    if args.video is None and not plane_wanted:
        raise UserError('give VIDEO (a clip of the board waved in front of the camera), or the '
                        "plane's picture (--plane-image, --plane-frame)")
    if args.video is not None and args.lens is not None:
        raise UserError('give the lens once: VIDEO (calibrate it) or --lens (read it)')
    if args.lens is not None and not plane_wanted:
        raise UserError('--lens is for the plane: give --plane-image or --plane-frame')
    if args.plane_image is not None:            # (before the lens, which takes a while)
        input_file(args.plane_image, '--plane-image', 'picture')
    if args.video is not None:
        output_file(args.output, '--output', YAML_SUFFIXES)
    if plane_wanted:
        output_file(args.plane_output, '--plane-output', YAML_SUFFIXES)
    try:
        lens = None
        if args.video is not None:
            lens = _calibrate(args, board)
        elif args.lens is not None:
            lens = calibration.read_lens(args.lens)
        if plane_wanted:
            _plane(args, plane_board, lens)
    except calibration.CalibrationError as exc:
        raise UserError(str(exc)) from None
    except VideoError as exc:
        raise UserError(str(exc)) from None
    return 0


def _calibrate(args, board) -> calibration.Lens:
    from saw_ros.cli.commands.track import Progress
    source = _frames(args.video, args.fps)
    size = tuple(source.size)
    found = calibration.detect_views(Progress(source).frames(), board, size)
    lens = calibration.calibrate(found, args.camera_name, args.max_views)
    calibration.write_lens(args.output, lens, f'{args.video} --board {args.board}')
    k, d = lens.K, lens.dist
    print(f'{args.video}: {found.summary()}')
    print(f'lens: fx {k[0, 0]:.2f} fy {k[1, 1]:.2f} cx {k[0, 2]:.2f} cy {k[1, 2]:.2f} px; '
          f'distortion k1 {d[0]:.5f} k2 {d[1]:.5f} p1 {d[2]:.5f} p2 {d[3]:.5f} k3 {d[4]:.5f}')
    print(f'RMS reprojection error {lens.rms_px:.3f} px over {lens.views} views (frames '
          f'{" ".join(map(str, lens.frames))})')
    print(f'camera calibration: {args.output}')
    return lens


def _plane(args, board, lens: Optional[calibration.Lens]) -> None:
    picture, where = _plane_picture(args)
    width, height = picture.shape[1], picture.shape[0]
    if lens is not None and (width, height) != (lens.width, lens.height):
        raise UserError(f'{where} is {width}x{height}, the lens was calibrated for '
                        f'{lens.width}x{lens.height}: the same camera and mode')
    view, why = calibration.Detector(board).find(picture)
    if view is None:
        raise UserError(f'{where}: the board lying in the plane was not found ({why}): whole, '
                        'in focus, the size given by --plane-board (or --board)')
    camera = CameraModel(width=width, height=height,
                         **(lens.camera_kw() if lens is not None else {}))
    h, rms = calibration.plane_from_view(view, camera.undistort)
    lens_file = '' if lens is None else str(args.lens or args.output)
    calibration.write_plane(args.plane_output, h, rms, where, lens_file)
    if lens is None:
        print('plane: no lens given (VIDEO or --lens): the picture is taken as undistorted')
    scale = CameraModel(width=width, height=height, plane=tuple(h.ravel())).scale
    print(f'plane: {len(view.image_points)} corners of the board in {where}, RMS '
          f"{1000 * rms:.3f} mm off the homography; {scale:.2f} px/m at the picture's centre")
    print(f'plane of motion: {args.plane_output}')
