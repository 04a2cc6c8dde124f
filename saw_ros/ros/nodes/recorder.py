"""
Node ``recorder``: record topics into a rosbag2 bag (MCAP storage) as ``ros2 bag record`` would.

ROS parameters:
  topics      string[]  topics to record; empty: ``msg_config/record_topics.yaml`` (every topic of
                        saw_ros and /clock, plus any topic under its ``prefixes``, less its
                        ``exclude``: the raw camera frames)
  exclude_topics string[] topics under a prefix not to record (default: the file's ``exclude``,
                        the raw camera frames; ``-p exclude_topics:="['']"`` records them too);
                        a topic named in ``topics`` or the file's ``topics`` is always recorded
  output      string    bag directory; empty: ``<bags_dir>/<YYYY-MM-DD_HH-MM-SS>_<label>``
  bags_dir    string    where new bags go (default ``bags``)
  label       string    what is recorded, for the directory name (default ``default``)
  queue_depth int       subscription history depth (default 3000: 3 s at 1 kHz, as the
                        simulator's publishers keep; PUBLISHER_DEPTH)
  compression string    ``zstd`` (default) or ``none``
  chunk_size  int       bytes per MCAP chunk (default 786432, rosbag2's)
  max_bag_size int      split: a new file ``<bag>_<n>.mcap`` once the open one holds this many
                        bytes (default 512 MiB; 0: no limit), as ros2 bag record --max-bag-size
  max_bag_duration float split: a new file before a message more than this many seconds after
                        its file's first (default 300; 0: no limit); both bound the recorder's
                        memory (mcap keeps an index entry per chunk until a file is finished)

Subscriptions are raw: the CDR bytes are written as received, never re-serialised. A callback
takes every message waiting on its subscription (the executor's per-message cost dominates
otherwise) and queues it; a writer thread does the MCAP work and compression, so disk and zstd
never hold up the executor. Topics that appear later are subscribed when discovery sees them.
Ctrl-C / SIGTERM drain the subscriptions, then finish the MCAP file and write metadata.yaml.
Every parameter is read once, at start: all are read-only (``ros2 param set`` is refused).

Loss. A subscription that cannot keep up loses the oldest messages of its queue (KEEP_LAST), and
a publisher's history can overwrite messages not yet delivered. Either way the publication
sequence numbers of what arrives have gaps: the final line gives the messages lost per topic,
``lost N (topic: n, ...)``, and metadata.yaml keeps them in ``custom_data``
(``saw_ros.lost_messages``, JSON). Sequence numbers start at 1, so what a publisher sent before
the subscription matched is known too: counted in the loss, and said apart (``..., M of them at
the start (topic: m, ...)``; ``saw_ros.lost_at_start``). Jazzy's rclpy gives no publisher GID in
the message info, so messages of several publishers on one topic are told apart by their
sequence numbers (``LossCounter``).
"""
from __future__ import annotations

import datetime
import json
import os
import queue
import sys
import threading
import time
from typing import Dict, List, Optional

import rclpy
from rclpy.context import Context
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from saw_ros.bag.schema import check_definitions, UnknownMessageType
from saw_ros.bag.writer import BagWriteError, BagWriter, INFINITE, qos_profile_dict
from saw_ros.core.params import spec_meta
from saw_ros.interface.topics import CLOCK, PREFIX
from saw_ros.ros.params import yaml_text
from saw_ros.ros.qos import message_class
from saw_ros.ros.runtime import (NodeFailure, run_module, run_node, single_threaded_executor,
                                 spin_node)
import yaml

