"""
The simulator node: the paper's robot on ROS 2 topics at 1 kHz of simulated time.

Steps ``core.Simulator`` and publishes every step exactly once (stamps = simulated time, 1 ms
apart at the default dt): /clock, /saw/pose, /saw/twist, /saw/contacts and /saw/contact_wrench;
/saw/joint_states (every joint of the URDF: the helix, the base link, each wave link's position
in the plane, its deflection on its flexure and its angle) at ``joint_states_rate`` (100 Hz);
and the robot for RViz /
Foxglove on /saw/markers, with TF of every link of the URDF (``link_tf``, so RobotModel draws the
wave without robot_state_publisher), at ``markers_rate`` (60 Hz) of simulated time.
docs/simulator.md lists the topics, frames, QoS and parameters.

Motor. The helix turns at conditions.frequency, or, with motor.voltage > 0, at the speed the
core's DC motor reaches under the contacts' load (docs/motor.md). /saw/joint_states carries the
helix's actual speed, and with a motor its torque (N m) as the helix's effort; /saw/motor the
supply voltage and the motor current as a BatteryState at MOTOR_RATE of simulated time.

Time. A wall-clock timer wakes the node every few milliseconds; each wake-up runs as many steps
as are due at ``real_time_factor`` (steps = rtf * elapsed wall time / dt), not one step per tick:
rclpy does not catch up missed timer ticks. When the machine cannot keep up the simulation falls
behind real time (never skipping or repeating a step) and says so, at most every few seconds.
``real_time_factor`` 0 runs as fast as the node can step and publish. Either way a wake-up
works for at most ``BATCH_BUDGET`` of wall time (and ``MAX_BATCH`` steps) so that parameter
changes and ~/reset are served in between.

Loss. The node publishes every step once, in order, reliably (the 1 kHz topics' messages of a
wake-up's steps at its end, topic after topic: ``_publish_batch``). Reliable KEEP_LAST queues do
not slow the publisher down, though: a subscriber that cannot keep up with the rate (rtf x 5100
messages/s) loses the oldest messages of its queue. Publisher acknowledgements cannot prevent
that (a KEEP_LAST reader acknowledges what it then drops, and Fast DDS acknowledges in bursts,
0-2 s late), so there is no back-pressure: pick a real_time_factor the subscribers sustain
(``saw-ros bench`` measures it), not 0, when every message must arrive.

Reset. ``~/reset`` puts the robot back in its initial state (centred in the gap, at rest, phase 0,
no contact memory) with the current parameters; simulated time goes on (stamps and /clock never
go backwards, so use_sim_time consumers, TF buffers and bags are not disturbed). ``duration``
counts simulated time since the node started, resets included.

Faults. Nothing a parameter or the physics does ends the node once it steps: a change the step
cannot integrate (core.stability) is refused with the limit; one the current state cannot take
(a narrower gap) and a divergence are answered by the same reset, an ERROR status on
/diagnostics and a log line with the time (docs/simulator.md, Faults and recovery).
"""
from __future__ import annotations

import math
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from saw_ros.core import stability
from saw_ros.core.dynamics import DivergenceError, Simulator
from saw_ros.core.kinematics import link_geometry
from saw_ros.core.params import ParameterError, Scenario
from saw_ros.core.params import spec_meta
from saw_ros.interface import frames, scene_markers, topics, urdf
from saw_ros.ros import conversions as conv
from saw_ros.ros import markers
from saw_ros.ros import tf
from saw_ros.ros.command import CommandInput
from saw_ros.ros.params import declare_spec
from saw_ros.ros.params import ScenarioParameters, SIMULATOR_EXCLUDED
from saw_ros.ros.qos import message_class, publisher_profile
from saw_ros.ros.runtime import NodeFailure, run_module, run_node, spin_node
from std_msgs.msg import String
from std_srvs.srv import Trigger

