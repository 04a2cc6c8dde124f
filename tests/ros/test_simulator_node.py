"""
The simulator node through real topics.

A subprocess in the run's isolated DDS domain, watched from the test with a private rclpy context.
Every wait is on a condition, with a timeout.
"""
import math
import re
import signal
import struct

import numpy as np
import pytest
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from saw_ros.core import Scenario, Simulator
from saw_ros.core.dynamics import GRAVITY
from saw_ros.core.kinematics import v_theory
from saw_ros.graph.process import ManagedProcess, node_command, wait_for
from saw_ros.interface import urdf
from saw_ros.ros import conversions as conv
from std_srvs.srv import Trigger

pytestmark = pytest.mark.ros

from saw_ros.interface import topics as table  # noqa: E402, I100
from saw_ros.ros.nodes.simulator import JOINT_STATES_RATE, TOPICS  # noqa: E402

MS = 1_000_000
# Steps between two messages of each topic: 1, and 10 for /saw/joint_states (100 Hz).
EVERY = {t: round(1000 / JOINT_STATES_RATE) if t == table.JOINT_STATES else 1 for t in TOPICS}
# Real time: 6000 messages/s, which one raw subscriber keeps up with on a shared 2-core machine.
# (real_time_factor 0 outruns any Python subscriber of all six topics: see the node's docstring.)
RTF = 1.0


def _type(topic):
    return TOPICS[topic]


def stamp_of(raw: bytes) -> int:
    """
    Stamp of a CDR message whose first field is a Time (Clock) or a Header.

    4 bytes of encapsulation, then int32 sec, uint32 nanosec.
    """
    sec, nanosec = struct.unpack_from('<iI', raw, 4)
    return sec * 1_000_000_000 + nanosec


