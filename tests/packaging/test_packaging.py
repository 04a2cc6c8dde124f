"""
`ros2 run` readiness of the install the suite runs against, in either layout.

- venv: scripts/bootstrap.sh's pip install into .venv (the venv is laid out like a ROS install
  prefix: executables in <venv>/lib/saw_ros/<exe>, the ament index entry, share/saw_ros);
- colcon: `colcon build` then `colcon test` in a workspace (install/saw_ros/..., tests run from
  the source folder with the install on PYTHONPATH and AMENT_PREFIX_PATH).
Tests that only make sense in one layout skip with the reason in the other. None writes into the
source tree. Also: package.xml format 3, setup.py's test requirement, the shared config.
"""
import os
from pathlib import Path
import re
import runpy
import subprocess
import sys
from unittest import mock
import xml.etree.ElementTree as ET

import pytest

from saw_ros.graph.process import isolated_ros_env

ROOT = Path(__file__).resolve().parents[2]
MARKER = Path('share', 'ament_index', 'resource_index', 'packages', 'saw_ros')


def installed_prefix():
    """
    Return the install prefix of saw_ros this suite runs against.

    The venv itself (bootstrap.sh), else the first prefix of AMENT_PREFIX_PATH that lists saw_ros
    (colcon test sets it), else None.
    """
    candidates = [sys.prefix] + os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
    for prefix in filter(None, candidates):
        if (Path(prefix) / MARKER).is_file():
            return Path(prefix)
    return None


PREFIX = installed_prefix()
BOOTSTRAP_VENV = PREFIX is not None and PREFIX.resolve() == (ROOT / '.venv').resolve()
COLCON = PREFIX is not None and (PREFIX / 'share/colcon-core/packages/saw_ros').is_file()
LAYOUT = 'venv' if BOOTSTRAP_VENV else 'colcon' if COLCON else 'other' if PREFIX else 'none'

needs_install = pytest.mark.skipif(
    PREFIX is None, reason='saw_ros is not installed here: run scripts/test.sh (bootstraps .venv) '
    'or colcon build + colcon test')
venv_only = pytest.mark.skipif(
    not BOOTSTRAP_VENV, reason=f"checks scripts/bootstrap.sh's .venv; this run's install is "
    f'{LAYOUT} ({PREFIX})')


def console_scripts():
    text = (ROOT / 'setup.py').read_text()
    nodes = re.search(r'NODES = \(([^)]*)\)', text).group(1)
    return re.findall(r"'([a-z_]+)'", nodes)


def setup_arguments():
    """Return the keyword arguments setup.py passes to setup(), without running setuptools."""
    captured = {}
    cwd = os.getcwd()
    os.chdir(ROOT)      # setup.py globs msg_config/ relative to its folder, as colcon runs it
    try:
        with mock.patch('setuptools.setup', lambda **kw: captured.update(kw)):
            runpy.run_path(str(ROOT / 'setup.py'), run_name='__main__')
    finally:
        os.chdir(cwd)
    return captured


def test_package_xml_is_format_3_ament_python():
    root = ET.parse(ROOT / 'package.xml').getroot()
    assert root.tag == 'package' and root.get('format') == '3'
    assert root.findtext('name') == 'saw_ros'
    assert root.find('export').findtext('build_type') == 'ament_python'
    depends = {e.text for e in root if e.tag in ('depend', 'exec_depend')}
    # Everything the simulator imports at run time.
    assert {'rclpy', 'builtin_interfaces', 'geometry_msgs', 'sensor_msgs', 'rosgraph_msgs',
            'std_srvs', 'rcl_interfaces', 'python3-numpy'} <= depends


def test_setup_installs_config_and_ament_marker_for_colcon():
    text = (ROOT / 'setup.py').read_text()
    assert "'share/ament_index/resource_index/packages'" in text
    assert 'msg_config' in text
    assert (ROOT / 'resource' / 'saw_ros').is_file()
    assert 'script_dir=$base/lib/saw_ros' in (ROOT / 'setup.cfg').read_text()
    assert 'simulator' in console_scripts()


def test_the_console_scripts_are_the_executables_that_take_stop_signals_while_starting():
    from saw_ros.ros.nodes import EXECUTABLES
    assert tuple(console_scripts()) == EXECUTABLES


def test_setup_declares_pytest_so_colcon_test_runs_the_suite():
    """
    Check that setup.py names pytest as a test requirement.

    colcon-core's python test step picks pytest only if tests_require or extras_require['test']
    names it; otherwise unittest finds no test and reports OK.
    """
    args = setup_arguments()
    test_requires = list(args.get('tests_require') or []) + list(
        (args.get('extras_require') or {}).get('test') or [])
    assert 'pytest' in [re.split(r'[ <>=!\[]', r)[0] for r in test_requires]
    # Every file of msg_config/ is installed (colcon: data_files; the nodes read them there).
    installed = {name for dest, files in args['data_files'] if dest.endswith('/msg_config')
                 for name in (Path(f).name for f in files)}
    assert installed == {p.name for p in (ROOT / 'msg_config').iterdir()}


@needs_install
@pytest.mark.parametrize('exe', console_scripts())
def test_executables_where_ros2_run_looks(exe):
    path = PREFIX / 'lib' / 'saw_ros' / exe
    assert path.exists(), f'{path} missing: run scripts/bootstrap.sh or colcon build'
    assert os.access(path, os.X_OK), f'{path} is not executable'


