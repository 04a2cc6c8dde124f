"""
Figures 17 and 18 of the validation campaign (paper Section 6).

Drawn from ``saw_ros.analysis.campaign``'s results: the plotting beside the other figures.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np


def plot_campaign(results, summary, figure17: Path, figure18: Path,
                  measured: str = 'virtual camera + tracker') -> None:
    """
    Draw Figures 17 and 18 of ``analysis.campaign``'s results and summary.

    Figure 17: tracked speed against slope and against voltage, with the linear fits and the
    paper's measured speeds; Figure 18: AR of simulation and tracking per condition.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    panels = ((a1, 'voltage', 'slope_deg', summary['speed_vs_slope_fits'], '{:g} V',
               'slope (deg)', '(A) speed against slope'),
              (a2, 'slope_deg', 'voltage', summary['speed_vs_voltage_fits'], '{:g} deg',
               'motor voltage (V)', '(B) speed against voltage'))
    for ax, group, along, fits, label, xlabel, title in panels:
        for i, key in enumerate(sorted({getattr(r, group) for r in results})):
            rows = [r for r in results if getattr(r, group) == key]
            along_x = [getattr(r, along) for r in rows]
            ax.plot(along_x, [100 * r.v_tracked for r in rows], 'o', color=f'C{i}',
                    label=label.format(key))
            ax.plot(along_x, [100 * r.v_sim for r in rows], 'x', color=f'C{i}', ms=5)
            if key in fits:
                a, b, r2 = fits[key]
                ax.plot(along_x, [100 * (a * u + b) for u in along_x], '-', color=f'C{i}', lw=1,
                        label=f'fit R$^2$={r2:.3f}')
        ax.set_xlabel(xlabel)
        ax.set_ylabel('speed (cm/s): o measured, x simulated')
        ax.set_title(title)
    refs = [r for r in results if math.isfinite(r.reference_speed)]
    for r in refs:
        a2.plot(r.voltage, 100 * r.reference_speed, 'k*', ms=10)
    if refs:
        a2.plot([], [], 'k*', label='paper, measured')
    for ax in (a1, a2):
        ax.legend(fontsize=7, ncol=2)
    fig.suptitle(f'Figure 17: speeds measured ({measured}) and simulated')
    fig.tight_layout()
    fig.savefig(figure17, dpi=100)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(10, 4.2))
    labels = [f'{r.slope_deg:g}°\n{r.voltage:g} V' for r in results]
    x = np.arange(len(results))
    ax.plot(x, [r.ar_sim for r in results], '^', label='simulation')
    ax.plot(x, [r.ar_tracked for r in results], 'o', mfc='none', label=f'measured ({measured})')
    ax.set_xticks(x)
    ax.set_xticklabels(labels, fontsize=7)
    ax.set_ylabel('advance ratio')
    ax.set_title(f'Figure 18: AR simulated and measured; mean relative error '
                 f'{100 * summary["mean_relative_error"]:.2f} %')
    ax.legend()
    fig.tight_layout()
    fig.savefig(figure18, dpi=100)
    plt.close(fig)
