"""
The Foxglove bridge node: the live graph over the Foxglove WebSocket protocol (issue 34).

What ``foxglove_bridge`` is to a ROS install, on the wheels alone: the Foxglove app (Open
connection > Foxglove WebSocket > ws://127.0.0.1:8765) sees every topic of the topic table
(saw_ros.interface.topics) as a channel with a ``ros2msg`` schema (the full concatenated message
definition, as foxglove_bridge and rosbag2 send it: saw_ros.bag.schema) and ``cdr`` messages,
and decodes them as it decodes foxglove_bridge's. The server is the Foxglove SDK's
(foxglove-sdk, pinned in requirements.txt).

- Raw CDR passed through: each topic is subscribed ``raw=True`` and its bytes logged on the
  channel as they came; nothing is deserialised.
- Taken in batches: every topic but the commands is subscribed on a second node that no
  executor spins (``foxglove_bridge_intake``), and a timer takes what each subscription holds
  every BATCH_PERIOD, so that no message costs an executor wake-up and a Python callback of its
  own, and the SDK sends a batch per wake-up of its own threads. A client subscribed to
  everything at real time (5 800 messages a second, 5 000 of them the simulator's 1 kHz
  streams) cost the bridge 0.12 of a core, now 0.09 (docs/measurements.md, issue 34 part C).
  A message reaches the clients up to BATCH_PERIOD later; its log time is the SDK's clock when
  the bridge hands it over. The commands (a client's own echo) keep a callback each.
- The simulator's 1 kHz streams and /clock read best effort (``best_effort``): a reliable
  reader cost the simulator's writers an acknowledgement protocol of its own, 20-28 us of a
  step's CPU; best effort 8-12, and the client still gets every message on a working machine.
  What DDS loses on the way in (the bridge's process without CPU for longer than its
  shared-memory queue holds) is counted, logged and sent to the clients as a status; the
  reliable reader before lost as much when stopped, silently (it takes from a history of
  the last messages only).
- A topic is subscribed only while at least one client subscribes to its channel (as
  foxglove_bridge does): an idle bridge takes no message. Latched topics are subscribed afresh
  for each new client, so that it gets the last message too.
- The camera as ``sensor_msgs/CompressedImage`` (/saw/camera/image_raw/compressed) only: the raw
  frames (2.7 MB each, 166 MB/s) are not offered.
- Clients may publish on the command topic (/saw/motor_controller/commands, the helix's
  voltage or frequency: saw_ros.ros.command) and nothing else. An advertisement of any other
  topic, in another encoding or with another type, and a message that is not one well-formed
  CDR ``Float64MultiArray``, are refused: counted, logged (at most once per WARN_EVERY seconds)
  and sent to the clients as a status; the bridge runs on. The simulator checks the value.
- Bound to 127.0.0.1 unless ``address`` says otherwise. Exposed, anyone who reaches the port reads
  every topic and can drive the motor: the protocol has no authentication (docs/viewers.md).
"""
from __future__ import annotations

import math
import queue
import time
from typing import Any, Dict, List, Optional, Tuple

from rclpy.event_handler import QoSSubscriptionEventType, SubscriptionEventCallbacks
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from saw_ros.bag.schema import message_definition
from saw_ros.core.params import spec_meta
from saw_ros.interface import topics
from saw_ros.ros.params import declare_spec, yaml_text
from saw_ros.ros.qos import message_class, profile, publisher_profile, with_depth
from saw_ros.ros.runtime import NodeFailure, run_module, run_node

