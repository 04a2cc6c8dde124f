"""
Statics of crawling between two surfaces (paper Section 3, Eqs. 1-5, Figure 4).

With one friction coefficient mu at four idealised contacts (1, 2 bottom; 3, 4 top), progress up
a slope alpha against a resisting force F_ext needs

    (4) bottom: Fn1 + Fn2 > 1/2 [F_ext/mu + m g (sin(alpha)/mu + cos(alpha))]
    (5) top:    Fn3 + Fn4 > 1/2 [F_ext/mu + m g (sin(alpha)/mu - cos(alpha))]
    (3) total:  the sum of both = (F_ext + m g sin(alpha)) / mu

The top surface is needed only where the right side of (5) is positive. Everything here is in
units of m g when ``weight`` is 1 (the paper's Figure 4 axis).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Optional, Tuple

import numpy as np
from numpy.typing import ArrayLike


@dataclass(frozen=True)
class StaticCase:
    """One curve family of Figure 4: F_ext in units of m g, and the COF."""

    name: str
    external_force: float   # in units of m g
    mu: float


# Figure 4's cases. The paper writes case C's force as "F_ext = 0.5" and means 0.5 m g like B.
FIGURE4_CASES = (StaticCase('A', 0.0, 0.4), StaticCase('B', 0.5, 0.4), StaticCase('C', 0.5, 0.8))


def minimal_normal_forces(slope: ArrayLike, external_force: float, mu: float,
                          weight: float = 1.0) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Minimal bottom, top and total normal forces (Eqs. 4, 5, 3) at slope(s) in rad.

    The top force is the raw right side of (5): negative means the top surface is not needed
    (the bottom one alone is then pressed by the weight, bottom = m g cos(alpha) at the least).
    """
    slope = np.asarray(slope, float)
    if mu <= 0:
        raise ValueError('mu must be > 0 for the statics')
    thrust = (external_force + weight * np.sin(slope)) / mu
    bottom = 0.5 * (thrust + weight * np.cos(slope))
    top = 0.5 * (thrust - weight * np.cos(slope))
    return bottom, top, bottom + top


def top_surface_needed_above(external_force: float, mu: float,
                             weight: float = 1.0) -> Optional[float]:
    """
    Smallest slope (rad) from which the top surface must press (Eq. 5 > 0); 0 if always.

    None if never within [0, 90] deg.

    Solves F_ext/mu + m g (sin(a)/mu - cos(a)) = 0, i.e. sin(a) - mu cos(a) = -F_ext/m g.
    """
    if external_force / mu - weight > 0:     # positive already at 0 deg
        return 0.0
    # R sin(a - phi) = -F_ext / (m g) with R = sqrt(1 + mu^2), phi = atan(mu)
    R = math.hypot(1.0, mu)
    phi = math.atan(mu)
    value = -external_force / (weight * R)
    if abs(value) > 1:
        return None
    a = math.asin(value) + phi
    return a if 0.0 <= a <= math.pi / 2 else None
