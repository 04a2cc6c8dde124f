"""
Drive the robot from your own node (issue 22), through real topics.

The simulator as a subprocess in the run's isolated DDS domain takes commands on
/saw/motor_controller/commands; the speed controller closes a loop around it. Every wait is on a
condition with a timeout.
"""
import math
import struct

import numpy as np
import pytest
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from saw_ros.graph.process import ManagedProcess, node_command, wait_for

pytestmark = pytest.mark.ros

from saw_ros.interface import topics as table  # noqa: E402, I100
from saw_ros.ros.nodes.simulator import TOPICS  # noqa: E402
from saw_ros.ros.qos import message_class, profile  # noqa: E402

NS = 1_000_000_000
LAST_V = 11.0           # V: the last command, held 1 s before the hand-back


def stamp_of(raw: bytes) -> int:
    sec, nanosec = struct.unpack_from('<iI', raw, 4)
    return sec * NS + nanosec


def start(name, params, tmp_path):
    return ManagedProcess(name, node_command(name, params=params), env=None, log_dir=tmp_path)


class Watcher:
    """
    The clock, the motor, the joint states and the pose, raw; a publisher of commands.

    Only what the tests read: each 1 kHz topic is a Python callback a step in this process, and
    with all six the watcher fell up to a second behind the simulator on a busy machine.
    """

    TOPICS = (table.CLOCK, table.MOTOR, table.JOINT_STATES, table.POSE)

    def __init__(self, context):
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        self.node = Node('command_watcher', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.raw = {name: [] for name in self.TOPICS}
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        for name in self.raw:
            self.node.create_subscription(message_class(table.topic(name).type), name,
                                          self.raw[name].append, qos, raw=True)
        # The simulator's wait_for_subscribers wants a reader on each of its topics: the others
        # on a node no executor spins (KEEP_LAST 1: DDS overwrites, nothing is ever taken).
        self.idle = Node('command_watcher_idle', context=context)
        for name in TOPICS:
            if name not in self.raw:
                self.idle.create_subscription(message_class(table.topic(name).type), name,
                                              lambda _: None, QoSProfile(depth=1), raw=True)
        entry = table.topic(table.MOTOR_COMMANDS)
        self.command_type = message_class(entry.type)
        self.publisher = self.node.create_publisher(self.command_type, entry.name,
                                                    profile(entry.qos))

    def spin(self, timeout):
        self.executor.spin_once(timeout_sec=timeout)

    def clock_ns(self):
        return stamp_of(self.raw[table.CLOCK][-1]) if self.raw[table.CLOCK] else 0

    def until_clock(self, seconds, timeout=30):
        assert wait_for(lambda: self.clock_ns() >= seconds * NS, timeout, spin=self.spin)

    def command(self, *values):
        self.publisher.publish(self.command_type(data=[float(v) for v in values]))

    def close(self):
        self.executor.shutdown(timeout_sec=1)
        self.node.destroy_node()
        self.idle.destroy_node()


def test_commands_drive_the_motor_bad_ones_are_refused_and_a_timeout_hands_back(
        ros_context, tmp_path):
    simulator = start('simulator', {'motor.voltage': 6.0, 'real_time_factor': 1.0,
                                    'duration': 4.0, 'wait_for_subscribers': 1,
                                    'command_timeout': 1.0}, tmp_path)
    watcher = Watcher(ros_context)
    try:
        assert wait_for(lambda: watcher.publisher.get_subscription_count() > 0, 20,
                        spin=watcher.spin), simulator.output()
        watcher.until_clock(0.5)
        sent_ns = watcher.clock_ns()
        watcher.command(12.0)
        watcher.until_clock(0.8)
        for bad in ((math.nan,), (1.0, 2.0), (100.0,), (-1.0,), ()):
            watcher.command(*bad)
        while watcher.clock_ns() < 1.5 * NS:         # a controller holding 12 V
            watcher.command(12.0)
            watcher.until_clock(watcher.clock_ns() / NS + 0.05)
        watcher.command(LAST_V)     # the last command, told apart on /saw/motor by its value
        assert wait_for(lambda: simulator.returncode is not None, 30, spin=watcher.spin)
        wait_for(lambda: False, 0.5, spin=watcher.spin)     # what is still in flight
    finally:
        watcher.close()
        if simulator.returncode is None:
            simulator.stop(timeout=5)
    log = simulator.output()
    assert simulator.wait(timeout=5) == 0 and 'Traceback' not in log, log
    BatteryState = message_class(table.topic(table.MOTOR).type)
    motor = [(stamp_of(r), deserialize_message(r, BatteryState).voltage)
             for r in watcher.raw[table.MOTOR]]
    volts = np.array([v for _, v in motor])
    t = np.array([s for s, _ in motor])
    # Only the parameter's 6 V and the good commands' 12 and LAST_V were ever applied.
    assert set(np.round(volts, 6)) <= {6.0, 12.0, LAST_V}, set(volts)
    assert (volts[t <= sent_ns] == 6.0).all()
    # From the step the command reached the simulator on, 12 V until the last command. (How long
    # it took to get there is the machine's: at real time on a loaded machine, 0.1 s and more;
    # the bad commands in between changed nothing.)
    applied_ns = t[(t > sent_ns) & (volts == 12.0)].min()
    latency_ns = applied_ns - sent_ns
    last_ns = t[volts == LAST_V].min()
    assert (volts[(t >= applied_ns) & (t < last_ns)] == 12.0).all()
    # 1 s of simulated time after the last command reached the simulator, the parameter drives
    # again, for good. (Measured from the step the simulator took it on, not from this
    # process's clock: that read up to 0.95 s behind the simulator's on a busy machine.)
    released_ns = t[(t > last_ns) & (volts == 6.0)].min()
    assert (volts[(t >= last_ns) & (t < released_ns)] == LAST_V).all()
    assert (volts[t >= released_ns] == 6.0).all()
    # Each change lies between the sample that shows it and the one before (a reader that fell
    # behind loses the oldest of its queue): 1 s must fit between those bounds, within a step.
    before_last_ns = t[t < last_ns].max()
    before_release_ns = t[t < released_ns].max()
    assert (before_release_ns - last_ns) / NS <= 1.0 + 0.002, (t[-5:], latency_ns)
    assert (released_ns - before_last_ns) / NS >= 1.0 - 0.002, (t[-5:], latency_ns)
    assert 'no command for 1 s' in log
    assert 'refused' in log and '5 command(s)' in log
    # The helix answered within a few steps of the command (the bench measures it exactly).
    JointState = message_class(table.topic(table.JOINT_STATES).type)
    joints = [(stamp_of(r), deserialize_message(r, JointState).effort[0])
              for r in watcher.raw[table.JOINT_STATES]]
    steps = np.array([s for s, _ in joints]) // 1_000_000
    effort = np.array([e for _, e in joints])
    jump = np.flatnonzero(np.diff(effort) > 0.5 * np.abs(effort).max())
    assert len(jump), 'no step in the motor torque after the command'
    # Not before the command was sent, and within 0.1 s of simulated time after the step that
    # applied it (from the step it was sent on, the transport's delay on a busy machine counts
    # too: 0.67 s beside two CPU hogs on the slower kind).
    answered_ms = steps[jump[0] + 1]
    assert sent_ns // 1_000_000 < answered_ms <= applied_ns // 1_000_000 + 100, (
        sent_ns, applied_ns, answered_ms)


