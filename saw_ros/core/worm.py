"""
The four-cell worm robot the paper compares the wave with (Section 7, Figures 19-21).

RECONSTRUCTION. The paper computes the worm with the analytic model of its reference [24]
(Zarrouk, Sharf, Shoham: worm-robot locomotion on compliant surfaces), which is not at hand. What
the paper says of it (``docs/worm-model.md``): one cell moves per step while the others
anchor; anchoring cells deform the compliant surface and the robot slides back with it (no
progress below about 300 N/m even on the level); a moving cell keeps some contact, so friction
opposes it and pushes the robot back, more so at a higher COF. Two models follow from that.

1. ``closed_form``: the quasi-static model of docs/worm-model.md. N cells, stroke s, one cell
   moves per step, N steps per cycle; the moving cell keeps a residual normal force F_m, each
   anchor has a tangential stiffness k_t and a normal force F_a. The anchors carry

       P = mu F_m + m g sin(alpha) + F_ext

   and hold while mu (N - 1) F_a >= P, deflecting back by u = P / ((N - 1) k_t); the advance per
   cycle is max(0, s - N u), AR = advance / s. Slipping anchors give no progress (AR 0, flagged).

   CALIBRATED, not derived: ``mu F_m`` (16.75 N at mu = 1, so F_m = 16.75 N) and the stiffness at
   which the paper's Figure 21 was drawn (``FIGURE21_STIFFNESS`` = 532 N/m) are the two unknowns
   solved from the paper's two worm numbers, AR 0.40 on the level and 0.29 vertical at COF 1.
   The model then *predicts* zero advance below 4 mu F_m / (3 s) = 319 N/m on the level, which
   the paper states separately ("about 300 N/m"). F_a only enters the slip check; it is derived
   from the gap and the surface law (a cell as tall as the wave robot, squeezed on both sides).

2. ``contact_law``: the same cells meeting the same surface law as the wave robot, stepped
   quasi-statically: each cell's contact is a tangential spring anchored where it touched, capped
   by Coulomb friction (mu times its normal force), with the stiffness the wave's contact law has
   at a slow rate (the hysteresis factor at rate 0, (1 + e) / 2 of k_t, from
   ``contact.hysteresis_factor``). The cells never lose contact (the moving cell keeps F_m), so
   anchors are never forgotten: a landed cell keeps its spring stretched, a lifted cell first
   sticks until its spring reaches the cap, and the load redistributes over the anchors after
   every step; anchors that reach their cap slip (``anchors_slip``; the advance is then what
   the slipping leaves, usually none, and AR 0 when no equilibrium exists at all). Same F_m and
   F_a as the closed form, so the difference between the two models is the contact law alone.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Iterable, List, Optional, Tuple, Union

import numpy as np

from saw_ros.core import walls
from saw_ros.core.contact import hysteresis_factor
from saw_ros.core.dynamics import GRAVITY
from saw_ros.core.params import ParameterError, RobotParams, Scenario, SurfaceParams

# The two calibrated constants (see the module docstring): solved from AR 0.40 (0 deg) and
# 0.29 (90 deg) at COF 1 with N = 4, s = 7 cm, m g = 3.07 N.
PAPER_WORM_AR_LEVEL = 0.40
PAPER_WORM_AR_VERTICAL = 0.29


def _calibrate(cells: int = 4, stroke: float = 0.07,
               weight: float = RobotParams.mass * GRAVITY) -> Tuple[float, float]:
    """Return (mu F_m in N, k in N/m) giving the paper's worm ARs: AR = 1 - N P / ((N - 1) k s)."""
    c = (cells - 1) * stroke / cells
    load_over_k_level = (1.0 - PAPER_WORM_AR_LEVEL) * c          # P0 / k
    load_over_k_vertical = (1.0 - PAPER_WORM_AR_VERTICAL) * c    # (P0 + m g) / k
    k = weight / (load_over_k_vertical - load_over_k_level)
    return load_over_k_level * k, k


CALIBRATED_MOVING_FRICTION, FIGURE21_STIFFNESS = _calibrate()   # 16.75 N, 532 N/m


