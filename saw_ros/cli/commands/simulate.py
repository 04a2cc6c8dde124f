"""
Run one scenario of the physics core and print AR, v, v_theory and CCI convergence.

Human-facing flags take degrees, mm and cm; everything inside is SI. Any model parameter can be
set by its dotted name in SI units with --set (see `saw-ros simulate --list`).

For example:
  saw-ros simulate                                  # the paper's default case, level
  saw-ros simulate --slope-deg 90 --duration 8      # vertical climb
  saw-ros simulate --voltage 6 --slope-deg 20 --csv run.csv
  saw-ros simulate --set surface.tangential_stiffness=300 --set surface.restitution=0.8
"""
import csv
import math
from pathlib import Path
import sys

import numpy as np

from saw_ros.analysis.shown import finite, shown
from saw_ros.cli.checks import output_file, params_file, spec_number
from saw_ros.cli.errors import UserError
from saw_ros.core import DivergenceError, Scenario, Simulator
from saw_ros.core.metrics import analyse
from saw_ros.interface.config import config_path, load_parameters, load_scenario

HELP = 'run one simulation and print AR, speed and CCI convergence (optionally a CSV)'


def add_scenario_arguments(p):
    """Flag shared by the commands that set up a scenario."""
    g = p.add_argument_group('scenario (human units)')
    g.add_argument('--params-file', type=Path, help='ROS parameters YAML (msg_config/ format)')
    g.add_argument('--slope-deg', type=float, help='surface slope, degrees (+ climbs)')
    g.add_argument('--gap-mm', type=float, help='gap between the surfaces, mm')
    g.add_argument('--kn', type=float, help='normal stiffness, N/m^1.5')
    g.add_argument('--kt', type=float, help='tangential stiffness, N/m')
    g.add_argument('--mu', type=float, help='coefficient of friction')
    g.add_argument('--external-force', type=float, help='resisting force along -x, N')
    g.add_argument('--frequency', type=float, help='helix frequency, Hz')
    g.add_argument('--voltage', type=float, help='motor voltage, V (sets the frequency)')
    g.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                   help='any model parameter by dotted name, SI units (repeatable)')


# flag -> (the parameter it sets, SI per flag unit, the flag's unit; None: the parameter's)
FLAGS = {'slope_deg': ('conditions.slope', math.pi / 180.0, 'deg'),
         'gap_mm': ('conditions.gap', 1e-3, 'mm'),
         'kn': ('surface.normal_stiffness', 1.0, None),
         'kt': ('surface.tangential_stiffness', 1.0, None),
         'mu': ('surface.friction_coefficient', 1.0, None),
         'external_force': ('conditions.external_force', 1.0, None),
         'frequency': ('conditions.frequency', 1.0, None),
         'voltage': ('motor.voltage', 1.0, None)}


def scenario_from_args(args) -> Scenario:
    """
    Return the Scenario of the flags; a UserError names the first bad one.

    Each human-unit flag is checked in its own unit against the range of the parameter it sets
    (spec tables), before the whole set is validated together (the gap against the robot, ...).
    """
    if args.params_file is not None:
        params_file(args.params_file)
        # Names the simulator does not know (a typo, another node's file) would be ignored
        # without a word: its own file, msg_config/simulator.yaml, lists every name it takes.
        known = set(Scenario().flat()) | set(load_parameters(config_path('simulator.yaml'),
                                                             'simulator'))
        unknown = sorted(set(load_parameters(args.params_file, 'simulator')) - known)
        if unknown:
            more = f', ... ({len(unknown)} in all)' if len(unknown) > 5 else ''
            raise UserError(f'--params-file {args.params_file}: not parameters of the simulator: '
                            f'{", ".join(unknown[:5])}{more} (saw-ros simulate --list names those '
                            f'of the model)')
        scenario = load_scenario(args.params_file)
    else:
        scenario = Scenario()
    meta = {name: m for name, _, m in scenario.describe()}
    values = {}
    for attr, (name, scale, unit) in FLAGS.items():
        value = getattr(args, attr)
        if value is not None:
            flag = '--' + attr.replace('_', '-')
            spec_number(value, flag, meta[name], scale, unit, name)
            values[name] = value * scale
    for item in args.set:
        name, sep, text = item.partition('=')
        name = name.strip()
        if not sep:
            raise UserError(f'--set {item!r}: write NAME=VALUE (saw-ros simulate --list)')
        if name not in meta:
            raise UserError(f'--set {name}: unknown parameter (saw-ros simulate --list names '
                            f'them all)')
        try:
            values[name] = int(text) if text.strip().lstrip('-').isdigit() and \
                name == 'robot.wave_links' else float(text)
        except ValueError:
            raise UserError(f'--set {name}={text}: {text!r} is not a number') from None
        spec_number(values[name], f'--set {name}', meta[name])
    return scenario.with_values(values)


def add_arguments(p):
    add_scenario_arguments(p)
    p.add_argument('--duration', type=float, default=None,
                   help='simulated seconds (default: integration.duration, 5 s)')
    p.add_argument('--csv', type=Path, help='write the time series (pose, velocities, per-tip '
                   'forces, helix speed; with a motor its torque and current) to this CSV file')
    p.add_argument('--plot', type=Path, metavar='PATH.png',
                   help='write position and speed over time to this PNG')
    p.add_argument('--list', action='store_true', help='list every parameter with unit and range')
    p.add_argument('--quiet', action='store_true', help='no progress bar')


def _fmt(value, unit='s'):
    return 'not reached' if value is None else f'{value:.3f} {unit}'


