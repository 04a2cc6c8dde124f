"""The simulator node with walls that bend (issue 23): their shape on /saw/walls, drawn bent."""
import numpy as np
import pytest
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from saw_ros.graph.process import ManagedProcess, node_command, wait_for

pytestmark = pytest.mark.ros

from saw_ros.interface import topics as table  # noqa: E402, I100
from saw_ros.ros.conversions import WALL_DTYPE  # noqa: E402
from saw_ros.ros.qos import message_class  # noqa: E402

SHEET = {'surface.foundation_stiffness': 1.5e5, 'surface.bending_stiffness': 6.25e-4}


def run_and_record(context, tmp_path, params):
    """Run the simulator to its duration; return the raw /saw/walls and /saw/markers received."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    sim = ManagedProcess('simulator', node_command('simulator', params=params), env=None,
                         log_dir=tmp_path)
    node = Node('walls_watcher', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    got = {table.WALLS: [], table.MARKERS: []}
    qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE)
    for name in got:
        node.create_subscription(message_class(table.topic(name).type), name, got[name].append,
                                 qos, raw=True)
    spin = lambda t: executor.spin_once(timeout_sec=t)  # noqa: E731
    try:
        assert wait_for(lambda: sim.returncode is not None, 60, spin=spin), sim.output()
        wait_for(lambda: False, 0.5, spin=spin)      # what is still in flight
    finally:
        executor.shutdown(timeout_sec=1)
        node.destroy_node()
    assert sim.wait(timeout=5) == 0 and 'Traceback' not in sim.output()
    return got


def surfaces_of(raw_markers):
    markers = deserialize_message(raw_markers, message_class(table.topic(table.MARKERS).type))
    return [m for m in markers.markers if m.ns == 'surfaces']


# The sheet quasi-static, and with its mass (issue 31: the walls' modes in the node's step).
@pytest.mark.parametrize('walls', [SHEET, dict(SHEET, **{'walls.mass': 0.33,
                                                         'walls.damping': 22.0})],
                         ids=['quasi-static', 'with-mass'])
def test_bending_walls_are_published_and_drawn_bent(ros_context, tmp_path, walls):
    got = run_and_record(ros_context, tmp_path, dict(walls, real_time_factor=1.0,
                                                     duration=1.0))
    assert len(got[table.WALLS]) > 20, 'no /saw/walls'
    cloud = deserialize_message(got[table.WALLS][-1], message_class(table.topic(table.WALLS).type))
    assert cloud.header.frame_id == 'surface'
    points = np.frombuffer(bytes(cloud.data), WALL_DTYPE)
    bottom, top = points[points['surface'] == 0], points[points['surface'] == 1]
    assert len(bottom) == len(top) == cloud.width // 2
    # The squeezed robot pushes both walls away: the bottom goes below 0, the top above the gap.
    assert bottom['deflection'].max() > 2e-4 and top['deflection'].max() > 2e-4
    np.testing.assert_allclose(bottom['y'], -bottom['deflection'], atol=1e-7)
    np.testing.assert_allclose(top['y'], 0.045 + top['deflection'], atol=1e-6)
    # /saw/markers draws them as triangle strips (namespace 'surfaces'), not the flat cubes.
    walls = surfaces_of(got[table.MARKERS][-1])
    assert len(walls) == 2 and all(m.type == m.TRIANGLE_LIST for m in walls)
    assert min(p.y for p in walls[0].points) < -2e-4


def test_rigid_walls_publish_no_shape(ros_context, tmp_path):
    got = run_and_record(ros_context, tmp_path, {'real_time_factor': 1.0, 'duration': 0.5})
    assert got[table.MARKERS] and not got[table.WALLS]
    walls = surfaces_of(got[table.MARKERS][-1])
    assert len(walls) == 2 and all(m.type == m.CUBE for m in walls)


# The soft-tissue set of docs/walls.md: walls that bend by millimetres under the robot.
TISSUE = {'surface.foundation_stiffness': 9e3, 'surface.bending_stiffness': 1.2e-5}
CAMERA_DURATION = 0.5   # s of simulated time, at real time


def test_camera_draws_the_walls_bent_as_published(ros_context, still_camera,
                                                  run_simulator_into_camera):
    """
    Simulator (soft-tissue walls) and camera in this process's executor, through real topics.

    Every frame is the renderer's picture with a /saw/walls shape stamped at or before it (bit
    for bit), never the flat picture, and the bottom wall's edge under the robot is lower than
    flat by the published deflection.
    """
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from saw_ros.ros import conversions as conv
    from saw_ros.ros.nodes.simulator import SimulatorNode
    from saw_ros.ros.qos import profile
    from sensor_msgs.msg import Image, PointCloud2

    simulator = SimulatorNode(context=ros_context, parameter_overrides=[
        Parameter(name, value=value) for name, value in TISSUE.items()] + [
        Parameter('real_time_factor', value=1.0),
        Parameter('duration', value=CAMERA_DURATION)])
    # A 640x360 picture around the robot's start (x 0), no follow, raw images only, a plain
    # grey wall behind (175: the silicone's edge measurable).
    camera = still_camera(ros_context)
    watcher = Node('walls_camera_watcher', context=ros_context)
    images, clouds = [], []
    watcher.create_subscription(Image, table.IMAGE, images.append, profile('image'))
    watcher.create_subscription(PointCloud2, table.WALLS, clouds.append, profile('tracking'))
    executor = SingleThreadedExecutor(context=ros_context)
    for node in (simulator, camera, watcher):
        executor.add_node(node)
    spin = lambda t: executor.spin_once(timeout_sec=t)  # noqa: E731
    frames = int(CAMERA_DURATION * 60)      # 1/60 .. 30/60 s: the first pose is at 1 ms
    run_simulator_into_camera(simulator, camera, (simulator, camera, watcher), executor, spin,
                              frames, images,
                              lambda: simulator._pub_walls.get_subscription_count() >= 2)

    assert len(images) == frames and camera.received['walls'] == len(clouds) >= frames
    shapes = [(conv.stamp_ns(c.header.stamp), conv.walls_of(c)) for c in clouds]
    stamps = [t for t, _ in shapes]
    assert stamps == sorted(stamps)
    renderer, cam = camera.renderer, camera.camera
    for image in images:
        t = conv.stamp_ns(image.header.stamp)
        got = np.frombuffer(bytes(image.data), np.uint8).reshape(cam.height, cam.width, 3)
        pose = camera.pose_at(t)
        assert not np.array_equal(got, renderer.render(pose)), f'flat walls at {t} ns'
        # The shape the camera had: the last received at or before t (the one stamped in the
        # same step may come after the frame's pose).
        before = [s for s in shapes if s[0] <= t][-3:]
        match = [ts for ts, walls in before
                 if np.array_equal(got, renderer.render(pose, walls=walls))]
        assert match, (t, [ts for ts, _ in before])
    # The last frame, bent: wherever the bottom wall is pushed away by more than a quarter of
    # its largest deflection and the robot does not cover its edge, the edge is lower than the
    # flat wall's (drawn without the robot: flat, the tips would dent it as deep) by the
    # deflection there (to a pixel: OpenCV draws horizontal edges on whole rows).
    _, (along, deflection) = shapes[stamps.index(match[-1])]
    w = deflection[0].max()
    assert w * cam.scale > 2.0, w                   # millimetres: pixels
    flat = renderer.render(pose._replace(x=pose.x + 5.0))
    v0 = cam.to_pixels(np.array([0j]))[0].imag      # the flat edge (slope 0: every column)
    pushed = along[deflection[0] > 0.25 * w]
    u0, u1 = (int(round(cam.to_pixels(np.array([x + 0j]))[0].real)) for x in pushed[[0, -1]])

    def edge(img, u, v):
        """Return the silicone's top edge in column u near row v; None where the robot is."""
        lo, hi = int(round(v)) - 4, int(round(v)) + 6
        bgr = img[lo:hi, u].astype(float)
        c = (bgr[:, 1] - 175.0) / 30.0              # background 175 .. silicone G 205
        if not ((np.abs(bgr[:, 0] - 175.0 - 25.0 * c) <= 2).all()
                and (np.abs(bgr[:, 2] - 175.0 - 35.0 * c) <= 2).all()):
            return None
        return hi - np.clip(c, 0.0, 1.0).sum()

    shifts = []
    for u in range(max(min(u0, u1), 0), min(max(u0, u1) + 1, cam.width)):
        x = cam.to_surface(np.array([u + v0 * 1j]))[0].real
        v = cam.to_pixels(np.array([x - 1j * float(np.interp(x, along, deflection[0]))]))[0].imag
        bent = edge(got, u, v)
        if bent is not None:
            shifts.append((bent - edge(flat, u, v0), v - v0))
    assert len(shifts) >= 10, (u0, u1, shifts)
    # To a pixel as a rule (edges on whole rows, sloped ones anti-aliased), a little more beside
    # a tip that dents the deflected wall.
    error = np.abs([s - want for s, want in shifts])
    assert np.median(error) <= 0.6 and error.max() <= 1.5, shifts
    assert max(s for s, _ in shifts) >= 0.5 * w * cam.scale, (shifts, w * cam.scale)


