"""
The robot's URDF, generated from the core's parameters (pure: no rclpy).

``urdf/saw.urdf`` is this module's output for the default robot
(``python -m saw_ros.interface.urdf --write urdf/saw.urdf``; tests/interface/test_urdf.py pins
it); the simulator publishes the URDF of the robot it simulates on ``/robot_description``.

Its joints are exactly the names of ``/saw/joint_states`` (``joint_names``), each moving the
link of the same name, so robot_state_publisher (remapped to /saw/joint_states) and RViz's
RobotModel draw every link where the core puts it: the wave's motion in the plane, not only its
turning. Frames as saw_ros.interface.frames and the core's body frame (saw_ros.core.kinematics):
``base_link`` at the centre of mass, x forward, y normal to the surfaces, z out of the side view.

- ``helix``: continuous, about x, at the wave's middle; its position is the wave phase.
- ``base_link_joint``: revolute about -z at the hinge on the head (the core's base-link angle is
  positive with the rear end up); the base link reaches back ``base_link_width``.
- each wave link NN, a chain of four joints from ``base_link``, all motion in the plane
  (robot_state_publisher has no planar joint: KDL reads URDF's ``planar`` as fixed):
  ``link_NN_x`` prismatic along body x from the centre's rest abscissa (0 in the kinematic
  model, where the centres keep their abscissa), ``link_NN_y`` prismatic along body y (the
  centre's height on the wave, A cos(...)), ``link_NN_flex`` prismatic along body y (the link's
  deflection e from that kinematic target on its flexure, core.flexure: 0 for rigid links),
  ``link_NN`` revolute about z (the backbone slope there, the core's link angle relative to
  body x). The first three move the frameless links ``link_NN_x``, ``link_NN_y`` and
  ``link_NN_flex``; ``link_NN`` carries the drawing.

The deflection is drawn normal to the backbone (body y), as the flexure acts; the core applies
it to the tips' depths along the walls' normal (core.flexure), the same to first order in the
body's pitch theta: the two differ by e sin(theta) along the walls (up to 0.23 mm for the
1463 N/m set of docs/compliant_robot.md at 6 V on the level, whose links deflect up to 3.6 mm
and whose body pitches up to 3.6 degrees) and by e (1 - cos(theta)) across them (7 um).

``link_frames`` gives every frame of the tree at a phase from the core's ``link_geometry`` (the
simulator's own TF, without robot_state_publisher); ``JointStateTable`` the joint values of
/saw/joint_states (100 Hz) from a table of the same (docs/viewers.md).
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys
from typing import List, Optional, Tuple

import numpy as np

from saw_ros.core.kinematics import cycle_phases, hinge_x, link_geometry, LinkGeometry
from saw_ros.core.kinematics import PhaseTable
from saw_ros.core.params import RobotParams

NAME = 'saw'
# Visual thickness across the side view (z): the drawing's, not a model parameter.
DEPTH = 0.04


def link_names(robot: RobotParams) -> List[str]:
    """Return the wave links' names, head first (the core's link order)."""
    return [f'link_{i:02d}' for i in range(robot.wave_links)]


def joint_names(robot: RobotParams) -> List[str]:
    """
    Return the joints of the URDF, in /saw/joint_states' order.

    The helix, the base link, every wave link's angle, then every link's position along x, then
    along y, then its deflection on its flexure: 2 + 4 n joints. The first 2 + n are those of
    the earlier, angle-only model, the first 2 + 3 n those of the rigid links' (issue 34), at
    the same places.
    """
    links = link_names(robot)
    return (['helix', 'base_link_joint'] + links + [f'{n}_x' for n in links]
            + [f'{n}_y' for n in links] + [f'{n}_flex' for n in links])


def flex_limit(robot: RobotParams) -> float:
    """
    Return the largest deflection of a link on its flexure, m: the ``link_NN_flex`` joints' limit.

    As far as the wave moves a link (2 A): more than the gap leaves it.
    """
    return 2.0 * robot.amplitude


def rest_abscissae(robot: RobotParams) -> np.ndarray:
    """Return each wave link centre's body abscissa at phase 0 (its joint's origin), m."""
    return np.asarray(link_geometry(robot, 0.0).centres.real, dtype=float)


# A frame of the robot's tree: parent, child, translation (m), rotation quaternion (x, y, z, w).
Frame = Tuple[str, str, Tuple[float, float, float], Tuple[float, float, float, float]]


def link_frames(robot: RobotParams, phase: float, geometry: Optional[LinkGeometry] = None,
                deflection: Optional[np.ndarray] = None) -> List[Frame]:
    """
    Return every joint's frame below ``base_link`` at wave ``phase``, from the core's geometry.

    The transforms robot_state_publisher computes from the URDF and exact joint values: helix,
    base link, and per wave link ``link_NN_x``, ``link_NN_y``, ``link_NN_flex``, ``link_NN``.
    ``geometry``: the core's ``link_geometry`` at ``phase``, when the caller has it already;
    ``deflection`` (n,): each link's deflection on its flexure (m, Simulator.deflection; None:
    rigid links, 0).
    """
    geo = link_geometry(robot, phase) if geometry is None else geometry
    flex = [0.0] * robot.wave_links if deflection is None else np.asarray(deflection).tolist()
    zero = (0.0, 0.0, 0.0)
    half, base = 0.5 * phase, 0.5 * float(geo.base_angle)     # half angles (quaternions)
    frames: List[Frame] = [
        ('base_link', 'helix', (_helix_x(robot), 0.0, 0.0),
         (math.sin(half), 0.0, 0.0, math.cos(half))),
        ('base_link', 'base_link_joint', (geo.hinge.real, geo.hinge.imag, 0.0),
         (0.0, 0.0, -math.sin(base), math.cos(base)))]      # about -z, as its joint's axis
    for name, centre, angle, e in zip(link_names(robot), geo.centres.tolist(),
                                      geo.angles.tolist(), flex):
        frames += [('base_link', f'{name}_x', (float(centre.real), 0.0, 0.0),
                    (0.0, 0.0, 0.0, 1.0)),
                   (f'{name}_x', f'{name}_y', (0.0, float(centre.imag), 0.0),
                    (0.0, 0.0, 0.0, 1.0)),
                   (f'{name}_y', f'{name}_flex', (0.0, float(e), 0.0), (0.0, 0.0, 0.0, 1.0)),
                   (f'{name}_flex', name, zero, (0.0, 0.0, math.sin(0.5 * angle),
                                                 math.cos(0.5 * angle)))]
    return frames


class JointStateTable(PhaseTable):
    """
    The joint values of /saw/joint_states after the helix, over one wave cycle (``joint_names``).

    Columns: base-link angle, link angles (rad), link centres along x from their rest abscissa
    and along y (m), all from the core's ``link_geometry``; the flexures' deflections, which the
    wave's phase does not give, are appended by ``values_and_rates``. Linear interpolation over
    4096 samples: within 1e-5 rad (the base link's angle, solved by Newton iterations in the
    core) and 1e-8 m; the simulator's TF uses the exact geometry (``link_frames``).
    """

    def __init__(self, robot: RobotParams, samples: int = 4096):
        """Tabulate ``robot``'s joint values at ``samples`` phases over a cycle."""
        geo = link_geometry(robot, cycle_phases(samples))
        rest = rest_abscissae(robot)
        super().__init__(np.concatenate([geo.base_angle[:, None], geo.angles,
                                         geo.centres.real - rest, geo.centres.imag], axis=1),
                         samples)
        self.derivative = self.slopes * self.scale      # d value / d phase, per sample

    def values_and_rates(self, phase: float, omega: float = 0.0,
                         deflection: Optional[np.ndarray] = None,
                         deflection_rate: Optional[np.ndarray] = None
                         ) -> Tuple[np.ndarray, np.ndarray]:
        """
        Return the joint values after the helix and their rates at ``phase``: 1 + 4 n each.

        ``phase`` is wrapped into [0, 2 pi); rates (rad/s, m/s) are for helix speed ``omega``.
        The links' flexure joints last: ``deflection`` (m) and ``deflection_rate`` (m/s), (n,)
        each (Simulator.deflection and deflection_rate; None: rigid links, 0).
        """
        i, w = self.index(phase % (2.0 * math.pi))
        values, rates = self.points[i] + w * self.slopes[i], self.derivative[i] * omega
        n = (values.size - 1) // 3
        return (np.concatenate([values, np.zeros(n) if deflection is None else deflection]),
                np.concatenate([rates, np.zeros(n) if deflection_rate is None
                                else deflection_rate]))


