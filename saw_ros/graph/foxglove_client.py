"""
A Foxglove WebSocket protocol client, the protocol the Foxglove app speaks to a live robot.

For the tests and the bench of the bridge (saw_ros.ros.nodes.foxglove_bridge): it connects,
learns the channels the server advertises, subscribes, and receives each message's raw payload
(CDR here) with its log time; it can advertise a channel of its own and publish on it. The
WebSocket itself is the ``websockets`` library's (pinned in requirements.txt). No rclpy here:
decoding the CDR is the caller's.

Protocol (Foxglove's ws-protocol spec, v1; the SDK's server 0.30 accepts it under the
subprotocol name ``foxglove.sdk.v1`` and answers HTTP 400 to ``foxglove.websocket.v1`` alone):
JSON text frames for control (server: serverInfo, advertise, unadvertise, status; client:
subscribe, unsubscribe, advertise), binary frames for data (server message data: opcode 1,
uint32 subscription id, uint64 log time ns, payload; client message data: opcode 1, uint32
client channel id, payload), little-endian.
"""
from __future__ import annotations

import json
import struct
import threading
import time
from typing import Dict, Iterable, List, Optional, Tuple

SUBPROTOCOLS = ['foxglove.sdk.v1', 'foxglove.websocket.v1']
MESSAGE_DATA = 1
_SERVER_HEADER = struct.Struct('<BIQ')
_CLIENT_HEADER = struct.Struct('<BI')


class FoxgloveClient:
    """
    One connection to a Foxglove WebSocket server, read on a thread of its own.

    ``keep``: topics whose payloads are kept (every one of them, with its log time and receive
    time); the others are only counted (``counts``), their last payload kept in ``last``.
    """

    def __init__(self, url: str, timeout: float = 10.0, keep: Iterable[str] = ()):
        from websockets.sync.client import connect
        from websockets.typing import Subprotocol
        # legacy=True: a connection of our own, not websockets' reconnecting iterator.
        self.ws = connect(url, subprotocols=[Subprotocol(p) for p in SUBPROTOCOLS], max_size=None,
                          open_timeout=timeout, legacy=True)
        self.keep = set(keep)
        self.channels: Dict[str, dict] = {}          # topic -> the server's channel
        self.messages: Dict[str, List[Tuple[int, float, bytes]]] = {}   # log ns, monotonic, data
        self.counts: Dict[str, int] = {}
        self.last: Dict[str, bytes] = {}
        self.statuses: List[dict] = []
        self.server_info: dict = {}
        self._subscriptions: Dict[int, str] = {}
        self._next_id = 1
        self._lock = threading.Lock()
        self.closed = False
        self.reader_tid: Optional[int] = None     # the reading thread's id (its CPU in /proc)
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        from websockets.exceptions import ConnectionClosed
        self.reader_tid = threading.get_native_id()
        try:
            for frame in self.ws:
                if isinstance(frame, str):
                    self._control(json.loads(frame))
                elif frame and frame[0] == MESSAGE_DATA:
                    _op, sub, log_ns = _SERVER_HEADER.unpack_from(frame)
                    topic = self._subscriptions.get(sub)
                    if topic is None:
                        continue
                    payload = bytes(frame[_SERVER_HEADER.size:])
                    self.counts[topic] = self.counts.get(topic, 0) + 1
                    self.last[topic] = payload
                    if topic in self.keep:
                        self.messages.setdefault(topic, []).append(
                            (log_ns, time.monotonic(), payload))
        except ConnectionClosed:
            pass
        finally:
            self.closed = True

    def _control(self, message: dict) -> None:
        op = message.get('op')
        if op == 'serverInfo':
            self.server_info = message
        elif op == 'advertise':
            with self._lock:
                for channel in message.get('channels', []):
                    self.channels[channel['topic']] = channel
        elif op == 'unadvertise':
            with self._lock:
                gone = set(message.get('channelIds', []))
                self.channels = {t: c for t, c in self.channels.items() if c['id'] not in gone}
        elif op == 'status':
            self.statuses.append(message)

    def subscribe(self, topic_names: Iterable[str]) -> List[str]:
        """Subscribe to the advertised channels of ``topic_names``; return those subscribed."""
        subscriptions, done = [], []
        with self._lock:
            for name in topic_names:
                channel = self.channels.get(name)
                if channel is None:
                    continue
                sub = self._next_id
                self._next_id += 1
                self._subscriptions[sub] = name
                subscriptions.append({'id': sub, 'channelId': channel['id']})
                done.append(name)
        if subscriptions:
            self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subscriptions}))
        return done

    def advertise(self, topic: str, schema_name: str, encoding: str = 'cdr') -> int:
        """Advertise a client channel; return its id (for ``publish``)."""
        channel_id = self._next_id
        self._next_id += 1
        self.ws.send(json.dumps({'op': 'advertise', 'channels': [
            {'id': channel_id, 'topic': topic, 'encoding': encoding, 'schemaName': schema_name}]}))
        return channel_id

    def publish(self, channel_id: int, payload: bytes) -> None:
        """Send one message on an advertised client channel."""
        self.ws.send(_CLIENT_HEADER.pack(MESSAGE_DATA, channel_id) + payload)

    def close(self) -> None:
        self.ws.close()
        self._thread.join(timeout=5.0)


def connect_when_up(url: str, timeout: float, keep: Iterable[str] = ()
                    ) -> Optional[FoxgloveClient]:
    """Connect as soon as the server accepts (it may still be starting); None after ``timeout``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            return FoxgloveClient(url, timeout=max(0.1, deadline - time.monotonic()), keep=keep)
        except OSError:
            time.sleep(0.1)
    return None
