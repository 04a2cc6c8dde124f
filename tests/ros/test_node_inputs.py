"""
Bad input to every node executable: one line naming the input, exit code 1, no traceback.

Issue 20's table, one row per node: a value out of range (the message gives the range with its
unit), a value of the wrong type, a params file that does not exist or is not YAML, an argument
that is not ROS's; a misspelt ``-p`` name is named in a warning and the node runs on; ``--help``
and ``-h`` list the node's parameters from the spec tables it declares, exit 0, start nothing and
write no file. Add a row whenever a user finds a new way in.

A bad input ends a node before it spins, so every node's main meets its bad inputs in one
process (a file per case for its output), which saves starting an interpreter for each of 63
cases; two executables are started for real for the exit code, and the misspelt names run each
node as its own process in the run's isolated DDS domain (tests/conftest.py).
"""
import importlib
import json
import os
from pathlib import Path
import subprocess
import sys

import pytest

from saw_ros.core.params import range_text
from saw_ros.graph.process import ManagedProcess, node_command, wait_for
from saw_ros.ros.nodes import EXECUTABLES

pytestmark = pytest.mark.ros

TIMEOUT = 60


def _frames(folder: Path) -> Path:
    """Return a folder of three small frame images (video_source plays them at -p fps)."""
    import cv2
    import numpy as np
    folder.mkdir()
    for i in range(3):
        cv2.imwrite(str(folder / f'{i:03d}.png'), np.full((48, 64, 3), 40 * i, np.uint8))
    return folder


