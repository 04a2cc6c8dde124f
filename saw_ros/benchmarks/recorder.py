"""Recorder throughput: the highest message rate it keeps with zero loss (publisher in another
process: the ``loadgen`` node, 6 topics of the simulator's types, rate raised until messages are
lost), and the messages lost and CPU share at the default load (1 kHz on the 6 simulator topics
plus 60 fps 1280x720 rgb8 images)."""
import os
import tempfile
import time
from pathlib import Path

KEYS = ('recorder_max_msgs_per_s', 'recorder_lost_messages', 'recorder_cpu_share',
        'recorder_default_load_msgs_per_s')


def _cpu_seconds(pid: int) -> float:
    try:
        with open(f'/proc/{pid}/stat') as f:
            fields = f.read().rsplit(')', 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')
    except (OSError, IndexError, ValueError):
        return float('nan')


def _trial(work: Path, name: str, env, **load):
    from saw_ros.bag import BagReader
    from saw_ros.process import ManagedProcess, node_command, wait_for
    out = work / name
    rec = ManagedProcess(f'rec_{name}', node_command('recorder', params={'output': str(out)}),
                         env, work / 'logs')
    wait_for(lambda: 'recording to' in rec.output(), 20)
    gen = ManagedProcess(f'gen_{name}', node_command('loadgen', params=load), env,
                         work / 'logs')
    wait_for(lambda: 'recording /' in rec.output(), 20)
    cpu0, t0 = _cpu_seconds(rec.proc.pid), time.monotonic()
    gen.wait(120)
    cpu1, t1 = _cpu_seconds(rec.proc.pid), time.monotonic()
    rec.stop(30)
    published, elapsed = {}, load.get('duration', 1.0)
    for line in gen.output().splitlines():
        if line.startswith('published '):
            _, topic, n = line.split()
            published[topic] = int(n)
        elif line.startswith('elapsed '):
            elapsed = float(line.split()[1])
    counts = {n: t.count for n, t in BagReader(str(out)).topics().items()}
    lost = sum(max(0, n - counts.get(t, 0)) for t, n in published.items())
    return sum(published.values()), elapsed, lost, (cpu1 - cpu0) / max(t1 - t0, 1e-9)


def run(quick: bool = False) -> dict:
    from saw_ros.process import isolated_ros_env
    env = isolated_ros_env()
    duration = 1.5 if quick else 3.0
    with tempfile.TemporaryDirectory(prefix='saw_bench_rec_') as tmp:
        work = Path(tmp)
        total, elapsed, lost, cpu = _trial(work, 'default', env, rate=1000.0, duration=duration,
                                           streams=6, image_fps=60.0)
        best = 0.0
        for rate in (1000.0, 1500.0, 2000.0, 3000.0, 4000.0):
            n, dt, loss, _ = _trial(work, f'r{int(rate)}', env, rate=rate, duration=duration,
                                    streams=6)
            if loss:
                break
            best = max(best, n / dt)
    return {'recorder_max_msgs_per_s': round(best),
            'recorder_lost_messages': lost,
            'recorder_cpu_share': round(cpu, 3),
            'recorder_default_load_msgs_per_s': round(total / elapsed)}
