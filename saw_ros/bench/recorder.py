"""
Recorder throughput: the highest message rate it keeps with zero loss, and its default load.

The publisher runs in another process (the ``loadgen`` node, 6 topics of the simulator's types),
its rate raised until messages are lost; at the default load (1 kHz on the 6 simulator topics
plus 60 fps 1280x720 rgb8 images) the bench reports the messages lost and the CPU share.
``recorder_lossless_foreign_hogs``: the most CPU-bound processes of another program (``while
True: pass``, normal priority; 1, 2, 4, 8 of them on the machine's cores) beside which the
recorder still loses nothing of the default load; 0 when it loses with one, None when the default
load alone failed, the top rung (8) flagged as a lower bound in ``..._capped``.

The recorder is started with ``exclude_topics`` empty: the default load includes the raw images.
Logs of every trial stay in ``log_dir('recorder')`` (the bag is deleted once counted); a trial
whose processes do not finish in time, or whose bag cannot be read, fails (the ladder stops
there; at the default load the figures are None), never crashes the bench.
"""
import os
from pathlib import Path
import shutil
import subprocess
import time

KEYS = ('recorder_max_msgs_per_s', 'recorder_lost_messages', 'recorder_cpu_share',
        'recorder_default_load_msgs_per_s', 'recorder_lossless_foreign_hogs',
        'recorder_lossless_foreign_hogs_capped')
HOGS = (1, 2, 4, 8)
DEFAULT_LOAD = {'rate': 1000.0, 'streams': 6, 'image_fps': 60.0}


def _cpu_seconds(pid: int) -> float:
    try:
        with open(f'/proc/{pid}/stat') as f:
            fields = f.read().rsplit(')', 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')
    except (OSError, IndexError, ValueError):
        return float('nan')


class TrialFailed(RuntimeError):
    """
    A trial's process hung or failed, or its bag is unreadable.

    The message says which, and where the logs are.
    """


def _trial(work: Path, name: str, env, **load):
    from saw_ros.bag import BagReader
    from saw_ros.bench.loadgen import published_counts
    from saw_ros.graph.process import ManagedProcess, node_command, wait_for
    out = work / name
    shutil.rmtree(out, ignore_errors=True)        # a reused --logs folder
    logs = work / 'logs'
    rec = ManagedProcess(f'rec_{name}', node_command('recorder', params={
        'output': str(out), 'exclude_topics': ['']}), env, logs)
    gen = None
    try:
        if not wait_for(lambda: 'recording to' in rec.output() or rec.returncode is not None,
                        30) or rec.returncode is not None:
            raise TrialFailed(f'recorder did not start; see {rec.log_path}')
        gen = ManagedProcess(f'gen_{name}',
                             node_command('loadgen', params=load, package='saw_ros.bench'),
                             env, logs)
        wait_for(lambda: 'recording /' in rec.output(), 20)
        cpu0, t0 = _cpu_seconds(rec.proc.pid), time.monotonic()
        try:
            gen_code = gen.wait(120)
        except subprocess.TimeoutExpired:
            raise TrialFailed(f'loadgen did not finish within 120 s; see {gen.log_path}') \
                from None
        cpu1, t1 = _cpu_seconds(rec.proc.pid), time.monotonic()
        if gen_code != 0:
            raise TrialFailed(f'loadgen exited with {gen_code}; see {gen.log_path}')
    finally:
        for proc in (gen, rec):
            if proc is not None and proc.returncode is None:
                proc.stop(30)
    if rec.returncode != 0:
        raise TrialFailed(f'recorder exited with {rec.returncode}; see {rec.log_path}')
    published, elapsed = published_counts(gen.output()), load.get('duration', 1.0)
    for line in gen.output().splitlines():
        if line.startswith('elapsed '):
            elapsed = float(line.split()[1])
    try:
        counts = {n: t.count for n, t in BagReader(str(out)).topics().items()}
    except Exception as exc:  # noqa: BLE001  (BagReadError, a truncated file...)
        raise TrialFailed(f'bag {out} unreadable: {exc}; see {rec.log_path}') from None
    shutil.rmtree(out, ignore_errors=True)        # counted: the logs are what is kept
    lost = sum(max(0, n - counts.get(t, 0)) for t, n in published.items())
    return sum(published.values()), elapsed, lost, (cpu1 - cpu0) / max(t1 - t0, 1e-9)


def run(quick: bool = False) -> dict:
    import json
    import sys

    from saw_ros.graph.process import isolated_ros_env

    from saw_ros.bench import log_dir
    env = isolated_ros_env()
    duration = 1.5 if quick else 3.0
    work = log_dir('recorder')
    try:
        total, elapsed, lost, cpu = _trial(work, 'default', env, duration=duration,
                                           **DEFAULT_LOAD)
        default = {'recorder_lost_messages': lost, 'recorder_cpu_share': round(cpu, 3),
                   'recorder_default_load_msgs_per_s': round(total / elapsed)}
    except TrialFailed as exc:
        print(f'bench recorder: default load failed: {exc}', file=sys.stderr, flush=True)
        default = {'recorder_lost_messages': None, 'recorder_cpu_share': None,
                   'recorder_default_load_msgs_per_s': None}
    best = 0.0
    for rate in (1000.0, 1500.0, 2000.0, 3000.0, 4000.0):
        try:
            n, dt, loss, _ = _trial(work, f'r{int(rate)}', env, rate=rate, duration=duration,
                                    streams=6)
        except TrialFailed as exc:
            print(f'bench recorder: {json.dumps({"rate": rate, "failed": str(exc)})}',
                  file=sys.stderr, flush=True)
            break
        if loss:
            break
        best = max(best, n / dt)
    hogs = None if default['recorder_lost_messages'] is None else foreign_hogs(
        work, env, duration)
    return {'recorder_max_msgs_per_s': round(best), **default,
            'recorder_lossless_foreign_hogs': hogs,
            'recorder_lossless_foreign_hogs_capped': hogs == HOGS[-1]}


def foreign_hogs(work: Path, env, duration: float) -> int:
    """Return the most CPU hogs (HOGS) beside which the default load is recorded without loss."""
    import sys
    held = 0
    for n in HOGS:
        hogs = [subprocess.Popen([sys.executable, '-c', 'while True: pass'],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                for _ in range(n)]
        try:
            _, _, lost, _ = _trial(work, f'hogs{n}', env, duration=duration, **DEFAULT_LOAD)
        except TrialFailed as exc:
            print(f'bench recorder: {n} hogs: {exc}', file=sys.stderr, flush=True)
            lost = None
        finally:
            for hog in hogs:
                hog.kill()
                hog.wait()
        if lost != 0:
            break
        held = n
    return held
