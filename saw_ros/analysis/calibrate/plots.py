"""The fit, sensitivity and convergence plots of a calibration (matplotlib, Agg)."""
from __future__ import annotations

from pathlib import Path
from typing import List

import numpy as np


def _plt():
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt
    return plt


def write_plots(data: dict, folder: Path) -> List[Path]:
    """fit.png, sensitivity.png and convergence.png."""
    plt = _plt()
    files = []
    targets = data['targets']
    labels = [t['label'] for t in targets]
    x = np.arange(len(targets))
    fig, ax = plt.subplots(figsize=(max(6.0, 1.3 * len(targets) + 2), 4.2))
    ax.axhspan(0.95, 1.05, color='0.9', label='within 5 %')
    ax.axhline(1.0, color='k', lw=0.8)
    ax.bar(x - 0.18, [t['default'] / t['measured'] for t in targets], 0.36, label='defaults',
           color='tab:gray')
    ax.bar(x + 0.18, [t['calibrated'] / t['measured'] for t in targets], 0.36,
           label='calibrated', color='tab:blue')
    ax.set_xticks(x, labels, rotation=20, ha='right', fontsize=8)
    ax.set_ylabel('model / measured')
    ax.set_title(f'fit: mean squared relative error {data["loss_default"]:.2e} -> '
                 f'{data["loss"]:.2e}')
    ax.legend(fontsize=8)
    files.append(_save(plt, fig, folder / 'fit.png'))

    S = np.array(data['sensitivity']['matrix'])
    names = [n.split('.', 1)[1] for n in data['sensitivity']['parameters']]
    fig, ax = plt.subplots(figsize=(max(5.0, 1.2 * len(names) + 2.5), 0.55 * len(labels) + 2))
    lim = max(1e-3, float(np.nanmax(abs(S))))
    im = ax.imshow(S, cmap='RdBu_r', vmin=-lim, vmax=lim, aspect='auto')
    ax.set_xticks(range(len(names)), names, rotation=25, ha='right', fontsize=8)
    ax.set_yticks(range(len(labels)), labels, fontsize=8)
    for (k, j), v in np.ndenumerate(S):
        ax.text(j, k, f'{v:.2f}', ha='center', va='center', fontsize=7)
    fig.colorbar(im, ax=ax, label='d ln(target) / d ln(parameter)')
    ax.set_title('sensitivity at the calibrated set')
    files.append(_save(plt, fig, folder / 'sensitivity.png'))

    h = data['history']
    fig, ax = plt.subplots(figsize=(6, 3.6))
    gens = [r['generation'] for r in h]
    ax.semilogy(gens, [r['best_so_far'] for r in h], label='best so far')
    ax.semilogy(gens, [r['best_loss'] for r in h], '.', label='best of the generation')
    ax.semilogy(gens, [r['median_loss'] for r in h], '.', alpha=0.5, label='median')
    ax.set_xlabel('generation')
    ax.set_ylabel('mean squared relative error')
    ax.legend(fontsize=8)
    files.append(_save(plt, fig, folder / 'convergence.png'))
    return files


def _save(plt, fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
