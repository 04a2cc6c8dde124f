"""
Starting and stopping ROS 2 processes without launch: isolated DDS, clean shutdown.

Used by the main job (``saw-ros demo``), the benchmarks and the integration tests. No rclpy import.

A node started in the background of a non-interactive shell ignores SIGINT, so every child gets
its own session (``start_new_session``) and is stopped with SIGINT to its process group, then
SIGTERM, then SIGKILL after timeouts (``docs/ros-notes.md``).
"""
from __future__ import annotations

import collections
import fcntl
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import tempfile
import time
from typing import Callable, Dict, IO, List, Optional, Sequence


# Domain ids 1-100 keep Fast DDS's port arithmetic valid.
DOMAIN_IDS = range(1, 101)
DOMAIN_LOCKS = Path(tempfile.gettempdir()) / 'saw_ros_domains'
HELD_DOMAINS = 16            # reservations one process keeps before it reuses its oldest
_held: 'collections.OrderedDict[int, IO[str]]' = collections.OrderedDict()
_kept: Dict[int, IO[str]] = {}   # reservations held until the process exits (keep=True)


def reserve_domain(keep: bool = False) -> int:
    """
    Return a DDS domain id that no other run of ours on this machine holds.

    A random id alone collides between concurrent runs (tests, benchmarks, the main job, the
    workers of a parallel test run): the other run's nodes then appear in ours. Each id has a
    lock file, as ROS's domain_coordinator has a port; this process holds the lock of the ids it
    hands out (the OS releases them when it exits), keeping its HELD_DOMAINS newest, and those
    reserved with ``keep`` for as long as it runs (a pytest worker's own domain, which every test
    of the worker uses: handed on after 16 graph runs, a second worker could take it).
    """
    DOMAIN_LOCKS.mkdir(exist_ok=True)
    ids = list(DOMAIN_IDS)
    random.shuffle(ids)
    for domain in ids:
        if domain in _held or domain in _kept:
            continue
        lock = open(DOMAIN_LOCKS / f'{domain}.lock', 'a')
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            continue
        if keep:
            _kept[domain] = lock
            return domain
        _held[domain] = lock
        while len(_held) > HELD_DOMAINS:
            _held.popitem(last=False)[1].close()
        return domain
    if keep:
        raise RuntimeError(f'every DDS domain id {DOMAIN_IDS.start}-{DOMAIN_IDS.stop - 1} is held '
                           f'by another run of ours ({DOMAIN_LOCKS}): none left to keep')
    return random.choice(ids)    # every id is taken: share one rather than fail


def isolated_ros_env(domain_id: Optional[int] = None, base: Optional[Dict[str, str]] = None):
    """
    Environment for a private DDS domain on this host only.

    ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST replaces the deprecated ROS_LOCALHOST_ONLY; the
    domain is ``reserve_domain()``'s unless given.
    """
    env = dict(os.environ if base is None else base)
    env.pop('ROS_LOCALHOST_ONLY', None)
    env['ROS_DOMAIN_ID'] = str(domain_id if domain_id is not None else reserve_domain())
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    # msg_config/fastdds.xml: faster discovery (with Fast DDS's defaults a participant that
    # misses the initial announcements is found up to 3 s late, and loses what was published
    # meanwhile) and deeper shared-memory queues. A user's own profile wins.
    if not (env.get('FASTRTPS_DEFAULT_PROFILES_FILE') or env.get('FASTDDS_DEFAULT_PROFILES_FILE')):
        from saw_ros.interface.config import config_path
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(config_path('fastdds.xml'))
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    env['PYTHONUNBUFFERED'] = '1'
    return env


def wait_for(condition: Callable[[], bool], timeout: float, poll: float = 0.02,
             spin: Optional[Callable[[float], None]] = None) -> bool:
    """
    Wait until ``condition()`` holds or ``timeout`` seconds pass.

    ``spin(t)`` replaces sleeping (an executor's spin_once) so that callbacks run while waiting.
    Returns the condition.
    """
    deadline = time.monotonic() + timeout
    while True:
        if condition():
            return True
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return bool(condition())
        if spin is not None:
            spin(min(poll, remaining))
        else:
            time.sleep(min(poll, remaining))


