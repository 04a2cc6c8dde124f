"""Simulator node throughput: the highest real-time factor it sustains with zero lost messages.

For each real_time_factor of a ladder, the simulator node runs ``duration`` of simulated time
(60 s; 10 s with --quick) as a subprocess, and ONE subscriber process takes every topic (/clock and the
five /saw streams; reliable, a 1000-message queue (1 s at 1 kHz) as a recorder would use, raw
CDR as rosbag2 records it). The subscriber counts every stamp of every topic:
lost = expected - received in-order unique stamps. A factor is sustained when nothing is lost and
the simulated time advanced at least 97 % as fast as asked. The ladder stops at the first factor
that fails; ``sim_max_realtime_factor`` is the last one sustained (0 if even the first fails),
``sim_lost_messages`` the messages lost at real_time_factor 1.0.

Both processes and the bench share a 2-core machine with whatever else runs: figures are noisy.
A rung whose simulator or subscriber does not exit in time is a failed rung (``hung`` names the
process, ``simulator_state`` says how far its log got, ``simulator_cpu_at_timeout`` whether it
was still stepping: a loaded machine that runs it below a third of the asked factor, or stuck);
the processes are stopped and their logs kept in ``log_dir('simulator_node')/rtf_<factor>/``
(the bench prints the folder).
"""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

KEYS = ('sim_max_realtime_factor', 'sim_lost_messages')
SUBSCRIBER_DEPTH = 1000     # 1 s at 1 kHz: rides out the scheduling hiccups of a shared machine
LADDER = (1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0)


