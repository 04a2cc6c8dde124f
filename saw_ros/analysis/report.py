"""
The main job's report (``saw-ros demo``): the comparison as text, and report.png from the bag.

``c``, ``comparison``: the comparison node's final summary (its comparison.json; keys as
``saw_ros.ros.nodes.comparison`` writes them).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Dict, List, Tuple

from saw_ros.bag.reader import BagReader
from saw_ros.interface import topics
from saw_ros.vision.camera import FPS


def write_report(bag_dir: Path, comparison: Dict[str, Any], out_dir: Path) -> Path:
    """
    Write report.png into ``out_dir`` and return its path.

    From the recording ``bag_dir``: true and tracked position and speed against simulated time,
    with the comparison's measuring window and speeds (``comparison``: the comparison node's
    summary, comparison.json).
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import numpy as np

    samples: Dict[str, List[Tuple[float, float]]] = {topics.POSE: [], topics.TRACKING_POSE: []}
    reader = BagReader(str(bag_dir))
    for m, pose in reader.decoded_messages(list(samples)):
        t = pose.header.stamp.sec + pose.header.stamp.nanosec * 1e-9
        samples[m.topic].append((t, pose.pose.position.x))
    truth, tracked = np.array(samples[topics.POSE]), np.array(samples[topics.TRACKING_POSE])
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    c = comparison
    if len(truth):
        ax1.plot(truth[:, 0], truth[:, 1] * 100, label='simulation (1 kHz ground truth)')
        v = np.gradient(truth[:, 1], truth[:, 0])
        ax2.plot(truth[:, 0], v * 100, lw=0.6, alpha=0.6, label='simulation')
    if len(tracked):
        ax1.plot(tracked[:, 0], tracked[:, 1] * 100, '.', ms=2, label=f'tracking ({FPS:g} fps)')
        k = round(FPS / 4)                     # a quarter of a second of frames
        if len(tracked) > 2 * k:
            v = (tracked[k:, 1] - tracked[:-k, 1]) / (tracked[k:, 0] - tracked[:-k, 0])
            ax2.plot(0.5 * (tracked[k:, 0] + tracked[:-k, 0]), v * 100, label='tracking '
                     '(0.25 s window)')
    if c.get('status') == 'steady':
        for ax in (ax1, ax2):
            ax.axvspan(c['steady_from_s'], c['steady_from_s'] + c['window_s'], color='0.9',
                       label='measuring window' if ax is ax2 else None)
        ax2.axhline(c['v_sim_m_s'] * 100, color='C0', ls='--', lw=1)
        ax2.axhline(c['v_tracked_m_s'] * 100, color='C1', ls='--', lw=1)
        ax2.axhline(c['v_theory_m_s'] * 100, color='k', ls=':', lw=1, label='v_theory')
        title = (f"AR simulation {c['ar_sim']:.3f}, tracking {c['ar_tracked']:.3f}, relative "
                 f"error {100 * c['relative_error']:.2f} % (slope {c['slope_deg']:.0f} deg, "
                 f"{c['frequency_hz']:.2f} Hz)")
    else:
        title = f"comparison: {c.get('status', 'no result')}"
    ax1.set_title(title, fontsize=10)
    ax1.set_ylabel('position x (cm)')
    ax2.set_ylabel('speed (cm/s)')
    ax2.set_xlabel('simulated time (s)')
    ax1.legend(fontsize=8)
    ax2.legend(fontsize=8, loc='lower right')
    fig.tight_layout()
    path = Path(out_dir) / 'report.png'
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def format_comparison(c: Dict[str, Any]) -> str:
    """Return the comparison node's summary as the lines the demo prints."""
    if c.get('status') != 'steady':
        return f"comparison: {c.get('status', 'no result')}"
    lines = [f"AR simulation       {c['ar_sim']:.4f}",
             f"AR tracking         {c['ar_tracked']:.4f}",
             f"relative error      {100 * c['relative_error']:.2f} %",
             f"v_theory            {100 * c['v_theory_m_s']:.3f} cm/s",
             f"v simulation        {100 * c['v_sim_m_s']:.3f} cm/s",
             f"v tracking          {100 * c['v_tracked_m_s']:.3f} cm/s",
             f"steady from         {c['steady_from_s']:.2f} s, measured over "
             f"{c['window_s']:.2f} s"]
    if 'reference_error_sim' in c and math.isfinite(c['reference_error_sim']):
        lines.append(f"simulation vs measured (paper): {100 * c['reference_error_sim']:.1f} % "
                     f"({c.get('reference_source', '')})")
    return '\n'.join(lines)
