"""
What a viewer of /saw/markers and /saw/tracking/markers shows (docs/figures/markers_view.png).

The same shapes as the simulator and the vision node publish (saw_ros.interface.scene_markers),
drawn with matplotlib at one instant of a short simulation of the default scenario; the
tracker's estimate is stood in for by the true marker positions shifted by 3 mm, to show how
tracking and truth part.

    python -m saw_ros.analysis.figures.markers_view docs/figures/markers_view.png
"""
from __future__ import annotations

import math
import sys

import numpy as np

from saw_ros.core import body, Scenario, Simulator
from saw_ros.interface import scene_markers

SECONDS = 2.0
CONTACT_DTYPE = np.dtype([('x', 'f8'), ('y', 'f8'), ('normal_force', 'f8'),
                          ('tangential_force', 'f8'), ('surface', 'u1'), ('slipping', 'u1')])


def snapshot(seconds: float = SECONDS):
    """Return (scenario, pose, phase, contacts) after ``seconds`` of the default scenario."""
    scenario = Scenario()
    sim = Simulator(scenario)
    for _ in range(int(round(seconds / scenario.integration.dt))):
        sim.step()
    c = sim.contacts
    index = np.flatnonzero(c.touching[0])
    tips = sim.tip_positions[0][index]
    points = np.zeros(len(index), CONTACT_DTYPE)
    points['x'], points['y'] = tips.real, tips.imag
    points['normal_force'] = c.normal[0][index]
    points['tangential_force'] = c.tangential[0][index]
    points['surface'] = index // (len(sim.tip_positions[0]) // 2)
    points['slipping'] = c.slipping[0][index]
    x, y, theta = sim.q[:3, 0].tolist()
    return scenario, (x, y, theta), float(sim.phase[0]), points


def draw(shapes, ax) -> None:
    """Draw scene_markers shapes on a matplotlib axis, in mm (the picture plane x-y)."""
    from matplotlib.patches import Circle, Polygon, Rectangle
    from matplotlib.transforms import Affine2D
    for s in shapes:
        colour = s.colour
        if s.kind == 'cube':
            w, h = s.scale[0] * 1e3, s.scale[1] * 1e3
            patch = Rectangle((-w / 2, -h / 2), w, h, color=colour, lw=0)
            patch.set_transform(Affine2D().rotate(s.yaw).translate(
                s.position[0] * 1e3, s.position[1] * 1e3) + ax.transData)
            ax.add_patch(patch)
        elif s.kind == 'sphere':
            ax.add_patch(Circle((s.position[0] * 1e3, s.position[1] * 1e3),
                                s.scale[0] * 500, color=colour, zorder=4 + s.position[2]))
        elif s.kind == 'sphere_list':
            p = np.array(s.points) * 1e3
            ax.plot(p[:, 0], p[:, 1], 'o', color=colour, ms=3, zorder=3)
        elif s.kind == 'triangle_list':
            p = np.array(s.points)[:, :2] * 1e3
            for triangle in p.reshape(-1, 3, 2):
                ax.add_patch(Polygon(triangle, color=colour, lw=0.3, ec='0.45', zorder=2))
        elif s.kind == 'arrow':
            (x0, y0, _), (x1, y1, _) = s.points
            ax.annotate('', xy=(x1 * 1e3, y1 * 1e3), xytext=(x0 * 1e3, y0 * 1e3), zorder=5,
                        arrowprops={'arrowstyle': '->', 'color': colour, 'lw': 1.5})


def figure(path: str) -> None:
    """Write the picture of one instant to ``path``."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    scenario, pose, phase, contacts = snapshot()
    x, y, theta = pose
    rot = complex(math.cos(theta), math.sin(theta))
    front = complex(x, y) + rot * body.FRONT_MARKER_X + 0.003
    back = complex(x, y) + rot * body.BACK_MARKER_X + 0.003
    shapes = scene_markers.scene(scenario.robot, scenario.conditions.gap, pose, phase, contacts)
    shapes += scene_markers.tracking((front.real, front.imag, 0.0), (back.real, back.imag, 0.0),
                                     (x + 0.003, y, theta))
    fig, ax = plt.subplots(figsize=(10, 3.2), dpi=120)
    draw(shapes, ax)
    ax.set_xlim((x - 0.2) * 1e3, (x + 0.2) * 1e3)
    ax.set_ylim(-25, scenario.conditions.gap * 1e3 + 25)
    ax.set_aspect('equal')
    ax.set_xlabel('x (mm, frame surface)')
    ax.set_ylabel('y (mm)')
    ax.set_title(f'/saw/markers at t = {SECONDS:g} s: surfaces, robot as on camera (tips orange, '
                 f'markers pink), contact forces (1 cm/N; green stick, red slip); '
                 f'/saw/tracking/markers: estimate (magenta)', fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


if __name__ == '__main__':
    figure(sys.argv[1] if len(sys.argv) > 1 else 'markers_view.png')
