"""The core against its stored trajectories (scripts/make_core_reference.py, issue 30)."""
import json
from pathlib import Path

import numpy as np
import pytest

from saw_ros.core.dynamics import simulate
from saw_ros.core.params import Scenario

REFERENCE = np.load(Path(__file__).parent / 'data' / 'core_reference.npz')
CASES = json.loads(str(REFERENCE['cases']))
DURATION = float(REFERENCE['duration'])
# Poses within a micrometre of the numpy core's over 4 s (the pitch times the robot's half
# length, about 0.1 m, stays far below it at 1e-6 rad).
POSITION = 1e-6
PITCH = 1e-6


@pytest.mark.parametrize('name', sorted(CASES))
def test_poses_stay_those_of_the_stored_run(name):
    run = simulate(Scenario().with_values(CASES[name]), DURATION)
    pose = run.q[:, 0, :3]
    stored = REFERENCE[f'{name}_pose']
    assert pose.shape == stored.shape
    np.testing.assert_allclose(pose[:, :2], stored[:, :2], rtol=0.0, atol=POSITION)
    np.testing.assert_allclose(pose[:, 2], stored[:, 2], rtol=0.0, atol=PITCH)
    np.testing.assert_allclose(run.omega[:, 0], REFERENCE[f'{name}_omega'], rtol=1e-6, atol=1e-9)
    assert np.ptp(stored[:, 0]) > 0.15           # the robot crawled: a run that compares