def subscriber(steps: int, timeout: float) -> int:
    """Child process: subscribe to every topic, count stamps, print one JSON line, exit."""
    import struct

    import rclpy
    from rclpy.node import Node

    from rclpy.qos import QoSProfile, ReliabilityPolicy

    rclpy.init()
    node = Node('bench_subscriber')
    unpack = struct.Struct('<iI').unpack_from
    step_ns = 1_000_000
    from saw_ros.nodes.simulator import TOPICS
    state = {t: {'count': 0, 'last': 0, 'bad': 0, 'first': 0, 'gaps': 0} for t in TOPICS}
    wall = {'first': None, 'last': None}

    def make_callback(topic):
        s = state[topic]

        def callback(raw):
            sec, nanosec = unpack(raw, 4)
            stamp = sec * 1_000_000_000 + nanosec
            if stamp > s['last']:
                s['count'] += 1
                if s['first'] == 0:
                    s['first'] = stamp // step_ns
                elif stamp - s['last'] != step_ns:
                    s['gaps'] += 1
            else:
                s['bad'] += 1          # a repeat or a step out of order
            s['last'] = stamp
            now = time.monotonic()
            if wall['first'] is None:
                wall['first'] = now
            wall['last'] = now
        return callback

    for topic, cls in TOPICS.items():
        qos = QoSProfile(depth=SUBSCRIBER_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
        node.create_subscription(cls, topic, make_callback(topic), qos, raw=True)
    # rclpy's EventsExecutor (C++, Jazzy: experimental) takes messages several times faster than
    # the SingleThreadedExecutor, whose per-message overhead would be what is measured.
    from saw_ros.nodes.common import make_executor
    executor = make_executor()
    executor.add_node(node)
    end = steps * step_ns
    deadline = time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
            if all(s['last'] >= end for s in state.values()):
                break
            if wall['last'] is not None and time.monotonic() - wall['last'] > 3.0:
                break                  # the publisher is gone
    except KeyboardInterrupt:
        pass
    span = (wall['last'] - wall['first']) if wall['first'] is not None else 0.0
    lost = sum(steps - s['count'] for s in state.values())
    print(json.dumps({'lost': lost, 'bad': sum(s['bad'] for s in state.values()),
                      'received': sum(s['count'] for s in state.values()),
                      'achieved_rtf': (steps - 1) * 1e-3 / span if span > 0 else 0.0,
                      'per_topic': {t: (s['count'], s['first'], s['gaps'])
                                    for t, s in state.items()}}), flush=True)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


def simulator_state(log: str) -> str:
    """How far a simulator's log got: where a rung that hung stood."""
    if 'subscribers present' not in log and 'waiting for' in log:
        return 'never started stepping (waiting for subscribers: discovery)'
    if 'reached after' not in log:
        return 'stepping, duration not reached'
    return 'duration reached, did not exit (stop path)'


def _cpu_share(pid: int, span: float = 1.0) -> float:
    """Fraction of a core ``pid`` uses over ``span`` s (nan if unreadable): a simulator still
    stepping (too slow for the timeout) uses CPU, one that is stuck does not."""
    import os

    def cpu():
        with open(f'/proc/{pid}/stat') as f:
            fields = f.read().rsplit(')', 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')
    try:
        c0, t0 = cpu(), time.monotonic()
        time.sleep(span)
        return round((cpu() - c0) / (time.monotonic() - t0), 3)
    except (OSError, IndexError, ValueError):
        return float('nan')


def _wait(proc, timeout: float):
    """Exit code, or None if ``proc`` is still running after ``timeout`` s."""
    try:
        return proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        return None


def measure(rtf: float, duration: float, log_dir: Path, timeout: float = None) -> dict:
    """One rung: simulator + subscriber processes in a private domain. Never raises for a
    process that hangs: the rung fails (``hung``) and the processes are stopped. ``timeout``:
    for the simulator (default 3 x the expected wall time + 30 s)."""
    from ..process import ManagedProcess, isolated_ros_env, node_command
    from . import tail
    env = isolated_ros_env()
    steps = int(round(duration * 1000))
    if timeout is None:
        timeout = duration / rtf * 3 + 30
    logs = Path(log_dir) / f'rtf_{rtf:g}'
    sub = ManagedProcess('subscriber', [sys.executable, '-m', __name__, '--subscriber',
                                        str(steps), str(timeout)], env, logs)
    sim = ManagedProcess('simulator', node_command('simulator', params={
        'real_time_factor': float(rtf), 'duration': float(duration), 'wait_for_subscribers': 1}),
        env, logs)
    result = {'rtf': rtf}
    hung = []
    try:
        sim_code = _wait(sim, timeout)
        if sim_code is None:
            hung.append(f'simulator did not exit within {timeout:.0f} s')
            result['simulator_state'] = simulator_state(sim.output())
            result['simulator_cpu_at_timeout'] = _cpu_share(sim.proc.pid)
        if _wait(sub, 30.0 if sim_code is not None else 5.0) is None:
            hung.append('subscriber did not exit')
    finally:
        for proc in (sim, sub):
            if proc.returncode is None:
                proc.stop(timeout=5)
    result['simulator_exit'] = sim.returncode
    for line in sub.output().splitlines():
        if line.startswith('{'):
            result.update(json.loads(line))
    result.setdefault('lost', 6 * steps)
    result['behind_warnings'] = sim.output().count('falling behind')
    if hung:
        result['hung'] = '; '.join(hung)
        result['logs'] = str(logs)
        result['simulator_log_tail'] = tail(sim.log_path, 3)
    result['sustained'] = (not hung and sim_code == 0 and result['lost'] == 0
                           and result.get('bad', 1) == 0
                           and result.get('achieved_rtf', 0.0) >= 0.97 * rtf)
    return result


def run(quick: bool = False) -> dict:
    from . import log_dir
    duration = 10.0 if quick else 60.0
    best, lost_at_1 = 0.0, None
    logs = log_dir('simulator_node')
    for rtf in LADDER:
        result = measure(rtf, duration, logs)
        print(f'bench simulator_node: {json.dumps(result)}', file=sys.stderr, flush=True)
        if rtf == 1.0:
            lost_at_1 = result['lost']
        if not result['sustained']:
            break
        best = rtf
    return {'sim_max_realtime_factor': best, 'sim_lost_messages': lost_at_1}


if __name__ == '__main__':
    if len(sys.argv) == 4 and sys.argv[1] == '--subscriber':
        raise SystemExit(subscriber(int(sys.argv[2]), float(sys.argv[3])))
    print(json.dumps(run(quick='--quick' in sys.argv)))