_STOP = object()
# (name, default, spec metadata); every one read once at start, so read-only. declare_spec checks
# the values against these ranges. exclude_topics' default (None) is record_topics.yaml's.
PARAMETERS = (
    ('topics', [''], spec_meta('', 'topics to record; empty: msg_config/record_topics.yaml')),
    ('exclude_topics', None, spec_meta('', 'topics under a prefix not to record (default: '
                                           "record_topics.yaml's exclude, the raw camera frames; "
                                           "[''] = none)")),
    ('output', '', spec_meta('', 'bag directory; empty: '
                                 '<bags_dir>/<YYYY-MM-DD_HH-MM-SS>_<label>')),
    ('bags_dir', 'bags', spec_meta('', 'where new bags go')),
    ('label', 'default', spec_meta('', 'what is recorded, for the directory name')),
    ('queue_depth', 3000, spec_meta('', 'subscription history depth', 1, None)),
    ('compression', 'zstd', spec_meta('', 'zstd or none', choices=('zstd', 'none'))),
    ('chunk_size', 768 * 1024, spec_meta('bytes', 'bytes per MCAP chunk', 1, None)),
    ('discovery_period', 0.25, spec_meta('s', 'seconds between looks for new topics', 0.0, None,
                                         low_open=True)),
    # Split files as ros2 bag record --max-bag-size / --max-bag-duration (rosbag2's default is
    # one file). Ours split by default: mcap's Writer keeps an index entry (~2.3 KB) per chunk
    # until its file is finished, so one file grew the recorder 0.9 MB a minute in the main
    # graph's soak (14.6 % in 30 min at real-time factor 0.5: 2.15 MB/s to disk, 383 chunks a
    # minute). A limit makes that grow with one file, not with the run: 512 MiB or 5 min,
    # whichever comes first, was a file every 4.2 min there, ~3.7 MB of index; the soak's
    # recorder grew 3.8 % (docs/measurements.md).
    ('max_bag_size', 512 << 20, spec_meta('bytes', 'start a new file of the bag once the open '
                                                   'one holds this many bytes (0: no limit)',
                                          0, None)),
    ('max_bag_duration', 300.0, spec_meta('s', 'start a new file before a message more than '
                                               "this after its file's first (0: no limit)",
                                          0.0, None)),
)
YAML_HEADER = """\
Parameters of the saw_ros recorder node (MCAP bags that ros2 bag opens):
  python -m saw_ros.ros.nodes.recorder --ros-args --params-file msg_config/recorder.yaml
Each comment gives the allowed range and unit; all are read at start-up only. exclude_topics is
left out: its default is msg_config/record_topics.yaml's exclude (the raw camera frames).
Generated by: python -m saw_ros.ros.nodes.recorder --write-yaml msg_config/recorder.yaml"""


def yaml_file() -> str:
    """msg_config/recorder.yaml, from PARAMETERS."""
    return yaml_text('recorder', YAML_HEADER, [e for e in PARAMETERS if e[1] is not None],
                     with_scenario=False)


# Types received on a second DDS participant (see Recorder.__init__).
LARGE_TYPES = {'sensor_msgs/msg/Image', 'sensor_msgs/msg/CompressedImage'}


def default_topics():
    """
    Return (topics, prefixes) from msg_config/record_topics.yaml.

    The file is found in the source tree or the installed share, as config_path finds it (no
    ament index needed).
    """
    from saw_ros.interface.config import config_path
    path = config_path('record_topics.yaml')
    if path.is_file():
        with open(path, encoding='utf-8') as f:
            doc = yaml.safe_load(f) or {}
        return list(doc.get('topics') or []), list(doc.get('prefixes') or [])
    return [CLOCK], [PREFIX]


def default_excluded() -> List[str]:
    """
    Return the ``exclude`` list of msg_config/record_topics.yaml.

    Those are topics under a prefix that the recorder leaves out by default.
    """
    from saw_ros.interface.config import config_path
    try:
        with open(config_path('record_topics.yaml'), encoding='utf-8') as f:
            return [t for t in (yaml.safe_load(f) or {}).get('exclude') or [] if t]
    except OSError:
        return []


