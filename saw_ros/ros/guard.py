"""
Guarded subscriptions: one bad message never ends a node (issue 33).

``InputGuard(node)`` subscribes for a node; a callback refuses a message by raising
``message_checks.Refused`` (the checks are the pure functions of
``saw_ros.interface.message_checks``), and anything else a callback raises on a message (a
struct.error on truncated bytes, a ValueError deep in a decoder) is refused the same way, as
'unreadable', instead of ending the node with a traceback. Only ``NodeFailure`` goes through: it is
the node's own decision to stop. Each refusal is:

- counted per topic and kind, and the counts published once a second on /diagnostics
  (diagnostic_msgs/DiagnosticArray, one status '<node>: inputs', key '<topic>: <kind>'; level
  WARN once anything was refused);
- said in a warning naming the topic and what is wrong, at most once per ``WARN_EVERY`` s a topic
  (the next one says how many more were refused meanwhile).

The simulator's command input (``saw_ros.ros.command``) refuses its commands through the same
guard.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable, Dict, Tuple

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType
from saw_ros.interface import topics
from saw_ros.interface.message_checks import Refused
from saw_ros.ros.qos import publisher_profile
from saw_ros.ros.runtime import NodeFailure

WARN_EVERY = 5.0        # s of wall time between two warnings about one topic's refused messages
REPORT_PERIOD = 1.0     # s of wall time between two /diagnostics reports of the counts


class InputGuard:
    """Subscriptions of ``node`` that refuse, count and report bad messages (module docstring)."""

    def __init__(self, node):
        self.node = node
        self.counts: Dict[Tuple[str, str], int] = {}
        self._last_warning: Dict[str, float] = {}
        self._unsaid: Dict[str, int] = {}
        entry = topics.topic(topics.DIAGNOSTICS)
        self._publisher = node.create_publisher(DiagnosticArray, entry.name,
                                                publisher_profile(entry.qos))
        # A steady clock: with use_sim_time the node's clock stands still until /clock runs.
        self._timer = node.create_timer(REPORT_PERIOD, self.report,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))

    @property
    def refused(self) -> int:
        return sum(self.counts.values())

    def guarded(self, topic: str, callback: Callable[[Any], None]) -> Callable[[Any], None]:
        """Return ``callback`` refusing (counted, warned) what it cannot take from ``topic``."""
        def on_message(msg) -> None:
            try:
                callback(msg)
            except NodeFailure:
                raise
            except Refused as exc:
                self.refuse(topic, exc.kind, exc.detail)
            except Exception as exc:  # noqa: BLE001  (any message must leave the node running)
                self.refuse(topic, 'unreadable', f'{type(exc).__name__}: {exc}')
        return on_message

    def subscribe(self, msg_type, topic: str, callback: Callable[[Any], None], qos, **kwargs):
        """``node.create_subscription`` with ``callback`` guarded."""
        return self.node.create_subscription(msg_type, topic, self.guarded(topic, callback), qos,
                                             **kwargs)

    def refuse(self, topic: str, kind: str, detail: str) -> None:
        """Count a refused message and warn about it (throttled per topic)."""
        key = (topic, kind)
        self.counts[key] = self.counts.get(key, 0) + 1
        now = time.monotonic()
        if now - self._last_warning.get(topic, -math.inf) < WARN_EVERY:
            self._unsaid[topic] = self._unsaid.get(topic, 0) + 1
            return
        more = self._unsaid.pop(topic, 0)
        self.node.get_logger().warning(
            f'message on {topic} refused, not used: {kind}: {detail}'
            + (f' ({more} more refused on {topic} since the last warning)' if more else ''))
        self._last_warning[topic] = now

    def status(self) -> DiagnosticStatus:
        """Return the node's input status: every (topic, kind) refused and how many times."""
        n = self.refused
        name = self.node.get_name()
        return DiagnosticStatus(
            name=f'{name}: inputs', hardware_id=name,
            level=DiagnosticStatus.WARN if n else DiagnosticStatus.OK,
            message=f'{n} messages refused' if n else 'no message refused',
            values=[KeyValue(key=f'{t}: {k}', value=str(c))
                    for (t, k), c in sorted(self.counts.items())])

    def report(self) -> None:
        msg = DiagnosticArray(status=[self.status()])
        msg.header.stamp = self.node.get_clock().now().to_msg()
        self._publisher.publish(msg)
