"""
The robot's rigid parts as they are drawn: one outline for the camera renderer and the viewers.

The paper gives the robot's length and its wave, not the shape of its head and tail. These are
our choices, kept in one place so that the virtual camera (saw_ros.vision.frames) and the
markers a viewer shows (saw_ros.interface.scene_markers) draw the same robot. Body frame: x
forward along the body axis from the centre of mass, y up; points are complex x + i y, metres.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Tuple

import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core.kinematics import hinge_x
from saw_ros.core.params import RobotParams

SPINE_HALF_HEIGHT = 0.003       # m: the spine is a 6 mm bar from the tail to the wave's hinge
HEAD_HALF_HEIGHT = 0.013        # m, at most 45 % of the gap (motor and batteries)
TAIL_LENGTH = 0.03              # m: the tail plate that carries the back marker
TAIL_HALF_HEIGHT = 0.012        # m
LINK_PLATE_WIDTH = 0.6          # share of the link width a drawn link plate takes (gaps between)
DENT_HALF_WIDTH = 0.6           # half-width of a surface's dent under a tip, in link widths
FRONT_MARKER_X = 0.16           # m: body x of the pink markers, on the body axis, symmetric
BACK_MARKER_X = -0.16           # about the COM, so that their midpoint is the COM


def rectangle(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    """Return the four corners of an axis-aligned box, complex, counter-clockwise."""
    return np.array([complex(x0, y0), complex(x1, y0), complex(x1, y1), complex(x0, y1)])


@dataclass(frozen=True)
class BodyOutline:
    """Head, spine and tail plate as rectangles (4 complex corners each), body frame."""

    head: np.ndarray
    spine: np.ndarray
    tail: np.ndarray


def outline(robot: RobotParams, gap: float) -> BodyOutline:
    """Return the rigid parts of ``robot`` drawn between surfaces ``gap`` apart."""
    half_length = robot.length / 2.0
    hinge = hinge_x(robot)
    head = min(HEAD_HALF_HEIGHT, 0.45 * gap)
    return BodyOutline(
        head=rectangle(hinge, half_length, -head, head),
        spine=rectangle(-half_length, hinge, -SPINE_HALF_HEIGHT, SPINE_HALF_HEIGHT),
        tail=rectangle(-half_length, -half_length + TAIL_LENGTH, -TAIL_HALF_HEIGHT,
                       TAIL_HALF_HEIGHT))


def link_plates(robot: RobotParams, centres: ArrayLike, directions: ArrayLike) -> np.ndarray:
    """
    Return each wave link as a plate from its down tip to its up tip: (..., n, 4) corners.

    ``centres`` and ``directions`` (unit, complex) as saw_ros.core.kinematics gives them; the
    plate is LINK_PLATE_WIDTH of the link wide along the link and 2 r tall across it.
    """
    along = 0.5 * LINK_PLATE_WIDTH * robot.link * np.asarray(directions)
    normal = 1j * np.asarray(directions) * robot.tip_distance
    centres = np.asarray(centres)
    return np.stack([centres + along + normal, centres - along + normal,
                     centres - along - normal, centres + along - normal], axis=-1)


def dent_half_width(robot: RobotParams) -> float:
    """Return the half-width of the dent a tip presses into a surface, m (a drawing choice)."""
    return DENT_HALF_WIDTH * robot.link


def dents(x: ArrayLike, depth: ArrayLike, half_width: float,
          samples: int = 9) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return each tip's dent in a surface as (abscissae, depths), two (tips, samples) arrays.

    A cos^2 bump ``depth`` deep, centred on the tip's x, zero at +-``half_width``: the squeezed
    band the camera and the viewers draw where a tip presses in.
    """
    x = np.asarray(x, float)[:, None]
    xs = np.linspace(x[:, 0] - half_width, x[:, 0] + half_width, samples, axis=1)
    return xs, np.asarray(depth, float)[:, None] * np.cos(0.5 * np.pi * (xs - x) / half_width) ** 2
