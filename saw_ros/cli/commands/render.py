"""Simulate a run and render it, as the camera node would, to an .mp4 you can watch or track.

Example: saw-ros render run.mp4 --duration 6 --slope-deg 10 --noise 10 --exposure 0.0167
then:    saw-ros track run.mp4 --px-per-m 1200 --slope-deg 10
"""
from __future__ import annotations

import math

from saw_ros.core import Scenario
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.frames import RenderOptions, Renderer
from saw_ros.vision.synthetic import simulate_run
from saw_ros.vision.video import VideoError, VideoWriter
from saw_ros.cli.errors import UserError

HELP = 'simulate a run and render it to an .mp4 (the virtual camera, offline)'


def add_arguments(p):
    p.add_argument('output', help='.mp4 file to write')
    p.add_argument('--duration', type=float, default=6.0, help='simulated time, s')
    p.add_argument('--slope-deg', type=float, default=0.0, help='slope of the surfaces, deg')
    p.add_argument('--gap', type=float, default=0.045, help='gap between the surfaces, m')
    p.add_argument('--frequency', type=float, default=1.0, help='helix frequency, Hz')
    p.add_argument('--fps', type=float, default=60.0, help='frames per second')
    p.add_argument('--px-per-m', type=float, default=1200.0, help='scale, px per metre')
    p.add_argument('--width', type=int, default=1280)
    p.add_argument('--height', type=int, default=720)
    p.add_argument('--noise', type=float, default=0.0, help='sensor noise sigma, grey levels')
    p.add_argument('--exposure', type=float, default=0.0, help='exposure for motion blur, s')
    p.add_argument('--brightness', type=float, default=1.0, help='brightness factor')


def run(args):
    scenario = Scenario().with_values({'conditions.slope': math.radians(args.slope_deg),
                                       'conditions.gap': args.gap,
                                       'conditions.frequency': args.frequency})
    try:
        camera = CameraModel(width=args.width, height=args.height, scale=args.px_per_m,
                             slope=math.radians(args.slope_deg), center_y=args.gap / 2)
        options = RenderOptions(noise=args.noise, exposure=args.exposure,
                                brightness=args.brightness)
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    run_ = simulate_run(scenario, args.duration + 0.1)
    renderer = Renderer(scenario.robot, scenario.conditions.gap, camera, options)
    try:
        with VideoWriter(args.output, args.fps, (camera.width, camera.height)) as writer:
            n = int(args.duration * args.fps)
            for k in range(n):
                t = k / args.fps
                writer.write(renderer.render(run_.pose_at(t), (), run_.pose_at, t))
    except VideoError as exc:
        raise UserError(str(exc)) from exc
    print(f'{args.output}: {n} frames, {camera.width}x{camera.height} at {args.fps:g} fps, '
          f'{camera.scale:g} px/m, slope {args.slope_deg:g} deg')
    return 0
