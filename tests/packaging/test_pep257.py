"""ament_pep257 on the package and its tests, as every ament_python package runs it."""
from pathlib import Path

from ament_pep257.main import main
import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    """Check the docstrings of saw_ros and tests with ament's pep257 configuration."""
    rc = main(argv=[str(ROOT / 'saw_ros'), str(ROOT / 'tests')])
    assert rc == 0, 'Found code style errors / warnings'
