"""
The comparison node: AR of the simulation against AR of the tracking (paper Figure 18).

Subscribes to the simulator's ground truth (/saw/pose, raw) and to the tracker's estimate
(/saw/tracking/pose). Waits for steady state (CCI of the true forward velocity under
``steady_threshold``), then reports both ARs, v_theory, both mean speeds and their relative
error as diagnostic_msgs/DiagnosticArray on /saw/comparison about once a second, and a final
summary when the ground truth stops (the run ended) or the node shuts down.

Parameters read once at start (simulator_node, reference_file, steady_threshold, report_period)
are read-only: ``ros2 param set`` refuses them with the reason. An invalid one ends the node at
start with the reason and exit code 1, in particular a ``reference_file`` that does not exist or
does not parse: the user asked for a comparison with measurements, so running on without them
would only hide a typo (leave the parameter out, or empty, to run without reference).

The run's conditions (robot geometry for v_theory, frequency or voltage, slope) are read from the
simulator node's own parameters and followed on /parameter_events, so that the comparison always
uses what the simulator runs. The math lives in saw_ros.analysis.compare. Memory stays bounded on
a run of any length: the comparator keeps the last 60 s of simulated time (``KEEP_S``), where it
finds the steady window; a longer run is compared over its last 60 s at most.
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from saw_ros.analysis.compare import find_reference, load_reference, reference_error, RunComparator
from saw_ros.core.params import Scenario, spec_meta
from saw_ros.interface import message_checks as checks
from saw_ros.interface import topics
from saw_ros.ros import cdr
from saw_ros.ros import conversions as conv
from saw_ros.ros.cdr import NS_PER_S
from saw_ros.ros.guard import InputGuard
from saw_ros.ros.params import declare_spec
from saw_ros.ros.params import yaml_text
from saw_ros.ros.qos import INPUT_DEPTH, LATCHED_QOS, STREAM_QOS, with_depth
from saw_ros.ros.ready import Readiness
from saw_ros.ros.runtime import NodeFailure, run_module, run_node, spin_events
from saw_ros.ros.simulator_parameters import SCENARIO_NAMES, SimulatorParameters
from sensor_msgs.msg import JointState

TRACK_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
# The tracking has caught up with the ground truth when its newest pose is stamped within this
# of the newest ground truth's: a frame of the 60 fps camera (16.7 ms; the last frame may precede
# the last step by up to one). A slower camera's last frame waits out idle_timeout instead.
TRACKING_CAUGHT_UP_NS = 20_000_000


# (name, default, spec metadata); read_only ones are read once, at start. declare_spec checks
# the values against these ranges, at start and on every change.
PARAMETERS = (
    ('simulator_node', 'simulator', spec_meta(
        '', 'name of the simulator node whose parameters define the run', read_only=True)),
    ('reference_file', '', spec_meta(
        '', 'CSV of measured results (slope_deg, voltage_V, speed_cm_s and/or advance_ratio); '
            'empty = none. See msg_config/reference_paper.csv', read_only=True)),
    ('steady_threshold', 0.02, spec_meta(
        '', 'CCI below which the ground truth counts as steady (fraction)', 0.0, None,
        low_open=True, read_only=True)),
    ('report_period', 1.0, spec_meta('s', 'wall-clock seconds between reports on '
                                          '/saw/comparison', 0.0, None, low_open=True,
                                     read_only=True)),
    ('idle_timeout', 2.0, spec_meta('s', 'wall-clock seconds without ground truth (and without '
                                         'tracking, while the tracking lags behind the ground '
                                         'truth) after which the run has ended and the final '
                                         'summary is published', 0.0,
                                    None, low_open=True, read_only=False)),
    ('report_path', '', spec_meta('', 'write the final summary as JSON here; empty = do not',
                                  read_only=False)),
    ('exit_when_done', False, spec_meta('', 'exit (code 0) after publishing the final summary',
                                        read_only=False)),
)
YAML_HEADER = """\
Parameters of the saw_ros comparison node (simulated against tracked advance ratio):
  python -m saw_ros.ros.nodes.comparison --ros-args --params-file msg_config/comparison.yaml
