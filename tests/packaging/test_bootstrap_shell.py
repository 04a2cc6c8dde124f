"""
`source scripts/bootstrap.sh` leaves the caller's shell as it was, but for the environment.

It used to leave `set -euo pipefail` in the user's interactive shell: the next failing command
closed the terminal. Sourced, it may change PATH, AMENT_PREFIX_PATH and PYTHONUNBUFFERED only,
and a failure in it still stops scripts/main.sh and scripts/test.sh (they set -e themselves).
"""
import os
from pathlib import Path
import shutil
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[2]
BOOTSTRAP = ROOT / 'scripts' / 'bootstrap.sh'
EXPORTED = {'PATH', 'AMENT_PREFIX_PATH', 'PYTHONUNBUFFERED'}
# Variables bash itself changes from one command to the next.
BASH_DYNAMIC = {'_', 'BASH_COMMAND', 'BASH_LINENO', 'BASH_SOURCE', 'BASH_ARGC', 'BASH_ARGV',
                'FUNCNAME', 'LINENO', 'PIPESTATUS', 'RANDOM', 'SECONDS', 'SRANDOM',
                'EPOCHREALTIME', 'EPOCHSECONDS', 'BASHPID', 'OLDPWD', 'COLUMNS', 'LINES'}

needs_venv = pytest.mark.skipif(
    Path(sys.prefix).resolve() != (ROOT / '.venv').resolve(),
    reason="sources scripts/bootstrap.sh, which would create .venv: this run's Python is "
           f'{sys.prefix}, not the bootstrapped venv')


def interactive_bash(script: str, cwd: Path, env=None) -> subprocess.CompletedProcess:
    """Run ``script`` in an interactive bash (``-i``: set -e there closes the shell)."""
    base = {'HOME': os.environ.get('HOME', '/tmp'), 'PATH': '/usr/bin:/bin', 'TERM': 'dumb'}
    return subprocess.run(['bash', '--norc', '--noprofile', '-i'], input=script, cwd=cwd,
                          env=dict(base, **(env or {})), capture_output=True, text=True,
                          timeout=300)


def _state(out: Path, tag: str) -> str:
    """Commands that write the shell's options, variable and function names to files."""
    return (f'set -o > {out}/{tag}.options; shopt > {out}/{tag}.shopt; '
            f'compgen -v | sort > {out}/{tag}.vars; declare -F > {out}/{tag}.functions\n')


@needs_venv
def test_sourcing_changes_nothing_but_the_documented_variables(tmp_path):
    script = (_state(tmp_path, 'before')
              + f'source {BOOTSTRAP} > /dev/null; echo "sourced $?"\n'
              + _state(tmp_path, 'after')
              + 'false\necho "survived $?"\n'
              + 'ls /no/such/path 2>/dev/null | cat; echo "survived pipe"\n'
              + 'echo "unset: $NOT_SET_ANYWHERE."\n'
              + 'echo "venv: $(command -v saw-ros)"\n'
              + 'echo "prefix: ${AMENT_PREFIX_PATH%%:*}"\n')
    out = interactive_bash(script, cwd=tmp_path)
    assert 'sourced 0' in out.stdout, out.stdout + out.stderr
    # The shell survives a failing command (set -e would have closed it), an unset variable
    # (set -u) and a failing pipe (pipefail).
    assert 'survived 1' in out.stdout and 'survived pipe' in out.stdout, out.stdout + out.stderr
    assert 'unset: .' in out.stdout, out.stdout + out.stderr
    for kind in ('options', 'shopt', 'functions'):
        before = (tmp_path / f'before.{kind}').read_text()
        assert (tmp_path / f'after.{kind}').read_text() == before, kind
    before = set((tmp_path / 'before.vars').read_text().split())
    after = set((tmp_path / 'after.vars').read_text().split())
    assert after - before - BASH_DYNAMIC <= EXPORTED, after - before
    # and the environment it documents is there
    venv = (ROOT / '.venv').resolve()
    assert f'venv: {venv}/bin/saw-ros' in out.stdout.replace(str(ROOT / '.venv'), str(venv))
    assert f'prefix: {ROOT / ".venv"}' in out.stdout or f'prefix: {venv}' in out.stdout


def test_a_failing_bootstrap_still_stops_a_script_and_spares_an_interactive_shell(tmp_path):
    # A copy of the script in a tree without .venv, with a Python that fails: creating the venv
    # fails at once.
    (tmp_path / 'scripts').mkdir()
    shutil.copy(BOOTSTRAP, tmp_path / 'scripts' / 'bootstrap.sh')
    env = {'HOME': os.environ.get('HOME', '/tmp'), 'PATH': '/usr/bin:/bin', 'PYTHON': '/bin/false'}
    script = subprocess.run(
        ['bash', '-c', 'set -euo pipefail; source scripts/bootstrap.sh; echo "went on"'],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60)
    assert script.returncode != 0 and 'went on' not in script.stdout, script.stdout
    shell = interactive_bash('source scripts/bootstrap.sh; echo "status $?"\n'
                             'echo "options: $-"\n', cwd=tmp_path, env={'PYTHON': '/bin/false'})
    assert 'status 1' in shell.stdout, shell.stdout + shell.stderr
    options = shell.stdout.split('options: ')[1].split()[0]
    assert 'e' not in options and 'u' not in options, options
    assert not (tmp_path / '.venv' / '.saw_ros_stamp').exists()
