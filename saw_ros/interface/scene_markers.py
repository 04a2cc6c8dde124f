"""
The robot as markers: which shapes a viewer draws, and where (pure: numpy, no messages).

Everything is in the ``surface`` frame: x along the surfaces, y up from the bottom surface, z out
of the picture plane. ``scene()`` turns the simulator's ground truth (pose, wave phase, contact
points) into a list of ``Shape`` and ``tracking()`` the tracker's estimate; saw_ros.ros.markers
makes them visualization_msgs/Marker (the simulator publishes /saw/markers, the vision node
/saw/tracking/markers), and ``docs/figures/markers_view.png`` is drawn from the same lists with
matplotlib. The robot is the camera's (saw_ros.core.body), so a viewer and the camera image
show the same thing.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, List, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from saw_ros.core import body
from saw_ros.core.kinematics import base_link_end, link_geometry, LinkGeometry
from saw_ros.core.params import RobotParams

Point = Tuple[float, float, float]
Colour = Tuple[float, float, float, float]
Numbers = Union[Sequence[float], np.ndarray]      # one value per tip

SURFACE_COLOUR: Colour = (0.55, 0.55, 0.6, 1.0)
SQUEEZE_COLOUR: Colour = (0.95, 0.55, 0.2, 0.8)     # the squeezed band of a surface
SQUEEZE_Z = -0.001          # m: just behind the link plates (z = 0) that press into it
BODY_COLOUR: Colour = (0.25, 0.25, 0.27, 1.0)      # the camera's dark grey
LINK_COLOUR: Colour = (0.78, 0.78, 0.76, 1.0)      # light grey plates, as on camera
MARKER_COLOUR: Colour = (1.0, 0.25, 0.6, 1.0)      # the pink of the real markers
TIP_COLOUR: Colour = (1.0, 0.6, 0.0, 1.0)
STICK_COLOUR: Colour = (0.0, 0.8, 0.0, 1.0)
SLIP_COLOUR: Colour = (0.9, 0.0, 0.0, 1.0)
TRACKING_COLOUR: Colour = (1.0, 0.0, 1.0, 0.9)

FORCE_SCALE = 0.01          # m of arrow per N of contact force (1 cm per N)
SURFACE_LENGTH = 1.0        # m of each surface drawn, centred under the robot
SURFACE_THICKNESS = 0.002   # m
DEPTH = 0.03                # m, extent of the robot's parts along z
TIP_DIAMETER = 0.004        # m
MARKER_DIAMETER = 0.012     # m, the true markers (the camera's 6 mm radius)
ESTIMATE_DIAMETER = 0.007   # m, the tracker's marker centres: smaller, in front of the truth
ESTIMATE_Z = DEPTH / 2 + 0.008   # m, in front of the body and the true markers
ESTIMATE_LENGTH = 0.1       # m, the arrow of the tracked pose


@dataclass(frozen=True, eq=False)
class Shape:
    """
    One marker: kind 'cube', 'sphere', 'arrow', 'sphere_list' or 'triangle_list'.

    A cube or sphere sits at ``position``, turned by ``yaw`` about z (the pitch in the picture
    plane), with its full extents ``scale``. An arrow, a sphere list and a triangle list are
    given by ``points`` (an arrow: start, end; its ``scale``: shaft diameter, head diameter, head
    length, as visualization_msgs wants it; a triangle list: three points a triangle), an
    (N, 3) float array of x, y, z (N x 3 numbers from numpy, not N Python tuples: the simulator
    builds the robot 60 times a simulated second). Not comparable with ``==`` (arrays).
    """

    namespace: str
    id: int                                     # noqa: A003
    kind: str
    colour: Colour
    scale: Point
    position: Point = (0.0, 0.0, 0.0)
    yaw: float = 0.0
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


def surfaces(gap: float, centre_x: float) -> List[Shape]:
    """Return the bottom (y = 0) and top (y = gap) surfaces as thin strips centred at centre_x."""
    scale = (SURFACE_LENGTH, SURFACE_THICKNESS, 2 * DEPTH)
    return [Shape('surfaces', i, 'cube', SURFACE_COLOUR, scale, (centre_x, y, 0.0))
            for i, y in enumerate((0.0, gap))]


def bent_surfaces(gap: float, along: np.ndarray, deflection: np.ndarray) -> List[Shape]:
    """
    Return the bottom and top surfaces bent as the walls are (core.walls): triangle strips.

    ``along``: abscissae (m, increasing); ``deflection`` (2, m): each wall's deflection there,
    bottom then top, > 0 away from the robot. Each surface is a band SURFACE_THICKNESS thick
    following its deflected line (the bottom's top face at y = -w, the top's lower face at
    y = gap + w), as thick along z as the flat strips.
    """
    shapes = []
    z = DEPTH
    for surface, (level, sign) in enumerate(((0.0, -1.0), (gap, 1.0))):
        face = level + sign * np.asarray(deflection[surface], float)
        back = face + sign * SURFACE_THICKNESS
        a = np.stack([along[:-1], face[:-1]], axis=1)
        b = np.stack([along[1:], face[1:]], axis=1)
        c = np.stack([along[:-1], back[:-1]], axis=1)
        d = np.stack([along[1:], back[1:]], axis=1)
        # Two triangles a segment (a b c, b d c), in the plane z = DEPTH (the strips' front).
        tri = np.stack([a, b, c, b, d, c], axis=1).reshape(-1, 2)
        shapes.append(Shape('surfaces', surface, 'triangle_list', SURFACE_COLOUR, (1.0, 1.0, 1.0),
                            points=np.column_stack([tri, np.full(len(tri), z)])))
    return shapes


def _to_surface(points: Union[np.ndarray, Sequence[Any]], x: float, y: float,
                theta: float) -> np.ndarray:
    """Return body-frame points (complex) in the surface frame (complex)."""
    return complex(x, y) + complex(math.cos(theta), math.sin(theta)) * np.asarray(points)


def _xyz(p: complex) -> Point:
    return (float(p.real), float(p.imag), 0.0)


def _points(xy: ArrayLike, z: float = 0.0) -> np.ndarray:
    """Return complex x + i y as an (N, 3) array of x, y, z."""
    xy = np.asarray(xy).ravel()
    out = np.empty((len(xy), 3))
    out[:, 0], out[:, 1], out[:, 2] = xy.real, xy.imag, z
    return out


def _cube(namespace: str, id_: int, colour: Colour, corners: ArrayLike, x: float, y: float,
          theta: float, depth: float = DEPTH) -> Shape:
    """Return a body-frame rectangle (4 complex corners, axis-aligned) as a cube at the pose."""
    corners = np.asarray(corners)
    centre = _to_surface([corners.mean()], x, y, theta)[0]
    size = (float(np.ptp(corners.real)), float(np.ptp(corners.imag)), depth)
    return Shape(namespace, id_, 'cube', colour, size, _xyz(centre), theta)


def robot(robot_params: RobotParams, gap: float, x: float, y: float, theta: float,
          phase: Optional[float], geometry: Optional[LinkGeometry] = None,
          deflection: Optional[np.ndarray] = None) -> List[Shape]:
    """
    Return the robot as the camera draws it (saw_ros.core.body), at pose and wave phase.

    Head, spine and tail plate at the pose (x, y, pitch theta about the centre of mass), the two
    pink markers where the camera draws them (the ground truth the tracker is measured against)
    and, with a wave phase, the base link, each wave link as a plate from its down tip to its
    up tip (saw_ros.core.kinematics at ``phase``, the helix joint's position) and the tips.
    ``deflection`` (n,): each link's deflection on its flexure (m, Simulator.deflection), drawn
    normal to the backbone as the URDF's ``link_NN_flex`` joints move it; None: rigid links.
    """
    parts = body.outline(robot_params, gap)
    shapes = [_cube('body', 0, BODY_COLOUR, parts.head, x, y, theta),
              _cube('body', 1, BODY_COLOUR, parts.spine, x, y, theta),
              _cube('body', 2, BODY_COLOUR, parts.tail, x, y, theta)]
    for i, marker_x in enumerate((body.FRONT_MARKER_X, body.BACK_MARKER_X)):
        centre = _to_surface([complex(marker_x, 0.0)], x, y, theta)[0]
        # In front of the body (+z), as the markers are stuck on its side.
        shapes.append(Shape('markers_truth', i, 'sphere', MARKER_COLOUR, (MARKER_DIAMETER,) * 3,
                            (float(centre.real), float(centre.imag), DEPTH / 2)))
    if phase is None:
        return shapes
    g = link_geometry(robot_params, float(phase)) if geometry is None else geometry
    hinge, rear = _to_surface([g.hinge, base_link_end(robot_params, g.base_angle)], x, y, theta)
    middle = 0.5 * (hinge + rear)
    shapes.append(Shape('base_link', 0, 'cube', LINK_COLOUR,
                        (abs(hinge - rear), 0.004, DEPTH), _xyz(middle),
                        float(np.angle(hinge - rear))))
    shift = 0.0 if deflection is None else 1j * np.asarray(deflection, float)
    plates = _to_surface(body.link_plates(robot_params, g.centres + shift,
                                          np.exp(1j * g.angles)), x, y, theta)
    # Two triangles per plate (corners 0 1 2 and 0 2 3).
    triangles = plates[:, [0, 1, 2, 0, 2, 3]].ravel()
    shapes.append(Shape('wave_links', 0, 'triangle_list', LINK_COLOUR, (1.0, 1.0, 1.0),
                        points=_points(triangles)))
    tips = _to_surface(np.concatenate([g.up_tips + shift, g.down_tips + shift]), x, y, theta)
    shapes.append(Shape('tips', 0, 'sphere_list', TIP_COLOUR, (TIP_DIAMETER,) * 3,
                        points=_points(tips)))
    return shapes


def squeezed(robot_params: RobotParams, gap: float, contacts: np.ndarray) -> List[Shape]:
    """
    Return the surfaces' squeezed bands: where each touching tip presses in, its dent.

    One triangle list per surface (0 bottom at y = 0, 1 top at y = gap): for every touching tip
    the band between the undeformed surface and the dent's profile (saw_ros.core.body.dents, the
    camera's), as deep as the tip's penetration.
    """
    half = body.dent_half_width(robot_params)
    shapes = []
    for surface, level, sign in ((0, 0.0, 1.0), (1, gap, -1.0)):
        depth = sign * (level - np.asarray(contacts['y'], float))
        pressed = (np.asarray(contacts['surface']) == surface) & (depth > 0.0)
        if not pressed.any():
            continue
        xs, d = body.dents(np.asarray(contacts['x'], float)[pressed], depth[pressed], half)
        # Each strip between two profile points: two triangles, (top a, top b, low b) and
        # (top a, low b, low a); top on the undeformed surface, low on the dent.
        a, b = xs[:, :-1], xs[:, 1:]
        top_a, top_b = a + 1j * level, b + 1j * level
        low_a, low_b = a + 1j * (level - sign * d[:, :-1]), b + 1j * (level - sign * d[:, 1:])
        corners = np.stack([top_a, top_b, low_b, top_a, low_b, low_a], axis=-1)
        shapes.append(Shape('squeezed', surface, 'triangle_list', SQUEEZE_COLOUR,
                            (1.0, 1.0, 1.0), points=_points(corners, SQUEEZE_Z)))
    return shapes


def force_arrows(x: Numbers, y: Numbers, normal: Numbers, tangential: Numbers, surface: Numbers,
                 slipping: Numbers, scale: float = FORCE_SCALE) -> List[Shape]:
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
                            points=np.array((start, end))))
    return shapes


def tracking(front: Optional[Point], back: Optional[Point],
             pose: Optional[Tuple[float, float, float]]) -> List[Shape]:
    """
    Return the tracker's marker centres (spheres) and its pose (x, y, pitch) as an arrow.

    Drawn in front of the robot (z = ESTIMATE_Z) and smaller than the true markers, so that the
    true pink marker shows around the estimate and any gap between them is visible.
    """
    shapes = []
    for i, centre in enumerate((front, back)):
        if centre is not None:
            shapes.append(Shape('tracking_markers', i, 'sphere', TRACKING_COLOUR,
                                (ESTIMATE_DIAMETER,) * 3,
                                (float(centre[0]), float(centre[1]), ESTIMATE_Z)))
    if pose is not None:
        px, py, pitch = pose
        end = (px + ESTIMATE_LENGTH * math.cos(pitch), py + ESTIMATE_LENGTH * math.sin(pitch),
               ESTIMATE_Z)
        shapes.append(Shape('tracking_pose', 0, 'arrow', TRACKING_COLOUR, (0.003, 0.006, 0.01),
                            points=np.array(((float(px), float(py), ESTIMATE_Z), end))))
    return shapes


def scene(robot_params: RobotParams, gap: float, pose: Tuple[float, float, float],
          phase: Optional[float], contacts: Optional[np.ndarray] = None,
          force_scale: float = FORCE_SCALE,
          walls: Optional[Tuple[np.ndarray, np.ndarray]] = None,
          geometry: Optional[LinkGeometry] = None,
          deflection: Optional[np.ndarray] = None) -> List[Shape]:
    """
    Return every shape of the ground truth at one instant (what /saw/markers draws).

    Surfaces with their squeezed bands under the touching tips, the robot, the contact forces.

    ``pose``: (x, y, pitch); ``phase``: the helix phase; ``contacts``: a structured array with the
    fields of /saw/contacts (x, y, normal_force, tangential_force, surface, slipping) or None.
    ``walls``: (abscissae, deflections (2, m)) of bending walls (``bent_surfaces``), or None for
    the flat ones. ``geometry``: the links' ``link_geometry`` at ``phase`` when the caller has it.
    ``deflection``: the links' deflections on their flexures (``robot``), or None.
    """
    x, y, theta = pose
    flat = surfaces(gap, x) if walls is None else bent_surfaces(gap, *walls)
    shapes = flat + robot(robot_params, gap, x, y, theta, phase, geometry, deflection)
    if contacts is not None and len(contacts):
        shapes += squeezed(robot_params, gap, contacts)
        shapes += force_arrows(contacts['x'], contacts['y'], contacts['normal_force'],
                               contacts['tangential_force'], contacts['surface'],
                               contacts['slipping'], force_scale)
    return shapes
