"""scripts/build_ros2launch.sh: ros2 launch into the venv from the user's sources, or one line."""
from pathlib import Path
import shutil
import subprocess

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / 'scripts' / 'build_ros2launch.sh'


def _run(*args):
    return subprocess.run([shutil.which('bash'), str(SCRIPT), *map(str, args)],
                          capture_output=True, text=True, timeout=60)


def test_without_sources_it_names_what_is_missing_in_one_line_and_installs_nothing(tmp_path):
    venv = tmp_path / 'venv'
    (venv / 'bin').mkdir(parents=True)
    (venv / 'bin' / 'python').symlink_to(shutil.which('python3'))
    sources = tmp_path / 'src'
    (sources / 'launch' / 'launch').mkdir(parents=True)       # a partial checkout
    (sources / 'launch' / 'launch' / 'setup.py').write_text('')
    out = _run(sources, venv)
    assert out.returncode == 1
    assert out.stderr.count('\n') == 1, out.stderr
    assert f'{sources}/rosidl_runtime_py/setup.py not found' in out.stderr
    assert 'jazzy checkouts of launch, launch_ros, ros2cli and rosidl_runtime_py' in out.stderr
    assert not (venv / 'build').exists()


def test_without_a_venv_it_says_to_bootstrap_first(tmp_path):
    out = _run(tmp_path, tmp_path / 'no_venv')
    assert out.returncode == 1 and out.stderr.count('\n') == 1
    assert 'no Python venv at' in out.stderr and 'scripts/bootstrap.sh' in out.stderr