# What the node publishes by steps, in this order (tests and benchmarks subscribe from here): the
# simulator's rows of the topic table (saw_ros.interface.topics) with a stream profile, every step
# (topics.step_topics()) but /saw/joint_states, every JOINT_STATES_RATE of simulated time.
TOPICS = {t.name: message_class(t.type) for t in topics.published_by('simulator')
          if t.qos in ('clock', 'stream')}
TICK_PERIOD = 0.01           # s of wall time between wake-ups (each costs ~0.1 ms of executor)
BATCH_BUDGET = 0.02          # s of wall time a wake-up may spend stepping
MAX_BATCH = 50               # steps per wake-up: bursts well below the queue depths (100, 200)
# /saw/motor per second of simulated time. Not every step: each 1 kHz topic costs the graph's
# real-time factor, and 100 Hz still resolves the current's ripple at the wave's link rate.
MOTOR_RATE = 100.0
# /saw/joint_states per second of simulated time (``joint_states_rate``'s default). Not every
# step: the 78 joints (2 + 4 a wave link) cost 5.4 us a message to fill and encode (4.0 us for
# the 59 before the flexures' joints, one run, load 3.2) and a 2.5 KB delivery to each reader
# (camera, recorder), while the camera draws the helix phase interpolated between samples (exact
# at a constant frequency, within 2e-4 rad with a motor, 12 V; 2 um of link height) and
# robot_state_publisher and viewers take joint states at tens of Hz (docs/ros.md,
# docs/measurements.md).
JOINT_STATES_RATE = 100.0
WALL_SAMPLES = 201           # points of each bending wall on /saw/walls (5 mm apart over 1 m)

MAX_LAG = 0.25               # s of wall time behind schedule before declaring "behind"
STATUS_PERIOD = 1.0          # s of simulated time between two statuses on /diagnostics
WARN_EVERY = 5.0             # s of wall time between "falling behind" warnings

# Names the simulator takes from its own parameters instead of the Scenario's.
EXCLUDED = SIMULATOR_EXCLUDED                 # integration.duration: replaced by `duration`
FROZEN = {
    'robot': 'the robot geometry is fixed for a run (tip tables are built from it); '
             'restart the node with the new value',
    'integration.dt': 'the time step is fixed for a run (stamps are steps * dt); restart the '
                      'node with the new value',
}


def _load_kernels(scenario: Scenario) -> None:
    """
    Step a throwaway copy of ``scenario`` once: the compiled kernels load here, not at step 1.

    They load from their disk cache at a process's first step, 0.3 s on a quiet machine and
    0.4-0.55 s under load: at step 1 the node then reported falling behind at t = 0.001 s and
    ran its first half second of simulated time late, which failed most pipeline rungs (docs/
    measurements.md). Here, the schedule starts after it.
    """
    try:
        Simulator(scenario).step()
    except DivergenceError:
        pass        # the node's own first step meets it, and recovers (docs/simulator.md)


