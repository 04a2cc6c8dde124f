"""Node ``player``: play a bag back onto its topics, as ``ros2 bag play --clock`` would.

Parameters
  bag                  string    bag directory (or .mcap file); required
  rate                 double    speed factor (default 1.0: original timing)
  topics               string[]  only these topics (default: all)
  clock                bool      publish /clock (default true): the recorded /clock messages when
                                 the bag has them, else from the log times at ``clock_rate``
  clock_rate           double    Hz of /clock made from log times (default 1000)
  queue_depth          int       publisher history depth (default 1000)
  wait_for_subscribers int       wait (up to 10 s) for this many subscriptions before playing

Each topic is offered with the QoS the bag's publishers offered (reliability, durability), the
bytes are published as recorded. The node exits 0 once everything is played and acknowledged.
"""
from __future__ import annotations

import time

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from saw_ros.bag.reader import BagReader, BagReadError
from saw_ros.conversions import clock_cdr
from saw_ros.nodes.common import NodeFailure, run_node
from saw_ros.nodes.recorder import message_class

SLEEP_MIN = 0.0005   # s: no sleep for a message due sooner than this (timing error < 0.5 ms)


def offered_qos(profiles, depth: int) -> QoSProfile:
    """rosbag2's adapt_offer_to_recorded_offers, with our history depth."""
    reliability, durability = ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE
    if profiles:
        rel = {p.get('reliability') for p in profiles}
        dur = {p.get('durability') for p in profiles}
        if rel == {'best_effort'}:
            reliability = ReliabilityPolicy.BEST_EFFORT
        if dur == {'transient_local'}:
            durability = DurabilityPolicy.TRANSIENT_LOCAL
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=reliability,
                      durability=durability)


class Player(Node):
    def __init__(self):
        super().__init__('player')
        p = {name: self.declare_parameter(name, default).value for name, default in (
            ('bag', ''), ('rate', 1.0), ('topics', ['']), ('clock', True),
            ('clock_rate', 1000.0), ('queue_depth', 1000), ('wait_for_subscribers', 0))}
        self.p = p
        if not p['bag']:
            raise NodeFailure('parameter bag is required (-p bag:=<bag directory>)')
        if p['rate'] <= 0:
            raise NodeFailure(f'rate must be > 0, not {p["rate"]}')
        try:
            self.reader = BagReader(p['bag'])
            topics = self.reader.topics()
        except BagReadError as exc:
            raise NodeFailure(str(exc)) from None
        wanted = [t for t in p['topics'] if t]
        self.topics = {n: t for n, t in topics.items() if not wanted or n in wanted}
        self.publishers_by_topic = {}
        for name, t in self.topics.items():
            try:
                msg_type = message_class(t.type)
            except (ImportError, AttributeError, ValueError):
                self.get_logger().warn(f'{name}: type {t.type} unknown here; not played')
                continue
            self.publishers_by_topic[name] = self.create_publisher(
                msg_type, name, offered_qos(t.offered_qos_profiles, int(p['queue_depth'])))
        self.clock_from_log = bool(p['clock']) and '/clock' not in topics
        if not p['clock']:
            self.publishers_by_topic.pop('/clock', None)
        self.clock_pub = None
        if self.clock_from_log:
            from rosgraph_msgs.msg import Clock
            from saw_ros.nodes.common import CLOCK_QOS
            self.clock_pub = self.create_publisher(Clock, '/clock', CLOCK_QOS)
        self.played = 0

    def _subscriber_count(self) -> int:
        pubs = list(self.publishers_by_topic.values())
        if self.clock_pub is not None:
            pubs.append(self.clock_pub)
        return sum(pub.get_subscription_count() for pub in pubs)

    def play(self) -> None:
        from saw_ros.process import wait_for
        need = int(self.p['wait_for_subscribers'])
        if need > 0 and not wait_for(lambda: self._subscriber_count() >= need, 10.0):
            self.get_logger().warn(f'only {self._subscriber_count()} of {need} subscriptions '
                                   'after 10 s; playing anyway')
        rate = float(self.p['rate'])
        clock_period = int(1e9 / self.p['clock_rate']) if self.clock_from_log else None
        next_clock = None
        start_wall = None
        start_bag = None
        self.get_logger().info(f'playing {self.reader.path} ({len(self.publishers_by_topic)} '
                               f'topics) at rate {rate}')
        for m in self.reader.messages(list(self.publishers_by_topic)):
            if start_wall is None:
                start_wall, start_bag = time.monotonic(), m.log_time
                next_clock = m.log_time
            if clock_period is not None:
                while next_clock <= m.log_time:
                    self._wait_until(start_wall + (next_clock - start_bag) / 1e9 / rate)
                    self._publish_clock(next_clock)
                    next_clock += clock_period
            self._wait_until(start_wall + (m.log_time - start_bag) / 1e9 / rate)
            self.publishers_by_topic[m.topic].publish(m.data)
            self.played += 1
        span = time.monotonic() - start_wall if start_wall is not None else 0.0
        for pub in list(self.publishers_by_topic.values()) + (
                [self.clock_pub] if self.clock_pub is not None else []):
            pub.wait_for_all_acked()
        self.get_logger().info(f'played {self.played} messages in {span:.3f} s')

    def _publish_clock(self, stamp_ns: int) -> None:
        # Pre-encoded, as the simulator publishes it (1 kHz by default).
        self.clock_pub.publish(clock_cdr(stamp_ns))

    @staticmethod
    def _wait_until(deadline: float) -> None:
        # A sleep costs ~60 us however short: messages due within SLEEP_MIN go out at once
        # (the 6 messages of one 1 kHz tick, recorded a few us apart, are one burst).
        delay = deadline - time.monotonic()
        if delay > SLEEP_MIN:
            time.sleep(delay)


def main(args=None) -> int:
    return run_node(Player, args=args, spin=lambda node: node.play())


if __name__ == '__main__':
    raise SystemExit(main())
