"""
The TF tree of the graph (REP 103, REP 105 style), pure: frame names and the static camera pose.

    surface -> base_link            /tf, simulator, at markers_rate (60 Hz of simulated time)
    surface -> base_link_tracked    /tf, vision, every tracked frame (the tracker's estimate)
    surface -> saw_camera           /tf_static, camera, once (latched)

``surface`` is the fixed frame (x along the surfaces in the direction of travel, y normal from
the bottom surface, z out of the side-view plane); ``base_link`` the robot body at its centre of
mass; ``saw_camera`` the camera's optical frame (REP 103 optical: z along the viewing direction,
x to the image's right, y down), so that the images and camera infos stamped in it can be placed
in ``surface``. The wave's links under ``base_link`` come from the URDF (saw_ros.interface.urdf)
through robot_state_publisher and /saw/joint_states, where one runs.
"""
from __future__ import annotations

import math
from typing import Sequence, Tuple

SURFACE = 'surface'
BASE_LINK = 'base_link'
TRACKED = 'base_link_tracked'
CAMERA = 'saw_camera'


def yaw_quaternion(theta: float) -> Tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation by ``theta`` about z (the robot's pitch in the side view)."""
    return 0.0, 0.0, math.sin(theta / 2.0), math.cos(theta / 2.0)


def _quaternion(m: Sequence[Sequence[float]]) -> Tuple[float, float, float, float]:
    """(x, y, z, w) of a proper rotation matrix (rows of a 3x3 nested sequence)."""
    trace = m[0][0] + m[1][1] + m[2][2]
    if trace > 0.0:
        s = 2.0 * math.sqrt(1.0 + trace)
        return ((m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s,
                0.25 * s)
    i = max(range(3), key=lambda k: m[k][k])
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * math.sqrt(1.0 + m[i][i] - m[j][j] - m[k][k])
    q = [0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (m[j][i] + m[i][j]) / s
    q[k] = (m[k][i] + m[i][k]) / s
    return q[0], q[1], q[2], (m[k][j] - m[j][k]) / s


def camera_pose(center_x: float, center_y: float, distance: float, slope: float,
                mirror: bool) -> Tuple[Tuple[float, float, float],
                                       Tuple[float, float, float, float]]:
    """
    ``saw_camera`` in ``surface``: (translation, quaternion x, y, z, w).

    From saw_ros.vision.camera.CameraModel's mapping: the level camera sees surface point
    (center_x, center_y) at its principal point from ``distance``; the image's u axis is the
    level horizontal, which is the surface x axis turned by -slope (mirrored: its opposite), and
    v points down. The optical z axis (u x v) then looks along -z of the surface frame, so the
    camera sits at +distance on z (mirrored: at -distance, looking along +z).
    """
    c, s = math.cos(slope), math.sin(slope)
    sign = -1.0 if mirror else 1.0
    x_axis = (sign * c, -sign * s, 0.0)       # image u (right), in surface axes
    y_axis = (-s, -c, 0.0)                    # image v (down)
    z_axis = (0.0, 0.0, -sign)                # u x v: the viewing direction
    rotation = [[x_axis[r], y_axis[r], z_axis[r]] for r in range(3)]
    return (center_x, center_y, sign * distance), _quaternion(rotation)
