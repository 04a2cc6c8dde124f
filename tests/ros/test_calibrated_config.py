"""The simulator node runs on msg_config/simulator_calibrated.yaml with --params-file."""
import subprocess
import sys

import pytest

from saw_ros.graph.process import isolated_ros_env
from saw_ros.interface.config import config_path, load_scenario


@pytest.mark.ros
def test_simulator_node_takes_the_calibrated_parameter_file():
    path = config_path('simulator_calibrated.yaml')
    motor = load_scenario(path).motor
    out = subprocess.run([sys.executable, '-m', 'saw_ros.ros.nodes.simulator', '--ros-args',
                          '--params-file', str(path), '-p', 'duration:=0.05', '-p',
                          'real_time_factor:=0.0', '-p', 'motor.voltage:=6.0'],
                         env=isolated_ros_env(), capture_output=True, text=True, timeout=60)
    log = out.stdout + out.stderr
    assert out.returncode == 0, log
    assert 'duration 0.05 s reached after 50 steps' in log
    # The helix runs on the calibrated motor: its no-load frequency at 6 V, from the file.
    assert f'helix {motor.frequency(6.0):g} Hz' in log