class Watcher:
    """Raw subscriptions to every simulator topic (cheap: decoded only when a test asks)."""

    def __init__(self, context):
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        self.node = Node('simulator_watcher', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.raw = {topic: [] for topic in TOPICS}
        # Reliable like the publisher; 10 s of queue so that a test process the machine
        # deschedules does not drop messages of its own making: with the CPU capped to a third
        # (scripts/slower_machine.sh) this Python reader of 5 000 messages/s fell over 1 s
        # behind the simulator and lost stamps past a 1 s queue.
        qos = QoSProfile(depth=10_000, reliability=ReliabilityPolicy.RELIABLE)
        for topic in TOPICS:
            self.node.create_subscription(_type(topic), topic, self.raw[topic].append, qos,
                                          raw=True)

    def spin(self, timeout):
        self.executor.spin_once(timeout_sec=timeout)

    def wait(self, condition, timeout):
        return wait_for(condition, timeout, spin=self.spin)

    def count(self, topic=table.CLOCK):
        return len(self.raw[topic])

    def stamps(self, topic):
        return np.array([stamp_of(r) for r in self.raw[topic]], dtype=np.int64)

    def messages(self, topic, start=0, stop=None):
        cls = _type(topic)
        return [deserialize_message(r, cls) for r in self.raw[topic][start:stop]]

    def call(self, srv_type, name, request, timeout=10.0):
        client = self.node.create_client(srv_type, name)
        try:
            assert client.wait_for_service(timeout_sec=timeout), f'{name} not available'
            future = client.call_async(request)
            self.executor.spin_until_future_complete(future, timeout_sec=timeout)
            assert future.done(), f'{name}: no answer within {timeout} s'
            return future.result()
        finally:
            self.node.destroy_client(client)

    def set_parameter(self, name, value):
        if isinstance(value, float):
            pv = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
        else:
            pv = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
        request = SetParameters.Request(parameters=[ParameterMsg(name=name, value=pv)])
        return self.call(SetParameters, '/simulator/set_parameters', request).results[0]

    def close(self):
        self.executor.shutdown(timeout_sec=1)
        self.node.destroy_node()


@pytest.fixture
def watcher(ros_context):
    w = Watcher(ros_context)
    yield w
    w.close()


@pytest.fixture
def start_simulator(tmp_path):
    procs = []

    def start(**params):
        params.setdefault('wait_for_subscribers', 1)
        proc = ManagedProcess(f'simulator{len(procs)}', node_command('simulator', params=params),
                              env=None, log_dir=tmp_path)
        procs.append(proc)
        return proc

    yield start
    for proc in procs:
        if proc.returncode is None:
            proc.stop(timeout=5)


def assert_every_step_once(stamps, first, last):
    """Stamps first..last ms, 1 ms apart, each exactly once, in order."""
    expected = np.arange(first, last + 1, dtype=np.int64) * MS
    assert len(stamps) == len(expected), (len(stamps), len(expected))
    gaps = np.flatnonzero(np.diff(stamps) != MS)
    assert gaps.size == 0, f'not 1 ms apart at {stamps[gaps[:5]]} ns'
    np.testing.assert_array_equal(stamps, expected)


def test_streams_every_step_and_advance_like_the_core(start_simulator, watcher):
    """
    3 s of simulated time.

    Every topic carries 3000 stamps 1 ms apart (the joint states every 10th), /clock gives the
    same times, the node exits 0 by itself, and the pose is the core's own trajectory (AR
    included).
    """
    steps = 3000
    proc = start_simulator(real_time_factor=RTF, duration=steps / 1000.0)
    done = watcher.wait(lambda: all(watcher.count(t) >= steps // EVERY[t] for t in TOPICS),
                        timeout=30)
    assert done, {t: watcher.count(t) for t in TOPICS}
    assert proc.wait(timeout=15) == 0, proc.output()
    assert 'Traceback' not in proc.output()
    clock = watcher.stamps(table.CLOCK)
    assert_every_step_once(clock, 1, steps)
    for topic in TOPICS:
        np.testing.assert_array_equal(watcher.stamps(topic), clock[EVERY[topic] - 1::EVERY[topic]],
                                      err_msg=topic)

    # The core, same parameters, same steps.
    scenario = Scenario()
    sim = Simulator(scenario)
    x = {}
    for k in range(1, steps + 1):
        sim.step()
        if k in (1000, steps):
            x[k] = (sim.q[0, 0], sim.q[3, 0], float(sim.phase[0]))
    poses = watcher.messages(table.POSE)
    twists = watcher.messages(table.TWIST, steps - 1)
    node_x = {k: poses[k - 1].pose.position.x for k in (1000, steps)}
    ar_core = (x[steps][0] - x[1000][0]) / 2.0 / v_theory(scenario.robot, scenario.frequency)
    ar_node = (node_x[steps] - node_x[1000]) / 2.0 / v_theory(scenario.robot, scenario.frequency)
    assert ar_core > 0.3
    assert ar_node == pytest.approx(ar_core, rel=1e-9, abs=1e-12)
    assert twists[0].twist.linear.x == pytest.approx(x[steps][1], rel=1e-12, abs=1e-15)
    assert all(p.header.frame_id == 'surface' for p in poses[:10])
    assert all(math.isfinite(p.pose.position.x) for p in poses)

    joints = watcher.messages(table.JOINT_STATES, steps // EVERY[table.JOINT_STATES] - 1)[0]
    assert list(joints.name) == urdf.joint_names(scenario.robot)
    assert joints.position[0] == pytest.approx(x[steps][2])
    assert joints.velocity[0] == pytest.approx(2 * math.pi * scenario.frequency)

    cloud = watcher.messages(table.CONTACTS, steps - 1)[0]
    points = conv.points_of(cloud)
    assert cloud.header.frame_id == 'surface' and cloud.is_dense and cloud.height == 1
    assert len(points) > 0 and (points['normal_force'] >= 0).all()
    assert set(points['surface'].tolist()) <= {0, 1}


def test_weight_parameters_reset_and_sigterm(start_simulator, watcher):
    """
    At rest on a slope the contacts carry the weight.

    An invalid or frozen parameter is refused while the node runs on; a valid one takes effect;
    ~/reset restarts the robot, not the time; SIGTERM exits 0 without a traceback. (Messages are
    decoded at the end: a test that stops spinning to decode at 6000 messages/s would lose messages
    of its own making.)
    """
    slope = 0.3
    proc = start_simulator(real_time_factor=RTF, **{'conditions.frequency': 0.0,
                                                    'conditions.slope': slope})
    assert watcher.wait(lambda: min(watcher.count(t) * EVERY[t] for t in TOPICS) >= 2000, 30), \
        proc.output()

    # Refused: out of range, and frozen at run time. The node runs on.
    bad = watcher.set_parameter('surface.friction_coefficient', -1.0)
    assert not bad.successful and 'friction_coefficient' in bad.reason, bad.reason
    frozen = watcher.set_parameter('robot.mass', 0.5)
    assert not frozen.successful and 'cannot change' in frozen.reason, frozen.reason
    seen = watcher.count()
    assert watcher.wait(lambda: watcher.count() >= seen + 300, 20), 'node stopped stepping'
    assert proc.returncode is None

    # Accepted at once: the wave starts (2 Hz) and the robot advances.
    good = watcher.set_parameter('conditions.frequency', 2.0)
    assert good.successful, good.reason
    # 1000 poses past the step the change took effect on (the node's log says when: a reader
    # running behind the node, as on a busy machine, has not seen it yet when the answer comes).
    applied = re.compile(r'parameters changed at t = ([0-9.]+) s')
    assert watcher.wait(lambda: applied.search(proc.output()), 30), proc.output()[-2000:]
    changed = int(round(float(applied.search(proc.output()).group(1)) * 1000))
    assert watcher.wait(lambda: watcher.count(table.POSE) >= changed + 1000, 120), (
        changed, watcher.count(table.POSE))

    # Reset: the robot back at its start; time goes on.
    answer = watcher.call(Trigger, '/simulator/reset', Trigger.Request())
    assert answer.success, answer.message
    # 200 poses past the step the reset came at (its answer says when; a reader running behind
    # the node, as on a busy machine, has not seen it yet when the answer comes).
    reset_s = float(re.search(r'at t = ([0-9.]+) s', answer.message).group(1))
    assert watcher.wait(lambda: watcher.count(table.POSE) >= reset_s * 1000 + 200, 60), \
        (answer.message, watcher.count(table.POSE))

    # SIGTERM: exit 0, no traceback.
    proc.signal(signal.SIGTERM)
    assert proc.wait(timeout=15) == 0, proc.output()
    watcher.wait(lambda: False, 0.3)
    out = proc.output()
    assert 'Traceback' not in out and 'parameter change refused' in out, out

    # Every stamp published once, from 1 ms on, through the refusals, the change and the reset.
    clock = watcher.stamps(table.CLOCK)
    assert_every_step_once(clock, 1, len(clock))
    # (Each topic against the clock over the time both cover: a reader far behind when the node
    # stopped may get the last of one topic and not of another.)
    for topic in TOPICS:
        stamps = watcher.stamps(topic)
        stamps = stamps[stamps <= clock[-1]]
        np.testing.assert_array_equal(stamps, clock[EVERY[topic] - 1::EVERY[topic]][:len(stamps)],
                                      err_msg=topic)

    # Mean over 1-2 s of simulated time (the robot rings between the compliant surfaces).
    mass = Scenario().robot.mass
    support, traction = [], []
    for cloud in watcher.messages(table.CONTACTS, 1000, 2000):
        p = conv.points_of(cloud)
        sign = np.where(p['surface'] == conv.BOTTOM, 1.0, -1.0)
        support.append(float((sign * p['normal_force']).sum()))
        traction.append(float(p['tangential_force'].sum()))
    assert np.mean(support) == pytest.approx(mass * GRAVITY * math.cos(slope), rel=0.03)
    assert np.mean(traction) == pytest.approx(mass * GRAVITY * math.sin(slope), rel=0.03)
    # The wrench (base_link axes) turned back into the surface frame says the same.
    poses = watcher.messages(table.POSE)
    thetas = [conv.pitch_of(p.pose.orientation) for p in poses[1000:2000]]
    wrench_y = [w.wrench.force.x * math.sin(th) + w.wrench.force.y * math.cos(th)
                for w, th in zip(watcher.messages(table.CONTACT_WRENCH, 1000, 2000), thetas)]
    assert np.mean(wrench_y) == pytest.approx(np.mean(support), rel=1e-3)

    xs = np.array([p.pose.position.x for p in poses])
    assert abs(xs[:changed].max() - xs[0]) < 0.01, 'at rest before the frequency change'
    jumps = np.flatnonzero(np.diff(xs) < -0.05)
    assert len(jumps) == 1, ('one reset, seen as one jump back of the pose', len(xs), changed,
                             xs.max(), np.diff(xs).min(), xs[-5:], proc.output()[-2000:])
    assert xs[jumps[0]] > 0.05, 'the robot advanced once the wave started'
    assert abs(xs[jumps[0] + 1]) < 1e-3, 'and started again from x = 0 after the reset'


def test_surfaces_too_soft_to_carry_the_robot_are_refused_at_start(start_simulator):
    """
    Surfaces far too soft to hold the robot: it would sink through the bottom one.

    Refused before the first step (exit 1, the reason, no traceback); a divergence while
    running is answered by a reset instead (tests/ros/test_simulator_faults.py).
    """
    proc = start_simulator(real_time_factor=0.0, **{'surface.normal_stiffness': 1.0})
    assert proc.wait(timeout=30) == 1, proc.output()
    out = proc.output()
    assert 'too soft' in out and 'Traceback' not in out, out


def test_as_fast_as_possible_still_serves_requests_and_stops_on_sigint(start_simulator,
                                                                       watcher):
    """
    Check real_time_factor 0: requests are served between batches of steps, Ctrl-C exits 0.

    Ctrl-C is SIGINT to the process group. (No stamp check: no Python subscriber keeps up at rtf
    0.)
    """
    proc = start_simulator(real_time_factor=0.0)
    assert watcher.wait(lambda: watcher.count() >= 100, 20), proc.output()
    assert watcher.set_parameter('conditions.slope', 0.1).successful
    assert watcher.set_parameter('real_time_factor', -2.0).successful is False
    assert watcher.call(Trigger, '/simulator/reset', Trigger.Request()).success
    assert proc.returncode is None
    proc.signal(signal.SIGINT)
    assert proc.wait(timeout=15) == 0, proc.output()
    assert 'Traceback' not in proc.output()
