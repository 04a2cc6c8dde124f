"""The camera draws a compliant robot's links deflected as /saw/joint_states says (issue 31)."""
import math

import numpy as np
import pytest
from saw_ros.graph.process import wait_for

pytestmark = pytest.mark.ros

from saw_ros.interface import topics as table  # noqa: E402, I100
from saw_ros.interface import urdf  # noqa: E402

COMPLIANT = {'flexure.stiffness': 863.0, 'flexure.damping': 0.05}
DURATION = 0.25         # s of simulated time, at real time


def _spin(executor):
    return lambda t: executor.spin_once(timeout_sec=t)


def test_camera_draws_the_links_deflected_as_the_joint_states_say(ros_context, still_camera,
                                                                  run_simulator_into_camera):
    """
    Simulator (a compliant robot) and camera in this executor, through real topics.

    Every frame is the renderer's picture of the robot with its links deflected by the
    link_NN_flex positions received (linear between the two joint states around the frame,
    bit for bit), and not the rigid robot's picture: the links flexed on camera.
    """
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from saw_ros.ros import conversions as conv
    from saw_ros.ros.nodes.simulator import SimulatorNode
    from saw_ros.ros.qos import profile
    from sensor_msgs.msg import Image, JointState

    simulator = SimulatorNode(context=ros_context, parameter_overrides=[
        Parameter(name, value=value) for name, value in COMPLIANT.items()] + [
        Parameter('real_time_factor', value=1.0), Parameter('duration', value=DURATION)])
    camera = still_camera(ros_context)
    watcher = Node('flexure_camera_watcher', context=ros_context)
    images, joints = [], []
    watcher.create_subscription(Image, table.IMAGE, images.append, profile('image'))
    watcher.create_subscription(JointState, table.JOINT_STATES, joints.append,
                                profile(table.topic(table.JOINT_STATES).qos))
    executor = SingleThreadedExecutor(context=ros_context)
    for node in (simulator, camera, watcher):
        executor.add_node(node)
    spin = _spin(executor)
    frames = int(DURATION * 60)
    joints_out, = (p for p in simulator._publishers_all if p.topic_name == table.JOINT_STATES)
    run_simulator_into_camera(simulator, camera, (simulator, camera, watcher), executor, spin,
                              frames, images, lambda: joints_out.get_subscription_count() >= 2)

    assert len(images) == frames and camera.guard.refused == 0
    robot = camera.renderer.robot
    names = [f'{n}_flex' for n in urdf.link_names(robot)]
    stamps = np.array([conv.stamp_ns(m.header.stamp) for m in joints], float)
    published = np.array([[m.position[list(m.name).index(n)] for n in names] for m in joints])
    assert np.abs(published).max() > 1e-4            # millimetres: the links do flex
    renderer, cam = camera.renderer, camera.camera
    for image in images:
        t = conv.stamp_ns(image.header.stamp)
        got = np.frombuffer(bytes(image.data), np.uint8).reshape(cam.height, cam.width, 3)
        pose = camera.pose_at(t)
        want = [np.interp(t, stamps, published[:, i]) for i in range(len(names))]
        np.testing.assert_allclose(pose.deflection, want, rtol=1e-9, atol=1e-15)
        assert np.array_equal(got, renderer.render(pose)), t
        assert not np.array_equal(got, renderer.render(pose._replace(deflection=None))), t


def test_camera_refuses_a_nan_or_absurd_deflection_and_runs_on(ros_context, capfd):
    """
    A link_NN_flex position NaN, or beyond the joint's limit: refused and counted.

    The camera runs on and takes the next good message, whose missing link joints are rigid.
    """
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from saw_ros.ros import conversions as conv
    from saw_ros.ros.nodes.camera import CameraNode
    from saw_ros.ros.qos import publisher_profile
    from sensor_msgs.msg import JointState

    camera = CameraNode(context=ros_context)
    source = Node('flex_source', context=ros_context)
    pub = source.create_publisher(JointState, table.JOINT_STATES,
                                  publisher_profile(table.topic(table.JOINT_STATES).qos))
    executor = SingleThreadedExecutor(context=ros_context)
    for node in (camera, source):
        executor.add_node(node)
    spin = _spin(executor)
    limit = urdf.flex_limit(camera.renderer.robot)

    def joints(t_ns, **flex):
        msg = JointState()
        conv.time_msg(t_ns, msg.header.stamp)
        msg.name = ['helix'] + list(flex)
        msg.position = [1.0] + list(flex.values())
        return msg
    counts = camera.guard.counts
    try:
        assert wait_for(lambda: pub.get_subscription_count() > 0, 10.0, spin=spin)
        pub.publish(joints(1_000_000, link_03_flex=math.nan))
        pub.publish(joints(2_000_000, link_03_flex=1.01 * limit))
        assert wait_for(lambda: counts.get((table.JOINT_STATES, 'not finite'), 0) == 1
                        and counts.get((table.JOINT_STATES, 'out of range'), 0) == 1, 5.0,
                        spin=spin), counts
        assert camera.received['joint_states'] == 0
        pub.publish(joints(3_000_000, link_03_flex=-0.99 * limit, link_05_flex=2e-3))
        assert wait_for(lambda: camera.received['joint_states'] == 1, 5.0, spin=spin)
        want = np.zeros(camera.renderer.robot.wave_links)
        want[3], want[5] = -0.99 * limit, 2e-3
        assert camera._deflections.at(3_000_000) == tuple(want)
    finally:
        executor.shutdown()
        camera.close()
        for node in (camera, source):
            node.destroy_node()
    err = capfd.readouterr().err
    assert 'link deflection has nan' in err and 'Traceback' not in err, err
