"""The tree's layers: imports point down only, and the pure layers never load rclpy."""
import ast
from pathlib import Path
import re
import subprocess
import sys

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / 'saw_ros'
# Each layer may import itself and the layers listed (transitively below it).
ALLOWED = {
    'core': set(),
    'interface': {'core'},
    'vision': {'core'},
    'bag': {'interface'},
    'analysis': {'core', 'vision', 'interface', 'bag'},
    'ros': {'core', 'vision', 'interface', 'bag', 'analysis'},
    'graph': {'interface', 'bag'},
    'cli': {'core', 'vision', 'interface', 'bag', 'analysis', 'graph'},
    'bench': {'core', 'vision', 'interface', 'bag', 'analysis', 'ros', 'graph', 'cli'},
}
PURE = ('core', 'interface', 'vision', 'bag', 'analysis', 'graph', 'cli')
ROS_MODULES = ('rclpy', 'rcl', 'rosidl_runtime_py', 'rpyutils')


def layer_of(module: str) -> str:
    parts = module.split('.')
    return parts[1] if len(parts) > 1 and parts[0] == 'saw_ros' else ''


def saw_ros_imports(path: Path):
    """Every ``saw_ros...`` module a file imports, at the top or inside a function."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module.startswith('saw_ros'):
                yield node.lineno, node.module
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith('saw_ros'):
                    yield node.lineno, alias.name


def test_every_module_is_in_a_known_layer():
    top = {p.name for p in PACKAGE.iterdir() if not p.name.startswith('__')}
    assert top == set(ALLOWED), 'a new top-level folder needs its place in ALLOWED'


@pytest.mark.parametrize('layer', sorted(ALLOWED))
def test_imports_point_down_only(layer):
    wrong = []
    for path in sorted((PACKAGE / layer).rglob('*.py')):
        for line, module in saw_ros_imports(path):
            target = layer_of(module)
            if target and target != layer and target not in ALLOWED[layer]:
                wrong.append(f'{path.relative_to(PACKAGE.parent)}:{line} imports {module}')
    assert not wrong, '\n'.join(wrong)


def ros_imports(path: Path):
    """Yield each import of a ROS module or *_msgs package in a file, at top level or in a def."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        else:
            continue
        for name in names:
            top = name.split('.')[0]
            if top in ROS_MODULES or top.endswith('_msgs'):
                yield node.lineno, name


@pytest.mark.parametrize('layer', PURE)
def test_pure_layers_import_no_rclpy_even_inside_a_function(layer):
    # What the next test cannot see: an import that runs only when a command needs it (saw-ros
    # bag record checked topic names with rclpy so, which a machine without ROS could not run).
    wrong = [f'{path.relative_to(PACKAGE.parent)}:{line} imports {name}'
             for path in sorted((PACKAGE / layer).rglob('*.py'))
             for line, name in ros_imports(path)]
    assert not wrong, '\n'.join(wrong)


def test_pure_layers_import_no_rclpy():
    code = f"""
import importlib, pkgutil, sys
for layer in {PURE!r}:
    package = importlib.import_module('saw_ros.' + layer)
    for m in pkgutil.walk_packages(package.__path__, package.__name__ + '.'):
        importlib.import_module(m.name)
bad = sorted(m for m in sys.modules if m.split('.')[0] in {ROS_MODULES!r}
             or m.split('.')[0].endswith('_msgs'))
print(bad)
"""
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == '[]'


def test_the_nodes_that_do_not_step_the_physics_start_without_numba():
    """Camera, vision and comparison read the core's tables, not its kernels (core.tips)."""
    code = """
import sys
import saw_ros.ros.nodes.camera, saw_ros.ros.nodes.comparison, saw_ros.ros.nodes.vision
print(sorted(m for m in sys.modules if m.split('.')[0] in ('numba', 'llvmlite')))
"""
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == '[]', result.stdout[:500]


def test_the_readme_names_the_layers_as_this_test_does():
    text = ' '.join((PACKAGE.parent / 'README.md').read_text().split())
    below_ros = re.search(r'Imports point down only: (.*?) are the pure layers below `ros`', text)
    assert below_ros, 'README.md: the sentence "Imports point down only: ..." is gone'
    assert set(re.findall(r'`(\w+)`', below_ros.group(1))) == ALLOWED['ros']
    no_rclpy = re.search(r'Layers that never load rclpy \([^)]*\): ([^.]*)\.', text)
    assert no_rclpy, 'README.md: the sentence "Layers that never load rclpy ..." is gone'
    assert tuple(re.findall(r'`(\w+)`', no_rclpy.group(1))) == PURE