@dataclass(frozen=True)
class WormParams:
    """The worm of the paper's Section 7 (SI units)."""

    cells: int = 4
    stroke: float = 0.07                 # m, the SAW's advance per cycle on a rigid surface
    mass: float = RobotParams.mass       # kg, the same robot mass as the wave
    moving_normal_force: float = CALIBRATED_MOVING_FRICTION   # N, F_m (calibrated at mu = 1)
    anchor_normal_force: Optional[float] = None    # N, F_a; None: from the gap and surface law
    height: float = 0.057                # m, an expanded cell as tall as the wave robot

    def __post_init__(self) -> None:
        if self.cells < 2:
            raise ParameterError(f'worm cells = {self.cells} is invalid: at least 2')
        for name in ('stroke', 'mass', 'height'):
            if not getattr(self, name) > 0:
                raise ParameterError(f'worm {name} = {getattr(self, name)!r} must be > 0')
        if self.moving_normal_force < 0:
            raise ParameterError('worm moving_normal_force must be >= 0')


def anchor_normal_force(worm: WormParams, scenario: Scenario) -> float:
    """
    Return F_a, the normal force of an expanded cell squeezed by (height - gap) / 2 into each side.

    That is the Hertz law on both sides (its friction acts on both), plus the cell's weight share
    on the bottom; at least the weight share (a cell shorter than the gap still rests on the
    bottom surface).
    """
    if worm.anchor_normal_force is not None:
        return worm.anchor_normal_force
    squeeze = max(0.0, (worm.height - scenario.conditions.gap) / 2.0)
    share = worm.mass * GRAVITY * math.cos(scenario.conditions.slope) / worm.cells
    return 2.0 * squeeze_force(scenario.surface, squeeze) + max(share, 0.0)


def squeeze_force(surface: SurfaceParams, squeeze: float) -> float:
    """
    Return one side's normal force (N) of a cell pressed ``squeeze`` (m) into a surface.

    The Hertz law against a rigid wall; against a bending one (core.walls) the wall gives way
    under the cell by g0 F (g0: the wall's compliance under one contact patch; the cells are
    7 cm apart, several decay lengths, so they do not feel each other), and
    F = kn (squeeze - g0 F)^p is solved by bisection.
    """
    kn, p = surface.normal_stiffness, surface.hertz_exponent
    rigid = kn * float(squeeze ** p)
    if surface.foundation_stiffness <= 0.0 or rigid <= 0.0:
        return rigid
    g0 = float(walls.deflection(0.0, 1.0, surface.foundation_stiffness,
                                surface.bending_stiffness, surface.contact_width))
    low, high = 0.0, rigid
    for _ in range(60):
        mid = 0.5 * (low + high)
        if kn * max(squeeze - g0 * mid, 0.0) ** p > mid:
            low = mid
        else:
            high = mid
    return 0.5 * (low + high)


def wall_relief(worm: 'WormParams', scenario: Scenario) -> float:
    """Return the share of its rigid-wall squeeze force a cell keeps against bending walls."""
    squeeze = max(0.0, (worm.height - scenario.conditions.gap) / 2.0)
    s = scenario.surface
    rigid = s.normal_stiffness * float(squeeze ** s.hertz_exponent)
    return squeeze_force(s, squeeze) / rigid if rigid > 0.0 else 1.0


@dataclass
class WormResult:
    advance_ratio: float       # advance per cycle / stroke (0 when slipping in the closed form)
    advance: float             # m per cycle
    anchors_slip: bool
    load: float                # N, P on the anchors while a cell moves


def _load(worm: WormParams, scenario: Scenario) -> float:
    mu = scenario.surface.friction_coefficient
    c = scenario.conditions
    # The moving cell's residual normal force is a squeeze too: bending walls relieve it as they
    # relieve the anchors (the calibrated F_m is the rigid walls').
    return mu * worm.moving_normal_force * wall_relief(worm, scenario) \
        + worm.mass * GRAVITY * math.sin(c.slope) + c.external_force


def closed_form(scenario: Scenario, worm: WormParams = WormParams()) -> WormResult:
    """Return the reconstructed analytic worm (module docstring, model 1) on this surface."""
    n, s = worm.cells, worm.stroke
    mu = scenario.surface.friction_coefficient
    k = scenario.surface.tangential_stiffness
    load = _load(worm, scenario)
    if mu * (n - 1) * anchor_normal_force(worm, scenario) < load:
        return WormResult(0.0, 0.0, True, load)
    u = load / ((n - 1) * k)
    advance = max(0.0, s - n * u)
    return WormResult(advance / s, advance, False, load)


def zero_advance_stiffness(scenario: Scenario, worm: WormParams = WormParams()) -> float:
    """Return the stiffness kt (N/m, closed form) below which the worm makes no progress."""
    return worm.cells * _load(worm, scenario) / ((worm.cells - 1) * worm.stroke)


