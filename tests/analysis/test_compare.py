import math

import numpy as np
import pytest

from saw_ros.analysis.compare import find_reference, load_reference, reference_error, RunComparator
from saw_ros.core import RobotParams, Scenario, simulate
from saw_ros.interface.config import config_path

ROBOT = RobotParams()


def feed_truth(comp, t, x):
    for row in zip(t, x):
        comp.add_truth(*row)


def test_before_steady_state_it_says_so_not_a_number():
    comp = RunComparator(ROBOT, 1.0)
    assert comp.result().status == 'waiting for data'
    t = np.arange(0, 0.5, 0.001)
    feed_truth(comp, t, 0.05 * t + 0.004 * (1 - np.exp(-t / 0.2)))
    r = comp.result()
    assert r.status == 'not steady yet' and math.isnan(r.ar_sim)


def test_sim_and_tracked_ar_from_the_same_window_over_whole_cycles():
    s = Scenario()
    tr = simulate(s, 4.0)
    q = tr.q[:, 0]
    comp = RunComparator(s.robot, s.frequency)
    feed_truth(comp, tr.t, q[:, 0])
    # A tracker 2 % slow, sampled at 60 Hz with a marker lost (NaN) now and then.
    frames = np.arange(0, 4.0, 1 / 60)
    tracked = 0.98 * np.interp(frames, tr.t, q[:, 0])
    tracked[::17] = np.nan
    for t, x in zip(frames, tracked):
        comp.add_tracked(t, x)
    r = comp.result()
    assert r.steady and r.window_s >= 1.0 and r.window_s * r.frequency == pytest.approx(
        round(r.window_s * r.frequency))
    assert r.ar_sim == pytest.approx(0.754, abs=0.01)
    assert r.relative_error == pytest.approx(0.02, abs=0.002)
    assert r.v_tracked == pytest.approx(0.98 * r.v_sim, rel=0.003)


def test_lost_truth_samples_do_not_hide_the_steady_state():
    s = Scenario()
    tr = simulate(s, 4.0)
    x = tr.q[:, 0, 0]
    keep = np.random.default_rng(3).random(len(x)) > 0.2     # a subscriber that lost 20 %
    comp = RunComparator(s.robot, s.frequency)
    feed_truth(comp, tr.t[keep], x[keep])
    for t in np.arange(0, 4.0, 1 / 60):
        comp.add_tracked(t, float(np.interp(t, tr.t, x)))
    r = comp.result()
    assert r.steady and r.steady_from < 1.0
    assert r.ar_sim == pytest.approx(0.754, abs=0.01)


def test_a_reset_of_simulated_time_starts_over():
    comp = RunComparator(ROBOT, 1.0)
    feed_truth(comp, [0.0, 0.001, 0.002], [0, 0, 0])
    comp.add_truth(0.0, 0.0)
    assert comp.truth.size == 1


def test_the_papers_reference_points_ship_with_their_source():
    points = load_reference(config_path('reference_paper.csv'))
    assert len(points) == 3 and all('Section 6.4.1' in p.source for p in points)
    p = find_reference(points, 20.0, 6.0)
    assert p.speed == pytest.approx(0.068)
    assert reference_error(p, 0.068, 0.1) == pytest.approx(0.0)
    assert reference_error(p, 0.0748, 0.1) == pytest.approx(0.1)


def test_bad_reference_files_are_refused_with_the_reason(tmp_path):
    bad = tmp_path / 'bad.csv'
    bad.write_text('slope,volts\n1,2\n')
    with pytest.raises(ValueError, match='needs columns'):
        load_reference(bad)
    with pytest.raises(FileNotFoundError):
        load_reference(tmp_path / 'missing.csv')
    empty = tmp_path / 'empty_row.csv'
    empty.write_text('slope_deg,voltage_V,speed_cm_s,advance_ratio\n20,6,,\n')
    with pytest.raises(ValueError, match='row 2 .*neither speed_cm_s nor advance_ratio'):
        load_reference(empty)


def test_a_motor_run_is_compared_over_whole_helix_turns_at_the_frequency_reached():
    """
    4 V climbing 20 deg: the helix slows and ripples, so the cycles are its turns.

    Fed the helix's wrapped angle (as /saw/joint_states gives it), the comparator finds the
    steady state, measures over whole turns and takes v_theory at the mean helix frequency
    there, as core.metrics does from the recorded speed.
    """
    from saw_ros.core.metrics import analyse_run, run_frequency, run_turns
    s = Scenario().with_values({'motor.voltage': 4.0, 'conditions.slope': math.radians(20)})
    tr = simulate(s, 5.0)
    comp = RunComparator(s.robot, s.frequency)
    feed_truth(comp, tr.t, tr.q[:, 0, 0])
    for row in zip(tr.t[::5], tr.q[::5, 0, 0]):
        comp.add_tracked(*row)
    for t, angle in zip(tr.t, np.remainder(run_turns(tr), 2 * math.pi)):
        comp.add_helix(t, angle)
    r = comp.result()
    assert r.steady, r.status
    assert r.frequency == pytest.approx(run_frequency(tr), rel=0.005)
    assert r.frequency < 0.95 * s.frequency
    cycles = r.window_s * r.frequency
    assert cycles == pytest.approx(round(cycles), abs=1e-6) and round(cycles) >= 1
    assert r.ar_sim == pytest.approx(analyse_run(tr).advance_ratio, rel=0.01)
    assert r.relative_error < 0.002


def test_a_long_run_keeps_a_bounded_window_and_still_compares():
    # 400 s of a steady 1 Hz wave at 1 kHz (the node's pose rate), tracked at 60 Hz 2 % slow:
    # the comparator keeps at most 1.5 x keep_s of it, and compares over what it keeps.
    comp = RunComparator(ROBOT, 1.0, keep_s=30.0)
    most = {'truth': 0, 'tracked': 0}
    for second in range(400):
        t = second + np.arange(0, 1, 0.001)
        x = 0.05 * t + 0.002 * np.sin(2 * np.pi * t)
        feed_truth(comp, t, x)
        for k in range(60):
            frame = second + k / 60
            comp.add_tracked(frame, 0.98 * (0.05 * frame + 0.002 * np.sin(2 * np.pi * frame)))
        most['truth'] = max(most['truth'], comp.truth.size)
        most['tracked'] = max(most['tracked'], comp.tracked.size)
    assert most['truth'] <= 45_000 + 1 and most['tracked'] <= 46 * 60 + 1
    assert comp.truth.column(0)[0] >= 400 - 45
    r = comp.result()
    assert r.steady and 30 - 1 <= r.window_s <= 45
    assert r.v_sim == pytest.approx(0.05, rel=1e-3)
    assert r.relative_error == pytest.approx(0.02, abs=1e-3)