def run(args):
    if args.list:
        for name, value, meta in Scenario().describe():
            print(f'{name:32s} {value!s:>10} {meta["unit"]:>14}  {meta["description"]}')
        return 0
    scenario = scenario_from_args(args)
    duration = args.duration if args.duration is not None else scenario.integration.duration
    if not math.isfinite(duration) or duration <= 0:
        raise UserError(f'--duration {duration:g}: must be a finite time > 0 s')
    if args.csv is not None:
        output_file(args.csv, '--csv', ('.csv',))
    if args.plot is not None:
        output_file(args.plot, '--plot', ('.png',))
    sim = Simulator(scenario)
    steps = int(round(duration / sim.dt))
    from tqdm import tqdm
    with tqdm(total=steps, unit='step', desc='simulate', disable=args.quiet or steps < 2000,
              file=sys.stderr, leave=False) as bar:
        try:
            tr = sim.run(duration, progress=bar.update, contacts=args.csv is not None)
        except DivergenceError as exc:
            print(f'saw-ros simulate: {exc}', file=sys.stderr)
            return 3
    q = tr.q[:, 0]
    # With a motor the helix frequency is an outcome: AR against the one it reached.
    motor = scenario.motor.voltage > 0.0
    m = analyse(tr.t, q, scenario.robot, scenario.frequency,
                omega=tr.omega[:, 0] if motor else None)
    c = scenario.conditions
    helix = (f'motor {scenario.motor.voltage:g} V, f {m.frequency:.3f} Hz (no load '
             f'{scenario.frequency:.3f})' if motor else f'f {scenario.frequency:.3f} Hz')
    print(f'scenario: slope {math.degrees(c.slope):.1f} deg, gap {c.gap * 1000:.1f} mm, '
          f'{helix}, kn {scenario.surface.normal_stiffness:g} N/m^'
          f'{scenario.surface.hertz_exponent:g}, '
          f'kt {scenario.surface.tangential_stiffness:g} N/m, '
          f'mu {scenario.surface.friction_coefficient:g}, F_ext {c.external_force:g} N, '
          f'{duration:g} s')
    still = m.frequency <= 0.0
    why_ar = ('not defined: the helix does not turn (0 Hz); give --frequency or --voltage above '
              '0' if still else 'not computed')
    print(f'v_theory            {shown(m.v_theory, "8.3f", " cm/s", scale=100)}')
    if m.steady_from is None and not still:
        # The mean is then over whole cycles from the middle of the run: say it is not steady.
        label = 'v (not steady)'
        note = (f'  steady state not reached within {duration:g} s: run longer (--duration '
                f'{2 * duration:g})')
    else:
        label, note = 'v (mean)' if still else 'v (steady mean)', ''
    print(f'{label:19s} {shown(m.v_mean, "8.3f", " cm/s", "not computed", 100)}{note}')
    print(f'AR                  {shown(m.advance_ratio, "8.4f", why=why_ar)}'
          f'{"  (not steady)" if note and finite(m.advance_ratio) else ""}')
    print(f'steady state from   {_fmt(m.steady_from)}  (CCI of vx < 2 %)')
    print(f'CCI < 2 %   after   {_fmt(m.cci_2pct_after)}  (all velocities)')
    print(f'CCI < 0.2 % after   {_fmt(m.cci_02pct_after)}')
    if args.csv:
        write_csv(args.csv, tr)
        print(f'time series written to {args.csv}')
    if args.plot:
        plot(args.plot, tr, m, scenario, duration)
        print(f'plot written to {args.plot}')
    return 0


def plot(path, tr, m, scenario, duration):
    """--plot: position and speed of the run, the steady mean and v_theory, as the demo's."""
    from saw_ros.cli.plot import write_time_plot
    q = tr.q[:, 0]
    levels = [(f'v_theory {shown(m.v_theory, ".2f", " cm/s", scale=100)}', m.v_theory)]
    if finite(m.v_mean) and m.steady_from is not None:
        levels.insert(0, (f'steady mean {100 * m.v_mean:.2f} cm/s', m.v_mean))
    c = scenario.conditions
    title = (f'simulation: slope {math.degrees(c.slope):.0f} deg, {m.frequency:.2f} Hz; AR '
             f'{shown(m.advance_ratio, ".3f", why="not defined")}'
             + ('' if m.steady_from is not None else f' (not steady within {duration:g} s)'))
    window = (m.steady_from, float(tr.t[-1])) if m.steady_from is not None else None
    write_time_plot(path, title, [('simulation', tr.t, q[:, 0])],
                    [('simulation vx', tr.t, q[:, 3])], [lv for lv in levels
                                                         if finite(lv[1])], window,
                    'simulated time (s)')


def write_csv(path: Path, tr) -> None:
    q = tr.q[:, 0]
    n = tr.normal.shape[-1] // 2
    tips = [f'{side}{i:02d}' for side in ('bottom', 'top') for i in range(n)]
    header = ['t_s', 'x_m', 'y_m', 'theta_rad', 'vx_m_s', 'vy_m_s', 'w_rad_s']
    header += [f'fn_{tip}_N' for tip in tips] + [f'ft_{tip}_N' for tip in tips]
    columns = [tr.t, q, tr.normal[:, 0], tr.tangential[:, 0]]
    # The helix (docs/motor.md): its speed, and with a motor the motor's torque and current.
    header.append('helix_rad_s')
    columns.append(tr.omega[:, 0])
    if tr.torque is not None:
        header += ['motor_torque_Nm', 'motor_current_A']
        columns += [tr.torque[:, 0], tr.current[:, 0]]
    data = np.column_stack(columns)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, 'w', newline='') as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(np.round(data, 9).tolist())