@needs_install
def test_installed_share_has_package_xml_and_every_config_file():
    share = PREFIX / 'share' / 'saw_ros'
    assert (share / 'package.xml').is_file()
    for path in (ROOT / 'msg_config').iterdir():
        assert (share / 'msg_config' / path.name).is_file(), \
            f'{path.name} not installed in {share}'


@needs_install
def test_installed_share_has_the_launch_file_urdf_and_viewer_layouts():
    """setup.py's data_files (colcon) and scripts/bootstrap.sh's venv: the same share layout."""
    share = PREFIX / 'share' / 'saw_ros'
    for dest, files in setup_arguments()['data_files']:
        for name in files:
            installed = PREFIX / dest / Path(name).name
            assert installed.is_file(), f'{installed} missing'
            assert installed.read_bytes() == (ROOT / name).read_bytes(), installed
    for name in ('launch/saw.launch.py', 'urdf/saw.urdf', 'viewers/saw_ros.rviz',
                 'viewers/foxglove_layout.json'):
        assert (share / name).is_file(), f'{share / name} missing'


@needs_install
def test_ament_index_finds_the_installed_package():
    """
    Check that the install is an ament prefix of saw_ros (what `ros2 run` needs).

    With AMENT_PREFIX_PATH as scripts/bootstrap.sh or a colcon setup.bash exports it.
    """
    code = ('from ament_index_python.packages import get_package_prefix, '
            'get_package_share_directory as share; '
            "print(get_package_prefix('saw_ros')); print(share('saw_ros'))")
    env = dict(os.environ, AMENT_PREFIX_PATH=str(PREFIX))
    out = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    prefix, share = out.stdout.split()
    assert Path(prefix).resolve() == PREFIX.resolve()
    assert (Path(share) / 'msg_config' / 'simulator.yaml').is_file()


@venv_only
def test_bootstrap_environment_exports_the_ament_prefix():
    """
    Check that `source scripts/bootstrap.sh` puts the venv first in AMENT_PREFIX_PATH.

    (The venv exists already: nothing is created.) So ament tools and `ros2 run` see saw_ros.
    """
    env = {k: v for k, v in os.environ.items() if k != 'AMENT_PREFIX_PATH'}
    out = subprocess.run(['bash', '-c', 'source scripts/bootstrap.sh >/dev/null && '
                          'echo "$AMENT_PREFIX_PATH"'], cwd=ROOT, env=env, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert Path(out.stdout.strip().split(os.pathsep)[0]).resolve() == PREFIX.resolve()


@needs_install
@pytest.mark.ros
def test_simulator_runs_from_lib_saw_ros_with_the_installed_config(tmp_path):
    exe = PREFIX / 'lib' / 'saw_ros' / 'simulator'
    config = PREFIX / 'share' / 'saw_ros' / 'msg_config' / 'simulator.yaml'
    out = subprocess.run([str(exe), '--ros-args', '--params-file', str(config), '-p',
                          'duration:=0.05', '-p', 'real_time_factor:=0.0'],
                         env=isolated_ros_env(), capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    assert 'duration 0.05 s reached after 50 steps' in out.stdout + out.stderr


def test_simulator_yaml_lists_every_parameter_with_the_core_defaults():
    """
    msg_config/simulator.yaml = the paper's set-up = the core defaults.

    Nothing missing or unknown (regenerate it with `python -m saw_ros.ros.nodes.simulator
    --write-yaml ...`).
    """
    import yaml

    from saw_ros.core import Scenario
    from saw_ros.ros.nodes.simulator import EXCLUDED, OWN_PARAMETERS
    data = yaml.safe_load((ROOT / 'msg_config' / 'simulator.yaml').read_text())
    params = data['simulator']['ros__parameters']
    flat = {}
    for key, value in params.items():
        if isinstance(value, dict):
            flat.update({f'{key}.{k}': v for k, v in value.items()})
        else:
            flat[key] = value
    expected = {n: v for n, v in Scenario().flat().items() if n not in EXCLUDED}
    expected.update({name: value for name, value, _ in OWN_PARAMETERS})
    assert flat == expected
    # Types as ROS will read them: a double written "0" would be refused as an integer.
    assert all(type(flat[n]) is type(v) for n, v in expected.items())


@pytest.mark.parametrize('node', ['simulator', 'camera', 'vision', 'comparison', 'recorder',
                                  'player', 'speed_controller', 'foxglove_bridge'])
def test_msg_config_yaml_is_generated_from_the_parameter_definitions(node, tmp_path):
    """
    Every node's msg_config/<node>.yaml is generated from its parameter definitions.

    It is what `python -m saw_ros.ros.nodes.<node> --write-yaml` writes from the spec()
    definitions the node declares its parameters from (core.params Scenario, vision TrackerConfig
    / CameraModel / RenderOptions, the node's own table): regenerating gives the same bytes.
    """
    import importlib
    module = importlib.import_module(f'saw_ros.ros.nodes.{node}')
    out = tmp_path / f'{node}.yaml'
    out.write_text(module.yaml_file())
    assert out.read_bytes() == (ROOT / 'msg_config' / f'{node}.yaml').read_bytes(), (
        f'regenerate: python -m saw_ros.ros.nodes.{node} --write-yaml msg_config/{node}.yaml')
