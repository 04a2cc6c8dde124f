"""Shared test set-up: every test run gets its own DDS domain on localhost only."""
import os

import pytest

from saw_ros.graph.process import (isolated_ros_env, ManagedProcess, reserve_domain,  # noqa: F401
                                   wait_for)

# Isolate DDS for the whole run before anything imports rclpy: a domain reserved for as long as
# this process runs keeps concurrent runs apart, and the workers of a parallel run (pytest-xdist:
# each worker is a process that imports this file) from one another; LOCALHOST keeps traffic on
# this machine.
if not os.environ.get('DISABLE_ROS_ISOLATION'):
    os.environ.update(isolated_ros_env(reserve_domain(keep=True)))


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


@pytest.fixture(autouse=True)
def no_process_outlives_its_test():
    """
    Stop what a test started and left running (a failed assertion before its stop()).

    Our nodes run in sessions of their own: nothing else would stop them, and a recorder left
    behind kept running (and its domain busy) long after the test had failed.
    """
    yield
    ManagedProcess.stop_all(timeout=5.0)


def pytest_collection_modifyitems(items):
    """
    Put the files that hold slow tests first, each file's tests in their order.

    scripts/test.sh gives pytest-xdist whole files (--dist loadfile) in this order: a long file
    started last (the ROS and vision files sort last by name) kept one worker busy after the
    others had finished, 20 s of a 4-minute run.
    """
    slow = {item.path for item in items if item.get_closest_marker('slow')}
    items.sort(key=lambda item: item.path not in slow)     # (a stable sort)