PARAMETERS = (
    ('address', '127.0.0.1', spec_meta(
        '', 'interface the WebSocket server listens on; 127.0.0.1 = this machine only. 0.0.0.0 '
            'exposes every topic and the motor to anyone who reaches the port')),
    ('port', 8765, spec_meta('', "TCP port of the server (8765: Foxglove's default); 0 = any "
                                 'free port (said in the log)', 0, 65535)),
    ('hold_until_clock', False, spec_meta(
        '', "hold the clients' subscriptions until the first /clock message: a client then "
            "cannot be the subscriber a simulator's wait_for_subscribers waits for, so a "
            'recording of the run misses nothing (saw-ros demo sets it)')),
)
# Not offered: the raw frames (the compressed ones are the camera's stream here).
NOT_SERVED = (topics.IMAGE,)
COMMAND_TOPICS = tuple(t.name for t in topics.TOPICS if t.qos == 'command')
WARN_EVERY = 5.0        # s of wall time between two warnings (refused or lost messages)
POLL_PERIOD = 0.05      # s between two looks at the clients' (un)subscriptions
# s between two takes of the subscriptions' queues (STREAM_DEPTH = 5 s of a 1 kHz stream, 30
# frames of the camera's): a viewer drawing at 60 Hz sees no difference; 20 ms saved little more.
BATCH_PERIOD = 0.01
LOST_CHECK_PERIOD = 1.0     # s between two looks at what DDS says the streams lost on the way in
# History of a best-effort stream's subscription: deeper than the shared-memory port queue
# (4096 messages in msg_config/fastdds.xml), so that what the port hands on in one burst after
# the bridge went without CPU never overwrites a message not yet taken. A message is then lost
# only at the port, and DDS counts it (a gap in the writer's sequence numbers): with 1000, a
# bridge stopped for 0.6 s while 20 000 poses went out lost 577 of them uncounted
# (tests/ros/test_foxglove_bridge.py). Memory only while the bridge is behind.
STREAM_DEPTH = 5000
# Messages the SDK's server queues for a client before it drops the oldest (its default 1024,
# silently: the SDK 0.30 tells its caller nothing). A bridge that catches up after going without
# CPU hands on a port queue's worth at once (4096 and more); with 1024, a client took 48 of them
# too few in the stopped-bridge test under load 12. Memory only while a client is behind.
CLIENT_BACKLOG = 16384

YAML_HEADER = """\
Parameters of the saw_ros Foxglove bridge (every topic over the Foxglove WebSocket protocol):
  python -m saw_ros.ros.nodes.foxglove_bridge --ros-args --params-file \\
      msg_config/foxglove_bridge.yaml
Read at start-up only.
Generated by: python -m saw_ros.ros.nodes.foxglove_bridge --write-yaml \\
      msg_config/foxglove_bridge.yaml"""


def yaml_file() -> str:
    """Return msg_config/foxglove_bridge.yaml, from PARAMETERS."""
    return yaml_text('foxglove_bridge', YAML_HEADER, PARAMETERS, with_scenario=False)


def served_topics() -> List[topics.Topic]:
    """Return the topic table's entries the bridge offers as channels."""
    return [t for t in topics.TOPICS if t.name not in NOT_SERVED]


class _Listener:
    """The server's callbacks (on the SDK's threads): queue (un)subscriptions, publish commands."""

    def __init__(self, bridge: 'FoxgloveBridge'):
        self.bridge = bridge

    def on_subscribe(self, client, channel) -> None:
        self.bridge.requests.put((+1, client.id, channel.topic))

    def on_unsubscribe(self, client, channel) -> None:
        self.bridge.requests.put((-1, client.id, channel.topic))

    def on_client_advertise(self, client, channel) -> None:
        self.bridge.advertised(client.id, channel)

    def on_client_unadvertise(self, client, client_channel_id: int) -> None:
        self.bridge.client_channels.pop((client.id, client_channel_id), None)

    def on_message_data(self, client, client_channel_id: int, data: bytes) -> None:
        self.bridge.client_message(client.id, client_channel_id, data)


