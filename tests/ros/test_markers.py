"""
The robot for viewers: /saw/markers from the simulator, through real topics.

The simulator node runs in this process's executor at full speed for 0.1 s of simulated time;
a subscriber decodes its MarkerArrays with rclpy (not our code) and checks them against the
core's own state at the same stamps.
"""
import math
import time

import numpy as np
import pytest
from saw_ros.analysis.figures.markers_view import snapshot
from saw_ros.core import Scenario, Simulator
from saw_ros.interface import scene_markers
from saw_ros.interface import topics as table
from saw_ros.ros import conversions as conv
from saw_ros.ros import markers

pytestmark = pytest.mark.ros

STEPS = 100


def test_marker_array_cdr_is_what_rclpy_serializes():
    from rclpy.serialization import deserialize_message, serialize_message
    from visualization_msgs.msg import MarkerArray
    scenario, pose, phase, contacts = snapshot(0.7)
    shapes = scene_markers.scene(scenario.robot, scenario.conditions.gap, pose, phase, contacts)
    shapes += scene_markers.tracking((0.3, 0.02, 0.0), (0.0, 0.021, 0.0), (0.15, 0.02, 0.05))
    ours = markers.marker_array_cdr(shapes, 1_234_567_891)
    # Colours are float32 on the wire: compare after rclpy's own round trip of its message.
    theirs = deserialize_message(serialize_message(markers.marker_array(shapes, 1_234_567_891)),
                                 MarkerArray)
    decoded = deserialize_message(ours, MarkerArray)
    assert decoded == theirs
    assert len(ours) == len(serialize_message(theirs))


def test_a_marker_arrays_stamp_is_read_from_its_first_marker():
    from saw_ros.ros.cdr import array_stamp_ns
    assert array_stamp_ns(markers.marker_array_cdr([], 1_234_567_891)) == 1_234_567_891


def test_decimator_starts_one_array_per_slot_of_stamps():
    decimator = markers.Decimator(60.0)
    due = [k for k in range(0, 101) if decimator.due(k * 1_000_000)]
    assert due == [0, 17, 34, 50, 67, 84, 100]
    assert not any(markers.Decimator(0.0).due(k * 1_000_000) for k in range(100))


def test_simulator_publishes_the_robot_at_60_hz_of_stamps(ros_context):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from saw_ros.graph.process import wait_for
    from saw_ros.ros.nodes.simulator import SimulatorNode
    from saw_ros.ros.qos import profile
    from visualization_msgs.msg import Marker, MarkerArray

    viewer = Node('viewer', context=ros_context)
    arrays = []
    viewer.create_subscription(MarkerArray, table.MARKERS, arrays.append, profile('tracking'))
    simulator = SimulatorNode(context=ros_context, parameter_overrides=[
        Parameter('real_time_factor', value=0.0), Parameter('duration', value=STEPS / 1000),
        Parameter('wait_for_subscribers', value=0)])
    executor = SingleThreadedExecutor(context=ros_context)
    for node in (viewer, simulator):
        executor.add_node(node)
    spin = lambda t: executor.spin_once(timeout_sec=t)  # noqa: E731
    try:
        # Matched before the first step (no spin has run a tick yet), so that no array is lost.
        simulator.started = False
        assert wait_for(lambda: simulator._pub_markers.get_subscription_count() > 0, 10.0,
                        spin=spin)
        simulator.started = True
        simulator._rebase(time.monotonic())
        assert wait_for(lambda: simulator.finished, 20.0, spin=spin)
        assert wait_for(lambda: len(arrays) >= 7, 5.0, spin=spin)
    finally:
        executor.shutdown()
        simulator.destroy_node()
        viewer.destroy_node()

    # Stamps 1..100 ms: one array at the first stamp of each 1/60 s slot.
    stamps = [conv.stamp_ns(a.markers[0].header.stamp) // 1_000_000 for a in arrays]
    assert stamps == [1, 17, 34, 50, 67, 84, 100]

    # The core, same parameters: every array drawn at that step's pose and phase.
    scenario = Scenario()
    sim = Simulator(scenario)
    states = {}
    for step in range(1, STEPS + 1):
        sim.step()
        states[step] = (sim.q[:3, 0].copy(), float(sim.phase[0]), int(sim.contacts.touching.sum()))
    for array, step in zip(arrays, stamps):
        (x, y, theta), phase, touching = states[step]
        assert array.markers[0].action == Marker.DELETEALL
        assert all(m.header.frame_id == 'surface' for m in array.markers)
        ns = {}
        for m in array.markers[1:]:
            ns.setdefault(m.ns, []).append(m)
        surfaces = sorted(m.pose.position.y for m in ns['surfaces'])
        assert surfaces == pytest.approx([0.0, scenario.conditions.gap])
        expected = scene_markers.robot(scenario.robot, scenario.conditions.gap, x, y, theta,
                                       phase)
        head = ns['body'][0]
        assert (head.pose.position.x, head.pose.position.y) == pytest.approx(
            expected[0].position[:2], abs=1e-12)
        assert 2 * math.atan2(head.pose.orientation.z, head.pose.orientation.w) == \
            pytest.approx(theta, abs=1e-12)
        plates, = ns['wave_links']
        want = next(s for s in expected if s.namespace == 'wave_links')
        np.testing.assert_allclose([(p.x, p.y) for p in plates.points],
                                   np.array(want.points)[:, :2], atol=1e-12)
        assert len(ns.get('contact_forces', [])) == touching


def test_viewer_configs_name_our_topics():
    import json
    from pathlib import Path
    docs = Path(__file__).resolve().parents[2] / 'docs'
    layout = json.loads((docs / 'foxglove_layout.json').read_text())
    text = json.dumps(layout)
    for name in (table.MARKERS, table.TRACKING_MARKERS, table.IMAGE_COMPRESSED, table.COMPARISON,
                 table.TWIST, table.TRACKING_TWIST_SMOOTHED, table.MOTOR_COMMANDS, table.MOTOR):
        assert name in text and name in table.BY_NAME
    assert layout['configById']['3D!saw_markers']['followTf'] == 'surface'
    rviz = (docs / 'saw_ros.rviz').read_text()
    assert 'Fixed Frame: surface' in rviz
    for name in (table.MARKERS, table.TRACKING_MARKERS, table.IMAGE, table.ROBOT_DESCRIPTION):
        assert f'Value: {name}\n' in rviz
    # The robot model (issue 34): the URDF on its latched topic, drawn from the simulator's TF.
    assert 'Class: rviz_default_plugins/RobotModel' in rviz
    assert 'Durability Policy: Transient Local' in rviz
    assert layout['configById']['3D!saw_markers']['topics'][table.ROBOT_DESCRIPTION]['visible']
