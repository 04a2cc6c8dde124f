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


def test_bending_walls_are_published_and_drawn_bent(ros_context, tmp_path):
    got = run_and_record(ros_context, tmp_path, dict(SHEET, real_time_factor=1.0,
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
