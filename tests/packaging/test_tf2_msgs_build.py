"""scripts/build_tf2_msgs.sh: the one message package the pip set-up builds, or one clear line."""
import os
from pathlib import Path
import shutil
import subprocess

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / 'scripts' / 'build_tf2_msgs.sh'


def _path_without(tmp_path, *missing):
    """Return a PATH of links to the tools the script uses, without ``missing``."""
    bin_dir = tmp_path / 'bin'
    bin_dir.mkdir()
    for tool in ('bash', 'cat', 'sha256sum', 'cut', 'mkdir', 'rm', 'grep', 'tail', 'dirname',
                 'cmake', 'cc', 'c++', 'tr', 'sed', 'head'):
        found = shutil.which(tool)
        if tool not in missing and found:
            os.symlink(found, bin_dir / tool)
    return str(bin_dir)


@pytest.mark.parametrize('missing', ['cmake', 'c++'])
def test_without_a_compiler_or_cmake_it_stops_with_one_line_naming_the_tool(tmp_path, missing):
    out = subprocess.run([shutil.which('bash'), str(SCRIPT), str(tmp_path / 'venv')],
                         env={'PATH': _path_without(tmp_path, missing)}, capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 1
    assert out.stderr.count('\n') == 1 and f"'{missing}' not found" in out.stderr, out.stderr
    assert 'Traceback' not in out.stderr and not (tmp_path / 'venv' / 'build').exists()


def test_a_failed_build_says_why_in_one_line(tmp_path):
    """A venv without the generators: cmake fails, and the line quotes its first error."""
    venv = tmp_path / 'venv'
    (venv / 'bin').mkdir(parents=True)
    system = '/usr/bin:/bin'
    if not (shutil.which('cmake', path=system) and shutil.which('c++', path=system)):
        pytest.skip('needs cmake and a C++ compiler')
    # Only the system's tools on PATH: CMake also searches the prefixes above PATH's entries,
    # where a sourced ROS environment or venv would provide ament_cmake.
    env = {'PATH': system, 'HOME': os.environ.get('HOME', '/tmp')}
    out = subprocess.run(['bash', str(SCRIPT), str(venv)], capture_output=True, text=True,
                         timeout=120, env=env)
    assert out.returncode == 1
    lines = out.stderr.splitlines()
    assert lines[0].startswith('[bootstrap] building tf2_msgs/TFMessage')
    assert len(lines) == 2 and lines[1].startswith('[bootstrap] error: building tf2_msgs failed: ')
    assert 'package not found: "ament_cmake"' in lines[1], lines[1]
    assert not (venv / '.tf2_msgs_stamp').exists()
