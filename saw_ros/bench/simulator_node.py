"""
Simulator node throughput: the highest real-time factor it sustains with zero lost messages.

For each real_time_factor of a ladder, the simulator node runs ``duration`` of simulated time (60
s; 10 s with --quick) as a subprocess, and ONE subscriber process takes every topic (/clock and the
five /saw streams; reliable, a 1000-message queue (1 s at 1 kHz) as a recorder would use, raw CDR
as rosbag2 records it). The subscriber counts every stamp of every topic: lost = expected -
received in-order unique stamps. A factor is sustained when nothing is lost and the simulated time
advanced at least 97 % as fast as asked. The ladder stops at the first factor that fails;
``sim_max_realtime_factor`` is the last one sustained (0 if even the first fails; the ladder
goes up to 50, ``sim_max_realtime_factor_is_lower_bound`` true when even that held, so that the
figure is the ladder's top, not the node's), ``sim_lost_messages`` the messages lost at
real_time_factor 1.0.

Both processes and the bench share a 2-core machine with whatever else runs: figures are noisy.
A rung whose simulator or subscriber does not exit in time is a failed rung (``hung`` names the
process, ``simulator_state`` says how far its log got, ``simulator_cpu_at_timeout`` whether it
was still stepping: a loaded machine that runs it below a third of the asked factor, or stuck);
the processes are stopped and their logs kept in ``log_dir('simulator_node')/rtf_<factor>/``
(the bench prints the folder). The rung's random DDS domain can be one another run on the
machine uses (concurrent tests, a demo): the subscriber looks for publishers of our topics
before subscribing and the rung moves to another domain (``busy_domains``); before, the other
simulator's messages were counted as ours and kept the subscriber alive past the rung, and
``sub.wait(30)`` raised TimeoutExpired out of the bench.
"""
from __future__ import annotations

import json
from pathlib import Path
import signal
import subprocess
import sys
import time
from typing import Any, Dict, Optional

KEYS = ('sim_max_realtime_factor', 'sim_lost_messages', 'sim_max_realtime_factor_is_lower_bound',
        'simulator_start_s')
SUBSCRIBER_DEPTH = 1000     # 1 s at 1 kHz: rides out the scheduling hiccups of a shared machine
# Up to a factor far above what this machine reaches (about 2-5): the top of the ladder must not
# be what is measured. When even the top rung holds, the figure is a lower bound (and says so).
LADDER = (1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 16.0, 20.0, 25.0, 30.0,
          40.0, 50.0)


BUSY_EXIT = 3               # the subscriber's exit code when its DDS domain is in use already
PROBE_S = 1.0               # s the subscriber looks for other publishers before subscribing


def steps_between(topic: str) -> int:
    """Return the simulator's steps between two messages on ``topic`` (joint states: 10)."""
    from saw_ros.interface import topics
    from saw_ros.ros.nodes.simulator import JOINT_STATES_RATE
    return round(1000 / JOINT_STATES_RATE) if topic == topics.JOINT_STATES else 1