def _helix_x(robot: RobotParams) -> float:
    """Return the helix joint's abscissa: the middle of the wave links."""
    return hinge_x(robot) - robot.base_link_width - robot.wave_links * robot.link / 2.0


def _f(value: float) -> str:
    return f'{value:.9g}'   # nm: the joint origins must not move a link a visible 1e-7 m


def _xyz(*values: float) -> str:
    return ' '.join(_f(v) for v in values)


def _box(size_x: float, size_y: float, x: float, colour: str) -> List[str]:
    return ['    <visual>',
            f'      <origin xyz="{_xyz(x, 0.0, 0.0)}" rpy="0 0 0"/>',
            f'      <geometry><box size="{_xyz(size_x, size_y, DEPTH)}"/></geometry>',
            f'      <material name="{colour}"/>',
            '    </visual>']


def urdf(robot: Optional[RobotParams] = None) -> str:
    """Return the URDF text of ``robot`` (default: the paper's robot)."""
    robot = robot or RobotParams()
    hinge = hinge_x(robot)
    head = robot.length / 2.0 - hinge                # hinge to the front end
    b = robot.link
    wave = robot.wave_links * b
    k = 2.0 * math.pi / robot.wavelength
    steepest = math.atan(robot.amplitude * k)       # largest backbone slope, rad
    lines = ['<?xml version="1.0"?>',
             '<!-- Generated by saw_ros.interface.urdf from saw_ros.core.params.RobotParams '
             f'(mass {_f(robot.mass)} kg, length {_f(robot.length)} m, {robot.wave_links} wave '
             f'links of {_f(b)} m): do not edit. -->',
             f'<robot name="{NAME}">',
             '  <material name="body"><color rgba="0.25 0.25 0.3 1"/></material>',
             '  <material name="helix"><color rgba="0.8 0.8 0.8 0.5"/></material>',
             '  <material name="link"><color rgba="0.95 0.6 0.1 1"/></material>',
             '  <link name="base_link">']
    lines += _box(head, robot.height, hinge + head / 2.0, 'body')
    # The core's body is planar: only the pitch inertia (about z) is modelled. iyy as izz and a
    # small ixx are what a slender bar along x would have; no ROS tool here uses them.
    inertia = robot.inertia
    lines += ['    <inertial>',
              '      <origin xyz="0 0 0" rpy="0 0 0"/>',
              f'      <mass value="{_f(robot.mass)}"/>',
              f'      <inertia ixx="{_f(inertia / 100.0)}" ixy="0" ixz="0" iyy="{_f(inertia)}" '
              f'iyz="0" izz="{_f(inertia)}"/>',
              '    </inertial>',
              '  </link>']
    # The helix: a cylinder along x through the wave links' centres.
    lines += ['  <joint name="helix" type="continuous">',
              '    <parent link="base_link"/>',
              '    <child link="helix"/>',
              f'    <origin xyz="{_xyz(_helix_x(robot), 0.0, 0.0)}" rpy="0 0 0"/>',
              '    <axis xyz="1 0 0"/>',
              '  </joint>',
              '  <link name="helix">',
              '    <visual>',
              '      <origin xyz="0 0 0" rpy="0 1.5707963 0"/>',
              f'      <geometry><cylinder radius="{_f(robot.amplitude)}" length="{_f(wave)}"/>'
              '</geometry>',
              '      <material name="helix"/>',
              '    </visual>',
              '  </link>']
    lines += ['  <joint name="base_link_joint" type="revolute">',
              '    <parent link="base_link"/>',
              '    <child link="base_link_joint"/>',
              f'    <origin xyz="{_xyz(hinge, 0.0, 0.0)}" rpy="0 0 0"/>',
              '    <axis xyz="0 0 -1"/>',
              f'    <limit lower="{_f(-math.pi / 2)}" upper="{_f(math.pi / 2)}" effort="0" '
              'velocity="0"/>',
              '  </joint>',
              '  <link name="base_link_joint">']
    lines += _box(robot.base_link_width, 2.0 * robot.tip_distance,
                  -robot.base_link_width / 2.0, 'link')
    lines += ['  </link>']
    # Each wave link: along x (a link may move half its width either way), along y (the
    # wave's crest and trough, and as much again), deflecting on its flexure (as far: more than
    # the gap leaves it), turning.
    for name, x in zip(link_names(robot), rest_abscissae(robot).tolist()):
        for suffix, parent, axis, origin, low, high in (
                ('_x', 'base_link', '1 0 0', x, -b / 2.0, b / 2.0),
                ('_y', f'{name}_x', '0 1 0', 0.0, -2.0 * robot.amplitude, 2.0 * robot.amplitude),
                ('_flex', f'{name}_y', '0 1 0', 0.0, -flex_limit(robot), flex_limit(robot)),
                ('', f'{name}_flex', '0 0 1', 0.0, -steepest, steepest)):
            lines += [f'  <joint name="{name}{suffix}" '
                      f'type="{"revolute" if suffix == "" else "prismatic"}">',
                      f'    <parent link="{parent}"/>',
                      f'    <child link="{name}{suffix}"/>',
                      f'    <origin xyz="{_xyz(origin, 0.0, 0.0)}" rpy="0 0 0"/>',
                      f'    <axis xyz="{axis}"/>',
                      f'    <limit lower="{_f(low)}" upper="{_f(high)}" effort="0" '
                      'velocity="0"/>',
                      '  </joint>',
                      f'  <link name="{name}{suffix}">']
            if suffix == '':
                lines += _box(b, 2.0 * robot.tip_distance, 0.0, 'link')
            lines += ['  </link>']
    lines += ['</robot>', '']
    return '\n'.join(lines)


def main(argv: Optional[List[str]] = None) -> int:
    """Print the default robot's URDF, or write it (``--write``)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    parser.add_argument('--write', metavar='PATH', help='write the default robot URDF here')
    args = parser.parse_args(argv)
    text = urdf()
    if args.write:
        Path(args.write).write_text(text, encoding='utf-8')
    else:
        sys.stdout.write(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
