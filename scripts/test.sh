#!/usr/bin/env bash
# The test command: bootstraps the environment, then runs the whole suite in parallel.
#
# pytest-xdist: WORKERS processes, each with a DDS domain of its own (tests/conftest.py reserves
# one per process), whole files to a worker (--dist loadfile: a module's shared graph run is made
# once). Four workers on two cores: most of the suite's time is ROS processes waiting on one
# another, not computing (eight ROS test files: 147 s with 2 workers, 95 s with 3, 68 s with 4,
# the same 40 s of CPU each; docs/measurements.md). Arguments go to pytest after ours (-n 1 runs
# the suite in one worker).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/bootstrap.sh"
cd "$ROOT"
WORKERS=4
code=0
python -m pytest -n "$WORKERS" --dist loadfile "$@" || code=$?
if [ "$code" -eq 5 ]; then
  # pytest's "no tests collected": a wrong path or filter, never a pass.
  echo "scripts/test.sh: pytest collected no tests (exit 5); check the paths and -k/-m given" >&2
fi
exit "$code"
