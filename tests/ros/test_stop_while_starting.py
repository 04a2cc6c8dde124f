"""
A Ctrl-C or SIGTERM while an executable is still importing ends it with exit code 0.

The signal goes out the moment the process catches SIGTERM (``saw_ros.ros.nodes`` took the
signals), which is while numpy, OpenCV and rclpy are still being imported; Python's defaults
would end it with a KeyboardInterrupt traceback or -15.
"""
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest
from saw_ros.graph.process import isolated_ros_env
from saw_ros.ros.nodes import EXECUTABLES, starting_as_executable

SIGTERM_BIT = 1 << (signal.SIGTERM - 1)


def catches_sigterm(pid: int) -> bool:
    status = Path(f'/proc/{pid}/status').read_text()
    caught = next(line for line in status.splitlines() if line.startswith('SigCgt:'))
    return bool(int(caught.split()[1], 16) & SIGTERM_BIT)


def command(executable: str, how: str):
    if how == 'module':
        return [sys.executable, '-m', f'saw_ros.ros.nodes.{executable}']
    script = Path(sys.executable).parent / executable    # the console script, as ros2 run
    if not script.exists():
        pytest.skip(f'no console script {script} here')
    return [str(script)]


@pytest.mark.skipif(not Path('/proc/self/status').exists(), reason='reads /proc')
@pytest.mark.parametrize('executable,how,sig', [
    ('simulator', 'module', signal.SIGINT), ('recorder', 'module', signal.SIGTERM),
    ('camera', 'script', signal.SIGINT), ('vision', 'script', signal.SIGTERM)])
def test_a_stop_during_the_imports_exits_0(tmp_path, executable, how, sig):
    argv = command(executable, how)
    if executable == 'recorder':
        argv += ['--ros-args', '-p', f'output:={tmp_path / "bag"}']
    proc = subprocess.Popen(argv, env=isolated_ros_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 20
        while not catches_sigterm(proc.pid):
            assert proc.poll() is None and time.monotonic() < deadline, 'it never took SIGTERM'
            time.sleep(0.001)
        proc.send_signal(sig)
        # still importing: rcl's library not even loaded
        assert 'librcl.so' not in Path(f'/proc/{proc.pid}/maps').read_text()
        out = proc.communicate(timeout=30)[0].decode(errors='replace')
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, out
    assert 'Traceback' not in out, out


def test_only_the_executables_take_the_signals():
    assert starting_as_executable('-m')
    for name in EXECUTABLES:
        assert starting_as_executable(f'/opt/ros/jazzy/lib/saw_ros/{name}')
    for argv0 in ('/usr/bin/pytest', '/x/bin/saw-ros', os.path.join('bin', 'python'), ''):
        assert not starting_as_executable(argv0)
    # this process (pytest) imported saw_ros.ros.nodes and kept its own handler
    from saw_ros.ros import runtime
    assert signal.getsignal(signal.SIGTERM) is not runtime._on_stop_signal


def test_a_stop_while_the_executor_is_built_leaves_no_traceback(monkeypatch):
    # run_node's handler raises KeyboardInterrupt between two bytecodes; landing inside rclpy's
    # SingleThreadedExecutor.__init__ (before it sets _sigint_gc), the half-built executor's
    # __del__ printed "Exception ignored in ... no attribute '_sigint_gc'" with a traceback.
    import gc

    import rclpy
    from rclpy import executors
    from rclpy.context import Context
    from saw_ros.ros.runtime import single_threaded_executor

    def interrupted(context):
        raise KeyboardInterrupt

    unraisable = []
    monkeypatch.setattr(sys, 'unraisablehook', unraisable.append)
    monkeypatch.setattr(executors, 'SignalHandlerGuardCondition', interrupted)
    context = Context()
    rclpy.init(context=context)
    try:
        with pytest.raises(KeyboardInterrupt):
            single_threaded_executor(context)
        gc.collect()
    finally:
        context.try_shutdown()
    assert not unraisable, [str(u.exc_value) for u in unraisable]
