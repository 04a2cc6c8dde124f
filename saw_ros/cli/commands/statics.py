"""
The paper's statics (Section 3, Eqs. 1-5, Figure 4).

The minimal normal forces the surfaces must press with for the robot to climb, and the slope above
which the top surface is needed.

For example:
  saw-ros statics                              # Figure 4's cases A, B, C at 90 deg
  saw-ros statics --slope-deg 30 --fext-mg 0.5 --mu 0.8
"""
import math

from saw_ros.cli.checks import number, spec_number
from saw_ros.cli.errors import UserError
from saw_ros.core.params import RobotParams, Scenario

HELP = 'minimal normal forces and top-surface threshold (paper Eqs. 3-5, Figure 4)'


def add_arguments(p):
    p.add_argument('--slope-deg', type=float, default=90.0, help='slope, degrees (default 90)')
    p.add_argument('--fext-mg', type=float, default=None,
                   help='resisting force in units of m g (with --mu: one custom case)')
    p.add_argument('--mu', type=float, default=None, help='coefficient of friction')
    p.add_argument('--mass', type=float, default=RobotParams.mass,
                   help=f'robot mass, kg (for newtons; default {RobotParams.mass:g})')


def run(args):
    from saw_ros.core.dynamics import GRAVITY
    from saw_ros.core.statics import (FIGURE4_CASES, minimal_normal_forces, StaticCase,
                                      top_surface_needed_above)
    meta = {name: m for name, _, m in Scenario().describe()}
    spec_number(args.slope_deg, '--slope-deg', meta['conditions.slope'], math.pi / 180.0, 'deg',
                'conditions.slope')
    spec_number(args.mass, '--mass', meta['robot.mass'], name='robot.mass')
    if (args.fext_mg is None) != (args.mu is None):
        raise UserError("give both --fext-mg and --mu, or neither (Figure 4's cases)")
    if args.mu is not None:
        # mu = 0 holds nothing: the statics divide by it.
        spec_number(args.mu, '--mu', dict(meta['surface.friction_coefficient'], low_open=True),
                    name='surface.friction_coefficient')
        number(args.fext_mg, '--fext-mg', 'm g')
    cases = FIGURE4_CASES if args.mu is None else (StaticCase('custom', args.fext_mg, args.mu),)
    mg = args.mass * GRAVITY
    print(f'slope {args.slope_deg:g} deg, m g = {mg:.3f} N')
    print(f'{"case":7s} {"F_ext":>8s} {"mu":>5s} {"top needed above":>17s} '
          f'{"bottom":>15s} {"top":>15s} {"total":>15s}')
    for c in cases:
        b, t, tot = (float(v) for v in minimal_normal_forces(math.radians(args.slope_deg),
                                                             c.external_force, c.mu))
        a = top_surface_needed_above(c.external_force, c.mu)
        above = 'never' if a is None else ('every slope' if a == 0 else
                                           f'{math.degrees(a):.2f} deg')
        fmt = lambda v: f'{v:5.3f} mg {v * mg:5.2f} N'  # noqa: E731
        top = fmt(t) if t > 0 else f'{"not needed":>15s}'
        print(f'{c.name:7s} {c.external_force:6.2f}mg {c.mu:5.2f} {above:>17s} {fmt(b):>15s} '
              f'{top:>15s} {fmt(tot):>15s}')
    return 0