def default_output(bags_dir: str, label: str) -> str:
    stamp = datetime.datetime.now().strftime('%Y-%m-%d_%H-%M-%S')
    return os.path.join(bags_dir, f'{stamp}_{label}')


class LossCounter:
    """
    Messages lost per topic, from the publication sequence numbers of what arrives.

    A publisher numbers its messages 1, 2, 3... (the DDS writer's sequence number, in rclpy's
    message info as ``publication_sequence_number``): gaps are messages lost in between, and a
    first number above 1 says how many the publisher sent before the recorder's first message
    (published before its subscription matched: lost at the start, counted in ``at_start`` as
    well). Without the publisher's GID (not in Jazzy's rclpy message info), a message continues
    the publisher whose last number is the closest below its own; a number at or below every
    last one starts a new publisher (numbers start again at 1). Sequence number 0 means the
    middleware does not give one: not counted. On ``latched`` topics (transient local: a late
    subscriber gets the publisher's last messages, the state it means to keep) the start is not
    a loss.
    """

    def __init__(self):
        self.lost: Dict[str, int] = {}            # topic: all lost (at the start and between)
        self.at_start: Dict[str, int] = {}        # topic: of them, before the first received
        self.latched: set = set()
        self._last: Dict[str, List[int]] = {}     # topic: last number of each publisher seen

    def add(self, topic: str, sequence: int) -> None:
        if not sequence:
            return
        lasts = self._last.get(topic)
        start = 0 if topic in self.latched else sequence - 1
        if lasts is None:
            self._last[topic] = [sequence]
            self.lost[topic] = self.at_start[topic] = start
            return
        if len(lasts) == 1 and lasts[0] < sequence:            # the usual case: one publisher
            self.lost[topic] += sequence - lasts[0] - 1
            lasts[0] = sequence
            return
        best = None
        for i, last in enumerate(lasts):
            if last < sequence and (best is None or last > lasts[best]):
                best = i
        if best is None:                                      # a publisher not seen before
            lasts.append(sequence)
            self.lost[topic] += start
            self.at_start[topic] += start
        else:
            self.lost[topic] += sequence - lasts[best] - 1
            lasts[best] = sequence

    def total(self) -> int:
        return sum(self.lost.values())

    def text(self) -> str:
        """
        Return ``lost 0``, or ``lost 12 (/saw/camera/image_raw: 12)``: the topics that lost any.

        Then those lost at the start, if any: ``..., 900 of them at the start (/clock: 900)``.
        """
        def listed(counts):
            return ', '.join(f'{t}: {n}' for t, n in sorted(counts.items()) if n)
        text = f'lost {self.total()}' + (f' ({listed(self.lost)})' if self.total() else '')
        start = sum(self.at_start.values())
        if start:
            text += f', {start} of them at the start ({listed(self.at_start)})'
        return text


def _entry(topic: str, data: bytes, info: dict) -> tuple:
    """Return what the writer thread gets for one message taken from a raw subscription."""
    return (topic, data, info['received_timestamp'] or time.time_ns(), info['source_timestamp'],
            info.get('publication_sequence_number', 0))


