#!/usr/bin/env python3
"""
Soak: the main job's graph for a long run, every node's memory sampled; flat and lossless or not.

The graph of ``saw-ros demo`` (simulator, camera, vision, comparison, recorder; the default
scenario, the same recording) at real-time factor 0.5 for ``--minutes`` of wall time (30). Every
``--every`` seconds (10) the resident memory (RSS, /proc/<pid>/status VmRSS) of each node
process of the run's own DDS domain is sampled. It passes when

- every node's RSS stays within ``--flat`` (5 %) after the first minute: the largest sample from
  then on is at most 5 % above the smallest (a leak grows without bound, a working set does not);
- nothing was lost: the recorder's final line says ``lost 0`` and the bag holds every step of the
  1 kHz streams, every camera frame and every tracking result (saw_ros.bench.pipeline.check,
  the bench's own loss count);
- every node exited 0.

It prints a table (per node: RSS at one minute, min, max, last, growth), writes ``rss.csv``
(wall seconds, node, RSS in MB), ``rss.png`` (RSS over time per node) and ``result.json`` into
``--out`` (default ``out/soak_<date-time>/``) with the nodes' logs; the bag (about 3 GB for
30 minutes) is deleted once counted unless ``--keep-bag``. Exit 0 pass, 1 fail. Outside the
test suite (it takes the whole duration): ``scripts/soak.sh``.
"""
import argparse
import csv
import json
import os
from pathlib import Path
import shutil
import sys
import time

FIRST_MINUTE = 60.0


def node_pids(domain: str) -> dict:
    """{node name: pid} of the saw_ros node processes running in DDS domain ``domain``."""
    found = {}
    for entry in os.listdir('/proc'):
        if not entry.isdigit():
            continue
        try:
            argv = Path(f'/proc/{entry}/cmdline').read_bytes().split(b'\0')
            if b'-m' not in argv:
                continue
            module = argv[argv.index(b'-m') + 1].decode()
            if not module.startswith('saw_ros.ros.nodes.'):
                continue
            environ = Path(f'/proc/{entry}/environ').read_bytes().split(b'\0')
        except (OSError, IndexError, ValueError):
            continue        # gone meanwhile, or not ours to read
        if f'ROS_DOMAIN_ID={domain}'.encode() in environ:
            found[module.rsplit('.', 1)[1]] = int(entry)
    return found


def rss_mb(pid: int) -> float:
    """Resident memory of ``pid`` in MB (nan once it has exited)."""
    try:
        for line in Path(f'/proc/{pid}/status').read_text().splitlines():
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float('nan')


NODES = ('simulator', 'camera', 'vision', 'comparison', 'recorder')


class Sampler:
    """
    Called by run_pipeline every 0.2 s (its progress hook): samples every ``every`` s.

    The clock starts when all five nodes run (the recorder starts last, and the simulator steps
    once it has matched), and sampling stops when the simulator has exited (the others are
    being stopped then).
    """

    def __init__(self, domain: str, every: float, minutes: float):
        self.domain, self.every, self.total = domain, every, 60.0 * minutes
        self.start = None
        self.next = 0.0
        self.rows = []                  # (wall s, node, MB)
        self.last_line = -60.0
        self.done = False

    def __call__(self):
        if self.done:
            return
        if self.start is None:
            if not set(NODES) <= set(node_pids(self.domain)):
                return
            self.start = time.monotonic()
        t = time.monotonic() - self.start
        if t < self.next:
            return
        self.next = t + self.every
        pids = node_pids(self.domain)
        if 'simulator' not in pids:
            self.done = True
            return
        for name, pid in sorted(pids.items()):
            mb = rss_mb(pid)
            if mb == mb:
                self.rows.append((round(t, 1), name, round(mb, 2)))
        if t - self.last_line >= 60.0:
            self.last_line = t
            now = ', '.join(f'{n} {mb:.0f}' for tt, n, mb in self.rows if tt == round(t, 1))
            print(f'soak: {t / 60:5.1f} of {self.total / 60:.0f} min, RSS MB: {now}', flush=True)


def flatness(rows, flat: float):
    """Per node: (RSS at the first minute, min, max, last, growth) over the samples after it."""
    table = {}
    for name in sorted({n for _, n, _ in rows}):
        after = [mb for t, n, mb in rows if n == name and t >= FIRST_MINUTE]
        if len(after) < 2:
            table[name] = None
            continue
        low, high = min(after), max(after)
        table[name] = (after[0], low, high, after[-1], (high - low) / low)
    return table


