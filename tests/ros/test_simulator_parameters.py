"""
Nodes take the simulator's parameters from the simulator (saw_ros.ros.simulator_parameters).

The camera draws the robot and the gap the simulator runs, not its own defaults: nobody sets
robot.* and conditions.gap on it by hand. (The comparison node's use: test_comparison_node.)
"""
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

from saw_ros.core import Scenario
from saw_ros.graph.process import ManagedProcess, node_command, wait_for

pytestmark = pytest.mark.ros

GAP = 0.05
MASS = 0.35


def test_the_camera_draws_the_robot_and_gap_the_simulator_runs(ros_context, tmp_path):
    from saw_ros.ros.nodes.camera import CameraNode
    camera = CameraNode(context=ros_context, parameter_overrides=[
        Parameter('width', value=320), Parameter('height', value=180),
        Parameter('texture', value=False), Parameter('image_transport', value='raw')])
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(camera)
    spin = lambda t: executor.spin_once(timeout_sec=t)   # noqa: E731
    default = Scenario()
    assert (camera.renderer.robot, camera.renderer.gap) == (default.robot, default.conditions.gap)
    sim = ManagedProcess('simulator', node_command('simulator', params={
        'conditions.gap': GAP, 'robot.mass': MASS, 'duration': 60.0, 'real_time_factor': 0.2}),
        None, tmp_path / 'logs')
    try:
        assert wait_for(lambda: camera.renderer.gap == GAP, 30, spin=spin), sim.output()
        ran = default.with_values({'conditions.gap': GAP, 'robot.mass': MASS})
        assert camera.renderer.robot == ran.robot
        assert camera.simulator_parameters.values['robot.mass'] == MASS
    finally:
        sim.stop()
        executor.shutdown()
        camera.destroy_node()