Each comment gives the allowed range and unit. simulator_node, reference_file, steady_threshold
and report_period are read at start-up only; the others can change while the node runs.
Generated by: python -m saw_ros.ros.nodes.comparison --write-yaml msg_config/comparison.yaml"""


def yaml_file() -> str:
    """msg_config/comparison.yaml, from PARAMETERS."""
    return yaml_text('comparison', YAML_HEADER, PARAMETERS, with_scenario=False)


def read_reference(path: str):
    """
    Return the reference points of ``path`` ('' = none).

    NodeFailure with a one-line reason if the file is missing or does not parse.
    """
    if not path:
        return []
    try:
        return load_reference(Path(path))
    except FileNotFoundError:
        reason = f'reference_file {path} does not exist'
    except OSError as exc:                              # a directory, no permission...
        reason = f'reference_file {path} cannot be read: {exc.strerror or exc}'
    except (ValueError, csv.Error) as exc:              # UnicodeDecodeError is a ValueError
        text = str(exc)        # load_reference's own messages start with the path
        reason = (f'reference_file {text}' if text.startswith(str(path)) else
                  f'reference_file {path} is not a reference CSV: {text}')
    raise NodeFailure(f'invalid parameters: {reason} (leave reference_file out to compare '
                      f'without measurements)')


class ComparisonNode(Node):
    def __init__(self, **kwargs):
        super().__init__('comparison', **kwargs)
        try:
            declare_spec(self, PARAMETERS)
        except (ParameterException, ValueError) as exc:
            raise NodeFailure(f'invalid parameters: {exc}') from None
        self.reference = read_reference(self.get_parameter('reference_file').value)
        self.scenario = Scenario()
        self.comparator = RunComparator(self.scenario.robot, float('nan'),
                                        self.get_parameter('steady_threshold').value)
        # The run's conditions, from the simulator (saw_ros.ros.simulator_parameters).
        # Every input through the guard: a pose that is not finite, in another frame or stamped
        # back (a single one; a replay's restart is a stream of them) is refused, counted on
        # /diagnostics and warned about, and never reaches the comparator.
        self.guard = InputGuard(self)
        self.simulator_parameters = SimulatorParameters(
            self, self.get_parameter('simulator_node').value, SCENARIO_NAMES, self._apply,
            self.guard)
        self.simulator = self.simulator_parameters.simulator
        self.final_sent = False
        self.done = False
        self._wall = Clock(clock_type=ClockType.STEADY_TIME)
        self._last_truth_wall = None
        self._last_truth_ns = None       # stamp of the latest pose
        self._last_tracked_wall = None
        self._last_tracked_ns = None     # stamp of the latest tracked pose
        self.publisher = self.create_publisher(DiagnosticArray, topics.COMPARISON, LATCHED_QOS)
        self._truth_order = checks.StampOrder()
        self._tracked_order = checks.StampOrder()
        self._truth_sub = self.guard.subscribe(PoseStamped, topics.POSE, self._on_truth,
                                               with_depth(STREAM_QOS, INPUT_DEPTH), raw=True)
        # The helix's angle from /saw/joint_states, used only while a motor drives it (its
        # cycles are then helix turns, docs/motor.md). Subscribed from the start, before the
        # simulator's parameters say whether a motor drives it: a subscription made when they
        # arrive missed the first joint states whenever they came late (a busy machine), and
        # the comparison then measured from a later start than the in-process campaign.
        self._helix = cdr.JointPosition('helix')
        self._helix_followed = True
        self._helix_sub = self.guard.subscribe(JointState, topics.JOINT_STATES, self._on_helix,
                                               with_depth(STREAM_QOS, INPUT_DEPTH), raw=True)
        # 'ground truth matched' once /saw/pose has a publisher (and /saw/joint_states, unless
        # the simulator's parameters say no motor drives the helix), said ready on /saw/ready
        # (run_pipeline waits for it).
        self._readiness = Readiness(self)
        self._match_timer = self.create_timer(0.05, self._report_matched, clock=self._wall)
        self.guard.subscribe(PoseStamped, topics.TRACKING_POSE, self._on_tracked, TRACK_QOS)
        self.create_timer(self.get_parameter('report_period').value, self._tick,
                          clock=self._wall)

    # -- the run's conditions, from the simulator ---------------------------------------------
    def _apply(self, merged) -> bool:
        """Take the simulator's values (SimulatorParameters' callback); False refuses them."""
        before = self.simulator_parameters.values
        try:
            self.scenario = Scenario().with_values(merged)
        except Exception as exc:  # the simulator validated them; keep the last good set
            self.get_logger().warning(f'ignoring simulator parameters: {exc}')
            return False
        if before and merged != before:
            # New conditions: a new steady state to wait for.
            self.comparator.reset()
            changed = sorted(k for k in merged if merged[k] != before.get(k))
            self.get_logger().info(f'simulator parameters changed ({", ".join(changed)}): '
                                   f'comparison restarted')
        self.comparator.robot = self.scenario.robot
        self.comparator.frequency = self.scenario.frequency
        self._follow_helix(self.scenario.motor.voltage > 0.0)
        return True

    def _follow_helix(self, on: bool) -> None:
        self._helix_followed = on
        if not on:
            self.comparator.helix.clear()

    # -- data --------------------------------------------------------------------------------
    def _report_matched(self):
        helix_matched = self._helix_sub.get_publisher_count() > 0 or (
            self.simulator_parameters.known and not self._helix_followed)
        if self._truth_sub.get_publisher_count() > 0 and helix_matched:
            self.get_logger().info('ground truth matched')
            self._readiness.announce()
            self._match_timer.cancel()
            self.destroy_timer(self._match_timer)

    def _on_truth(self, data: bytes):
        t_ns, frame_id, x, y, q = cdr.pose_stamped(data)
        checks.frame(frame_id, (topics.topic(topics.POSE).frame,))
        checks.pose(x, y, q)
        self._truth_order.check(t_ns)
        t = t_ns / NS_PER_S
        if self._truth_order.restarted:
            self.get_logger().warning(
                f'simulated time went back from {self._last_truth_ns / NS_PER_S:.3f} s to '
                f'{t:.3f} s (a replay restarted?): comparison restarted')
        self._last_truth_ns = t_ns
        self._last_truth_wall = time.monotonic()     # (rclpy's Clock.now() costs 10x, per pose)
        self.comparator.add_truth(t, x)

    def _on_helix(self, data: bytes):
        t_ns, angle = self._helix(data)
        if angle is None:
            raise checks.Refused('no helix position', "no position for the joint 'helix'")
        checks.finite('helix position', (angle,))
        if self._helix_followed:
            self.comparator.add_helix(t_ns / NS_PER_S, angle)

    def _on_tracked(self, msg: PoseStamped):
        checks.frame(msg.header.frame_id, (topics.topic(topics.TRACKING_POSE).frame,))
        o, p = msg.pose.orientation, msg.pose.position
        checks.pose(p.x, p.y, (o.x, o.y, o.z, o.w))
        t_ns = conv.stamp_ns(msg.header.stamp)
        self._tracked_order.check(t_ns)
        self._last_tracked_ns = t_ns
        self._last_tracked_wall = time.monotonic()
        self.comparator.add_tracked(t_ns / NS_PER_S, p.x)

    # -- reports -----------------------------------------------------------------------------
    def _tick(self):
        if not self.simulator_parameters.known:
            self.simulator_parameters.request()
            return
        timeout = self.get_parameter('idle_timeout').value
        now = time.monotonic()
        idle = self._last_truth_wall is not None and now - self._last_truth_wall > timeout
        # The ground truth has ended, but the tracker (a busy machine's vision node, seconds
        # behind) still delivers frames from before its end: the final summary waits for them,
        # or its window would end at the last frame tracked so far, a whole turn short of the
        # in-process campaign's.
        tracking_behind = self._last_tracked_ns is not None and \
            self._last_truth_ns - self._last_tracked_ns > TRACKING_CAUGHT_UP_NS and \
            now - self._last_tracked_wall <= timeout
        idle = idle and not tracking_behind
        if idle and not self.final_sent:
            self.publish(final=True)
        elif not idle:
            self.publish(final=False)
        if self.final_sent and self.get_parameter('exit_when_done').value:
            self.done = True

    def summary(self):
        r = self.comparator.result()
        c = self.scenario.conditions
        out = {'status': r.status, 'slope_deg': math.degrees(c.slope),
               'voltage_V': self.scenario.motor.voltage, 'frequency_hz': r.frequency,
               'v_theory_m_s': r.v_theory, 'steady_from_s': r.steady_from,
               'window_s': r.window_s, 'v_sim_m_s': r.v_sim, 'v_tracked_m_s': r.v_tracked,
               'ar_sim': r.ar_sim, 'ar_tracked': r.ar_tracked,
               'relative_error': r.relative_error, 'truth_samples': r.truth_samples,
               'tracked_samples': r.tracked_samples}
        point = find_reference(self.reference, out['slope_deg'], out['voltage_V'])
        if point is not None and r.steady:
            out['reference_error_sim'] = reference_error(point, r.v_sim, r.v_theory)
            out['reference_source'] = point.source
        return r, out

    def publish(self, final: bool):
        r, values = self.summary()
        status = DiagnosticStatus(name='saw_ros: comparison' + (' (final)' if final else ''),
                                  hardware_id=self.simulator)
        if r.steady:
            status.level = DiagnosticStatus.OK
            status.message = (f'AR sim {r.ar_sim:.4f}, AR tracked {r.ar_tracked:.4f}, '
                              f'relative error {100 * r.relative_error:.2f} %')
        else:
            status.level = DiagnosticStatus.WARN if final else DiagnosticStatus.OK
            status.message = r.status
        status.values = [KeyValue(key=k, value=v if isinstance(v, str) else f'{v:.6g}')
                         for k, v in values.items()
                         if r.steady or k in ('status', 'slope_deg', 'voltage_V', 'frequency_hz',
                                              'v_theory_m_s', 'truth_samples',
                                              'tracked_samples')]
        msg = DiagnosticArray(status=[status])
        if self._last_truth_ns is not None:
            conv.time_msg(self._last_truth_ns, msg.header.stamp)
        self.publisher.publish(msg)
        if final:
            self.final_sent = True
            self.get_logger().info(f'final comparison: {status.message}')
            path = self.get_parameter('report_path').value
            if path:
                Path(path).parent.mkdir(parents=True, exist_ok=True)
                Path(path).write_text(json.dumps(values, indent=2, default=str) + '\n')

    def close(self):
        if not self.final_sent and self.simulator_parameters.known and \
                self._last_truth_ns is not None:
            self.publish(final=True)


def spin_until_done(node: ComparisonNode) -> None:
    # The events executor: rclpy.spin_once(node) per message rebuilt the executor's wait set
    # for each of the 1000 poses a second.
    spin_events(node, until=lambda: node.done)


def main(args=None):
    return run_node(ComparisonNode, args, spin=spin_until_done, name='comparison',
                    parameters=lambda: PARAMETERS)


if __name__ == '__main__':
    run_module(main, yaml_file)
