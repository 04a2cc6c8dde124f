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
