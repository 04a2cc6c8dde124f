"""
mypy on saw_ros, as ros2/demos checks its Python (its test_mypy.py) beside flake8 and pep257.

``core/`` and ``interface/`` are checked with ``--strict`` (every function annotated, no Any
returned where a type is promised), the rest with mypy's default checks. The modules listed
below do not pass the default checks yet; the list only shrinks: a module that starts to pass
must leave it (the test says so), and a module not listed must pass. Packages without type
information (rclpy and the message packages, mcap, cmaes, tqdm, yaml, dask) are taken as Any.
"""
from pathlib import Path

from mypy import api
import pytest

ROOT = Path(__file__).resolve().parents[2]
STRICT_LAYERS = ('core', 'interface')
# Modules that do not pass mypy's default checks yet (none now; the list only shrinks).
NOT_YET_CHECKED: set = set()


def failing(paths, *flags: str, cache: Path):
    """Return the modules (relative to saw_ros/) mypy reports errors in, and its report."""
    out, err, _ = api.run(['--ignore-missing-imports', '--follow-imports=silent',
                           '--no-error-summary', '--cache-dir', str(cache), *flags,
                           *map(str, paths)])
    assert not err, err
    bad = {line.split(':', 1)[0] for line in out.splitlines() if ': error:' in line}
    return {str(Path(p).resolve().relative_to(ROOT / 'saw_ros')) for p in bad}, out


def check(paths, listed, flags, cache):
    wrong, report = failing(paths, *flags, cache=cache)
    new = sorted(wrong - listed)
    assert not new, f'mypy {" ".join(flags)}: errors in {new}:\n{report}'
    fixed = sorted(m for m in listed - wrong if (ROOT / 'saw_ros' / m).exists())
    assert not fixed, f'{fixed} pass(es) mypy {" ".join(flags)} now: take them off the list'


@pytest.mark.linter
@pytest.mark.mypy
@pytest.mark.slow
def test_mypy_strict_on_core_and_interface(tmp_path):
    paths = sorted(p for layer in STRICT_LAYERS for p in (ROOT / 'saw_ros' / layer).rglob('*.py'))
    check(paths, set(), ['--strict'], tmp_path)


@pytest.mark.linter
@pytest.mark.mypy
@pytest.mark.slow
def test_mypy_on_the_package(tmp_path):
    check([ROOT / 'saw_ros'], NOT_YET_CHECKED, [], tmp_path)