def _duration_dict(duration) -> dict:
    ns = getattr(duration, 'nanoseconds', 0)
    if ns <= 0 or ns >= 2 ** 63 - 1:
        return dict(INFINITE)
    return {'sec': ns // 1_000_000_000, 'nsec': ns % 1_000_000_000}


def _policy_name(policy) -> str:
    name = getattr(policy, 'name', str(policy)).lower()
    return 'unknown' if name in ('unknown', '') else name


def offered_profile(qos) -> dict:
    """Return an rclpy QoSProfile (a publisher's, from graph info) as rosbag2 stores it."""
    history = _policy_name(qos.history)
    return qos_profile_dict(
        history=history, depth=qos.depth, reliability=_policy_name(qos.reliability),
        durability=_policy_name(qos.durability), deadline=_duration_dict(qos.deadline),
        lifespan=_duration_dict(qos.lifespan), liveliness=_policy_name(qos.liveliness),
        liveliness_lease_duration=_duration_dict(qos.liveliness_lease_duration),
        avoid_ros_namespace_conventions=qos.avoid_ros_namespace_conventions)


def request_qos(offers: List, depth: int) -> QoSProfile:
    """
    rosbag2's adapt_request_to_offers.

    Reliable / transient_local only if every publisher offers it, so that the subscription connects
    to all of them.
    """
    reliable = bool(offers) and all(q.reliability == ReliabilityPolicy.RELIABLE for q in offers)
    latched = bool(offers) and all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL
                                   for q in offers)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=(ReliabilityPolicy.RELIABLE if reliable
                                   else ReliabilityPolicy.BEST_EFFORT),
                      durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                                  else DurabilityPolicy.VOLATILE))


