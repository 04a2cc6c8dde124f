"""`ros2 run` readiness of the pip install (scripts/bootstrap.sh): executables where ros2 run looks
(<prefix>/lib/saw_ros/<exe>), the ament index entry, package.xml format 3, the shared config."""
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from saw_ros.process import isolated_ros_env

ROOT = Path(__file__).resolve().parents[1]
PREFIX = Path(sys.prefix)          # the venv is laid out like a ROS install prefix


def console_scripts():
    text = (ROOT / 'setup.py').read_text()
    nodes = re.search(r"NODES = \(([^)]*)\)", text).group(1)
    return re.findall(r"'([a-z_]+)'", nodes)


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
    assert "msg_config" in text
    assert (ROOT / 'resource' / 'saw_ros').is_file()
    assert 'script_dir=$base/lib/saw_ros' in (ROOT / 'setup.cfg').read_text()
    assert 'simulator' in console_scripts()


@pytest.mark.parametrize('exe', console_scripts())
def test_executables_where_ros2_run_looks(exe):
    path = PREFIX / 'lib' / 'saw_ros' / exe
    assert path.exists(), f'{path} missing: run scripts/bootstrap.sh'
    assert os.access(path, os.X_OK), f'{path} is not executable'


def test_ament_index_finds_the_package_with_the_bootstrap_environment():
    script = ('source scripts/bootstrap.sh >/dev/null && python -c "'
              'from ament_index_python.packages import get_package_prefix, '
              'get_package_share_directory as share; '
              "print(get_package_prefix('saw_ros')); print(share('saw_ros'))\"")
    out = subprocess.run(['bash', '-c', script], cwd=ROOT, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    prefix, share = out.stdout.split()
    assert Path(prefix).resolve() == PREFIX.resolve()
    assert (Path(share) / 'package.xml').is_file()
    assert (Path(share) / 'msg_config' / 'simulator.yaml').is_file()


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
    """msg_config/simulator.yaml = the paper's set-up = the core defaults, nothing missing or
    unknown (regenerate it with `python -m saw_ros.nodes.simulator --write-yaml ...`)."""
    import yaml

    from saw_ros.core import Scenario
    from saw_ros.nodes.simulator import EXCLUDED, OWN_PARAMETERS
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
