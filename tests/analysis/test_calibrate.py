"""
`analysis.calibrate`: recovers parameters it knows, resumes exactly, reads both CSV formats.

Synthetic targets come from our own model with a known parameter set, so the right answer is
known. Budgets are small (2 s runs at 3 Hz) to keep the file fast.
"""
import math

import numpy as np
import pytest

from saw_ros.analysis import calibrate as cal
from saw_ros.core.params import Scenario
from saw_ros.interface.config import config_path, load_parameters, load_scenario

# A soft surface, where AR responds to kn and e (near the default kn the AR is flat in kn).
TRUTH = {'surface.normal_stiffness': 5000.0, 'surface.restitution': 0.6}
CONDITIONS = ((0.0, 3.0), (90.0, 3.0), (30.0, 3.0), (-30.0, 3.0), (60.0, 3.0))
DURATION = 2.0


def synthetic_targets(truth):
    """Return the model's own ARs at ``truth``: targets whose answer is known."""
    targets = [cal.Target(f'{s:g} deg {f:g} Hz', s, 'ar', 1.0, frequency=f)
               for s, f in CONDITIONS]
    model = cal.Model(targets, duration=DURATION)
    measured = model.outcomes([truth])[0]
    return [cal.Target(t.name, t.slope_deg, 'ar', float(m), frequency=t.frequency)
            for t, m in zip(targets, measured)]


def test_recovers_known_parameters(tmp_path):
    targets = synthetic_targets(TRUTH)
    # Start 20 % off in both.
    base = Scenario().with_values({'surface.normal_stiffness': 4000.0,
                                   'surface.restitution': 0.72})
    params = cal.make_parameters(['surface.normal_stiffness:2500:10000',
                                  'surface.restitution:0.3:1.0'], base)
    settings = cal.Settings(generations=16, popsize=8, seed=3, sigma=0.2, duration=DURATION)
    result = cal.calibrate(targets, params, tmp_path, settings, base=base, plots=False)
    values = result.values
    for name, true in TRUTH.items():
        assert values[name] == pytest.approx(true, rel=0.05), (name, values)
    assert result.data['loss'] < 1e-4 < result.data['loss_default']
    names = {p['name'] for p in result.data['parameters']}
    assert names == set(TRUTH)
    # Every target's error is reported, before and after.
    assert all(t['error_calibrated_pct'] < t['error_default_pct'] + 1e-9
               for t in result.data['targets'])


def test_resume_ends_where_an_uninterrupted_run_ends(tmp_path):
    targets = synthetic_targets(TRUTH)[:2]
    params = cal.make_parameters(['surface.restitution', 'motor.hz_per_volt'])
    settings = cal.Settings(generations=4, popsize=4, seed=7, duration=1.5)
    whole = cal.calibrate(targets, params, tmp_path / 'whole', settings, plots=False)
    assert cal.calibrate(targets, params, tmp_path / 'cut', settings, stop_after=2,
                         plots=False) is None
    assert cal.load_state(tmp_path / 'cut')['generation'] == 2
    resumed = cal.calibrate([], [], tmp_path / 'cut', settings, resume=True, plots=False)
    assert resumed.values == whole.values
    assert [h['best_loss'] for h in resumed.data['history']] == \
        [h['best_loss'] for h in whole.data['history']]


def test_sensitivity_and_identifiability_see_a_flat_parameter():
    # motor.hz_per_volt does nothing at constant frequency: the AR targets cannot see it.
    targets = synthetic_targets(TRUTH)[:3]
    params = cal.make_parameters(['surface.normal_stiffness:2500:10000', 'motor.hz_per_volt'])
    model = cal.Model(targets, duration=DURATION)
    S, centre, _ = cal.sensitivity(model, params, {**TRUTH, 'motor.hz_per_volt': 0.24})
    assert S.shape == (3, 2)
    assert np.all(abs(S[:, 1]) < 1e-9) and np.any(abs(S[:, 0]) > 0.02)
    ident = cal.identifiability(S, params, 0.0)
    assert ident['not_identified'] == ['motor.hz_per_volt']
    assert ident['relative_std']['motor.hz_per_volt'] is None
    assert any('motor.hz_per_volt' in f['direction'] for f in ident['flat_directions'])


def test_reads_the_paper_reference_format(tmp_path):
    targets = cal.load_targets(config_path('reference_paper.csv'))
    assert [(t.slope_deg, t.voltage, t.quantity) for t in targets] == [
        (20.0, 6.0, 'speed'), (20.0, 4.0, 'speed'), (-20.0, 7.0, 'speed')]
    assert targets[1].measured == pytest.approx(0.0435)
    paper = cal.paper_targets()
    assert [t.claim for t in paper] == ['', '', '', 'A1', 'A2']
    assert [(t.slope_deg, t.frequency, t.measured) for t in paper[3:]] == [
        (0.0, 1.0, 0.72), (90.0, 1.0, 0.61)]