def test_the_speed_controller_holds_its_target_on_ground_truth(ros_context, tmp_path):
    """A PI loop through real topics: 4 cm/s held from a 6 V start."""
    target = 0.04
    simulator = start('simulator', {'motor.voltage': 6.0, 'real_time_factor': 1.0,
                                    'duration': 7.0, 'wait_for_subscribers': 1}, tmp_path)
    controller = start('speed_controller', {'feedback': 'ground_truth', 'target_speed': target,
                                            'rate': 50.0}, tmp_path)
    watcher = Watcher(ros_context)
    try:
        assert wait_for(lambda: simulator.returncode is not None, 60,
                        spin=watcher.spin), simulator.output()
        wait_for(lambda: False, 0.5, spin=watcher.spin)
    finally:
        watcher.close()
        controller.stop(timeout=5)
        if simulator.returncode is None:
            simulator.stop(timeout=5)
    assert 'Traceback' not in controller.output() + simulator.output()
    Pose = message_class(table.topic(table.POSE).type)
    poses = [deserialize_message(r, Pose) for r in watcher.raw[table.POSE]]
    t = np.array([p.header.stamp.sec + p.header.stamp.nanosec / NS for p in poses])
    x = np.array([p.pose.position.x for p in poses])
    late = t >= 5.0
    assert late.sum() > 1000, 'the watcher missed most of the run'
    speed = np.polyfit(t[late], x[late], 1)[0]       # over two of the slowed helix's turns
    assert speed == pytest.approx(target, rel=0.05), speed
    assert 'holding 0.04 m/s on ground_truth feedback' in controller.output()
