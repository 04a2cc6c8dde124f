"""Helpers of the ROS tests that feed the camera node as the simulator node would."""
import math

import pytest


def _drive_camera(sim, pub_pose, pub_joints, duration, vision, camera, spin):
    """
    Publish the core's pose and helix phase at every step, as the simulator node does.

    50 steps at a time; after each burst, wait until the vision node has had every frame due
    (1/60 s of simulated time each). Return {step: true x} of every step published.
    """
    from sensor_msgs.msg import JointState

    from saw_ros.graph.process import wait_for
    from saw_ros.ros import conversions as conv
    joints = JointState()
    joints.name = ['helix']
    truth = {}

    def publish():
        t_ns = sim.steps * 1_000_000
        q = sim.q[:, 0]
        pub_pose.publish(conv.pose_msg(q[0], q[1], q[2], t_ns))
        conv.time_msg(t_ns, joints.header.stamp)
        joints.position = [float(sim.phase[0])]
        pub_joints.publish(joints)
        truth[sim.steps] = q[0]

    publish()
    while sim.t < duration - 1e-9:
        for _ in range(50):
            sim.step()
            publish()
        due = int(math.floor(sim.t * 60 + 1e-9)) + 1
        assert wait_for(lambda: vision.results >= due, 20.0, spin=spin), \
            (camera.frames, vision.results, due)
    return truth


@pytest.fixture
def drive_camera():
    """Return the helper above that feeds the camera node the core's steps."""
    return _drive_camera


def _run_simulator_into_camera(simulator, camera, nodes, executor, spin, frames, images, matched):
    """
    Run the in-process simulator node until it finishes and ``frames`` images have arrived.

    The simulator holds its first step until the camera's inputs, ``matched()`` (what else the
    test waits on) and the camera's knowledge of the robot are in place, so that no input is lost;
    what is still in flight after the end is taken; then the executor and ``nodes`` are shut.
    """
    import time

    from saw_ros.graph.process import wait_for
    try:
        simulator.started = False
        assert wait_for(lambda: all(s.get_publisher_count() > 0 for s in camera._inputs)
                        and camera._pub_image.get_subscription_count() > 0 and matched()
                        and camera.simulator_parameters.known, 10.0, spin=spin)
        simulator.started = True
        simulator._rebase(time.monotonic())
        assert wait_for(lambda: simulator.finished and len(images) >= frames, 20.0, spin=spin), \
            (simulator.steps, camera.frames, len(images))
        wait_for(lambda: False, 0.2, spin=spin)         # what is still in flight
    finally:
        executor.shutdown()
        camera.close()
        for node in nodes:
            node.destroy_node()


@pytest.fixture
def run_simulator_into_camera():
    """Return the helper above that runs the simulator node into the camera node, in process."""
    return _run_simulator_into_camera


def _still_camera(context):
    """Return a camera node of a 640x360 picture around x = 0: no follow, no texture, raw."""
    from rclpy.parameter import Parameter

    from saw_ros.ros.nodes.camera import CameraNode
    return CameraNode(context=context, parameter_overrides=[
        Parameter('width', value=640), Parameter('height', value=360),
        Parameter('center_x', value=0.0), Parameter('follow', value=False),
        Parameter('texture', value=False), Parameter('image_transport', value='raw')])


@pytest.fixture
def still_camera():
    """Return the helper above: the camera whose frames the in-process tests compare."""
    return _still_camera
