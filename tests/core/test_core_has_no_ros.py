"""The physics core (and the other ROS-free layers) must import without rclpy."""
import subprocess
import sys

CODE = '''
import sys, importlib, pkgutil
import saw_ros.core
for m in pkgutil.iter_modules(saw_ros.core.__path__):
    importlib.import_module('saw_ros.core.' + m.name)
import saw_ros.interface.config, saw_ros.graph.process
bad = sorted(m for m in sys.modules if m.split('.')[0] in ('rclpy', 'rosidl_runtime_py', 'rcl'))
print(bad)
sys.exit(1 if bad else 0)
'''


def test_core_imports_no_rclpy():
    result = subprocess.run([sys.executable, '-c', CODE], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.strip() == '[]'