class SimulatorNode(Node):
    """One SAW robot between two compliant surfaces, stepped in (scaled) real time."""

    def __init__(self, **kwargs):
        super().__init__('simulator', **kwargs)
        try:
            self.params = ScenarioParameters(self, exclude=EXCLUDED, frozen=FROZEN,
                                             on_change=self._on_scenario)
            self.sim = Simulator(self.params.scenario)
            _load_kernels(self.params.scenario)
            declare_spec(self, OWN_PARAMETERS, read_only=False)
            # (declare_spec checked them, and checks every change: core.params.check_value)
            self._rtf = float(self.get_parameter('real_time_factor').value)
            self._duration = float(self.get_parameter('duration').value)
            self.dt_ns = conv.dt_nanoseconds(self.params.scenario.integration.dt)
        except (ParameterError, ParameterException, ValueError) as exc:
            # ParameterException: rclpy refused a start-up value (wrong type, outside the
            # descriptor's range) before the Scenario could check it.
            raise NodeFailure(f'invalid parameters: {exc}') from exc
        self._wait_subscribers = int(self.get_parameter('wait_for_subscribers').value)
        self.started = self._wait_subscribers <= 0
        self.add_post_set_parameters_callback(self._apply_own)
        self.add_on_set_parameters_callback(self._validate_integrable)

        scenario = self.params.scenario
        self.dt = scenario.integration.dt
        self._joints = urdf.JointStateTable(scenario.robot)
        self._joint_names = urdf.joint_names(scenario.robot)
        motor_topic = topics.topic(topics.MOTOR)
        self._pub_motor = self.create_publisher(message_class(motor_topic.type), topics.MOTOR,
                                                publisher_profile(motor_topic.qos))
        self._motor_every = max(1, int(round(1.0 / (MOTOR_RATE * self.dt))))
        self._motor_msg = message_class(motor_topic.type)()

        self._publishers_all = tuple(
            self.create_publisher(msg_type, topic, publisher_profile(topics.topic(topic).qos))
            for topic, msg_type in TOPICS.items())
        # Each step's messages go straight to the publishers' handles: they are bytes, and
        # Publisher.publish's type checks and handle guard cost as much as the write itself.
        self._stream_publishers = tuple(p.handle.publish_raw for p in self._publishers_all)
        # The 1 kHz messages of the steps of one wake-up, per topic (_publish_batch).
        self._batch: tuple = tuple([] for _ in self._publishers_all)
        self._joints_every = max(1, int(round(
            1.0 / (float(self.get_parameter('joint_states_rate').value) * self.dt))))
        self._contacts_cdr = conv.ContactsCdr()
        self._joints_cdr = conv.JointStateCdr(self._joint_names)
        # The robot for a viewer, from this node's own state: at markers_rate of simulated time.
        self._markers = markers.Decimator(float(self.get_parameter('markers_rate').value))
        self._pub_markers = self.create_publisher(
            message_class(topics.topic(topics.MARKERS).type), topics.MARKERS,
            publisher_profile(topics.topic(topics.MARKERS).qos))
        # TF surface -> base_link with the markers (the viewers' rate, not 1 kHz: /saw/pose has
        # every step), and the URDF of this robot, latched (saw_ros.interface.urdf).
        self._pub_tf = tf.publisher(self)
        self._publish_tf = self._pub_tf.handle.publish_raw
        self._link_tf = bool(self.get_parameter('link_tf').value)
        walls_topic = topics.topic(topics.WALLS)
        self._pub_walls = self.create_publisher(message_class(walls_topic.type), walls_topic.name,
                                                publisher_profile(walls_topic.qos))
        self._pub_description = self.create_publisher(
            String, topics.ROBOT_DESCRIPTION,
            publisher_profile(topics.topic(topics.ROBOT_DESCRIPTION).qos))
        self._pub_description.publish(String(data=urdf.urdf(scenario.robot)))

        self.create_service(Trigger, '~/reset', self._on_reset)
        # The drive from your own node (saw_ros.ros.command): /saw/motor_controller/commands.
        self.commands = CommandInput(self, self.sim,
                                     float(self.get_parameter('command_timeout').value))
        # Faults (a divergence, a change the state cannot take) and the recoveries: on
        # /diagnostics when they happen and in a status every STATUS_PERIOD of simulated time.
        self._pub_diagnostics = self.create_publisher(
            DiagnosticArray, topics.DIAGNOSTICS,
            publisher_profile(topics.topic(topics.DIAGNOSTICS).qos))
        self._status_every = max(1, int(round(STATUS_PERIOD / self.dt)))
        self._recoveries = 0                # since the start
        self._recoveries_reported = 0       # at the last status
        self._last_fault = ''
        self._last_fault_log = -math.inf    # wall time of the last fault logged
        self._faults_unlogged = 0

        self.steps = 0                  # steps published since start = stamp / dt (monotonic)
        self.finished = False
        self._behind_since_warning = 0  # steps run late since the last warning
        self._last_warning = -math.inf
        self._rebase(time.monotonic())
        self._timer = self.create_timer(TICK_PERIOD, self._tick)
        if not self.started:
            self.get_logger().info(f'waiting for {self._wait_subscribers} subscriber(s) on every '
                                   f'topic before the first step')
        self.get_logger().info(
            f'simulating at {1.0 / self.dt:g} Hz of simulated time, real_time_factor '
            f'{self._rtf:g}, duration {self._duration:g} s (0 = until stopped), helix '
            f'{scenario.frequency:g} Hz (from {scenario.frequency_source}), slope '
            f'{math.degrees(scenario.conditions.slope):g} deg')

    # -- parameters ----------------------------------------------------------------------------
    def _validate_integrable(self, parameters) -> SetParametersResult:
        """Refuse, with the limit, contacts the step cannot integrate (core.stability)."""
        scenario, _ = self.params.check(parameters)
        if scenario is not None and scenario is not self.params.scenario:
            try:
                stability.check(scenario)
            except ParameterError as exc:
                self.get_logger().warning(f'parameter change refused: {exc}')
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_own(self, parameters) -> None:
        for p in parameters:
            if p.name == 'real_time_factor':
                self._rtf = float(p.value)
                self._rebase(time.monotonic())
            elif p.name == 'duration':
                self._duration = float(p.value)
            elif p.name == 'command_timeout':
                self.commands.timeout = float(p.value)

    def _on_scenario(self, scenario) -> None:
        self.sim.set_scenarios([scenario])
        # A narrower gap (or a smaller max_penetration) can leave the robot where no step can
        # take it on from: such a change is applied through a reset (docs/simulator.md).
        reason = self.sim.placement_error()
        if reason is not None:
            self._recover(f'the new parameters do not fit the current state: {reason}')
        self.get_logger().info(
            f'parameters changed at t = {self.steps * self.dt:.3f} s: helix '
            f'{scenario.frequency:g} Hz (from {scenario.frequency_source}), slope '
            f'{math.degrees(scenario.conditions.slope):g} deg, '
            f'external force {scenario.conditions.external_force:g} N, mu '
            f'{scenario.surface.friction_coefficient:g}')

    # -- services ------------------------------------------------------------------------------
    def _on_reset(self, request, response):
        self.sim.reset()
        t = self.steps * self.dt
        response.success = True
        response.message = (f'robot reset to its initial state at t = {t:.3f} s; simulated '
                            f'time goes on')
        self.get_logger().info(response.message)
        return response

    # -- faults --------------------------------------------------------------------------------
    def _recover(self, reason: str) -> None:
        """Reset the robot with the current parameters, report it on /diagnostics and log it."""
        self.sim.reset()
        self._recoveries += 1
        t = self.sim.t
        self._last_fault = f'{reason}; robot reset to its initial state at t = {t:.3f} s'
        self._publish_status(DiagnosticStatus.ERROR, self._last_fault, t)
        # Every fault is on /diagnostics; the log says each one too, but at most one line per
        # WARN_EVERY (a parameter file that diverges again after every reset would flood it).
        now = time.monotonic()
        if now - self._last_fault_log >= WARN_EVERY:
            more = (f' ({self._faults_unlogged} more since the last such line)'
                    if self._faults_unlogged else '')
            self.get_logger().error(f'{self._last_fault}; simulated time goes on{more}')
            self._last_fault_log = now
            self._faults_unlogged = 0
        else:
            self._faults_unlogged += 1

    def _status(self) -> None:
        """Publish the periodic status: OK, or WARN when the last period needed recoveries."""
        new = self._recoveries - self._recoveries_reported
        self._recoveries_reported = self._recoveries
        if new:
            self._publish_status(DiagnosticStatus.WARN, f'{new} recoveries in the last '
                                 f'{STATUS_PERIOD:g} s; last: {self._last_fault}',
                                 self.steps * self.dt)
        else:
            self._publish_status(DiagnosticStatus.OK, 'stepping', self.steps * self.dt)

    def _publish_status(self, level, message: str, t: float) -> None:
        msg = DiagnosticArray()
        ns = int(round(t / self.dt)) * self.dt_ns
        conv.time_msg(ns, msg.header.stamp)
        msg.status.append(DiagnosticStatus(
            level=level, name=self.get_name(), message=message, hardware_id='saw_ros',
            values=[KeyValue(key='t', value=f'{t:.3f}'),
                    KeyValue(key='recoveries', value=str(self._recoveries))]))
        self._pub_diagnostics.publish(msg)

    # -- stepping ------------------------------------------------------------------------------
    def _rebase(self, now: float) -> None:
        """Schedule the next steps from ``now``: step k is due at now + (k - steps) dt / rtf."""
        self._anchor_wall = now
        self._anchor_steps = self.steps

    def _end_steps(self) -> int:
        return int(round(self._duration / self.dt)) if self._duration > 0 else -1

    def _tick(self) -> None:
        if self.finished:
            return
        now = time.monotonic()
        if not self.started:
            if min(p.get_subscription_count() for p in self._publishers_all) < \
                    self._wait_subscribers:
                return
            self.started = True
            self._rebase(now)
            self.get_logger().info('subscribers present: starting')
        if self._rtf > 0.0:
            due = self._anchor_steps + int((now - self._anchor_wall) * self._rtf / self.dt)
            todo = due - self.steps
            if todo * self.dt / self._rtf > MAX_LAG:
                self._fell_behind(now, todo)
        else:
            todo = MAX_BATCH
        end = self._end_steps()
        if end >= 0:
            todo = min(todo, end - self.steps)
        todo = min(todo, MAX_BATCH)
        deadline = now + BATCH_BUDGET
        try:
            for _ in range(todo):
                self._step()
                if time.monotonic() > deadline:
                    break
        finally:
            self._publish_batch()
        if end >= 0 and self.steps >= end:
            self.finished = True
            self.get_logger().info(f'duration {self._duration:g} s reached after {self.steps} '
                                   f'steps: stopping')

    def _fell_behind(self, now: float, todo: int) -> None:
        """Too far behind schedule: run on from here (slower than real time), never skip."""
        self._behind_since_warning += todo
        self._rebase(now)
        if now - self._last_warning >= WARN_EVERY:
            self.get_logger().warning(
                f'falling behind real time at t = {self.steps * self.dt:.3f} s: '
                f'{self._behind_since_warning * self.dt:.3f} s of simulated time ran late '
                f'since the last warning (real_time_factor {self._rtf:g} is more than this '
                f'machine sustains); every step is still published')
            self._last_warning = now
            self._behind_since_warning = 0

    def step_and_publish(self) -> None:
        """One physics step, then its messages, all stamped (steps + 1) * dt."""
        self._step()
        self._publish_batch()

    def _publish_batch(self) -> None:
        """
        Publish the batch's 1 kHz messages, topic after topic, each topic's in step order.

        One topic's messages back to back: a reader's shared-memory thread then takes several
        a wake-up, where one message a step from each topic in turn woke every reader once a
        message (the writer pays each wake-up too; docs/measurements.md, issue 34 part C).
        """
        for publish, messages in zip(self._stream_publishers, self._batch):
            for data in messages:
                publish(data)
            messages.clear()

    def _step(self) -> None:
        """One physics step; its 1 kHz messages join the batch, the others go out at once."""
        sim = self.sim
        self.commands.poll()
        # Every step, not once a batch: a node catching up steps up to MAX_BATCH at a time, and
        # the hand-back came that much late (1.011 s for a 1 s timeout under a CPU cap).
        self.commands.check_timeout()
        try:
            sim.step()
        except DivergenceError as exc:
            # Never an exit while the node was asked to run on: the state of this step is the
            # initial one, and every topic goes on (docs/simulator.md, Faults).
            self._recover(str(exc))
        contacts = sim.contacts
        q = sim.q[:, 0]
        if not math.isfinite(q.sum() + contacts.normal.sum() + contacts.tangential.sum()):
            self._recover(f'simulation diverged at t = {sim.t:.3f} s: non-finite state or '
                          f'forces')
        self.steps += 1
        if self.steps % self._status_every == 0:
            self._status()
        ns = self.steps * self.dt_ns
        x, y, theta, vx, vy, w = q.tolist()
        points = conv.contact_points(sim.tip_positions[0], contacts.normal[0],
                                     contacts.tangential[0], contacts.touching[0],
                                     contacts.slipping[0])
        fx, fy, mz = sim.contact_wrench[:, 0].tolist()      # the core's, surface axes
        fx, fy = conv.body_axes(fx, fy, theta)
        driven = bool(sim.driven[0])
        # Serialized messages (conversions' CDR encoders): ten times cheaper to publish.
        clock, pose, twist, contacts_out, wrench, joints = self._batch
        clock.append(conv.clock_cdr(ns))
        pose.append(conv.pose_cdr(x, y, theta, ns))
        twist.append(conv.twist_cdr(vx, vy, w, ns))
        contacts_out.append(self._contacts_cdr(points, ns))
        wrench.append(conv.wrench_cdr(fx, fy, mz, ns))
        if self.steps % self._joints_every == 0:
            # The helix's speed and torque are the core's: constant, or the motor's under load.
            omega = float(sim.omega[0])
            # The links' flexures (core.flexure): their deflections, 0 for rigid links.
            values, rates = self._joints.values_and_rates(
                float(sim.phase[0]), omega, sim.deflection[0], sim.deflection_rate[0])
            joints.append(self._joints_cdr(
                float(sim.phase[0]), omega, values, rates, ns,
                float(sim.motor_torque[0]) if driven else None))
        if self.steps % self._motor_every == 0:
            volts = float(sim.motor.voltage[0]) if driven else 0.0   # the commanded one too
            self._pub_motor.publish(conv.motor_msg(volts, float(sim.current[0]), ns,
                                                   out=self._motor_msg))
        if self._markers.due(ns):
            scenario = self.params.scenario
            walls = None
            if sim.walls is not None:
                # The bending walls (core.walls): drawn bent, and their shape on /saw/walls.
                along = x + np.linspace(-0.5, 0.5, WALL_SAMPLES) * scene_markers.SURFACE_LENGTH
                walls = (along, sim.walls.shape(sim.tip_positions.real, along)[0])
                self._pub_walls.publish(conv.walls_cloud(*walls, scenario.conditions.gap, ns))
            # The links' geometry once for both: the drawing and the link frames.
            phase = float(sim.phase[0])
            geometry = link_geometry(scenario.robot, phase)
            deflection = sim.deflection[0]          # the links on their flexures
            self._pub_markers.publish(markers.marker_array_cdr(scene_markers.scene(
                scenario.robot, scenario.conditions.gap, (x, y, theta), phase, points,
                walls=walls, geometry=geometry, deflection=deflection), ns))
            # The link frames from the core's exact geometry at this phase (the joint states'
            # table is within 1e-5 rad of it): RViz's RobotModel without robot_state_publisher.
            transforms = [(frames.SURFACE, frames.BASE_LINK, (x, y, 0.0),
                           frames.yaw_quaternion(theta))]
            if self._link_tf:
                transforms += urdf.link_frames(scenario.robot, phase % (2 * math.pi), geometry,
                                               deflection)
            self._publish_tf(tf.message_cdr(transforms, ns))

    def close(self) -> None:
        """
        Say how many steps went out (every topic got each of them once).

        Tests compare that with recordings. run_node then waits for subscribers to acknowledge
        them (common.flush).
        """
        self.get_logger().info(f'stopped after {self.steps} steps (t = '
                               f'{self.steps * self.dt:.3f} s)')
        if self.commands.refused:
            self.get_logger().warning(
                f'{self.commands.refused} command(s) on {topics.MOTOR_COMMANDS} were refused '
                f'(not one finite value in range), {self.commands.applied} applied')


