"""
Simulate a run and render it, as the camera node would, to an .mp4 you can watch or track.

Example: saw-ros render run.mp4 --duration 6 --slope-deg 10 --noise 10 --exposure 0.0167
then:    saw-ros track run.mp4 --px-per-m 1200 --slope-deg 10
A compliant robot (docs/compliant_robot.md), its links drawn deflected on their flexures:
         saw-ros render compliant.mp4 --flexure-stiffness 863 --flexure-damping 2.6
"""
from __future__ import annotations

import math
from typing import Optional

from saw_ros.cli.checks import number, output_file, spec_number, VIDEO_SUFFIXES
from saw_ros.cli.errors import UserError
from saw_ros.core import Scenario
from saw_ros.core.params import ConditionParams, FlexureParams, spec_entries
from saw_ros.vision.camera import CameraModel, FPS
from saw_ros.vision.frames import Renderer, RenderOptions
from saw_ros.vision.synthetic import simulate_run
from saw_ros.vision.video import VideoError, VideoWriter

HELP = 'simulate a run and render it to an .mp4 (the virtual camera, offline)'


def spec_option(p, cls, name: str, flag: Optional[str] = None) -> None:
    """
    Return a --flag for dataclass field ``cls.name`` with its default.

    Unit and description from the field's spec() (the camera node's parameter of the same name
    reads the same one).
    """
    (_, default, meta), = spec_entries(cls, (name,))
    unit = f", {meta['unit']}" if meta['unit'] else ''
    flag = flag or '--' + name.replace('_', '-')
    p.add_argument(flag, dest=name, type=type(default), default=default,
                   metavar=flag.lstrip('-').replace('-', '_').upper(),
                   help=f"{meta['description']}{unit} (default {default:g})")


def add_arguments(p):
    p.add_argument('output', help='.mp4 file to write')
    p.add_argument('--duration', type=float, default=6.0, help='simulated time, s')
    p.add_argument('--slope-deg', type=float, default=0.0, help='slope of the surfaces, deg')
    spec_option(p, ConditionParams, 'gap')
    spec_option(p, ConditionParams, 'frequency')
    spec_option(p, FlexureParams, 'stiffness', '--flexure-stiffness')
    spec_option(p, FlexureParams, 'damping', '--flexure-damping')
    p.add_argument('--fps', type=float, default=FPS, help=f'frames per second ({FPS:g})')
    spec_option(p, CameraModel, 'scale', '--px-per-m')
    spec_option(p, CameraModel, 'width')
    spec_option(p, CameraModel, 'height')
    for name in ('noise', 'exposure', 'brightness'):
        spec_option(p, RenderOptions, name)


SPEC_FLAGS = ((ConditionParams, 'gap', '--gap'), (ConditionParams, 'frequency', '--frequency'),
              (FlexureParams, 'stiffness', '--flexure-stiffness'),
              (FlexureParams, 'damping', '--flexure-damping'),
              (CameraModel, 'scale', '--px-per-m'), (CameraModel, 'width', '--width'),
              (CameraModel, 'height', '--height'), (RenderOptions, 'noise', '--noise'),
              (RenderOptions, 'exposure', '--exposure'),
              (RenderOptions, 'brightness', '--brightness'))


def check_arguments(args) -> None:
    """Every flag against its spec() range, the output's kind: before anything is simulated."""
    output_file(args.output, 'OUTPUT', VIDEO_SUFFIXES)
    number(args.duration, '--duration', 's', 0.0, None, low_open=True)
    number(args.fps, '--fps', 'Hz', 0.0, None, low_open=True)
    (_, _, slope), = spec_entries(ConditionParams, ('slope',))
    spec_number(args.slope_deg, '--slope-deg', slope, math.pi / 180.0, 'deg', 'conditions.slope')
    for cls, name, flag in SPEC_FLAGS:
        (_, _, meta), = spec_entries(cls, (name,))
        spec_number(getattr(args, name), flag, meta)


def run(args):
    check_arguments(args)
    scenario = Scenario().with_values({'conditions.slope': math.radians(args.slope_deg),
                                       'conditions.gap': args.gap,
                                       'conditions.frequency': args.frequency,
                                       'flexure.stiffness': args.stiffness,
                                       'flexure.damping': args.damping})
    try:
        camera = CameraModel(width=args.width, height=args.height, scale=args.scale,
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
