"""Node ``player``: play a bag back onto its topics, as ``ros2 bag play --clock`` would.

Parameters
  bag                  string    bag directory (or .mcap file); required
  rate                 double    speed factor (default 1.0: original timing)
  topics               string[]  only these topics (default: all)
  clock                bool      publish /clock (default true): the recorded /clock messages when
                                 the bag has them, else from the log times at ``clock_rate``
  clock_rate           double    Hz of /clock made from log times (default 1000; 0 < rate <= 1e6)
  queue_depth          int       publisher history depth (default 1000)
  wait_for_subscribers int       wait (up to 10 s) for this many subscriptions before playing

Every parameter is read once, at start: all are read-only (``ros2 param set`` is refused with
"Trying to set a read-only parameter"); invalid values end the node at start with the reason
and exit code 1. The parameter services are served while playing (a thread spins the node).

Each topic is offered with the QoS the bag's publishers offered (reliability, durability), the
bytes are published as recorded. The node exits 0 once everything is played; like every node
it then waits at most ``common.FLUSH_TIMEOUT`` s in all for reliable subscribers to acknowledge
the last messages, and says which topics were not acknowledged.
"""
from __future__ import annotations

import math
import threading
import time

from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from saw_ros.core.params import spec_meta
from saw_ros.bag.reader import BagReader, BagReadError
from saw_ros.ros.conversions import clock_cdr
from saw_ros.interface.topics import CLOCK
from saw_ros.ros.qos import CLOCK_QOS, message_class
from saw_ros.ros.runtime import NodeFailure, run_node

SLEEP_MIN = 0.0005   # s: no sleep for a message due sooner than this (timing error < 0.5 ms)
MAX_CLOCK_RATE = 1e6  # Hz: one /clock a microsecond at most
# (name, default, spec metadata); every one read once at start, so read-only. The node checks
# the bounds itself, with its own message (clock_rate: no ROS range, for that reason).
PARAMETERS = (
    ('bag', '', spec_meta('', 'bag directory (or .mcap file) to play; required')),
    ('rate', 1.0, spec_meta('', 'speed factor: 1 = the recorded timing, 2 = twice as fast', 0.0,
                            None, low_open=True)),
    ('topics', [''], spec_meta('', 'only these topics (empty: all)')),
    ('clock', True, spec_meta('', 'publish /clock: the recorded one, or made from log times at '
                                  'clock_rate')),
    ('clock_rate', 1000.0, spec_meta('Hz', '/clock rate made from log times', 0.0,
                                     MAX_CLOCK_RATE, low_open=True, ros_range=False)),
    ('queue_depth', 1000, spec_meta('', 'publisher history depth', 1, None)),
    ('wait_for_subscribers', 0, spec_meta('', 'wait (up to 10 s) for this many subscriptions '
                                              'before playing', 0, None)),
)


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
        from saw_ros.ros.params import declare_spec
        try:
            # Read once, here: read-only, so that `ros2 param set` says so instead of
            # reporting a change that would not happen.
            p = declare_spec(self, PARAMETERS)
        except ParameterException as exc:
            raise NodeFailure(f'invalid parameters: {exc}') from None
        self.p = p
        if not p['bag']:
            raise NodeFailure('parameter bag is required (-p bag:=<bag directory>)')
        if not (math.isfinite(p['rate']) and p['rate'] > 0):
            raise NodeFailure(f'invalid parameters: rate = {p["rate"]} must be a finite '
                              f'number > 0 (1 = recorded timing)')
        if not (math.isfinite(p['clock_rate']) and 0 < p['clock_rate'] <= MAX_CLOCK_RATE):
            raise NodeFailure(f'invalid parameters: clock_rate = {p["clock_rate"]} Hz must be '
                              f'> 0 and <= {MAX_CLOCK_RATE:g}')
        if p['queue_depth'] < 1 or p['wait_for_subscribers'] < 0:
            raise NodeFailure(f'invalid parameters: queue_depth = {p["queue_depth"]} must be '
                              f'>= 1, wait_for_subscribers = {p["wait_for_subscribers"]} >= 0')
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
                self.get_logger().warning(f'{name}: type {t.type} unknown here; not played')
                continue
            self.publishers_by_topic[name] = self.create_publisher(
                msg_type, name, offered_qos(t.offered_qos_profiles, int(p['queue_depth'])))
        self.clock_from_log = bool(p['clock']) and CLOCK not in topics
        if not p['clock']:
            self.publishers_by_topic.pop(CLOCK, None)
        self.clock_pub = None
        if self.clock_from_log:
            from rosgraph_msgs.msg import Clock
            self.clock_pub = self.create_publisher(Clock, CLOCK, CLOCK_QOS)
        self.played = 0
        self._executor = None       # serves the parameter services while playing
        self._spinner = None
        self._stopping = False

    def _subscriber_count(self) -> int:
        pubs = list(self.publishers_by_topic.values())
        if self.clock_pub is not None:
            pubs.append(self.clock_pub)
        return sum(pub.get_subscription_count() for pub in pubs)

    def play(self) -> None:
        need = int(self.p['wait_for_subscribers'])
        deadline = time.monotonic() + 10.0
        while self._subscriber_count() < need and time.monotonic() < deadline:
            time.sleep(0.02)     # discovery runs in the DDS threads; nothing to spin here
        if self._subscriber_count() < need:
            self.get_logger().warning(f'only {self._subscriber_count()} of {need} subscriptions '
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


    def start_services(self) -> None:
        """Serve the parameter services (and the rest of the node's callbacks) from a thread
        while play() publishes: a `ros2 param set` then gets its answer (refused: read-only)."""
        from rclpy.executors import SingleThreadedExecutor
        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self)
        self._spinner = threading.Thread(target=self._spin, name='player-services', daemon=True)
        self._spinner.start()

    def _spin(self) -> None:
        executor = self._executor
        try:
            while self.context.ok() and not self._stopping:
                executor.spin_once(timeout_sec=0.1)
        except Exception:  # noqa: BLE001  (context shut down while spinning)
            pass

    def close(self) -> None:
        """Stop the service thread before the node is destroyed."""
        self._stopping = True
        if self._executor is not None:
            self._spinner.join(2.0)
            self._executor.remove_node(self)
            self._executor.shutdown(timeout_sec=0)
            self._executor = None


def _play(node: Player) -> None:
    node.start_services()
    node.play()


def main(args=None) -> int:
    return run_node(Player, args=args, spin=_play)


if __name__ == '__main__':
    raise SystemExit(main())