def test_camera_refuses_a_cloud_that_is_not_the_walls_and_keeps_running(ros_context, capfd):
    """A /saw/walls cloud with other fields: one warning, no shape kept, the next good one is."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from saw_ros.graph.process import wait_for
    from saw_ros.ros import conversions as conv
    from saw_ros.ros.nodes.camera import CameraNode
    from saw_ros.ros.qos import publisher_profile
    from sensor_msgs.msg import PointCloud2

    camera = CameraNode(context=ros_context)
    source = Node('walls_source', context=ros_context)
    pub = source.create_publisher(PointCloud2, table.WALLS, publisher_profile('tracking'))
    executor = SingleThreadedExecutor(context=ros_context)
    for node in (camera, source):
        executor.add_node(node)
    spin = lambda t: executor.spin_once(timeout_sec=t)  # noqa: E731
    along = np.linspace(-0.5, 0.5, 201)
    good = conv.walls_cloud(along, np.full((2, 201), 1e-3), 0.045, 2_000_000)
    bad = PointCloud2(height=1, width=good.width, fields=list(good.fields)[:3],     # x, y, z
                      point_step=good.point_step, row_step=good.row_step, is_dense=True)
    bad.data = bytes(good.data)
    conv.time_msg(1_000_000, bad.header.stamp)
    try:
        assert wait_for(lambda: pub.get_subscription_count() > 0, 10.0, spin=spin)
        for msg in (bad, bad):
            pub.publish(msg)
        refused = lambda: camera.guard.counts.get((table.WALLS, 'not a wall shape'), 0)  # noqa
        assert wait_for(lambda: refused() == 2, 5.0, spin=spin)
        wait_for(lambda: False, 0.2, spin=spin)
        assert camera.received['walls'] == 0 and camera._walls.before(10 ** 10) is None
        pub.publish(good)
        assert wait_for(lambda: camera.received['walls'] == 1, 5.0, spin=spin)
        assert refused() == 2
        shape = camera._walls.before(2_000_000)
        np.testing.assert_allclose(shape.deflection, 1e-3, rtol=1e-6)
    finally:
        executor.shutdown()
        camera.close()
        for node in (camera, source):
            node.destroy_node()
    err = capfd.readouterr().err
    assert err.count('message on /saw/walls refused, not used: not a wall shape') == 1 and \
        'Traceback' not in err, err
    assert 'wrong or missing: deflection, surface' in err
