"""
The comparison node through real topics.

Simulator node + a stand-in tracker (98 % of the true position, 60 Hz of simulated time) ->
/saw/comparison.
"""
import collections
import json
import math
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from saw_ros.core import Scenario, simulate
from saw_ros.core.metrics import analyse
from saw_ros.graph.process import ManagedProcess, node_command, wait_for
from saw_ros.interface import topics as table
from saw_ros.ros.qos import LATCHED_QOS, STREAM_QOS

pytestmark = pytest.mark.ros

SLOPE = math.radians(10)


class StandInTracker(Node):
    """
    Republishes the ground truth as a tracker would: every 1/60 s, position scaled.

    Each frame goes out LAG_S of wall time after its pose came, longer than the comparison's
    idle_timeout: a vision node seconds behind on a busy machine.
    """

    LAG_S = 2.5

    def __init__(self, context):
        super().__init__('stand_in_tracker', context=context)
        self.next_frame = 0.0
        self.pending = collections.deque()      # (wall time to publish at, message)
        self.published = 0
        self.pub = self.create_publisher(PoseStamped, table.TRACKING_POSE, 100)
        self.create_subscription(PoseStamped, table.POSE, self.on_pose, STREAM_QOS)
        self.create_timer(0.01, self.release)
        self.reports = []
        self.create_subscription(DiagnosticArray, table.COMPARISON, self.reports.append,
                                 LATCHED_QOS)

    def on_pose(self, msg):
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        if t + 1e-9 >= self.next_frame:
            self.next_frame += 1 / 60
            msg.pose.position.x *= 0.98
            self.pending.append((time.monotonic() + self.LAG_S, msg))

    def release(self):
        while self.pending and self.pending[0][0] <= time.monotonic():
            self.pub.publish(self.pending.popleft()[1])
            self.published += 1


def values(report):
    return {kv.key: kv.value for kv in report.status[0].values}


def test_comparison_reports_both_ars_and_their_error_then_a_final_summary(ros_context, tmp_path):
    report_path = tmp_path / 'comparison.json'
    executor = SingleThreadedExecutor(context=ros_context)
    tracker = StandInTracker(ros_context)
    executor.add_node(tracker)
    logs = tmp_path / 'logs'
    comparison = ManagedProcess('comparison', node_command(
        'comparison', params={'report_path': str(report_path), 'idle_timeout': 1.0,
                              'exit_when_done': True, 'report_period': 0.5}), None, logs)
    sim = None
    try:
        spin = lambda t: executor.spin_once(timeout_sec=t)  # noqa: E731
        # Start the simulator once the comparison node has joined the graph.
        assert wait_for(lambda: 'comparison' in tracker.get_node_names(), 30, spin=spin)
        sim = ManagedProcess('simulator', node_command(
            'simulator', params={'duration': 4.0, 'real_time_factor': 1.0,
                                 'conditions.slope': SLOPE}), None, logs)
        assert wait_for(lambda: any('final' in r.status[0].name for r in tracker.reports), 60,
                        spin=spin), comparison.output() + sim.output()
        steady = [r for r in tracker.reports if values(r).get('status') == 'steady']
        assert steady, [(r.status[0].name, values(r)) for r in tracker.reports][-2:]
        final = values(tracker.reports[-1])
        assert wait_for(lambda: not tracker.pending, 10, spin=spin)     # every frame out
        assert comparison.wait(20) == 0
        assert sim.wait(20) == 0
    finally:
        for p in (sim, comparison):
            if p is not None and p.returncode is None:
                p.stop()
        executor.shutdown()
        tracker.destroy_node()
    s = Scenario().with_values({'conditions.slope': SLOPE})
    tr = simulate(s, 4.0)
    core_ar = analyse(tr.t, tr.q[:, 0], s.robot, s.frequency).advance_ratio
    assert float(final['ar_sim']) == pytest.approx(core_ar, rel=0.01)
    assert float(final['relative_error']) == pytest.approx(0.02, abs=0.003)
    assert float(final['slope_deg']) == pytest.approx(10.0)
    # The final summary waited for the lagging tracker's last frames (it came 1-1.5 s after the
    # ground truth's end, before them, with a window short of the in-process campaign's).
    assert int(float(final['tracked_samples'])) == tracker.published, final
    saved = json.loads(report_path.read_text())
    assert saved['status'] == 'steady' and saved['ar_tracked'] == pytest.approx(
        float(final['ar_tracked']), rel=1e-5)
