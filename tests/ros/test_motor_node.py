"""
The simulator node with its DC motor driving the helix (docs/motor.md), through real topics.

A subprocess in the run's isolated DDS domain, watched from the test with a private rclpy context;
every wait is on a condition, with a timeout.
"""
import math
import struct

import numpy as np
import pytest
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from saw_ros.core import Scenario, Simulator
from saw_ros.graph.process import ManagedProcess, node_command, wait_for

pytestmark = pytest.mark.ros

from saw_ros.interface import topics as table  # noqa: E402, I100
from saw_ros.ros.nodes.simulator import JOINT_STATES_RATE, MOTOR_RATE, TOPICS  # noqa: E402
from saw_ros.ros.qos import message_class  # noqa: E402

MS = 1_000_000
VOLTS = 4.0
SLOPE = math.radians(20.0)
STEPS = 2500


def stamp_of(raw: bytes) -> int:
    sec, nanosec = struct.unpack_from('<iI', raw, 4)
    return sec * 1_000_000_000 + nanosec


@pytest.fixture
def simulator(tmp_path):
    params = {'motor.voltage': VOLTS, 'conditions.slope': SLOPE, 'real_time_factor': 1.0,
              'duration': STEPS / 1000.0, 'wait_for_subscribers': 1}
    proc = ManagedProcess('simulator', node_command('simulator', params=params), env=None,
                          log_dir=tmp_path)
    yield proc
    if proc.returncode is None:
        proc.stop(timeout=5)


def test_the_motor_slows_the_helix_climbing_and_reports_its_current(ros_context, simulator):
    """
    4 V at +20 deg: the helix turns below its no-load speed, exactly as the core's motor.

    /saw/joint_states carries the core's helix speed and motor torque (effort), at 100 Hz;
    /saw/motor, at 100 Hz of simulated time, the supply voltage and minus the current
    (V - k w) / R at the same stamps.
    """
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    node = Node('motor_watcher', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    raw = {name: [] for name in list(TOPICS) + [table.MOTOR]}
    joints_every = round(1000 / JOINT_STATES_RATE)     # steps between two joint states
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    # Every per-step topic, so that the node (wait_for_subscribers 1) starts.
    for name in raw:
        node.create_subscription(message_class(table.topic(name).type), name, raw[name].append,
                                 qos, raw=True)
    spin = lambda timeout: executor.spin_once(timeout_sec=timeout)  # noqa: E731
    try:
        assert wait_for(lambda: simulator.returncode is not None,
                        60, spin=spin), simulator.output()
        assert simulator.wait(timeout=15) == 0, simulator.output()
        # What is still in flight after the node exits.
        wait_for(lambda: len(raw[table.JOINT_STATES]) >= STEPS // joints_every, 3, spin=spin)
    finally:
        executor.shutdown(timeout_sec=1)
        node.destroy_node()
    assert 'Traceback' not in simulator.output()
    assert 'motor.voltage = 4 V' in simulator.output()

    JointState = message_class(table.topic(table.JOINT_STATES).type)
    BatteryState = message_class(table.topic(table.MOTOR).type)
    joints = [deserialize_message(r, JointState) for r in raw[table.JOINT_STATES]]
    motor = [deserialize_message(r, BatteryState) for r in raw[table.MOTOR]]
    # Steps are compared by stamp: a subscriber on this shared 2-core machine may lose some
    # (test_simulator_node checks that every step goes out once; this test is about the motor).
    steps = np.array([stamp_of(r) for r in raw[table.JOINT_STATES]]) // MS
    assert len(steps) > 0.8 * STEPS / joints_every and (np.diff(steps) > 0).all()
    assert (steps % joints_every == 0).all()
    omega = np.array([j.velocity[0] for j in joints])
    effort = np.array([j.effort[0] for j in joints])
    assert len(joints[0].effort) == len(joints[0].name)

    # The core, same parameters, same steps.
    scenario = Scenario().with_values({'motor.voltage': VOLTS, 'conditions.slope': SLOPE})
    sim = Simulator(scenario)
    core_omega, core_torque, core_current = [], [], []
    for _ in range(STEPS):
        sim.step()
        core_omega.append(sim.omega[0])
        core_torque.append(sim.motor_torque[0])
        core_current.append(sim.current[0])
    core_omega, core_torque = np.array(core_omega), np.array(core_torque)
    np.testing.assert_allclose(omega, core_omega[steps - 1], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(effort, core_torque[steps - 1], rtol=1e-12, atol=1e-12)

    # Slower than at no load once spun up: the climb loads the motor.
    no_load = 2 * math.pi * scenario.frequency
    spun_up = omega[steps > 1000]
    assert len(spun_up) > 500 // joints_every
    assert 0.7 * no_load < np.mean(spun_up) < 0.97 * no_load

    # /saw/motor: 100 Hz of simulated time, the supply voltage, minus the resistor's current.
    every = int(round(1000 / MOTOR_RATE))
    motor_steps = np.array([stamp_of(r) for r in raw[table.MOTOR]]) // MS
    assert len(motor_steps) > 0.8 * STEPS / every and (motor_steps % every == 0).all()
    assert (np.diff(motor_steps) > 0).all() and motor_steps.max() <= STEPS
    m = scenario.motor
    k, R = m.torque_constant, m.resistance
    current = -np.array([b.current for b in motor])
    expected = (VOLTS - k * core_omega[motor_steps - 1]) / R
    # (BatteryState holds float32)
    np.testing.assert_allclose(current, expected, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(current, np.array(core_current)[motor_steps - 1], rtol=1e-5,
                               atol=1e-6)
    assert all(b.voltage == pytest.approx(VOLTS) for b in motor)
    assert all(b.header.frame_id == 'base_link' for b in motor)
    assert current[-50:].mean() > 0.0
    assert all(b.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
               for b in motor[-50:])