def spin(node: SimulatorNode) -> None:
    """
    Spin until stopped, or with ``duration`` set until the run is complete.

    A stop (SIGINT, SIGTERM) takes effect between two batches of steps, never inside one. On the
    EventsExecutor: the SingleThreadedExecutor's Python wait set (two QoS event handlers per
    publisher) cost about 1 ms a wake-up, 0.2 of a core at 200 wake-ups a second whatever the
    real-time factor.
    """
    spin_node(node, until=lambda: node.finished)


# The node's own parameters beside the Scenario's (name, default, spec metadata): declared and
# written to msg_config/simulator.yaml from here.
OWN_PARAMETERS = (
    # Bounded so that no timer arithmetic overflows (1e308 ended the node with an
    # OverflowError): 1000 is 40 times what the node steps (25 000 steps/s), and stamps keep
    # their seconds in an int32.
    ('real_time_factor', 1.0, spec_meta('', 'simulated seconds per wall-clock second; 0 = as '
                                            'fast as possible', 0.0, 1000.0)),
    ('duration', 0.0, spec_meta('s', 'simulated time, then the node exits with code 0; 0 = run '
                                     'until stopped', 0.0, float(2 ** 31 - 1))),
    ('markers_rate', markers.RATE, spec_meta(
        'Hz', 'visualization_msgs/MarkerArray of the robot on /saw/markers, and surface -> '
        'base_link on /tf, per simulated second (at most one per step); 0 = none', 0.0, None,
        read_only=True)),
    ('joint_states_rate', JOINT_STATES_RATE, spec_meta(
        'Hz', '/saw/joint_states per simulated second (at most one per step: 1/dt or more = every '
        'step, as the command latency benchmark needs the motor torque)', 0.0, None,
        low_open=True, read_only=True)),
    ('link_tf', True, spec_meta(
        '', "with surface -> base_link, every link frame of the robot's URDF on /tf (at "
        "markers_rate), so that RViz's RobotModel and Foxglove draw the robot without "
        'robot_state_publisher; false where robot_state_publisher turns /saw/joint_states into '
        'TF', read_only=True)),
    ('command_timeout', 0.5, spec_meta(
        's', 'simulated time without a command on /saw/motor_controller/commands after which '
        'the helix returns to its parameter (motor.voltage or conditions.frequency); 0 = the '
        'last command holds until the next', 0.0, float(2 ** 31 - 1))),
    ('wait_for_subscribers', 0, spec_meta('', 'before the first step, wait until every topic has '
                                              'at least this many subscribers (tests, benchmarks, '
                                              'recordings that must see every step); 0 = start '
                                              'at once', 0, None, read_only=True)),
)
YAML_HEADER = """\
Parameters of the saw_ros simulator node:
  python -m saw_ros.ros.nodes.simulator --ros-args --params-file msg_config/simulator.yaml
  (ros2 run saw_ros simulator --ros-args --params-file ... on a ROS 2 install)
Defaults = the paper's experimental set-up (Shachaf, Katz, Zarrouk, Biomimetics 2023;
docs/model.md section 8). SI units; each comment gives the allowed range and unit.
Integers are taken for doubles at start (ros2 param set needs 0.0, not 0). robot.* and
integration.dt cannot change while the node runs; every other parameter can, and takes effect at
the next step.
Generated by: python -m saw_ros.ros.nodes.simulator --write-yaml msg_config/simulator.yaml"""


def yaml_file() -> str:
    """Return msg_config/simulator.yaml, from the Scenario and OWN_PARAMETERS."""
    from saw_ros.ros.params import yaml_text
    return yaml_text('simulator', YAML_HEADER, OWN_PARAMETERS, exclude=EXCLUDED)


def parameters():
    """Every parameter the node declares: the Scenario's (less EXCLUDED), then its own."""
    return [e for e in Scenario().describe() if e[0] not in EXCLUDED] + list(OWN_PARAMETERS)


def main(args=None) -> int:
    return run_node(SimulatorNode, args=args, spin=spin, name='simulator',
                    parameters=parameters)


if __name__ == '__main__':
    run_module(main, yaml_file)
