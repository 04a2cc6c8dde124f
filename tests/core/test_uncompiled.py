"""The kernels run uncompiled (NUMBA_DISABLE_JIT=1) give the compiled kernels' numbers."""
import json
import os
import subprocess
import sys

import numpy as np

from saw_ros.core.dynamics import simulate
from saw_ros.core.params import Scenario

# A batch that takes every branch of the step: rigid walls at constant frequency, bending
# walls (the silicone sheet of docs/walls.md) driven by the motor, on a slope.
VALUES = [{}, {'surface.foundation_stiffness': 1.5e5, 'surface.bending_stiffness': 6.25e-4,
               'motor.voltage': 6.0, 'conditions.slope': 0.3}]
DURATION = 0.15
RUN = ('import json, sys; from saw_ros.core.dynamics import simulate; '
       'from saw_ros.core.params import Scenario; import numba; '
       'assert numba.config.DISABLE_JIT; '
       'r = simulate([Scenario().with_values(v) for v in json.loads(sys.argv[1])], '
       f'{DURATION}); print(json.dumps(r.q[-1].tolist()))')


def test_the_uncompiled_kernels_step_as_the_compiled_ones():
    compiled = simulate([Scenario().with_values(v) for v in VALUES], DURATION)
    env = dict(os.environ, NUMBA_DISABLE_JIT='1')
    out = subprocess.run([sys.executable, '-c', RUN, json.dumps(VALUES)], env=env, check=True,
                         capture_output=True, text=True, timeout=300)
    uncompiled = np.array(json.loads(out.stdout.splitlines()[-1]))
    assert np.ptp(compiled.q[:, :, 0], axis=0).min() > 5e-4       # both robots moved
    # The same operations in the same order; only the math library may differ in a last bit.
    np.testing.assert_allclose(uncompiled, compiled.q[-1], rtol=0.0, atol=1e-9)


def test_the_uncompiled_walls_with_mass_step_as_the_compiled_ones():
    """The walls' modes (core.dynamic_walls: swing_walls, load_walls) too: the tissue set."""
    values = [{'surface.foundation_stiffness': 9e3, 'surface.bending_stiffness': 1.2e-5,
               'walls.mass': 0.13, 'walls.damping': 6.8}]
    compiled = simulate([Scenario().with_values(v) for v in values], DURATION)
    env = dict(os.environ, NUMBA_DISABLE_JIT='1')
    out = subprocess.run([sys.executable, '-c', RUN, json.dumps(values)], env=env, check=True,
                         capture_output=True, text=True, timeout=300)
    uncompiled = np.array(json.loads(out.stdout.splitlines()[-1]))
    assert np.abs(compiled.q[-1, 0, 1] - compiled.q[0, 0, 1]) > 1e-3      # it landed
    np.testing.assert_allclose(uncompiled, compiled.q[-1], rtol=0.0, atol=1e-9)


def test_the_uncompiled_flexures_on_bending_walls_step_as_the_compiled_ones():
    """Flexures on the sheet (driven, on a slope) and on the tissue with mass (flex_walls)."""
    values = [{**VALUES[1], 'flexure.stiffness': 2000.0, 'flexure.damping': 0.5},
              {'surface.foundation_stiffness': 9e3, 'surface.bending_stiffness': 1.2e-5,
               'walls.mass': 0.13, 'walls.damping': 6.8, 'flexure.stiffness': 863.0,
               'flexure.damping': 2.6}]
    compiled = simulate([Scenario().with_values(v) for v in values], DURATION)
    env = dict(os.environ, NUMBA_DISABLE_JIT='1')
    out = subprocess.run([sys.executable, '-c', RUN, json.dumps(values)], env=env, check=True,
                         capture_output=True, text=True, timeout=300)
    uncompiled = np.array(json.loads(out.stdout.splitlines()[-1]))
    assert np.ptp(compiled.q[:, :, 1], axis=0).min() > 5e-4             # both robots moved
    np.testing.assert_allclose(uncompiled, compiled.q[-1], rtol=0.0, atol=1e-9)