def _equilibrium(b: np.ndarray, k: np.ndarray, cap: np.ndarray,
                 demand: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return the body position X (per row) where sum_j clip(-k (X - b_j), -cap_j, cap_j) = demand.

    b, cap: (S, N). Returns (X, ok): ok False where the caps cannot carry the demand.
    """
    total = cap.sum(axis=1)
    ok = total >= demand
    # The sum falls from +total to -total between min(b - cap/k) and max(b + cap/k).
    lo = (b - cap / k).min(axis=1) - 1e-9
    hi = (b + cap / k).max(axis=1) + 1e-9
    for _ in range(50):          # the bracket is < 1 m wide: 1e-15 m
        mid = 0.5 * (lo + hi)
        f = np.clip(-k * (mid[:, None] - b), -cap, cap).sum(axis=1) - demand
        lo = np.where(f > 0, mid, lo)
        hi = np.where(f > 0, hi, mid)
    return 0.5 * (lo + hi), ok


def contact_law(scenarios: Union[Scenario, Iterable[Scenario]], worm: WormParams = WormParams(),
                cycles: int = 3, increments: int = 10) -> List[WormResult]:
    """
    Return the worm's cells meeting the wave's contact law quasi-statically, per scenario.

    This is model 2 of the module docstring, for a list of scenarios at once. AR from the last
    cycle: 3 cycles of 10 increments per step agree with 8 cycles of 200 to 5e-4 in AR.
    """
    scenarios = [scenarios] if isinstance(scenarios, Scenario) else list(scenarios)
    S, n, s = len(scenarios), worm.cells, worm.stroke
    surf = [sc.surface for sc in scenarios]
    k = np.array([float(hysteresis_factor(0.0, x.restitution, x.hysteresis_speed))
                  * x.tangential_stiffness for x in surf])[:, None]
    mu = np.array([x.friction_coefficient for x in surf])[:, None]
    f_a = np.array([anchor_normal_force(worm, sc) for sc in scenarios])[:, None]
    demand = np.array([worm.mass * GRAVITY * math.sin(sc.conditions.slope)
                       + sc.conditions.external_force for sc in scenarios])
    offsets = -s * np.arange(n, dtype=float)          # cell positions relative to the body
    c = np.tile(offsets, (S, 1))
    anchor = c.copy()                                  # body at X = 0, springs unstretched
    X = np.zeros(S)
    slipped = np.zeros(S, bool)
    start_of_cycle: List[np.ndarray] = []
    normal = np.repeat(f_a, n, axis=1)

    anchors_slid = np.zeros(S, bool)

    def settle(moving: Optional[int] = None) -> np.ndarray:
        nonlocal X
        cap = mu * normal
        X, ok = _equilibrium(anchor - c, k, cap, demand)
        x = X[:, None] + c
        force = np.clip(-k * (x - anchor), -cap, cap)
        # Capped contacts slip: the anchor follows so that the spring holds mu Fn exactly.
        capped = np.abs(force) >= cap * (1 - 1e-9)
        anchor[:] = np.where(capped, x + force / k, anchor)
        if moving is not None:
            anchors_slid[:] |= np.delete(capped, moving, axis=1).any(axis=1)
        return ok

    settle()
    for _ in range(cycles):
        start_of_cycle.append(X.copy())
        for i in range(n):                     # front cell first, as an inchworm
            normal[:, i] = worm.moving_normal_force
            for _ in range(increments):
                c[:, i] += s / increments
                slipped |= ~settle(i)
            normal[:, i] = f_a[:, 0]
            slipped |= ~settle()
        # Re-reference: every cell moved one stroke; shift the offsets back, the body forward.
        c -= s
        X += s
    start_of_cycle.append(X.copy())
    advance = start_of_cycle[-1] - start_of_cycle[-2]
    load = np.array([_load(worm, sc) for sc in scenarios])
    out: List[WormResult] = []
    for j in range(S):
        if slipped[j]:                   # no equilibrium: the robot slides away
            out.append(WormResult(0.0, float('nan'), True, float(load[j])))
        else:
            adv = float(advance[j])
            if abs(adv) < 1e-9:          # no progress: round-off of a zero advance
                adv = 0.0
            out.append(WormResult(max(adv, 0.0) / s, adv, bool(anchors_slid[j]),
                                  float(load[j])))
    return out
