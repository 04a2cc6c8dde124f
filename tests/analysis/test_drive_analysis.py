"""The paper's next step, offline (issue 22): the shaped drive and the speed held by camera."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from saw_ros.analysis import shape_drive, speed_hold
from saw_ros.core.params import Scenario

BASE = Scenario().with_values({'motor.voltage': 6.0})


def test_the_motor_follows_slow_harmonics_and_filters_fast_ones():
    """A first-order lag: the response falls with the harmonic, and the ninth is mostly gone."""
    response = shape_drive.motor_bandwidth(BASE, [1, 3, 9, 18], measure=3.0)
    values = [response[k] for k in (1, 3, 9, 18)]
    assert all(a > b for a, b in zip(values, values[1:])), response
    # J R / k^2 of the defaults: the closed-form lag |1 / (1 + i w tau)| at the ninth harmonic
    # (the contacts' load adds its own damping, so the simulation may pass less, never much more).
    m = BASE.motor
    tau = m.inertia * m.resistance / m.torque_constant ** 2
    helix_hz = 1.33
    lag = 1.0 / math.hypot(1.0, 2 * math.pi * 9 * helix_hz * tau)
    assert response[9] < 1.5 * lag and response[9] < 0.3


def test_a_constant_profile_is_the_constant_drive_and_the_curve_brackets_it():
    dims = 2 * len(shape_drive.HARMONICS)
    one = shape_drive.evaluate(BASE, [6.0], np.zeros((1, dims)), measure=2.0)
    curve = shape_drive.ConstantCurve(BASE, shape_drive.HARMONICS, points=3)
    assert curve.speed[0] < one.speed[0] < curve.speed[-1]
    # The cost of the constant drive itself against the curve through it is 1 (no penalty).
    assert shape_drive.cost(one, curve, float(one.speed[0]))[0] == pytest.approx(1.0, rel=0.02)
    # Slower is calmer near 6 V (why the search compares at the same speed).
    assert curve.vibration[0] < curve.vibration[-1]


def test_shape_drive_quick_writes_its_report_and_never_claims_an_unmet_constraint(tmp_path):
    out = tmp_path / 'sd'
    run = subprocess.run([sys.executable, '-m', 'saw_ros.cli.main', 'shape-drive', '--quick',
                          '--workers', '1', '--quiet', '--out', str(out)],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    summary = json.loads((out / 'result.json').read_text())
    for name in ('report.md', 'spectrum.png', 'profile.png', 'slopes.png', 'convergence.png'):
        assert (out / name).stat().st_size > 0
    r = summary['result']
    if r['feasible']:
        assert abs(r['shaped']['speed'] / r['constant']['speed'] - 1) <= 0.02
        assert r['shaped']['power'] <= r['matched']['power']
        assert 'less' in run.stdout
    else:
        assert 'no profile met the constraints' in run.stdout
    text = (out / 'report.md').read_text()
    assert 'nan' not in text.lower().replace('nanosec', '')
    assert f"{r['shaped']['vibration']:.3f}" in text


@pytest.fixture(scope='module')
def level_voltage():
    return speed_hold.voltage_for(Scenario(), speed_hold.TARGET)


def test_the_voltage_found_gives_the_target_speed(level_voltage):
    closed = speed_hold.hold('open_loop', slopes_deg=(0.0,), segment=5.0, settle=2.0,
                             voltage=level_voltage)
    assert closed.error_pct < 1.0


def test_the_loop_on_ground_truth_beats_the_open_loop_when_the_slope_steps(level_voltage):
    kw = {'slopes_deg': (0.0, 20.0), 'segment': 4.0, 'settle': 2.0, 'voltage': level_voltage}
    open_loop = speed_hold.hold('open_loop', **kw)
    closed = speed_hold.hold('ground_truth', **kw)
    assert open_loop.per_slope[20.0] > 3.0        # a climb slows the fixed voltage
    assert closed.per_slope[20.0] < 0.5 * open_loop.per_slope[20.0]
    assert closed.voltage.max() > level_voltage    # it pushed harder up the slope
    assert closed.voltage.max() <= speed_hold.VOLTAGE_LIMITS[1]
