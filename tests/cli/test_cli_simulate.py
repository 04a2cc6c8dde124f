import csv
import math
import subprocess
import sys

import pytest

from saw_ros.core import Scenario


def saw_ros(*args, timeout=120):
    return subprocess.run([sys.executable, '-m', 'saw_ros.cli.main', *args], capture_output=True,
                          text=True, timeout=timeout)


def test_simulate_prints_ar_and_writes_the_time_series(tmp_path):
    out = tmp_path / 'run.csv'
    r = saw_ros('simulate', '--slope-deg', '20', '--duration', '2.5', '--csv', str(out),
                '--quiet')
    assert r.returncode == 0, r.stderr
    assert 'AR' in r.stdout and 'v_theory' in r.stdout and 'CCI < 0.2 %' in r.stdout
    ar = float(next(line for line in r.stdout.splitlines() if line.startswith('AR')).split()[1])
    assert 0.5 < ar < 0.9
    with open(out) as f:
        rows = list(csv.reader(f))
    assert rows[0][:7] == ['t_s', 'x_m', 'y_m', 'theta_rad', 'vx_m_s', 'vy_m_s', 'w_rad_s']
    assert 'fn_bottom00_N' in rows[0] and 'ft_top18_N' in rows[0]
    assert len(rows) == 2502 and float(rows[-1][0]) == 2.5
    assert rows[0][-1] == 'helix_rad_s' and float(rows[-1][-1]) == pytest.approx(2 * math.pi)


def test_simulate_with_a_motor_reports_the_helix_frequency_reached(tmp_path):
    out = tmp_path / 'motor.csv'
    r = saw_ros('simulate', '--slope-deg', '20', '--voltage', '4', '--duration', '2.5', '--csv',
                str(out), '--quiet')
    assert r.returncode == 0, r.stderr
    assert 'motor 4 V, f 0.8' in r.stdout and '(no load 0.902)' in r.stdout, r.stdout
    with open(out) as f:
        rows = list(csv.DictReader(f))
    motor = Scenario().with_values({'motor.voltage': 4.0}).motor
    last = rows[-1]
    omega, current = float(last['helix_rad_s']), float(last['motor_current_A'])
    assert omega < 2 * math.pi * 0.902
    assert current == pytest.approx((4.0 - motor.torque_constant * omega) / motor.resistance,
                                    rel=1e-6)
    assert float(last['motor_torque_Nm']) == pytest.approx(motor.torque_constant * current,
                                                           rel=1e-6)


def test_bad_arguments_give_a_clear_message_and_nonzero_exit_without_traceback():
    for args in (['--mu', '-1'], ['--gap-mm', '10'], ['--set', 'surface.foo=1'],
                 ['--duration', '-3']):
        r = saw_ros('simulate', *args, '--quiet')
        assert r.returncode == 2, args
        assert 'error:' in r.stderr and 'Traceback' not in r.stderr
