import numpy as np
import pytest

from saw_ros.core import RobotParams
from saw_ros.core.metrics import analyse, cci, mean_velocity, steady_state_start


def test_cci_of_a_periodic_signal_is_zero_and_detects_a_transient():
    t = np.arange(0, 5, 0.001)
    v = 0.05 + 0.01 * np.sin(2 * np.pi * 3 * t) + 0.02 * np.exp(-t / 0.2)
    tc, index = cci(t, v, 1.0)
    assert index[tc > 2.0].max() < 1e-3
    start = steady_state_start(t, v, 1.0)
    # |0.02 e^{-t/0.2} (1 - e^{-5})| / 0.05 < 0.02 from t = 0.2 ln(20) = 0.6 s
    assert start == pytest.approx(0.2 * np.log(0.02 * (1 - np.exp(-5)) / (0.02 * 0.05)),
                                  abs=0.01)


def test_mean_velocity_over_whole_cycles_cancels_the_ripple():
    t = np.arange(0, 4.0001, 0.001)
    x = 0.05 * t + 0.004 * np.sin(2 * np.pi * 2 * t)
    assert mean_velocity(t, x, 1.25, 2.0) == pytest.approx(0.05, rel=1e-6)


def test_analyse_reports_ar_against_v_theory():
    robot = RobotParams()
    t = np.arange(0, 4.0001, 0.001)
    q = np.zeros((len(t), 6))
    q[:, 3] = 0.05
    q[:, 0] = 0.05 * t
    m = analyse(t, q, robot, 1.0)
    assert m.v_mean == pytest.approx(0.05)
    assert m.advance_ratio == pytest.approx(0.05 / m.v_theory)
    assert m.steady_from == pytest.approx(0.0)