FOOTAGE = """\
video,slope_deg,voltage_V,frequency_hz,v_measured,ar_measured,window_s,v_theory,v_sim,ar_sim,\
relative_error,frames,frames_ok,px_per_m,scale_from,notes
level_6V.mp4,0,6,1.44,0.0755316,0.747496,1.38,0.101,0.0755,0.7475,7.5e-05,60,60,600,px_per_m,a
fixed_hz.mp4,10,,1.2,,0.74,1.6,0.084,0.062,0.739,0.0005,60,60,600.1,marker_spacing,b
"""


def test_reads_the_footage_campaign_format(tmp_path):
    path = tmp_path / 'footage.csv'
    path.write_text(FOOTAGE)
    level, fixed = cal.load_targets(path)
    # With a voltage the speed is the measurement (the AR column used an assumed frequency).
    assert (level.name, level.quantity, level.voltage, level.frequency) == \
        ('level_6V.mp4', 'speed', 6.0, None)
    assert level.measured == pytest.approx(0.0755316)
    assert (fixed.quantity, fixed.frequency, fixed.measured) == ('ar', 1.2, 0.74)
    assert fixed.condition() == {'conditions.slope': pytest.approx(math.radians(10)),
                                 'motor.voltage': 0.0, 'conditions.frequency': 1.2}


@pytest.mark.parametrize('text, message', [
    ('', 'empty'),
    ('slope_deg,voltage_V,speed_cm_s\n', 'no targets'),
    ('slope,voltage_V,speed_cm_s\n0,6,7\n', 'needs columns'),
    ('slope_deg,voltage_V,speed_cm_s\n0,6,fast\n', "'fast' is not a number"),
    ('slope_deg,voltage_V,speed_cm_s\n0,,7\n', 'needs voltage_V or frequency_hz'),
    ('slope_deg,voltage_V,speed_cm_s\n0,6,7,9\n', 'more fields than columns'),
    ('slope_deg,voltage_V,speed_cm_s,advance_ratio\n0,6,,\n', 'no measured speed or AR'),
    ('slope_deg,voltage_V,speed_cm_s\n120,6,7\n', 'slope_deg must be given'),
])
def test_damaged_targets_are_clear_errors(tmp_path, text, message):
    path = tmp_path / 'targets.csv'
    path.write_text(text)
    with pytest.raises(cal.CalibrationError, match=message):
        cal.load_targets(path)


@pytest.mark.parametrize('spec, message', [
    ('surface.stiffness', "unknown parameter 'surface.stiffness'"),
    ('surface.restitution:0.5:1.5', r'outside its allowed range \(0, 1\]'),
    ('surface.normal_stiffness:-5:100', 'outside its allowed range'),
    ('surface.restitution:0.9:0.5', 'low < high'),
    ('surface.restitution:a:b', 'bounds must be numbers'),
    ('conditions.slope', 'set by the condition of each target'),
    ('robot.wave_links:10:20', 'integer'),
    ('surface.tangential_stiffness', 'give its bounds'),
])
def test_bad_parameters_are_clear_errors(spec, message):
    with pytest.raises(cal.CalibrationError, match=message):
        cal.make_parameters([spec])


def test_a_start_below_log_bounds_sits_on_the_lower_bound():
    # flexure.stiffness defaults to 0 (rigid links): a fit of it starts at its lower bound.
    (flexure,) = cal.make_parameters(['flexure.stiffness:100:10000'])
    assert flexure.log and flexure.unit_of(0.0) == 0.0 and flexure.unit_of(1e5) == 1.0
    assert flexure.unit_of(1000.0) == pytest.approx(0.5)


def test_damaged_state_is_a_clear_error(tmp_path):
    (tmp_path / cal.STATE_FILE).write_bytes(b'not a pickle')
    with pytest.raises(cal.CalibrationError, match='damaged'):
        cal.load_state(tmp_path)
    with pytest.raises(cal.CalibrationError, match='nothing to resume'):
        cal.load_state(tmp_path / 'elsewhere')


def test_shipped_calibrated_file_loads_and_differs_only_in_calibrated_names():
    path = config_path('simulator_calibrated.yaml')
    calibrated = load_parameters(path, 'simulator')
    defaults = load_parameters(config_path('simulator.yaml'), 'simulator')
    assert set(calibrated) == set(defaults)
    changed = {k for k in defaults if calibrated[k] != defaults[k]}
    assert changed and changed <= set(cal.DEFAULT_FIT)
    scenario = load_scenario(path)
    assert scenario.flat() == Scenario().with_values({k: calibrated[k] for k in changed}).flat()
    # The shipped fit moves only the motor: the constant-frequency ARs (A1, A2) train nothing.
    assert cal.trained_claims_of(path) == []
