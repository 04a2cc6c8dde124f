"""The paper's two remedies together (issue 31): the shaped drive on the compliant robot."""
import numpy as np
import pytest

from saw_ros.analysis import shape_drive
from saw_ros.core.params import Scenario

RIGID = Scenario().with_values({'motor.voltage': 6.0})
BUDGET = {'generations': 2, 'population': 4, 'seed': 3}


def test_rigid_flexures_shaped_against_the_rigid_robot_give_the_rigid_shaped_drive():
    """1e9 N/m links follow the rigid ones to 1e-7 m: the search and both comparisons agree."""
    stiff = RIGID.with_values({'flexure.stiffness': 1e9})
    rigid = shape_drive.optimise(RIGID, **BUDGET)
    combined = shape_drive.optimise(stiff, reference=RIGID, **BUDGET)
    assert rigid.reference is None and rigid.reference_reduction_pct is None
    # The same candidates (CMA-ES saw the same costs, to the rigid limit's rounding)...
    assert combined.mean_voltage == pytest.approx(rigid.mean_voltage, rel=1e-6)
    np.testing.assert_allclose(combined.coefficients, rigid.coefficients, atol=1e-6)
    for key in ('speed', 'vibration', 'power'):
        assert combined.shaped[key] == pytest.approx(rigid.shaped[key], rel=1e-4)
    # ... and the rigid reference at the shaped speed is the rigid robot's own matched drive.
    assert combined.reference_reaches_speed
    assert combined.reference_voltage == pytest.approx(rigid.matched_voltage, rel=1e-4)
    assert combined.reference_reduction_pct == pytest.approx(rigid.vibration_reduction_pct,
                                                             abs=0.05)


def test_a_reference_the_robot_cannot_match_in_speed_gives_no_figure():
    """A reduction against a robot at another speed would be wrong: None, not a number."""
    result = shape_drive.optimise(RIGID, **BUDGET)
    slow = dict(result.shaped, speed=0.9 * result.shaped['speed'])
    result.reference, result.reference_voltage = slow, result.matched_voltage
    assert not result.reference_reaches_speed and result.reference_reduction_pct is None
    result.reference = dict(result.matched)
    assert result.reference_reduction_pct == pytest.approx(result.vibration_reduction_pct)
