"""
What the targets pin down: local sensitivity at the optimum and the linearised covariance.

The relative change of every target per relative change of every parameter (central
differences, one batch), and from it the parameters' covariance for a target error of the
fit's own RMS residual (at least 2 %): which parameters are pinned down, which directions are
flat, which pairs trade off against each other.
"""
from __future__ import annotations

import math
from typing import Any, Dict, List, Tuple

import numpy as np

from saw_ros.analysis.calibrate.model import Model
from saw_ros.analysis.calibrate.parameters import allowed, Parameter


# Relative step of the finite differences around the optimum.
SENSITIVITY_STEP = 0.05
# Floor of the target error used for the parameter uncertainty: the paper states its speeds to
# two or three digits and its AR read off a figure; a perfect fit does not make them exact.
MIN_TARGET_ERROR = 0.02
# A parameter is pinned down when its 1-sigma band is within +-20 % of its value.
IDENTIFIED_REL_STD = 0.20
CORRELATED = 0.9


def sensitivity(model: Model, params: List[Parameter], values: Dict[str, float]
                ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return (S, centre outcomes, default outcomes of the base) from one batch.

    S[k, j] = relative change of target k per relative change of parameter j, central
    differences of SENSITIVITY_STEP (one-sided where a step would leave the parameter's range).
    """
    meta = {name: m for name, _, m in model.base.describe()}
    steps = []
    candidates = [dict(values), {}]
    for p in params:
        v = values[p.name]
        up, down = v * (1 + SENSITIVITY_STEP), v * (1 - SENSITIVITY_STEP)
        if v == 0.0:
            up, down = v + SENSITIVITY_STEP * (p.high - p.low), v
        if not allowed(p.name, meta[p.name], up):
            up = v
        if not allowed(p.name, meta[p.name], down):
            down = v
        steps.append((up, down))
        candidates += [{**values, p.name: up}, {**values, p.name: down}]
    out = model.outcomes(candidates)
    centre, default = out[0], out[1]
    S = np.zeros((len(model.targets), len(params)))
    for j, (p, (up, down)) in enumerate(zip(params, steps)):
        scale = values[p.name] if values[p.name] != 0.0 else (p.high - p.low)
        S[:, j] = (out[2 + 2 * j] - out[3 + 2 * j]) / centre / ((up - down) / scale)
    return S, centre, default


def identifiability(S: np.ndarray, params: List[Parameter], residual_rms: float) -> dict:
    """
    Return what the targets pin down: a linearised covariance of the relative parameters.

    cov = sigma^2 (S^T S)^-1 with sigma the target error (the fit's RMS relative residual, at
    least MIN_TARGET_ERROR); directions S does not see (singular values near zero, or fewer
    targets than parameters) are flat: no finite band.
    """
    sigma = max(float(residual_rms), MIN_TARGET_ERROR)
    names = [p.name for p in params]
    S = np.nan_to_num(S)
    _, s, vt = np.linalg.svd(S, full_matrices=True)
    s = np.concatenate([s, np.zeros(len(names) - len(s))])
    tiny = 1e-9 + 1e-6 * (s.max() if len(s) else 0.0)
    flat: List[Dict[str, Any]] = []
    std = np.zeros(len(names))
    for k in range(len(names)):
        extent = float('inf') if s[k] <= tiny else sigma / s[k]   # 1-sigma relative move
        if extent > IDENTIFIED_REL_STD:
            parts = [(names[j], float(vt[k, j])) for j in np.argsort(-abs(vt[k]))
                     if abs(vt[k, j]) >= 0.3]
            flat.append({'one_sigma_relative_move': extent, 'direction': {
                n: round(c, 3) for n, c in parts}})
        share = vt[k] ** 2
        if math.isfinite(extent):
            std += share * extent ** 2
        else:
            # A parameter with a part (5 % or more) in an unseen direction has no finite band.
            std[share >= 0.05 ** 2] = float('inf')
    std = np.sqrt(std)
    pairs = []
    finite = [j for j in range(len(names)) if math.isfinite(std[j])]
    if finite:
        sub = S[:, finite]
        cov = np.linalg.pinv(sub.T @ sub) * sigma ** 2
        d = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
        corr = cov / np.outer(d, d)
        for a in range(len(finite)):
            for b in range(a + 1, len(finite)):
                if abs(corr[a, b]) >= CORRELATED:
                    pairs.append({'a': names[finite[a]], 'b': names[finite[b]],
                                  'correlation': round(float(corr[a, b]), 3)})
    # Pairs that only move together inside a flat direction are correlated too.
    for f in flat:
        members = list(f['direction'])
        for a in range(len(members)):
            for b in range(a + 1, len(members)):
                pair = {'a': members[a], 'b': members[b], 'correlation': None,
                        'flat_direction': True}
                if not any({p['a'], p['b']} == {members[a], members[b]} for p in pairs):
                    pairs.append(pair)
    return {'target_error': sigma,
            'relative_std': {n: (float(v) if math.isfinite(v) else None)
                             for n, v in zip(names, std)},
            'identified': [n for n, v in zip(names, std) if v <= IDENTIFIED_REL_STD],
            'not_identified': [n for n, v in zip(names, std) if not v <= IDENTIFIED_REL_STD],
            'flat_directions': flat, 'correlated': pairs,
            'singular_values': [float(v) for v in s]}
