"""
Placing the tips: the step's first kernel, reading kinematics' tables (docs/core.md).

Apart from core.kinematics so that the nodes that only draw or measure the robot (camera,
vision, comparison) never import numba.
"""
from __future__ import annotations

import math
from typing import Tuple

import numba
import numpy as np

from saw_ros.core.contact import OFFSET_X, OFFSET_Y, PENETRATION, SEEN, X
from saw_ros.core.jit import CACHE


@numba.njit(cache=CACHE)
def turned_table_value(table: np.ndarray, scale: float, phase: float, column: int, cos: float,
                       sin: float) -> Tuple[float, float]:
    """
    Return a PhaseTable's complex column at ``phase``, turned by an angle: (x, y) (kernel).

    ``table`` (2, samples + 1, K): the table's points and slopes (``PhaseTable.stacked``),
    ``scale`` its samples per radian, (cos, sin) of the angle (the robot's pitch).
    """
    u = phase * scale
    row = int(u)
    weight = u - row
    value = table[0, row, column] + weight * table[1, row, column]
    return value.real * cos - value.imag * sin, value.real * sin + value.imag * cos


@numba.njit(cache=CACHE)
def place_tips(table: np.ndarray, scale: float, side: np.ndarray, pose: np.ndarray, phase: float,
               gap: float, tips: np.ndarray) -> None:
    """
    Place one scenario's tips at its pose and wave phase (compiled kernel).

    ``table``: the TipTable's points and slopes (2, samples + 1, P); ``side`` (P,) -1 for the
    bottom surface's tips, +1 for the top's; ``pose`` x, y, theta. Writes the rows OFFSET_X,
    OFFSET_Y (offsets from the COM, surface axes), X (abscissa), PENETRATION into the rigid
    surfaces (> 0 inside: side (y_tip - level), the top surface at y = gap, the bottom at 0)
    and SEEN = PENETRATION (the depth the contact law sees while the walls are rigid) of
    ``tips`` (core.contact's TIP_FIELDS rows).
    """
    cos, sin = math.cos(pose[2]), math.sin(pose[2])
    for p in range(tips.shape[1]):
        bx, by = turned_table_value(table, scale, phase, p, cos, sin)
        tips[OFFSET_X, p], tips[OFFSET_Y, p] = bx, by
        tips[X, p] = bx + pose[0]
        depth = (by + pose[1]) * side[p]
        if side[p] > 0.0:
            depth -= gap
        tips[PENETRATION, p] = depth
        tips[SEEN, p] = depth
