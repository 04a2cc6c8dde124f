#!/usr/bin/env python3
"""
Store the core's reference trajectories: tests/core/data/core_reference.npz.

Made once, from the numpy core before it became compiled kernels (issue 30), so that
tests/core/test_reference_trajectories.py holds today's and every later core to the same poses
within 1e-6 m. Each case is 4 s of one scenario, the pose (x, y, theta) and the helix phase and
speed at every step (integration.dt = 1 ms): the default scenario (the paper's rigid surfaces at
1 Hz), its motor at 6 V, and the two bending walls of docs/walls.md (silicone sheet, soft
tissue). The parameters that differ from the defaults are stored beside each trajectory, so the
test rebuilds the same scenarios from the file alone.

    python scripts/make_core_reference.py            # refuses to overwrite
    python scripts/make_core_reference.py --force    # the core's behaviour changed on purpose
"""
import argparse
import json
from pathlib import Path
import sys

import numpy as np

from saw_ros.core.dynamics import simulate
from saw_ros.core.params import Scenario

DURATION = 4.0
OUT = Path(__file__).resolve().parents[1] / 'tests' / 'core' / 'data' / 'core_reference.npz'
CASES = {
    'default': {},
    'motor_6V': {'motor.voltage': 6.0},
    'silicone_sheet': {'surface.foundation_stiffness': 1.5e5,
                       'surface.bending_stiffness': 6.25e-4},
    'soft_tissue': {'surface.foundation_stiffness': 9e3, 'surface.bending_stiffness': 1.2e-5},
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--force', action='store_true', help='overwrite the stored file')
    args = parser.parse_args()
    if OUT.exists() and not args.force:
        print(f'{OUT} exists: the reference is made once (--force to replace it)',
              file=sys.stderr)
        return 1
    arrays = {'cases': np.array(json.dumps(CASES)), 'duration': np.array(DURATION)}
    for name, values in CASES.items():
        run = simulate(Scenario().with_values(values), DURATION)
        arrays[f'{name}_pose'] = run.q[:, 0, :3]
        arrays[f'{name}_omega'] = run.omega[:, 0]
        print(f'{name}: {len(run.t)} samples, x {run.q[-1, 0, 0]:.6f} m at {run.t[-1]:g} s')
    OUT.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(OUT, **arrays)
    print(f'wrote {OUT} ({OUT.stat().st_size / 1024:.0f} KB)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
