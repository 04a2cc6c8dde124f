"""
``--plot PATH.png`` of ``simulate`` and ``track``: position and speed over time (as the demo).

Two panels sharing the time axis (position x in cm, speed in cm/s), the measured lines
(steady-state mean, v_theory) as horizontal lines and the window they were measured over shaded.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence, Tuple

import numpy as np

Series = Tuple[str, Sequence[float], Sequence[float]]      # label, t (s), value (m or m/s)


def write_time_plot(path, title: str, positions: Sequence[Series], speeds: Sequence[Series],
                    levels: Sequence[Tuple[str, float]] = (),
                    window: Optional[Tuple[float, float]] = None,
                    time_label: str = 'time (s)') -> Path:
    """Write the two-panel PNG at ``path``; ``levels``: (label, m/s) horizontal speed lines."""
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    for label, t, x in positions:
        ax1.plot(t, 100 * np.asarray(x, float), label=label)
    for label, t, v in speeds:
        ax2.plot(t, 100 * np.asarray(v, float), lw=0.7, label=label)
    for k, (label, level) in enumerate(levels):
        ax2.axhline(100 * level, color=f'C{k + len(speeds)}', ls='--', lw=1, label=label)
    if window is not None:
        for ax in (ax1, ax2):
            ax.axvspan(*window, color='0.9', label='measuring window' if ax is ax2 else None)
    ax1.set_title(title, fontsize=10)
    ax1.set_ylabel('position x (cm)')
    ax2.set_ylabel('speed (cm/s)')
    ax2.set_xlabel(time_label)
    ax1.legend(fontsize=8)
    ax2.legend(fontsize=8, loc='lower right')
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