def batch_policy(pid: int) -> bool:
    """
    Put a just-started process under SCHED_BATCH (True; False where Linux's policies are missing).

    Its threads, all started later, inherit the policy. A SCHED_BATCH thread that wakes up does
    not preempt the running one; otherwise it gets the same fair share of the CPU. The main
    job's consumers (camera, vision, comparison, recorder) run so: each of the simulator's 6000
    messages a second woke a reader thread that preempted the simulator, 18 000 context
    switches a second on its main thread, and on two cores it fell behind real time. Batched,
    it was switched ~7 700 times a second and used 0.35 of a core instead of 0.56
    (docs/measurements.md). Unprivileged; a consumer waits at most a scheduler tick longer to
    take its messages, which its 1 s queues absorb.
    """
    try:
        os.sched_setscheduler(pid, os.SCHED_BATCH, os.sched_param(0))
    except (AttributeError, OSError):
        return False
    return True


class ManagedProcess:
    """A child process in its own session, its output in a log file, stopped cleanly."""

    # Started and not yet waited for: what stop_all() stops (a child is in a session of its own,
    # so nothing else stops it when its starter fails or returns early).
    live: 'set[ManagedProcess]' = set()

    def __init__(self, name: str, argv: Sequence[str], env: Dict[str, str],
                 log_dir: Path, cwd: Optional[Path] = None, batch: bool = False):
        """``batch``: run it under Linux's SCHED_BATCH (``batch_policy``)."""
        self.name = name
        self.argv = list(argv)
        self.log_path = Path(log_dir) / f'{name}.log'
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        self._log = open(self.log_path, 'wb')
        self.proc = subprocess.Popen(self.argv, env=env, cwd=cwd, stdout=self._log,
                                     stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                     start_new_session=True)
        ManagedProcess.live.add(self)
        if batch:
            batch_policy(self.proc.pid)

    @classmethod
    def stop_all(cls, timeout: float = 10.0) -> List[str]:
        """Stop every process still running (see ``stop``); return their names."""
        left = [p for p in list(cls.live) if p.returncode is None]
        for p in left:
            p.stop(timeout)
        return [p.name for p in left]

    @property
    def returncode(self) -> Optional[int]:
        return self.proc.poll()

    def output(self) -> str:
        if not self._log.closed:    # still readable after wait()/stop() closed the log
            self._log.flush()
        return self.log_path.read_text(errors='replace')

    def signal(self, sig: int) -> None:
        try:
            os.killpg(self.proc.pid, sig)
        except ProcessLookupError:
            pass

    def stop(self, timeout: float = 10.0) -> int:
        """SIGINT, then SIGTERM, then SIGKILL; returns the exit code (negative: killed)."""
        for sig, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, timeout / 2),
                          (signal.SIGKILL, 5.0)):
            if self.proc.poll() is not None:
                break
            self.signal(sig)
            try:
                self.proc.wait(wait)
            except subprocess.TimeoutExpired:
                continue
        code = self.proc.wait()
        self._log.close()
        ManagedProcess.live.discard(self)
        return code

    def wait(self, timeout: Optional[float] = None) -> int:
        code = self.proc.wait(timeout)
        self._log.close()
        ManagedProcess.live.discard(self)
        return code


NODE_PACKAGE = 'saw_ros.ros.nodes'


def node_command(executable: str, *ros_args: str, params: Optional[Dict[str, object]] = None,
                 params_file: Optional[Path] = None, package: str = NODE_PACKAGE) -> List[str]:
    """
    Return the argv that runs one of our executables (a module of ``package``) with ROS arguments.

    The module runs as ``python -m`` under this Python (no PATH lookup).
    """
    argv = [sys.executable, '-m', f'{package}.{executable}']
    extra = list(ros_args)
    if params_file is not None:
        extra += ['--params-file', str(params_file)]
    for key, value in (params or {}).items():
        if isinstance(value, bool):
            value = 'true' if value else 'false'
        extra += ['-p', f'{key}:={value}']
    if extra:
        argv += ['--ros-args'] + extra
    return argv
