"""The comparison node: AR of the simulation against AR of the tracking (paper Figure 18).

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
uses what the simulator runs. The math lives in saw_ros.analysis.compare.
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import (ParameterEvent, ParameterType,
                                SetParametersResult)
from rcl_interfaces.srv import GetParameters
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from saw_ros.ros import cdr
from saw_ros.ros import conversions as conv
from saw_ros.analysis.compare import RunComparator, find_reference, load_reference, reference_error
from saw_ros.core.params import Scenario, spec_meta
from saw_ros.interface import topics
from saw_ros.ros.params import SIMULATOR_EXCLUDED, declare_spec
from saw_ros.ros.qos import INPUT_DEPTH, LATCHED_QOS, STREAM_QOS, with_depth
from saw_ros.ros.runtime import NodeFailure, run_node, spin_events
from saw_ros.ros.ready import Readiness

TRACK_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


def _value(p):
    """rcl_interfaces/ParameterValue -> Python value (only the types we declare)."""
    return {ParameterType.PARAMETER_DOUBLE: p.double_value,
            ParameterType.PARAMETER_INTEGER: p.integer_value,
            ParameterType.PARAMETER_BOOL: p.bool_value,
            ParameterType.PARAMETER_STRING: p.string_value}.get(p.type)


# (name, default, spec metadata); read_only ones are read once, at start. The node checks the
# bounds itself (POSITIVE), with its own message.
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
    ('idle_timeout', 2.0, spec_meta('s', 'wall-clock seconds without ground truth after which the '
                                         'run has ended and the final summary is published', 0.0,
                                    None, low_open=True, read_only=False)),
    ('report_path', '', spec_meta('', 'write the final summary as JSON here; empty = do not',
                                  read_only=False)),
    ('exit_when_done', False, spec_meta('', 'exit (code 0) after publishing the final summary',
                                        read_only=False)),
)
POSITIVE = ('steady_threshold', 'report_period', 'idle_timeout')


def _check_positive(name, value) -> None:
    if name in POSITIVE and not (math.isfinite(value) and value > 0):
        raise ValueError(f'{name} = {value} must be a finite number > 0')


def read_reference(path: str):
    """The reference points of ``path`` ('' = none); NodeFailure with a one-line reason if the
    file is missing or does not parse."""
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
            for name in POSITIVE:
                _check_positive(name, self.get_parameter(name).value)
        except (ParameterException, ValueError) as exc:
            raise NodeFailure(f'invalid parameters: {exc}') from None
        self.add_on_set_parameters_callback(self._validate)
        self.reference = read_reference(self.get_parameter('reference_file').value)
        self.scenario_values = {}
        self.scenario = Scenario()
        self.comparator = RunComparator(self.scenario.robot, float('nan'),
                                        self.get_parameter('steady_threshold').value)
        self.simulator = self.get_parameter('simulator_node').value.strip('/')
        self.final_sent = False
        self.done = False
        self._wall = Clock(clock_type=ClockType.STEADY_TIME)
        self._last_truth_wall = None
        self._last_truth_ns = None       # stamp of the latest pose
        self.publisher = self.create_publisher(DiagnosticArray, topics.COMPARISON, LATCHED_QOS)
        self._truth_sub = self.create_subscription(PoseStamped, topics.POSE, self._on_truth,
                                                   with_depth(STREAM_QOS, INPUT_DEPTH), raw=True)
        # 'ground truth matched' once /saw/pose has a publisher, said ready on /saw/ready
        # (run_pipeline waits for it).
        self._readiness = Readiness(self)
        self._match_timer = self.create_timer(0.05, self._report_matched, clock=self._wall)
        self.create_subscription(PoseStamped, topics.TRACKING_POSE, self._on_tracked,
                                 TRACK_QOS)
        self.create_subscription(ParameterEvent, '/parameter_events', self._on_parameter_event,
                                 QoSProfile(depth=100))
        self._param_client = self.create_client(
            GetParameters, f'/{self.simulator}/get_parameters')
        self._pending = None
        self.create_timer(self.get_parameter('report_period').value, self._tick,
                          clock=self._wall)

    def _validate(self, parameters) -> SetParametersResult:
        """Run-time changes of the live parameters (the others are read-only)."""
        for p in parameters:
            try:
                _check_positive(p.name, p.value)
            except (TypeError, ValueError) as exc:
                self.get_logger().warning(f'parameter change refused: {exc}')
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    # -- the run's conditions, from the simulator ---------------------------------------------
    def _request_parameters(self):
        if self._pending is not None or not self._param_client.service_is_ready():
            return
        # rclpy answers nothing at all if one name is not declared: ask only for what the
        # simulator declares (it replaces integration.duration by its own `duration`).
        names = [n for n in Scenario().flat() if n not in SIMULATOR_EXCLUDED]
        self._pending = self._param_client.call_async(GetParameters.Request(names=names))
        self._pending.add_done_callback(lambda f, names=names: self._on_parameters(names, f))

    def _on_parameters(self, names, future):
        self._pending = None
        result = future.result()
        if result is None:
            return
        values = {n: _value(v) for n, v in zip(names, result.values)}
        self._apply({k: v for k, v in values.items() if v is not None})

    def _on_parameter_event(self, event: ParameterEvent):
        if event.node.strip('/') != self.simulator or not self.scenario_values:
            return
        changed = {p.name: _value(p.value) for p in list(event.changed_parameters)
                   + list(event.new_parameters)}
        self._apply({k: v for k, v in changed.items() if k in self.scenario_values})

    def _apply(self, values):
        merged = dict(self.scenario_values, **values)
        try:
            self.scenario = Scenario().with_values(merged)
        except Exception as exc:  # the simulator validated them; keep the last good set
            self.get_logger().warning(f'ignoring simulator parameters: {exc}')
            return
        if self.scenario_values and merged != self.scenario_values:
            # New conditions: a new steady state to wait for.
            self.comparator.reset()
            changed = sorted(k for k in merged if merged[k] != self.scenario_values.get(k))
            self.get_logger().info(f'simulator parameters changed ({", ".join(changed)}): '
                                   f'comparison restarted')
        self.scenario_values = merged
        self.comparator.robot = self.scenario.robot
        self.comparator.frequency = self.scenario.frequency

    # -- data --------------------------------------------------------------------------------
    def _report_matched(self):
        if self._truth_sub.get_publisher_count() > 0:
            self.get_logger().info('ground truth matched')
            self._readiness.announce()
            self._match_timer.cancel()
            self.destroy_timer(self._match_timer)

    def _on_truth(self, data: bytes):
        t_ns, x, _y, _theta = cdr.pose_stamped_ns(data)
        t = t_ns / 1e9
        if self._last_truth_ns is not None and t_ns < self._last_truth_ns:
            self.get_logger().warning(
                f'simulated time went back from {self._last_truth_ns / 1e9:.3f} s to {t:.3f} s'
                ' (a replay restarted?): comparison restarted')
        self._last_truth_ns = t_ns
        self._last_truth_wall = self._wall.now()
        self.comparator.add_truth(t, x)

    def _on_tracked(self, msg: PoseStamped):
        self.comparator.add_tracked(conv.stamp_ns(msg.header.stamp) / 1e9,
                                    msg.pose.position.x)

    # -- reports -----------------------------------------------------------------------------
    def _tick(self):
        if not self.scenario_values:
            self._request_parameters()
            return
        idle = self._last_truth_wall is not None and (
            self._wall.now() - self._last_truth_wall).nanoseconds * 1e-9 > self.get_parameter(
            'idle_timeout').value
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
        if not self.final_sent and self.scenario_values and self._last_truth_ns is not None:
            self.publish(final=True)


def spin_until_done(node: ComparisonNode) -> None:
    # The events executor: rclpy.spin_once(node) per message rebuilt the executor's wait set
    # for each of the 1000 poses a second.
    spin_events(node, until=lambda: node.done)


def main(args=None):
    return run_node(ComparisonNode, args, spin=spin_until_done)


if __name__ == '__main__':
    raise SystemExit(main())
