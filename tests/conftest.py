"""Shared test set-up: every test run gets its own DDS domain on localhost only."""
import os

import pytest

from saw_ros.graph.process import isolated_ros_env, wait_for  # noqa: F401  (re-exported for tests)

# Isolate DDS for the whole run before anything imports rclpy: a reserved domain keeps concurrent
# runs apart, LOCALHOST keeps traffic on this machine.
if not os.environ.get('DISABLE_ROS_ISOLATION'):
    os.environ.update(isolated_ros_env())


@pytest.fixture
def ros_context():
    """Yield a private rclpy Context, shut down after the test (no global state across tests)."""
    import rclpy
    from rclpy.context import Context
    context = Context()
    rclpy.init(context=context)
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)
