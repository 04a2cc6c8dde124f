"""ament_flake8 on the package and its tests, as every ament_python package runs it."""
from pathlib import Path

from ament_flake8.main import main_with_errors
import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8():
    """Check saw_ros and tests with ament's flake8 configuration."""
    rc, errors = main_with_errors(argv=[str(ROOT / 'saw_ros'), str(ROOT / 'tests')])
    assert rc == 0, \
        'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors)
