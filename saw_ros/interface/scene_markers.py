"""
The robot as markers: which shapes a viewer draws, and where (pure: numpy, no messages).

Everything is in the ``surface`` frame: x along the surfaces, y up from the bottom surface, z out
of the picture plane. ``scene()`` turns the simulator's ground truth (pose, wave phase, contact
points) and the tracker's estimate into a list of ``Shape``; the ``markers`` node
(saw_ros.ros.nodes.markers) makes them visualization_msgs/Marker, and
``docs/figures/markers_view.png`` is drawn from the same list with matplotlib.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import List, Optional, Sequence, Tuple

import numpy as np

from saw_ros.core.kinematics import base_link_end, link_geometry
from saw_ros.core.params import RobotParams

Point = Tuple[float, float, float]
Colour = Tuple[float, float, float, float]

SURFACE_COLOUR: Colour = (0.55, 0.55, 0.6, 1.0)
BODY_COLOUR: Colour = (0.25, 0.35, 0.8, 0.8)
LINK_COLOUR: Colour = (0.1, 0.1, 0.1, 1.0)
TIP_COLOUR: Colour = (1.0, 0.6, 0.0, 1.0)
STICK_COLOUR: Colour = (0.0, 0.8, 0.0, 1.0)
SLIP_COLOUR: Colour = (0.9, 0.0, 0.0, 1.0)
TRACKING_COLOUR: Colour = (1.0, 0.0, 1.0, 0.9)

FORCE_SCALE = 0.01          # m of arrow per N of contact force (1 cm per N)
SURFACE_LENGTH = 1.0        # m of each surface drawn, centred under the robot
SURFACE_THICKNESS = 0.002   # m
DEPTH = 0.03                # m, extent of the robot's parts along z
BODY_HEIGHT = 0.008         # m, the body drawn as a thin bar on the wave's axis
TIP_DIAMETER = 0.004        # m
MARKER_DIAMETER = 0.012     # m, the tracker's marker centres
ESTIMATE_LENGTH = 0.1       # m, the arrow of the tracked pose


@dataclass(frozen=True)
class Shape:
    """
    One marker: kind 'cube', 'sphere', 'arrow', 'line_list' or 'sphere_list'.

    A cube or sphere sits at ``position``, turned by ``yaw`` about z (the pitch in the picture
    plane), with its full extents ``scale``. An arrow, a line list and a sphere list are given
    by ``points`` (an arrow: start, end; its ``scale``: shaft diameter, head diameter, head
    length, as visualization_msgs wants it).
    """

    namespace: str
    id: int                                     # noqa: A003
    kind: str
    colour: Colour
    scale: Point
    position: Point = (0.0, 0.0, 0.0)
    yaw: float = 0.0
    points: Tuple[Point, ...] = ()


def surfaces(gap: float, centre_x: float) -> List[Shape]:
    """Return the bottom (y = 0) and top (y = gap) surfaces as thin strips centred at centre_x."""
    scale = (SURFACE_LENGTH, SURFACE_THICKNESS, 2 * DEPTH)
    return [Shape('surfaces', i, 'cube', SURFACE_COLOUR, scale, (centre_x, y, 0.0))
            for i, y in enumerate((0.0, gap))]


def _to_surface(points, x: float, y: float, theta: float) -> np.ndarray:
    """Return body-frame points (complex) in the surface frame (complex)."""
    return complex(x, y) + complex(math.cos(theta), math.sin(theta)) * np.asarray(points)


def _xyz(p: complex) -> Point:
    return (float(p.real), float(p.imag), 0.0)


def robot(robot_params: RobotParams, x: float, y: float, theta: float,
          phase: Optional[float]) -> List[Shape]:
    """
    Return the body (a bar at the pose), and with a wave phase the base link, wave links and tips.

    The links come from saw_ros.core.kinematics at ``phase`` (the helix joint's position), in
    the body frame turned by the pitch ``theta`` about the centre of mass (x, y).
    """
    shapes = [Shape('body', 0, 'cube', BODY_COLOUR, (robot_params.length, BODY_HEIGHT, DEPTH),
                    (x, y, 0.0), theta)]
    if phase is None:
        return shapes
    g = link_geometry(robot_params, float(phase))
    hinge, rear = _to_surface([g.hinge, base_link_end(robot_params, g.base_angle)], x, y, theta)
    middle = 0.5 * (hinge + rear)
    shapes.append(Shape('base_link', 0, 'cube', LINK_COLOUR,
                        (robot_params.base_link_width, 0.003, DEPTH), _xyz(middle),
                        float(np.angle(hinge - rear))))
    half = 0.5 * robot_params.link * np.exp(1j * g.angles)
    ends = _to_surface(np.stack([g.centres + half, g.centres - half, g.centres, g.up_tips,
                                 g.centres, g.down_tips], axis=-1).ravel(), x, y, theta)
    shapes.append(Shape('wave_links', 0, 'line_list', LINK_COLOUR, (0.002, 0.0, 0.0),
                        points=tuple(_xyz(p) for p in ends)))
    tips = _to_surface(np.concatenate([g.up_tips, g.down_tips]), x, y, theta)
    shapes.append(Shape('tips', 0, 'sphere_list', TIP_COLOUR, (TIP_DIAMETER,) * 3,
                        points=tuple(_xyz(p) for p in tips)))
    return shapes


def force_arrows(x: Sequence[float], y: Sequence[float], normal: Sequence[float],
                 tangential: Sequence[float], surface: Sequence[int],
                 slipping: Sequence[int], scale: float = FORCE_SCALE) -> List[Shape]:
    """
    Return one arrow per touching tip: the contact force on the tip, ``scale`` m per N.

    Normal force pushes away from the surface (+y on the bottom one, surface 0; -y on the top
    one, surface 1), the tangential force is along +x. Green where the tip sticks, red where it
    slips.
    """
    shapes = []
    for i in range(len(x)):
        up = 1.0 if int(surface[i]) == 0 else -1.0
        start = (float(x[i]), float(y[i]), 0.0)
        end = (start[0] + scale * float(tangential[i]), start[1] + up * scale * float(normal[i]),
               0.0)
        colour = SLIP_COLOUR if int(slipping[i]) else STICK_COLOUR
        shapes.append(Shape('contact_forces', i, 'arrow', colour, (0.002, 0.004, 0.004),
                            points=(start, end)))
    return shapes


def tracking(front: Optional[Point], back: Optional[Point],
             pose: Optional[Tuple[float, float, float]]) -> List[Shape]:
    """Return the tracker's marker centres (spheres) and its pose (x, y, pitch) as an arrow."""
    shapes = []
    for i, centre in enumerate((front, back)):
        if centre is not None:
            shapes.append(Shape('tracking_markers', i, 'sphere', TRACKING_COLOUR,
                                (MARKER_DIAMETER,) * 3, tuple(float(c) for c in centre)))
    if pose is not None:
        px, py, pitch = pose
        end = (px + ESTIMATE_LENGTH * math.cos(pitch), py + ESTIMATE_LENGTH * math.sin(pitch),
               0.0)
        shapes.append(Shape('tracking_pose', 0, 'arrow', TRACKING_COLOUR, (0.004, 0.008, 0.012),
                            points=((float(px), float(py), 0.0), end)))
    return shapes


def scene(robot_params: RobotParams, gap: float, pose: Tuple[float, float, float],
          phase: Optional[float], contacts=None, front: Optional[Point] = None,
          back: Optional[Point] = None, tracked_pose=None,
          force_scale: float = FORCE_SCALE) -> List[Shape]:
    """
    Return every shape of one instant.

    ``pose``: (x, y, pitch) of the ground truth; ``contacts``: a structured array with the
    fields of /saw/contacts (x, y, normal_force, tangential_force, surface, slipping) or None.
    """
    x, y, theta = pose
    shapes = surfaces(gap, x) + robot(robot_params, x, y, theta, phase)
    if contacts is not None and len(contacts):
        shapes += force_arrows(contacts['x'], contacts['y'], contacts['normal_force'],
                               contacts['tangential_force'], contacts['surface'],
                               contacts['slipping'], force_scale)
    return shapes + tracking(front, back, tracked_pose)