def expected_messages(steps: int) -> int:
    """Return the messages the simulator publishes in ``steps`` steps on its stepped topics."""
    from saw_ros.ros.nodes.simulator import TOPICS
    return sum(steps // steps_between(t) for t in TOPICS)


def subscriber(steps: int, timeout: float) -> int:
    """
    Child process: subscribe to every topic, count stamps, print one JSON line, exit.

    First it makes sure no other process publishes our topics in its domain: the random domain
    ids of concurrent runs collide on a shared machine, and another simulator's messages then
    count as ours (received > sent) and kept this process alive past the rung (HEAD of issue 10:
    the bench's sub.wait(30) raised TimeoutExpired). Busy: prints 'domain busy', exits BUSY_EXIT
    and measure() retries in another domain. Else it prints 'subscribed' (measure() starts the
    simulator then) and counts until every topic has delivered the last step, 3 s pass without a
    message, the deadline, or SIGINT/SIGTERM from measure() once the simulator has exited.
    """
    import signal
    import struct

    import rclpy
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    from saw_ros.ros.nodes.simulator import TOPICS
    from saw_ros.graph.process import wait_for

    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.append(True))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = Node('bench_subscriber')
    busy = lambda: {t: n for t in TOPICS if (n := node.count_publishers(t))}  # noqa: E731
    if wait_for(lambda: bool(busy()), PROBE_S):
        print(f'domain busy: publishers of {busy()} already', flush=True)
        node.destroy_node()
        rclpy.try_shutdown()
        return BUSY_EXIT
    unpack = struct.Struct('<iI').unpack_from
    step_ns = 1_000_000
    state = {t: {'count': 0, 'last': 0, 'bad': 0, 'first': 0, 'gaps': 0, 'end': False}
             for t in TOPICS}
    every = {t: steps_between(t) for t in TOPICS}
    wall = {'first': None, 'last': None, 'clock': None}

    def make_callback(topic):
        s = state[topic]
        spacing = every[topic] * step_ns

        def callback(raw):
            sec, nanosec = unpack(raw, 4)
            stamp = sec * 1_000_000_000 + nanosec
            if stamp > s['last']:
                s['count'] += 1
                if s['first'] == 0:
                    s['first'] = stamp // step_ns
                elif stamp - s['last'] != spacing:
                    s['gaps'] += 1
            else:
                s['bad'] += 1          # a repeat or a step out of order
            s['last'] = stamp
            if stamp >= end - end % spacing:
                s['end'] = True
            now = time.monotonic()
            if wall['first'] is None:
                wall['first'] = now
            if wall['clock'] is None and topic == '/clock':
                wall['clock'] = now
            wall['last'] = now
        return callback

    end = steps * step_ns
    subs = []
    for topic, cls in TOPICS.items():
        qos = QoSProfile(depth=SUBSCRIBER_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
        subs.append(node.create_subscription(cls, topic, make_callback(topic), qos, raw=True))
    # rclpy's EventsExecutor (C++, Jazzy: experimental) takes messages several times faster than
    # the SingleThreadedExecutor, whose per-message overhead would be what is measured.
    from saw_ros.ros.runtime import make_executor
    executor = make_executor()
    executor.add_node(node)
    print('subscribed', flush=True)
    deadline = time.monotonic() + timeout
    publishers = 0                     # the most publishers any topic had: 1 = ours only
    while time.monotonic() < deadline and not stop:
        executor.spin_once(timeout_sec=0.1)
        publishers = max([publishers] + [sub.get_publisher_count() for sub in subs])
        if all(s['end'] for s in state.values()):
            break
        if wall['last'] is not None and time.monotonic() - wall['last'] > 3.0:
            break                      # the publisher is gone
    span = (wall['last'] - wall['first']) if wall['first'] is not None else 0.0
    lost = sum(steps // every[t] - s['count'] for t, s in state.items())
    print(json.dumps({'lost': lost, 'bad': sum(s['bad'] for s in state.values()),
                      'received': sum(s['count'] for s in state.values()),
                      'achieved_rtf': (steps - 1) * 1e-3 / span if span > 0 else 0.0,
                      'publishers': publishers, 'first_clock_monotonic': wall['clock'],
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
    """
    Fraction of a core ``pid`` uses over ``span`` s (nan if unreadable).

    A simulator still stepping (too slow for the timeout) uses CPU, one that is stuck does not.
    """
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


def measure(rtf: float, duration: float, log_dir: Path, timeout: Optional[float] = None,
            attempts: int = 3) -> dict:
    """
    One rung: simulator + subscriber processes in a private domain.

    Never raises for a process that hangs: the rung fails (``hung``) and the processes are stopped.
    ``timeout``: for the simulator (default 3 x the expected wall time + 30 s). A domain that
    another run uses already (the subscriber finds publishers of our topics before ours starts, or
    more than one publisher during the rung) is tried again in another, ``attempts`` times in all.
    """
    from saw_ros.bench import tail
    logs = Path(log_dir) / f'rtf_{rtf:g}'
    busy = []
    for _ in range(attempts):
        result = _rung(rtf, duration, logs, timeout)
        if not result.get('domain_busy') and result.get('publishers', 1) <= 1:
            break
        busy.append(result['domain'])
        print(f'bench simulator_node: domain {result["domain"]} in use by another run; trying '
              f'another', file=sys.stderr, flush=True)
    if busy:
        result['busy_domains'] = busy
    if result.get('domain_busy') or result.get('publishers', 1) > 1:
        result['sustained'] = False
        result['problem'] = (f'every domain tried ({busy}) was in use by another run: its '
                             f'messages would count as ours')
    if 'hung' in result:
        result['simulator_log_tail'] = tail(logs / 'simulator.log', 3)
    return result


def _rung(rtf: float, duration: float, logs: Path, timeout) -> dict:
    from saw_ros.graph.process import ManagedProcess, isolated_ros_env, node_command, wait_for
    env = isolated_ros_env()
    steps = int(round(duration * 1000))
    if timeout is None:
        timeout = duration / rtf * 3 + 30
    result: Dict[str, Any] = {'rtf': rtf, 'domain': int(env['ROS_DOMAIN_ID'])}
    # By module name: __name__ is '__main__' when this file runs as `python -m ...`.
    sub = ManagedProcess('subscriber', [sys.executable, '-m', 'saw_ros.bench.simulator_node',
                                        '--subscriber', str(steps), str(timeout)], env, logs)
    sim = None
    hung = []
    sim_code = None
    started = 0.0
    try:
        wait_for(lambda: sub.returncode is not None or 'subscribed' in sub.output(), 30)
        if 'domain busy' in sub.output():
            _wait(sub, 10)
            result['domain_busy'] = True
            return result
        if sub.returncode is not None and 'subscribed' not in sub.output():
            from saw_ros.bench import tail
            result['problem'] = f'subscriber exited with {sub.returncode}: {tail(sub.log_path, 2)}'
        elif 'subscribed' not in sub.output():
            hung.append('subscriber did not start within 30 s')
        else:
            started = time.monotonic()      # the system-wide clock the subscriber stamps with
            sim = ManagedProcess('simulator', node_command('simulator', params={
                'real_time_factor': float(rtf), 'duration': float(duration),
                'wait_for_subscribers': 1}), env, logs)
            sim_code = _wait(sim, timeout)
            if sim_code is None:
                hung.append(f'simulator did not exit within {timeout:.0f} s')
                result['simulator_state'] = simulator_state(sim.output())
                result['simulator_cpu_at_timeout'] = _cpu_share(sim.proc.pid)
            # The simulator is done: the subscriber has every message it will get (the
            # simulator waited for acknowledgements); give it 10 s to notice, then tell it.
            if _wait(sub, 10.0 if sim_code is not None else 0.0) is None:
                sub.signal(signal.SIGINT)
                if _wait(sub, 10.0) is None:
                    hung.append('subscriber did not exit')
    finally:
        for proc in (sim, sub):
            if proc is not None and proc.returncode is None:
                proc.stop(timeout=5)
    result['simulator_exit'] = sim.returncode if sim is not None else None
    for line in sub.output().splitlines():
        if line.startswith('{'):
            result.update(json.loads(line))
    result.setdefault('lost', expected_messages(steps))     # the subscriber said nothing
    if sim is not None and result.get('first_clock_monotonic') is not None:
        result['start_s'] = result['first_clock_monotonic'] - started
    result['behind_warnings'] = sim.output().count('falling behind') if sim is not None else 0
    if hung:
        result['hung'] = '; '.join(hung)
        result['logs'] = str(logs)
    if 'problem' in result:
        result['logs'] = str(logs)
    result['sustained'] = (not hung and sim_code == 0 and result['lost'] == 0
                           and result.get('bad', 1) == 0 and result.get('publishers', 1) <= 1
                           and result.get('achieved_rtf', 0.0) >= 0.97 * rtf)
    return result


def run(quick: bool = False) -> dict:
    from saw_ros.bench import log_dir
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
    return {'sim_max_realtime_factor': best, 'sim_lost_messages': lost_at_1,
            'sim_max_realtime_factor_is_lower_bound': best == LADDER[-1],
            'simulator_start_s': start_time(logs)}


def start_time(logs: Path, runs: int = 3) -> Optional[float]:
    """
    Return s from starting the simulator node's process to its first /clock (best of ``runs``).

    Kernels loaded from their disk cache (the runs before compiled them). A subscriber is
    already waiting (the node waits for one): its discovery is part of the figure, as it is of
    any run. None when no run delivered a /clock.
    """
    starts = [measure(1.0, 1.0, logs).get('start_s') for _ in range(runs)]
    got = [s for s in starts if s is not None]
    return round(min(got), 3) if got else None


if __name__ == '__main__':
    if len(sys.argv) == 4 and sys.argv[1] == '--subscriber':
        raise SystemExit(subscriber(int(sys.argv[2]), float(sys.argv[3])))
    print(json.dumps(run(quick='--quick' in sys.argv)))