class Recorder(Node):
    def __init__(self, **kwargs):
        super().__init__('recorder', **kwargs)
        from saw_ros.ros.params import declare_spec
        try:
            # All read once, here: read-only, so that `ros2 param set` is refused with the
            # reason instead of reporting a change that would not happen.
            declare_spec(self, parameters())
        except ParameterException as exc:
            raise NodeFailure(f'invalid parameters: {exc}') from None

        topics = [t for t in self.get_parameter('topics').value if t]
        if topics:
            self._topics, self._prefixes = topics, []
        else:
            self._topics, self._prefixes = default_topics()
        self._excluded = {t for t in self.get_parameter('exclude_topics').value if t}
        output = self.get_parameter('output').value or default_output(
            self.get_parameter('bags_dir').value, self.get_parameter('label').value)
        try:
            check_definitions()  # before creating anything: else one line saying what to source
            self.bag = BagWriter(
                output, chunk_size=int(self.get_parameter('chunk_size').value),
                compression=self.get_parameter('compression').value,
                max_bag_size=int(self.get_parameter('max_bag_size').value),
                max_bag_duration_ns=round(1e9 * self.get_parameter('max_bag_duration').value))
        except (BagWriteError, UnknownMessageType, ValueError) as exc:
            raise NodeFailure(f'refusing to record: {exc}') from None
        self._depth = int(self.get_parameter('queue_depth').value)
        self._queue: 'queue.SimpleQueue' = queue.SimpleQueue()
        self._subs: Dict[str, Optional[dict]] = {}
        self._unmatched: Dict[str, tuple] = {}   # topic: (type, subscribed at), not matched yet
        self.received = 0
        self.losses = LossCounter()     # fed by the writer thread
        self._write_error = None
        self._closed = False
        self._writer = threading.Thread(target=self._write_loop, name='bag-writer', daemon=True)
        self._writer.start()
        # Large messages (camera images) arrive on a DDS participant of their own: their bursts
        # of fragments then never delay the receipt and acknowledgement of the 1 kHz streams,
        # whose publishers keep only a short history (measured: a shared participant lost
        # 1-5 % of each 1 kHz stream while 60 fps 1280x720 images were recorded). Made now, not
        # when the first image topic appears: a new participant took 0.65-0.8 s to match the
        # camera on the busy 2-core machine, and the main job's bag lacked the first frames
        # (the camera's writer keeps 1 s of them for a late reader).
        self._large = self._large_participant()
        self._large_thread = threading.Thread(target=self._spin_large, name='large-spin',
                                              daemon=True)
        self._large_thread.start()
        self.get_logger().info(
            f'recording to {self.bag.directory} '
            f'({", ".join(self._topics + [p + "*" for p in self._prefixes])}'
            + (f'; not {", ".join(sorted(self._excluded))}' if self._excluded and self._prefixes
               else '') + ')')
        self._discover()
        self._timer = self.create_timer(float(self.get_parameter('discovery_period').value),
                                        self._discover)
        self._match_timer = self.create_timer(0.02, lambda: self._unmatched and
                                              self._report_matched())

    # ---- discovery
    def _wanted(self, name: str) -> bool:
        return name in self._topics or (name not in self._excluded and any(
            name.startswith(p) for p in self._prefixes))

    def _discover(self) -> None:
        if self._write_error is not None:
            raise NodeFailure(f'writing {self.bag.directory} failed: {self._write_error}')
        for name, types in self.get_topic_names_and_types():
            if name in self._subs or not self._wanted(name) or not types:
                continue
            offers = [info.qos_profile for info in self.get_publishers_info_by_topic(name)]
            if not offers:
                continue  # only subscribers so far: wait for a publisher to adapt QoS to
            type_name = types[0]
            try:
                msg_type = message_class(type_name)
            except (ImportError, AttributeError, ValueError):
                self.get_logger().warning(f'{name}: type {type_name} unknown here; not recorded')
                self._subs[name] = None
                continue
            self._queue.put(('topic', name, type_name, [offered_profile(q) for q in offers]))
            node = self._large[1] if type_name in LARGE_TYPES else self
            self._subs[name] = self._subscribe(node, name, msg_type,
                                               request_qos(offers, self._depth))
            self._unmatched[name] = (type_name, time.monotonic())
        self._report_matched()

    def _report_matched(self) -> None:
        """
        Log 'recording <topic>' once the subscription has matched a publisher.

        From then on nothing published on it is missed (scripts and tests wait for this line).
        """
        for name, (type_name, since) in list(self._unmatched.items()):
            holder = self._subs.get(name)
            if holder is None or holder['sub'].get_publisher_count() < 1:
                continue
            del self._unmatched[name]
            self.get_logger().info(f'recording {name} [{type_name}] '
                                   f'(matched after {time.monotonic() - since:.2f} s)')

    @staticmethod
    def _large_participant():
        """(context, node, executor) of the images' own participant."""
        context = Context()
        rclpy.init(context=context)
        node = Node('recorder_large', context=context)
        executor = single_threaded_executor(context)
        executor.add_node(node)
        return context, node, executor

    def _spin_large(self):
        context, _, executor = self._large
        try:
            while context.ok() and not self._closed:
                executor.spin_once(timeout_sec=0.1)
        except Exception:  # noqa: BLE001  (shut down while spinning)
            pass

    def _subscribe(self, node, name, msg_type, qos):
        put = self._queue.put
        holder = {}

        def on_message(data, info):
            put(_entry(name, data, info))
            self.received += 1
            # Take everything else already waiting: one executor round per burst, not per message.
            sub = holder['sub']
            handle = sub.handle
            taken = 0
            with handle:
                while taken < 10000:
                    got = handle.take_message(msg_type, True)
                    if got is None:
                        break
                    put(_entry(name, *got))
                    taken += 1
            self.received += taken

        # No QoS event handlers (rclpy's default: incompatible QoS and type, two per
        # subscription): the QoS is the publishers' own, and each handler is one more Python
        # object in every executor round; with them, 19 subscriptions cost 0.085 of a core idle.
        holder['sub'] = node.create_subscription(
            msg_type, name, on_message, qos, raw=True,
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
        holder['type'] = msg_type
        return holder

    def _drain(self) -> None:
        """Take what the subscriptions already hold (called once spinning has stopped)."""
        for name, holder in self._subs.items():
            if holder is None:
                continue
            try:
                handle = holder['sub'].handle
                with handle:    # (its __enter__ returns None, not the handle)
                    while True:
                        got = handle.take_message(holder['type'], True)
                        if got is None:
                            break
                        self._queue.put(_entry(name, *got))
                        self.received += 1
            except Exception as exc:  # noqa: BLE001  (context gone: nothing more to take)
                self.get_logger().debug(f'{name}: drain stopped: {exc}')

    # ---- writer thread
    def _write_loop(self) -> None:
        bag = self.bag
        get = self._queue.get
        count = self.losses.add
        while True:
            item = get()
            if item is _STOP:
                return
            if item[0] != 'topic':
                count(item[0], item[4])
            elif all(q['durability'] == 'transient_local' for q in item[3]):
                self.losses.latched.add(item[1])
            if self._write_error is not None:
                continue
            try:
                if item[0] == 'topic':
                    bag.add_topic(item[1], item[2], item[3])
                else:
                    bag.write(item[0], item[1], item[2], item[3] or item[2], item[4] or 0)
            except Exception as exc:  # noqa: BLE001  (disk full...): reported by the node
                self._write_error = exc

    def close(self) -> None:
        """
        Finish the bag: drain subscriptions, let the writer thread empty its queue.

        Write the summary and metadata.yaml. Idempotent.
        """
        if self._closed:
            return
        self._closed = True
        self._large_thread.join(2.0)
        self._drain()
        self._queue.put(_STOP)
        self._writer.join()
        lost = {t: self.losses.lost.get(t, 0) for t in self._counts()}
        at_start = {t: self.losses.at_start.get(t, 0) for t in self._counts()}
        self.bag.custom_data = dict(self.bag.custom_data or {}, **{
            'saw_ros.lost_messages': json.dumps(lost, sort_keys=True),
            'saw_ros.lost_at_start': json.dumps(at_start, sort_keys=True)})
        self.bag.close()
        counts = ', '.join(f'{t}: {n}' for t, n in self._counts().items())
        done = (f'bag {self.bag.directory} finished: {self.bag.message_count} messages '
                f'({counts}); {self.losses.text()}')
        warning = None
        start = sum(self.losses.at_start.values())
        if self.losses.total() > start:
            warning = (f'{self.losses.text()}: messages lost before they were recorded (gaps '
                       f"in the publishers' sequence numbers); the recorder or the machine "
                       f'did not keep up: record fewer topics (the raw camera frames above all) '
                       f'or raise queue_depth')
        elif start:
            warning = (f'{self.losses.text()}: published before the subscriptions matched '
                       "(the publishers' first sequence numbers); start the recorder first and "
                       "the publishers after its 'recording <topic>' lines")
        if self.context.ok():
            self.get_logger().info(done)
            if warning:
                self.get_logger().warning(warning)
        else:  # after Ctrl-C the context is gone and /rosout with it
            print(f'[recorder] {done}', file=sys.stderr, flush=True)
            if warning:
                print(f'[recorder] WARNING: {warning}', file=sys.stderr, flush=True)
        if self._write_error is not None:
            self.get_logger().error(f'writing failed: {self._write_error}')
        self._large[2].shutdown(0.5)
        self._large[1].destroy_node()
        rclpy.try_shutdown(context=self._large[0])

    def _counts(self):
        meta = self.bag.metadata()
        return {e['topic_metadata']['name']: e['message_count']
                for e in meta['topics_with_message_count']}


# s of sleep between executor rounds: each subscription's callback takes all its waiting
# messages, so letting 3 ms of them gather makes one round per burst instead of one per message
# (the SingleThreadedExecutor costs ~100 us a round; 6000 messages/s cost most of a core).
# The subscriptions' queues hold a second (1000 messages); recording adds no loss.
ROUND_PAUSE = 0.003


def _spin(node) -> None:
    spin_node(node, executor=single_threaded_executor(node.context), pause=ROUND_PAUSE)


def parameters():
    """PARAMETERS as declared: exclude_topics' default from msg_config/record_topics.yaml."""
    return [(n, d if d is not None else (default_excluded() or ['']), m)
            for n, d, m in PARAMETERS]


def main(args=None) -> int:
    return run_node(Recorder, args=args, spin=_spin, name='recorder', parameters=parameters)


if __name__ == '__main__':
    run_module(main, yaml_file)
