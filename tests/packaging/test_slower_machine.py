"""scripts/slower_machine.sh, which our 'slower kind' suite figures are measured with, caps CPU."""
import os
from pathlib import Path
import subprocess
import sys

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / 'scripts' / 'slower_machine.sh'
# A busy loop for WALL_S of wall time, printing the CPU seconds it got.
BUSY = ('import os, time\n'
        't = time.monotonic()\n'
        'while time.monotonic() - t < {wall}: pass\n'
        'c = os.times()\n'
        'print(c.user + c.system)\n')
WALL_S = 1.5


def _run(env: dict, *command: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(SCRIPT), *command], env={**os.environ, **env}, text=True,
                          capture_output=True, timeout=60)


@pytest.mark.parametrize('value', ['x', '0', '-1', 'inf', '100'])
def test_bad_slowdown_refused_in_one_line(value: str) -> None:
    done = _run({'SLOWDOWN': value}, 'true')
    assert done.returncode == 2
    assert len(done.stderr.splitlines()) == 1 and value in done.stderr
    assert 'Traceback' not in done.stderr


def test_cap_holds_a_busy_loop_to_its_share() -> None:
    # The cap is an upper bound: a busy loop alone takes at most cores / SLOWDOWN of a second
    # every second (it may take less on a loaded machine, which is why only the bound is tested).
    done = _run({'SLOWDOWN': '4'}, sys.executable, '-c', BUSY.format(wall=WALL_S))
    if done.returncode == 2 and 'no writable cgroup' in done.stderr:
        pytest.skip(done.stderr.strip())
    assert done.returncode == 0, done.stderr
    cap = min(1.0, os.cpu_count() / 4.0)
    cpu_s = float(done.stdout.split()[-1])
    # The process's start (the interpreter) is inside the loop's wall time too.
    assert 0.0 < cpu_s <= cap * WALL_S * 1.15 + 0.05, (cpu_s, cap)