def _bag(folder: Path) -> Path:
    """Return a small bag (50 ms of /clock and /saw/pose) for the player."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'bag'))
    from test_bag_format import write_bag
    write_bag(folder, n=50)
    return folder


# node: (parameters with which it starts normally, a misspelt name, (name, value out of range,
# the range as the refusal states it), (name, value of the wrong kind, what it must be), and
# whether it ends by itself). Integers are given for doubles on purpose (fps, px_per_m,
# steady_threshold): they are taken as doubles.
CASES = {
    'simulator': ({'duration': 0.02, 'real_time_factor': 0.0}, 'conditons.slope',
                  ('conditions.slope', 2.0, '[-1.5708, 1.5708] rad'),
                  ('real_time_factor', 'fast', 'must be a number in'), True),
    'camera': ({}, 'jpeg_qualty', ('jpeg_quality', 101, '[1, 100]'),
               ('width', 'wide', 'must be an integer in'), False),
    'vision': ({'px_per_m': 1200}, 'plane_distanse', ('plane_distance', 0, '(0, inf) m'),
               ('px_per_m', 'many', 'must be a number in'), False),
    'comparison': ({}, 'report_periode', ('steady_threshold', -1, '(0, inf)'),
                   ('report_period', 'soon', 'must be a number in'), False),
    'recorder': ({'output': '{tmp}/bag'}, 'queue_dept', ('chunk_size', 0, '[1, inf) bytes'),
                 ('queue_depth', 1.5, 'must be an integer in'), False),
    'player': ({'bag': '{bag}', 'rate': 100.0}, 'clock_rat',
               ('clock_rate', 2e6, '(0, 1e+06] Hz'), ('rate', 'fast', 'must be a number in'),
               True),
    'video_source': ({'path': '{frames}', 'fps': 30, 'px_per_m': 1200}, 'px_per_mm',
                     ('px_per_m', -5, '[0, inf) px/m'), ('loop', 'maybe', 'must be true or false'),
                     True),
    'speed_controller': ({}, 'target_sped', ('target_speed', 1, '[-0.5, 0.5] m/s'),
                         ('kp', 'high', 'must be a number in'), False),
    'foxglove_bridge': ({'port': 0}, 'prot', ('port', 70000, '[0, 65535]'),
                        ('hold_until_clock', 'maybe', 'must be true or false'), False),
}


def test_every_executable_has_a_row():
    assert set(CASES) == set(EXECUTABLES)


def _start(argv, cwd):
    return subprocess.Popen(argv, cwd=cwd, env=dict(os.environ), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, text=True)


def _finish(proc):
    try:
        out = proc.communicate(timeout=TIMEOUT)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    return proc.returncode, out


def _filled(params, paths):
    return {k: v.format(**paths) if isinstance(v, str) else v for k, v in params.items()}


# The mistakes decided from the command line alone (runtime.check_command_line, before rclpy
# starts) are the same code in every node: each node's main meets them in one process, its
# output (fd 1 and 2, rcutils writes the FATAL line itself) in a file per case, which saves
# starting 27 interpreters. Values only a started node can judge run as real executables below.
COMMAND_LINE_RUNNER = """
import importlib, json, os, sys
codes = []
for node, argv, cwd, out in json.loads(sys.argv[1]):
    module = importlib.import_module('saw_ros.ros.nodes.' + node)
    sys.stdout.flush(); sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    fd = os.open(out, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
    os.dup2(fd, 1); os.dup2(fd, 2)
    os.chdir(cwd)
    try:
        codes.append(module.main(args=argv))
    finally:
        sys.stdout.flush(); sys.stderr.flush()
        os.dup2(saved[0], 1); os.dup2(saved[1], 2); os.close(fd)
print(json.dumps(codes))
"""


def _mains(cases, tmp_path):
    """Run ``(node, argv, cwd)`` cases through each node's main in one process; (code, out)s."""
    runs = [(node, argv, str(cwd), str(tmp_path / f'out_{i}.txt'))
            for i, (node, argv, cwd) in enumerate(cases)]
    proc = subprocess.run([sys.executable, '-c', COMMAND_LINE_RUNNER, json.dumps(runs)],
                          env=dict(os.environ), stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, text=True,
                          timeout=TIMEOUT, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout
    codes = json.loads(proc.stdout.splitlines()[-1])
    return [(code, Path(out).read_text()) for code, (_, _, _, out) in zip(codes, runs)]


def _one_fatal_line(node, case, code, out, texts):
    lines = [line for line in out.splitlines() if line.strip()]
    assert code == 1, (case, out)
    assert 'Traceback' not in out and len(lines) == 1, (case, out)
    assert lines[0].startswith('[FATAL]') and f'[{node}]:' in lines[0], (case, lines[0])
    for text in texts:
        assert text in lines[0], (case, text, lines[0])


def test_command_line_mistakes_end_every_node_with_one_line(tmp_path):
    """A params file missing or not YAML, an argument not ROS's: every node's main refuses."""
    cases, expected = [], []
    for node in sorted(CASES):
        ok = _filled(CASES[node][0], {'tmp': tmp_path / node, 'bag': tmp_path / 'no_bag',
                                      'frames': tmp_path / 'no_frames'})
        not_yaml = tmp_path / f'{node}_not_yaml.yaml'
        not_yaml.write_text(f'{node}:\n  ros__parameters: [a, b\n')
        missing = tmp_path / f'{node}_missing.yaml'
        table = {
            'params file missing': (node_command(node, params=ok, params_file=missing),
                                    (f'params file {missing} does not exist',)),
            'params file not YAML': (node_command(node, params=ok, params_file=not_yaml),
                                     (f'params file {not_yaml} is not YAML', 'at line')),
            'unknown argument': ([sys.executable, '-m', node, '--frobnicate'],
                                 ('unknown argument --frobnicate', '--ros-args')),
        }
        for case, (argv, texts) in table.items():
            cases.append((node, [node] + argv[3:], tmp_path))
            expected.append((node, case, texts))
    for (node, case, texts), (code, out) in zip(expected, _mains(cases, tmp_path)):
        _one_fatal_line(node, case, code, out, texts)
    assert not any((tmp_path / node).exists() for node in CASES)   # nothing created


def test_a_bad_value_ends_every_node_with_one_line(tmp_path):
    """
    Out of range and of the wrong type: each node's main refuses at its start, exit code 1.

    In the one process of the cases above (each main starts and shuts down rclpy); the exit
    code of a real executable is test_a_bad_value_ends_the_executable below.
    """
    cases, expected = [], []
    for node in sorted(CASES):
        ok, _, (low, value, allowed), (name, wrong, kind), _ = CASES[node]
        work = tmp_path / node
        work.mkdir()
        ok = _filled(ok, {'tmp': work, 'bag': work / 'no_bag', 'frames': work / 'no_frames'})
        table = {   # case: (argv, texts the one line holds)
            'out of range': (node_command(node, params=dict(ok, **{low: value})),
                             (f'{low} = ', 'out of range', f'allowed {allowed}')),
            'wrong type': (node_command(node, params=dict(ok, **{name: wrong})),
                           (f'{name} = {wrong!r} is invalid', kind)),
        }
        for case, (argv, texts) in table.items():
            cases.append((node, [node] + argv[3:], work))
            expected.append((node, case, texts))
    for (node, case, texts), (code, out) in zip(expected, _mains(cases, tmp_path)):
        _one_fatal_line(node, case, code, out, texts)
    assert not any((tmp_path / node / 'bag').exists() for node in CASES)   # recorder: refused


def test_a_bad_value_ends_the_executable(tmp_path):
    """The simulator and the recorder as processes: exit code 1 and the one line."""
    for node in ('simulator', 'recorder'):
        ok, _, (low, value, allowed), _, _ = CASES[node]
        ok = _filled(ok, {'tmp': tmp_path})
        code, out = _finish(_start(node_command(node, params=dict(ok, **{low: value})),
                                   tmp_path))
        _one_fatal_line(node, 'out of range', code, out, (f'{low} = ', 'out of range'))
    assert not (tmp_path / 'bag').exists()


@pytest.mark.parametrize('node', sorted(CASES))
def test_a_misspelt_parameter_is_named_in_a_warning_and_the_node_runs(node, tmp_path):
    ok, typo, _, _, ends = CASES[node]
    paths = {'tmp': tmp_path}
    if node == 'player':
        paths['bag'] = _bag(tmp_path / 'src')
    if node == 'video_source':
        paths['frames'] = _frames(tmp_path / 'frames')
    params = dict(_filled(ok, paths), **{typo: 1.0})
    proc = ManagedProcess(node, node_command(node, params=params), dict(os.environ),
                          tmp_path / 'logs', cwd=tmp_path)
    warned = f'[{node}]: unknown parameter ignored: {typo} '
    if ends:
        code = proc.wait(TIMEOUT)
    else:
        assert wait_for(lambda: warned in proc.output() or proc.returncode is not None,
                        TIMEOUT), proc.output()
        code = proc.stop()
    out = proc.output()
    assert code == 0, out
    assert warned in out and 'Traceback' not in out, out
    if node == 'video_source':      # the integers for px_per_m and fps were taken
        assert 'published 3 frames (0.100 s of video' in out, out
        assert 'CameraInfo K is zero' not in out, out


def _entries(node):
    module = importlib.import_module(f'saw_ros.ros.nodes.{node}')
    return list(module.parameters() if hasattr(module, 'parameters') else module.PARAMETERS)


def _check_help(node, code, out, work):
    assert code == 0, out
    assert out.startswith(f'usage: {node} '), out
    assert '[INFO]' not in out and 'Traceback' not in out, out
    assert list(work.iterdir()) == [], 'a file was written'
    lines = out.splitlines()
    for name, default, meta in _entries(node):
        line = next((x for x in lines if x.startswith(f'  {name}: ')), None)
        assert line is not None, f'{name} missing from the help:\n{out}'
        numeric = isinstance(default, (int, float)) and not isinstance(default, bool)
        if numeric:
            assert range_text(dict(meta, unit='')) in line, line
            assert f'default {default!r}' in line, line
        if meta.get('unit'):
            assert f'[{meta["unit"]}]' in line, line


def test_help_lists_the_parameters_and_starts_nothing(tmp_path):
    """Every node's -h or --help, each in a folder of its own that stays empty."""
    cases = []
    for node in sorted(CASES):
        work = tmp_path / node
        work.mkdir()
        flag = '-h' if node in ('camera', 'player', 'vision') else '--help'
        cases.append((node, [node, flag], work))
    for (node, _, work), (code, out) in zip(cases, _mains(cases, tmp_path)):
        _check_help(node, code, out, work)


def test_help_from_the_console_script(tmp_path):
    """The console script ros2 run starts (bin/recorder), as a real process."""
    script = Path(sys.executable).parent / 'recorder'
    if not script.exists():
        pytest.skip(f'no console script at {script} (the package is not installed here)')
    work = tmp_path / 'cwd'
    work.mkdir()
    code, out = _finish(_start([str(script), '--help'], work))
    _check_help('recorder', code, out, work)


def test_simulator_help_publishes_nothing(tmp_path, ros_context):
    """The same subscriber sees a simulator run, and nothing from a simulator asked for help."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rosgraph_msgs.msg import Clock

    from saw_ros.interface import topics
    from saw_ros.ros.qos import CLOCK_QOS
    node = Node('help_listener', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    got = []
    node.create_subscription(Clock, topics.CLOCK, got.append, CLOCK_QOS)
    spin = lambda t: executor.spin_once(timeout_sec=t)    # noqa: E731
    params = {'duration': 3.0, 'real_time_factor': 1.0}
    try:
        helped = _start(node_command('simulator', params=params) + ['--help'], tmp_path)
        code, out = _finish(helped)
        assert code == 0, out
        # A negative, so a bound: a simulator started by --help would have run until its
        # duration before exiting, and what it published would wait in this subscription.
        assert not wait_for(lambda: got, 1.0, spin=spin), 'the simulator published'
        run = _start(node_command('simulator', params=params), tmp_path)
        assert wait_for(lambda: got, TIMEOUT, spin=spin), 'this subscriber sees nothing'
        run.terminate()
        assert _finish(run)[0] == 0
    finally:
        executor.shutdown()
        node.destroy_node()
