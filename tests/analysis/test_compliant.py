"""The open-loop flexure study (issue 31): its replay holds the rigid run, and it measures."""
import numpy as np
import pytest

from saw_ros.analysis import compliant
from saw_ros.core.params import Scenario

BASE = Scenario().with_values({'motor.voltage': 6.0})


@pytest.fixture(scope='module')
def run():
    return compliant.rigid_run(BASE, settle=1.0, measure=0.5)


def test_rigid_links_replayed_give_the_runs_own_vibration(run):
    """The replay's contact law (hysteresis included) rebuilds the body's normal force."""
    assert abs(compliant.rigid_check(run)) < 5e-3
    np.testing.assert_allclose(compliant.rigid_force(run) - run.normal_force,
                               np.mean(compliant.rigid_force(run) - run.normal_force),
                               atol=0.05 * np.std(run.normal_force))


def test_softer_flexures_calm_the_forcing_and_stiff_ones_change_nothing(run):
    rows = compliant.sweep(run, stiffnesses=(500.0, 1e7), ratios=(0.2,))
    soft, stiff = rows
    assert soft['reduction_pct'] > 30.0
    assert abs(stiff['reduction_pct']) < 0.5
    assert soft['largest_deflection_mm'] > 10 * stiff['largest_deflection_mm']
    # Balanced: the soft links carry the rigid run's mean load, the body settled for it.
    force, _, shift = compliant.balanced(run, compliant.flexure_of(500.0, 0.2, 0.004))
    rigid = compliant.steady(run, compliant.rigid_force(run))
    assert compliant.steady(run, force).mean() == pytest.approx(rigid.mean(), rel=1e-3)
    assert shift > 0


def test_the_report_is_written(run, tmp_path):
    rows = compliant.sweep(run, stiffnesses=(500.0, 5000.0), ratios=(0.2,))
    printed = compliant.printed_rows(run, compliant.LINK_MASS)
    summary = compliant.write_report(rows, printed, run, BASE, tmp_path / 'out')
    text = (tmp_path / 'out' / 'report.md').read_text()
    assert 'Open loop' in text and 'TPU' in text
    assert (tmp_path / 'out' / 'compliant.png').stat().st_size > 10000
    assert len((tmp_path / 'out' / 'compliant.csv').read_text().splitlines()) == 3
    assert summary['TPU_reduction_pct'] == pytest.approx(printed[0]['reduction_pct'])


def test_the_compliant_robot_itself_is_compared_at_equal_speed():
    """Closed loop: the batch's rigid run is the rigid robot; a stiff flexure is close to it."""
    result = compliant.closed_loop(BASE, stiffnesses=(1462.8, 1e7), ratios=(0.7,),
                                   settle=1.0, measure=1.0)
    soft, stiff = result['rows']
    assert stiff['speed_share'] == pytest.approx(1.0, abs=2e-3)
    assert abs(stiff['vibration'] / result['rigid']['vibration'] - 1.0) < 0.03
    # The soft flexure crawls at least as fast and shakes less than the rigid robot would at
    # its speed (docs/compliant_robot.md: 32 % over the standard 4 s window).
    assert soft['speed_share'] > 0.95
    assert soft['reduction_pct'] > 15.0
    assert result['best'] is not None and result['best']['reduction_pct'] >= soft['reduction_pct']
    assert soft['energy_per_m'] > 0


def test_level_to_vertical_each_slope_against_its_own_rigid_robot(tmp_path):
    """Closed loop on two slopes: the rigid robot of each slope, the best and the robust one."""
    study = compliant.closed_loop_slopes(BASE, (0.0, 90.0), stiffnesses=(1462.8, 1e7),
                                         ratios=(0.7,), settle=1.0, measure=1.0)
    level, vertical = study['slopes']
    assert (level['slope_deg'], vertical['slope_deg']) == (0.0, 90.0)
    # Climbing vertically costs the rigid robot speed and energy (docs/compliant_robot.md).
    assert vertical['rigid']['speed'] < 0.95 * level['rigid']['speed']
    assert vertical['rigid']['energy_per_m'] > level['rigid']['energy_per_m']
    for r in (level, vertical):
        stiff = r['rows'][1]
        assert stiff['speed_share'] == pytest.approx(1.0, abs=5e-3)
    # The robust structure is the one whose least reduction over the slopes is the largest.
    best = study['robust']
    assert best is not None and best['stiffness'] == 1462.8
    assert best['reductions'] == [level['rows'][0]['reduction_pct'],
                                  vertical['rows'][0]['reduction_pct']]
    assert best['least'] == min(best['reductions']) > 15.0
    # With the shaped drive on top (a short search), against each slope's rigid robot.
    shaped = compliant.shaped_slopes(BASE, (0.0, 90.0), best['stiffness'],
                                     best['damping_ratio'], generations=2, population=4)
    assert [r['slope_deg'] for r in shaped] == [0.0, 90.0]
    for r in shaped:
        assert r['speed'] > 0.05 and r['energy_per_m'] > 0.0
        if r['feasible']:
            assert r['reduction_pct'] == pytest.approx(
                100.0 * (1.0 - r['vibration'] / r['rigid_vibration']))
        else:
            assert r['drive_pct'] == 0.0 and 'constant voltage' in r['why']
    assert shaped[1]['energy_per_m'] > shaped[0]['energy_per_m']
    compliant.write_slopes(study, BASE, tmp_path, shaped)
    text = (tmp_path / 'report.md').read_text()
    assert '## From level to vertical' in text and '| 90 deg |' in text
    assert f'{best["least"]:.1f} % less vibration' in text
    assert 'With the shaped drive on top' in text and '2 generations of 4' in text
    for r, alone in zip(shaped, best['reductions']):
        assert f'| {r["slope_deg"]:g} deg | {alone:.1f} % | ' in text
    assert len((tmp_path / 'slopes.csv').read_text().splitlines()) == 1 + 2 * 2
    assert (tmp_path / 'slopes.png').stat().st_size > 10000


def test_a_slope_that_leaves_the_model_is_reported_not_dropped(tmp_path):
    """A 100 N tether throws the robot back beyond the model: each slope says so."""
    base = BASE.with_values({'conditions.external_force': 100.0})
    study = compliant.closed_loop_slopes(base, (0.0, 30.0), stiffnesses=(1462.8,),
                                         ratios=(0.7,), settle=0.5, measure=0.5)
    assert all('diverged' in r['error'] for r in study['slopes'])
    assert study['robust'] is None
    compliant.write_slopes(study, base, tmp_path)
    text = (tmp_path / 'report.md').read_text()
    assert text.count('not run: simulation diverged') == 2
    assert 'No single structure' in text


def test_the_robust_structure_keeps_the_speed_on_every_slope():
    """A structure too slow on one slope is out, whatever it does on the others."""
    def rows(*figures):
        return {'rows': [{'stiffness': k, 'damping_ratio': 0.7, 'speed_share': share,
                          'reduction_pct': reduction} for k, share, reduction in figures]}
    slopes = [rows((1.0, 1.0, 50.0), (2.0, 1.0, 20.0), (3.0, 1.0, float('nan'))),
              rows((1.0, 0.9, 60.0), (2.0, 0.96, 10.0), (3.0, 1.0, 90.0))]
    best = compliant.robust(slopes)
    assert (best['stiffness'], best['least'], best['reductions']) == (2.0, 10.0, [20.0, 10.0])
    assert compliant.robust([rows((1.0, 0.5, 10.0))]) is None