class FoxgloveBridge(Node):
    """Serves the topic table over a Foxglove WebSocket server, subscribing on demand."""

    def __init__(self, **kwargs):
        super().__init__('foxglove_bridge', **kwargs)
        import foxglove
        from foxglove.websocket import Capability
        p = declare_spec(self, PARAMETERS)
        self.entries = {t.name: t for t in served_topics()}
        self.channels = {}
        for entry in self.entries.values():
            schema = foxglove.Schema(name=entry.type, encoding='ros2msg',
                                     data=message_definition(entry.type).encode())
            self.channels[entry.name] = foxglove.Channel(entry.name, schema=schema,
                                                         message_encoding='cdr')
        self.requests: 'queue.SimpleQueue[Tuple[int, int, str]]' = queue.SimpleQueue()
        self.watchers: Dict[str, set] = {name: set() for name in self.entries}
        self.subscriptions_by_topic: Dict[str, Any] = {}
        self.client_channels: Dict[Tuple[int, int], Optional[str]] = {}
        self.forwarded = 0          # messages passed to the server
        self.published = 0          # client commands published
        self.refused = 0
        self.lost: Dict[str, int] = {}      # topic -> messages DDS lost before the bridge
        self._lost_unlogged = 0
        self._last_lost_warning = -math.inf
        self._refused_unlogged = 0
        self._last_warning = -math.inf
        self.command_publishers = {}
        for name in COMMAND_TOPICS:
            entry = topics.topic(name)
            self.command_publishers[name] = (self.create_publisher(
                message_class(entry.type), name, publisher_profile(entry.qos)),
                message_class(entry.type), entry.type)
        try:
            self.server = foxglove.start_server(
                name='saw_ros', host=p['address'], port=p['port'],
                capabilities=[Capability.ClientPublish], supported_encodings=['cdr'],
                server_listener=_Listener(self), message_backlog_size=CLIENT_BACKLOG)
        except Exception as exc:  # noqa: BLE001  (the SDK raises its own error types)
            raise NodeFailure(f'cannot serve on {p["address"]}:{p["port"]}: {exc}') from None
        self.url = f'ws://{p["address"]}:{self.server.port}'
        # Until the simulator runs (its first /clock), the clients' subscriptions wait in the
        # queue; the /clock subscription that watches for it goes once it came.
        self._clock_watch: Any = None
        self.running = not p['hold_until_clock']
        if not self.running:
            clock = topics.topic(topics.CLOCK)
            self._clock_watch = self.create_subscription(
                message_class(clock.type), clock.name, self._clock_came, profile(clock.qos),
                raw=True)
        self.create_timer(POLL_PERIOD, self._apply_requests)
        # The batched subscriptions: on a node no executor spins (an executor would wake for
        # each message). Not the command line's node name or remappings: the topics are the
        # table's, as the channels are.
        self.intake = Node('foxglove_bridge_intake', context=self.context,
                           use_global_arguments=False, enable_rosout=False,
                           start_parameter_services=False)
        self.batched: Dict[str, Tuple[Any, Any, Any]] = {}    # topic -> handle, type, log
        # topic -> its subscription's message-lost event, read by polling (nothing spins it)
        self.lost_events: Dict[str, Any] = {}
        self._batch_timer = self.create_timer(BATCH_PERIOD, self._take_batches)
        self._batch_timer.cancel()          # running only while a client subscribes
        self.create_timer(LOST_CHECK_PERIOD, self._check_lost)
        self.get_logger().info(
            f'Foxglove WebSocket on {self.url}: {len(self.channels)} topics; clients may '
            f'publish on {", ".join(COMMAND_TOPICS)} only (Foxglove: Open connection > Foxglove '
            'WebSocket)')

    # -- topics out: subscribed while a client subscribes ----------------------------------
    def _clock_came(self, _data: bytes) -> None:
        self.running = True

    def _apply_requests(self) -> None:
        """Subscribe and unsubscribe as the clients did (on the executor's thread)."""
        if not self.running:
            return
        if self._clock_watch is not None:
            self.destroy_subscription(self._clock_watch)
            self._clock_watch = None
        while True:
            try:
                delta, client, name = self.requests.get_nowait()
            except queue.Empty:
                break
            if name not in self.entries:
                continue
            wanted = self.watchers[name]
            if delta > 0:
                wanted.add(client)
                latched = self.entries[name].qos == 'latched'
                if name not in self.subscriptions_by_topic or latched:
                    self._subscribe(name)
            else:
                wanted.discard(client)
                if not wanted:
                    self._unsubscribe(name)
        if self.batched and self._batch_timer.is_canceled():
            self._batch_timer.reset()
        elif not self.batched and not self._batch_timer.is_canceled():
            self._batch_timer.cancel()

    def _subscribe(self, name: str) -> None:
        self._unsubscribe(name)
        entry = self.entries[name]
        channel = self.channels[name]
        qos = profile(entry.qos)
        if entry.qos in ('stream', 'clock'):
            qos = best_effort(with_depth(qos, STREAM_DEPTH))

        # The SDK's own log call (Channel.log checks the payload's type and the encoding in
        # Python first); no log time: the SDK stamps the message with its clock.
        log = channel.base.log
        msg_type = message_class(entry.type)
        # No QoS event handlers: one Python object less per subscription in every executor
        # round (the recorder's reason, docs/measurements.md).
        no_events = SubscriptionEventCallbacks(use_default_callbacks=False)
        if entry.qos != 'command':
            subscription = self.intake.create_subscription(
                msg_type, name, _never_called, qos, raw=True, event_callbacks=no_events)
            self.batched[name] = (subscription.handle, msg_type, log)
            if qos.reliability == ReliabilityPolicy.BEST_EFFORT:
                with subscription.handle:
                    self.lost_events[name] = _rclpy.EventHandle(
                        subscription.handle,
                        QoSSubscriptionEventType.RCL_SUBSCRIPTION_MESSAGE_LOST)
        else:
            def forward(data: bytes) -> None:
                log(data)
                self.forwarded += 1
            subscription = self.create_subscription(msg_type, name, forward, qos, raw=True,
                                                    event_callbacks=no_events)
        self.subscriptions_by_topic[name] = subscription

    def _unsubscribe(self, name: str) -> None:
        subscription = self.subscriptions_by_topic.pop(name, None)
        if subscription is None:
            return
        batch = self.batched.pop(name, None)
        if batch is not None:
            # A latched topic is subscribed afresh for each new client: what the old
            # subscription holds is still for the clients already watching.
            self._take(*batch)
            event = self.lost_events.pop(name, None)
            if event is not None:
                self._count_lost(name, event)
                event.destroy_when_not_in_use()
            self.intake.destroy_subscription(subscription)
        else:
            self.destroy_subscription(subscription)

    def _take_batches(self) -> None:
        for handle, msg_type, log in self.batched.values():
            self._take(handle, msg_type, log)

    def _take(self, handle, msg_type, log) -> None:
        """Forward every message a batched subscription holds."""
        taken = 0
        with handle:
            take = handle.take_message
            while True:
                got = take(msg_type, True)
                if got is None:
                    break
                log(got[0])
                taken += 1
        self.forwarded += taken

    def _check_lost(self) -> None:
        for name, event in self.lost_events.items():
            self._count_lost(name, event)
        self._warn_lost()

    def _count_lost(self, name: str, event) -> None:
        """
        Add what DDS says a best-effort stream lost since the last look.

        Fast DDS counts a best-effort reader's gaps in the writer's sequence numbers: the
        messages that never reached the bridge's process (its shared-memory queue full while
        it went without CPU). The clients miss them, so they are told (``_warn_lost``).
        """
        with event:
            change = event.take_event().total_count_change
        if change > 0:
            self.lost[name] = self.lost.get(name, 0) + change
            self._lost_unlogged += change

    def _warn_lost(self) -> None:
        """Log and send the clients the losses not yet told, at most once per WARN_EVERY."""
        now = time.monotonic()
        if not self._lost_unlogged or now - self._last_lost_warning < WARN_EVERY:
            return
        text = (f'{self._lost_unlogged} message(s) lost before the bridge since the last '
                'warning (read best effort, not sent again): the clients miss them. Total so '
                'far: ' + self._lost_by_topic())
        self.get_logger().warning(text)
        self._status(f'saw_ros bridge: {text}')
        self._last_lost_warning = now
        self._lost_unlogged = 0

    def _status(self, message: str) -> None:
        """Send the clients a warning status (one they miss changes nothing here)."""
        try:
            from foxglove import StatusLevel
            self.server.publish_status(message, StatusLevel.Warning)
        except Exception:  # noqa: BLE001,S110  (a status the clients miss changes nothing here)
            pass

    # -- commands in: the command topic only ----------------------------------------------
    def advertised(self, client: int, channel) -> None:
        """Accept a client's channel on a command topic in cdr of its type; refuse any other."""
        publisher = self.command_publishers.get(channel.topic)
        if publisher is None:
            reason = f'clients may publish on {", ".join(COMMAND_TOPICS)} only'
        elif channel.encoding != 'cdr':
            reason = f'encoding {channel.encoding!r}, not cdr'
        elif channel.schema_name not in (publisher[2], publisher[2].replace('/msg/', '/')):
            reason = f'type {channel.schema_name!r}, not {publisher[2]}'
        else:
            self.client_channels[(client, channel.id)] = channel.topic
            return
        self.client_channels[(client, channel.id)] = None
        self._refuse(f'client {client} advertised {channel.topic}: {reason}')

    def client_message(self, client: int, channel_id: int, data: bytes) -> None:
        """Publish a client's command as it came, once it decodes as its type."""
        name = self.client_channels.get((client, channel_id))
        if name is None:
            self._refuse(f'client {client}: a message on a channel that is not a command topic '
                         f'(channel {channel_id})')
            return
        publisher, msg_type, type_name = self.command_publishers[name]
        try:
            deserialize_message(data, msg_type)
        except Exception as exc:  # noqa: BLE001  (rclpy raises its own error types)
            self._refuse(f'client {client} on {name}: not a CDR {type_name} ({exc})')
            return
        publisher.publish(data)
        self.published += 1

    def _refuse(self, reason: str) -> None:
        self.refused += 1
        now = time.monotonic()
        if now - self._last_warning < WARN_EVERY:
            self._refused_unlogged += 1
            return
        more = f' ({self._refused_unlogged} more refused since the last warning)' \
            if self._refused_unlogged else ''
        self.get_logger().warning(f'refused, not published: {reason}{more}')
        self._status(f'saw_ros bridge refused: {reason}')
        self._last_warning = now
        self._refused_unlogged = 0

    def close(self) -> None:
        try:
            self._take_batches()        # what came since the last batch
            self._check_lost()
        except Exception as exc:  # noqa: BLE001  (the context already gone: nothing to take)
            self.get_logger().debug(f'last batch not taken: {exc}')
        self.server.stop()
        for event in self.lost_events.values():
            event.destroy_when_not_in_use()
        self.intake.destroy_node()
        lost = sum(self.lost.values())
        self.get_logger().info(
            f'stopped: {self.forwarded} messages forwarded, {self.published} client commands '
            f'published, {self.refused} refused, {lost} lost before the bridge' + (
                f' ({self._lost_by_topic()})' if lost else ''))

    def _lost_by_topic(self) -> str:
        return ', '.join(f'{k} {v}' for k, v in self.lost.items())


def best_effort(qos: QoSProfile) -> QoSProfile:
    """
    ``qos`` read best effort: what the bridge asks of the simulator's 1 kHz writers.

    A reliable reader costs its writer an acknowledgement protocol of its own (heartbeats to
    it, its ACKNACKs taken in by the writer's receive thread, a NACK-suppression timer on the
    writer's event thread). The simulator, which paces the graph, paid 20-28 us of CPU a step
    for a reliable bridge and 8-12 for a best-effort one (docs/measurements.md, issue 34 part
    C). Nothing is repaired: a message the bridge's
    process cannot take in (its shared-memory port queue full) is not sent again, which a
    viewer survives and the graph's recordings, reliable, do not depend on.
    """
    return QoSProfile(history=qos.history, depth=qos.depth,
                      reliability=ReliabilityPolicy.BEST_EFFORT, durability=qos.durability)


def _never_called(_data: bytes) -> None:
    """Stand for the callback of a subscription that no executor spins (taken in batches)."""


def main(args=None) -> int:
    return run_node(FoxgloveBridge, args=args, events=True, name='foxglove_bridge',
                    parameters=lambda: list(PARAMETERS))


if __name__ == '__main__':
    run_module(main, yaml_file)
