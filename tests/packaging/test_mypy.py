"""
mypy on saw_ros, as ros2/demos checks its Python (its test_mypy.py) beside flake8 and pep257.

``core/`` and ``interface/`` are checked with what ``--strict`` turns on (every function
annotated, no Any returned where a type is promised), the rest with mypy's default checks; every
module passes. One mypy run with the strict flags set per module in a config file: two runs
(one ``--strict``) analysed numpy's stubs twice, half the test's time. Packages without type
information (rclpy and the message packages, mcap, cmaes, tqdm, yaml, dask) are taken as Any.
"""
from pathlib import Path

from mypy import api
import pytest

ROOT = Path(__file__).resolve().parents[2]
STRICT_LAYERS = ('core', 'interface')
# --strict's flags (mypy --help) that a module section may set; warn_redundant_casts may only be
# global, so every module has it.
STRICT_FLAGS = ('disallow_any_generics', 'disallow_subclassing_any', 'disallow_untyped_calls',
                'disallow_untyped_defs', 'disallow_incomplete_defs', 'check_untyped_defs',
                'disallow_untyped_decorators', 'warn_unused_ignores', 'warn_return_any',
                'strict_equality', 'extra_checks')


def config() -> str:
    strict = '\n'.join(f'{flag} = True' for flag in STRICT_FLAGS)
    modules = ','.join(f'saw_ros.{layer}.*,saw_ros.{layer}' for layer in STRICT_LAYERS)
    return (f'[mypy]\nignore_missing_imports = True\nfollow_imports = silent\n'
            f'warn_redundant_casts = True\n\n'
            f'[mypy-{modules}]\n{strict}\nimplicit_reexport = False\n')


@pytest.mark.linter
@pytest.mark.mypy
@pytest.mark.slow
def test_mypy(tmp_path):
    ini = tmp_path / 'mypy.ini'
    ini.write_text(config())
    out, err, _ = api.run(['--config-file', str(ini), '--no-error-summary', '--cache-dir',
                           str(tmp_path / 'cache'), str(ROOT / 'saw_ros')])
    assert not err, err
    assert ': error:' not in out, out


def test_the_strict_layers_are_checked_strictly(tmp_path):
    """The config's strict section reaches core and interface: an unannotated def fails there."""
    # One cache for the three runs (the same config): the standard library's stubs are analysed
    # once, not three times (13 -> 5 s).
    cache = tmp_path / 'cache'
    for layer, fails in (('core', True), ('interface', True), ('vision', False)):
        pkg = tmp_path / layer / 'saw_ros' / layer
        pkg.mkdir(parents=True)
        (pkg.parent / '__init__.py').write_text('')
        (pkg / '__init__.py').write_text('')
        (pkg / 'probe.py').write_text('def half(x):\n    return x / 2\n')
        ini = tmp_path / layer / 'mypy.ini'
        ini.write_text(config())
        out, _, _ = api.run(['--config-file', str(ini), '--no-error-summary', '--cache-dir',
                             str(cache), str(pkg / 'probe.py')])
        assert ('Function is missing a type annotation' in out) == fails, (layer, out)
