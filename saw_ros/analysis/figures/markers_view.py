"""
What a viewer of /saw/markers and /saw/tracking/markers shows (docs/figures/markers_view.png).

The same shapes as the simulator and the vision node publish (saw_ros.interface.scene_markers),
drawn with matplotlib at one instant of a short simulation of the default scenario; the
tracker's estimate is stood in for by the true marker positions shifted by 3 mm, to show how
tracking and truth part.

    python -m saw_ros.analysis.figures.markers_view docs/figures/markers_view.png

``viewer_pictures`` draws what docs/foxglove_layout.json and docs/saw_ros.rviz show, panel by
panel, from a real 3 s run: the rendered camera frame, the tracker on every frame, the markers
of both topics at the last frame, the simulated and tracked speeds:

    python -m saw_ros.analysis.figures.markers_view --viewers docs/figures
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


VIEW_SECONDS = 3.0


def _viewer_run(seconds: float = VIEW_SECONDS):
    """Return what the panels show: shapes at the last frame, its image, the speeds, the ARs."""
    from saw_ros.core.kinematics import v_theory
    from saw_ros.vision.camera import CameraModel
    from saw_ros.vision.frames import Renderer
    from saw_ros.vision.synthetic import frames, simulate_run
    from saw_ros.vision.tracker import Tracker
    scenario = Scenario()
    run = simulate_run(scenario, seconds)
    gap = scenario.conditions.gap
    camera = CameraModel(center_x=float(np.interp(seconds / 2, run.t, run.x)), center_y=gap / 2)
    renderer = Renderer(scenario.robot, gap, camera)
    tracker = Tracker(camera)
    tracked, image, res, t = [], None, None, 0.0
    for _, t, _, image in frames(run, renderer, run.frame_times()):
        res = tracker.update(image, t)
        if res.velocity_smoothed is not None:
            tracked.append((t, res.velocity_smoothed.real))
    traj = run.trajectory
    if res is None or traj is None:
        raise RuntimeError(f'the {seconds:g} s run gave no frame to show')
    _, pose, phase, points = snapshot(t)           # the ground truth at the last frame
    shapes = scene_markers.scene(scenario.robot, gap, pose, phase, points)
    xyz = (lambda p: None if p is None else (p.real, p.imag, 0.0))  # noqa: E731
    at = res.position
    shapes += scene_markers.tracking(xyz(res.front), xyz(res.back),
                                     (at.real, at.imag, res.pitch)
                                     if res.ok and at is not None and res.pitch is not None
                                     else None)
    vth = v_theory(scenario.robot, scenario.frequency)
    half = traj.t >= seconds - 1.0 / scenario.frequency          # the last whole cycle
    v_sim = float(np.polyfit(traj.t[half], traj.q[half, 0, 0], 1)[0])
    tr = np.array(tracked)
    last = tr[:, 0] >= seconds - 1.0 / scenario.frequency
    v_tracked = float(tr[last, 1].mean())
    values = {'ar_sim': v_sim / vth, 'ar_tracked': v_tracked / vth,
              'relative_error': abs(v_tracked - v_sim) / v_sim, 'v_theory_m_s': vth,
              'v_sim_m_s': v_sim, 'v_tracked_m_s': v_tracked}
    return shapes, pose, image, (traj.t, traj.q[:, 0, 3]), tr, values


def viewer_pictures(folder) -> None:
    """Write foxglove_view.png and rviz_view.png: what the two viewer files show, drawn by us."""
    from pathlib import Path

    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    shapes, pose, image, (t, vx), tracked, values = _viewer_run()
    folder = Path(folder)

    def scene_panel(ax, dark):
        draw(shapes, ax)
        ax.set_xlim((pose[0] - 0.25) * 1e3, (pose[0] + 0.25) * 1e3)
        ax.set_ylim(-20, 65)
        ax.set_aspect('equal')
        ax.set_facecolor('#303030' if dark else 'white')
        ax.tick_params(labelsize=6, colors='0.6' if dark else 'k')

    # Foxglove: 3D and Image on the left, Plot and Raw Messages on the right (the layout file).
    fig = plt.figure(figsize=(12, 6.2), dpi=100, facecolor='#15151a')
    grid = fig.add_gridspec(2, 2, width_ratios=(6, 4), height_ratios=(55, 45), wspace=0.08,
                            hspace=0.25, left=0.03, right=0.98, top=0.94, bottom=0.05)
    panels = {}
    for key, cell, title in (('3d', grid[0, 0], '3D  /saw/markers  /saw/tracking/markers'),
                             ('image', grid[1, 0], 'Image  /saw/camera/image_raw/compressed'),
                             ('plot', grid[0, 1], 'Plot  forward speed (m/s)'),
                             ('raw', grid[1, 1], 'Raw Messages  /saw/comparison')):
        ax = fig.add_subplot(cell)
        ax.set_title(title, fontsize=8, color='0.85', loc='left')
        panels[key] = ax
    scene_panel(panels['3d'], dark=False)        # the layout's backgroundColor: white
    panels['image'].imshow(image[:, :, ::-1])
    panels['image'].axis('off')
    ax = panels['plot']
    ax.set_facecolor('#1e1e24')
    ax.plot(t, vx, lw=0.5, color='#4e98e2', label='/saw/twist.twist.linear.x')
    ax.plot(tracked[:, 0], tracked[:, 1], lw=1.2, color='#f5774d',
            label='/saw/tracking/twist_smoothed.twist.linear.x')
    ax.tick_params(labelsize=6, colors='0.7')
    ax.legend(fontsize=6, loc='lower right')
    ax = panels['raw']
    ax.set_facecolor('#1e1e24')
    ax.axis('off')
    text = 'status:\n  - name: "comparison"\n    values:\n' + ''.join(
        f'      - key: "{k}"  value: "{v:.4g}"\n' for k, v in values.items())
    ax.text(0.02, 0.95, text, va='top', family='monospace', fontsize=7, color='0.85',
            transform=ax.transAxes)
    fig.savefig(folder / 'foxglove_view.png', facecolor=fig.get_facecolor())
    plt.close(fig)

    # RViz: the two MarkerArray displays on the fixed frame surface, the Image display below.
    fig = plt.figure(figsize=(10, 6.4), dpi=100, facecolor='#d6d6d6')
    grid = fig.add_gridspec(2, 1, height_ratios=(50, 50), hspace=0.15, left=0.05, right=0.98,
                            top=0.95, bottom=0.03)
    ax = fig.add_subplot(grid[0])
    scene_panel(ax, dark=False)
    ax.set_title('RViz: Fixed Frame surface, TopDownOrtho; MarkerArray /saw/markers and '
                 '/saw/tracking/markers', fontsize=8, loc='left')
    ax = fig.add_subplot(grid[1])
    ax.imshow(image[:, :, ::-1])
    ax.axis('off')
    ax.set_title('Image display: /saw/camera/image_raw', fontsize=8, loc='left')
    fig.savefig(folder / 'rviz_view.png', facecolor=fig.get_facecolor())
    plt.close(fig)


if __name__ == '__main__':
    if len(sys.argv) > 2 and sys.argv[1] == '--viewers':
        viewer_pictures(sys.argv[2])
    else:
        figure(sys.argv[1] if len(sys.argv) > 1 else 'markers_view.png')