def plot(rows, path: Path, flat: float) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(9, 5))
    for name in sorted({n for _, n, _ in rows}):
        pts = [(t / 60.0, mb) for t, n, mb in rows if n == name]
        ax.plot([p[0] for p in pts], [p[1] for p in pts], label=name)
    ax.axvline(FIRST_MINUTE / 60.0, color='grey', linestyle=':', label='first minute')
    ax.set_xlabel('wall time (min)')
    ax.set_ylabel('RSS (MB)')
    ax.set_title(f'soak: node memory (flat = within {100 * flat:.0f} % after the first minute)')
    ax.legend()
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--minutes', type=float, default=30.0, help='wall minutes (30)')
    parser.add_argument('--real-time-factor', type=float, default=0.5,
                        help='simulated seconds per wall second (0.5)')
    parser.add_argument('--every', type=float, default=10.0, help='seconds between samples (10)')
    parser.add_argument('--flat', type=float, default=0.05,
                        help='largest RSS growth after the first minute (0.05)')
    parser.add_argument('--out', type=Path, default=None,
                        help='output folder (default out/soak_<date-time>)')
    parser.add_argument('--keep-bag', action='store_true', help='keep the recording')
    args = parser.parse_args(argv)
    if args.minutes < 2.0 or args.real_time_factor <= 0 or args.every <= 0:
        print('soak: --minutes must be at least 2 (one minute of warm-up, then samples), '
              '--real-time-factor and --every above 0', file=sys.stderr)
        return 2

    from saw_ros.analysis.compare import KEEP_S
    from saw_ros.bench.pipeline import check
    from saw_ros.graph.pipeline import PipelineError, run_pipeline
    from saw_ros.graph.process import isolated_ros_env
    from saw_ros.interface.config import config_path

    out = args.out or Path('out') / time.strftime('soak_%Y-%m-%d_%H-%M-%S')
    out.mkdir(parents=True, exist_ok=True)
    env = isolated_ros_env()
    duration = 60.0 * args.minutes * args.real_time_factor       # simulated seconds
    sampler = Sampler(env['ROS_DOMAIN_ID'], args.every, args.minutes)
    print(f'soak: {args.minutes:g} min of the main graph at real-time factor '
          f'{args.real_time_factor:g} ({duration:g} s simulated), RSS every {args.every:g} s, '
          f'into {out}', flush=True)
    failures = []
    run = None
    try:
        run = run_pipeline(out, duration, args.real_time_factor, env=env, bag_dir=out / 'bag',
                           reference_file=config_path('reference_paper.csv'), progress=sampler)
    except PipelineError as exc:
        failures.append(f'the graph failed: {exc}')
    with open(out / 'rss.csv', 'w', newline='') as f:
        writer = csv.writer(f)
        writer.writerow(['wall_s', 'node', 'rss_mb'])
        writer.writerows(sampler.rows)
    if sampler.rows:
        plot(sampler.rows, out / 'rss.png', args.flat)
    table = flatness(sampler.rows, args.flat)
    lost, by_topic = None, {}
    if run is not None:
        failures += [f'{name} exited with {code}' for name, code in run.exit_codes.items()
                     if code != 0]
        final = [line for line in run.logs['recorder'].read_text(errors='replace').splitlines()
                 if 'finished:' in line] if 'recorder' in run.logs else []
        if not final or not final[-1].endswith('; lost 0'):
            failures.append(f"recorder: {final[-1] if final else 'no final line'}")
        try:
            result = check(run, duration, args.real_time_factor)
            by_topic = {k: v for k, v in result['lost_by_topic'].items() if v}
            if duration > KEEP_S:
                # The comparison keeps the last KEEP_S..1.5 KEEP_S s (analysis.compare): its
                # sample counts are a window's, not the run's; the bag counts the same streams.
                for key in ('comparison truth', 'comparison tracked'):
                    by_topic.pop(key, None)
            lost = sum(by_topic.values())
        except Exception as exc:  # noqa: BLE001  (a bag the check cannot read: said, a failure)
            failures.append(f'the bag could not be checked: {exc}')
        if lost:
            failures.append(f'lost {lost}: {by_topic}')
    print(f"\n{'node':<12}{'1 min MB':>10}{'min MB':>10}{'max MB':>10}{'last MB':>10}"
          f"{'growth':>9}")
    for name, row in table.items():
        if row is None:
            failures.append(f'{name}: fewer than 2 samples after the first minute')
            print(f'{name:<12}  (fewer than 2 samples after the first minute)')
            continue
        at_minute, low, high, last, growth = row
        print(f'{name:<12}{at_minute:>10.1f}{low:>10.1f}{high:>10.1f}{last:>10.1f}'
              f'{100 * growth:>8.1f}%')
        if growth > args.flat:
            failures.append(f'{name}: RSS grew {100 * growth:.1f} % after the first minute '
                            f'({low:.1f} -> {high:.1f} MB)')
    if not table:
        failures.append('no node memory sampled')
    print(f'lost: {lost if lost is not None else "not counted"}'
          + (f' {by_topic}' if by_topic else ''))
    (out / 'result.json').write_text(json.dumps({
        'minutes': args.minutes, 'real_time_factor': args.real_time_factor,
        'simulated_s': duration, 'every_s': args.every, 'flat': args.flat, 'lost': lost,
        'lost_by_topic': by_topic,
        'rss_mb': {n: dict(zip(('first_minute', 'min', 'max', 'last', 'growth'), r))
                   for n, r in table.items() if r is not None},
        'failures': failures, 'passed': not failures}, indent=1))
    if run is not None and run.bag_dir is not None and not args.keep_bag:
        shutil.rmtree(run.bag_dir, ignore_errors=True)
    for failure in failures:
        print(f'soak: FAIL {failure}', file=sys.stderr)
    print(f"soak: {'FAIL' if failures else 'pass'}; {out / 'rss.csv'}, {out / 'rss.png'}, "
          f"{out / 'result.json'}", flush=True)
    return 1 if failures else 0


if __name__ == '__main__':
    sys.exit(main())
