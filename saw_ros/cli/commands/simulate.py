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

from saw_ros.core import DivergenceError, Scenario, Simulator
from saw_ros.core.metrics import analyse
from saw_ros.core.params import ParameterError
from saw_ros.interface.config import load_scenario

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


def scenario_from_args(args) -> Scenario:
    scenario = load_scenario(args.params_file) if args.params_file else Scenario()
    values = {}
    simple = {'slope_deg': ('conditions.slope', math.radians),
              'gap_mm': ('conditions.gap', lambda v: v / 1000.0),
              'kn': ('surface.normal_stiffness', float),
              'kt': ('surface.tangential_stiffness', float),
              'mu': ('surface.friction_coefficient', float),
              'external_force': ('conditions.external_force', float),
              'frequency': ('conditions.frequency', float), 'voltage': ('motor.voltage', float)}
    for attr, (name, convert) in simple.items():
        value = getattr(args, attr)
        if value is not None:
            values[name] = convert(value)
    for item in args.set:
        name, sep, text = item.partition('=')
        if not sep:
            raise ParameterError(f'--set expects NAME=VALUE, got {item!r}')
        try:
            values[name.strip()] = int(text) if text.strip().lstrip('-').isdigit() and \
                name.strip() == 'robot.wave_links' else float(text)
        except ValueError:
            raise ParameterError(f'--set {name}: {text!r} is not a number') from None
    return scenario.with_values(values)


def add_arguments(p):
    add_scenario_arguments(p)
    p.add_argument('--duration', type=float, default=None,
                   help='simulated seconds (default: integration.duration, 5 s)')
    p.add_argument('--csv', type=Path, help='write the time series (pose, velocities, per-tip '
                   'forces, helix speed; with a motor its torque and current) to this CSV file')
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
        raise ParameterError(f'--duration {duration} must be > 0 s')
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
    print(f'v_theory            {m.v_theory * 100:8.3f} cm/s')
    print(f'v (steady mean)     {m.v_mean * 100:8.3f} cm/s')
    print(f'AR                  {m.advance_ratio:8.4f}')
    print(f'steady state from   {_fmt(m.steady_from)}  (CCI of vx < 2 %)')
    print(f'CCI < 2 %   after   {_fmt(m.cci_2pct_after)}  (all velocities)')
    print(f'CCI < 0.2 % after   {_fmt(m.cci_02pct_after)}')
    if args.csv:
        write_csv(args.csv, tr)
        print(f'time series written to {args.csv}')
    return 0


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
