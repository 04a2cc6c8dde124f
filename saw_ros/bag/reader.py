"""Read a bag directory (or one ``.mcap`` file): messages in file order, and a summary like
``ros2 bag info``. Unfinished files (the recorder was killed) are read up to their last complete
chunk; ``BagReader.complete`` then says False.
"""
from __future__ import annotations

import glob
import os
from dataclasses import dataclass, field
from typing import Dict, Iterable, Iterator, List, Optional

import yaml
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader


class BagReadError(OSError):
    """Not a bag, or not readable (the message says which and why)."""


@dataclass
class BagMessage:
    topic: str
    type: str
    data: bytes
    log_time: int        # ns since the epoch: when the recorder received it
    publish_time: int    # ns since the epoch: when it was sent (log_time if unknown)
    sequence: int
    channel: Channel
    schema: Optional[Schema]


@dataclass
class TopicSummary:
    name: str
    type: str
    serialization_format: str
    count: int = 0
    first: Optional[int] = None
    last: Optional[int] = None
    offered_qos_profiles: List[dict] = field(default_factory=list)
    type_hash: str = ''

    @property
    def rate(self) -> float:
        """Mean message rate in Hz over this topic's own span."""
        if self.count < 2 or self.first is None or self.last == self.first:
            return 0.0
        return (self.count - 1) * 1e9 / (self.last - self.first)


def _channel_qos(channel: Channel) -> List[dict]:
    text = channel.metadata.get('offered_qos_profiles', '')
    try:
        profiles = yaml.safe_load(text) if text else []
    except yaml.YAMLError:
        return []
    return profiles if isinstance(profiles, list) else []


class BagReader:
    def __init__(self, path: str):
        path = os.path.abspath(path)
        if not os.path.exists(path):
            raise BagReadError(f'no bag at {path}')
        self.path = path
        self.metadata: Optional[dict] = None
        if os.path.isdir(path):
            meta_path = os.path.join(path, 'metadata.yaml')
            if os.path.isfile(meta_path):
                with open(meta_path, encoding='utf-8') as f:
                    doc = yaml.safe_load(f) or {}
                self.metadata = doc.get('rosbag2_bagfile_information')
                if self.metadata is None:
                    raise BagReadError(f'{meta_path} has no rosbag2_bagfile_information')
                names = self.metadata.get('relative_file_paths') or []
                self.files = [os.path.join(path, n) for n in names]
            else:
                self.files = sorted(glob.glob(os.path.join(path, '*.mcap')))
            if not self.files:
                raise BagReadError(f'{path} holds no .mcap file (not a bag directory)')
        else:
            self.files = [path]
        for f in self.files:
            if not os.path.isfile(f):
                raise BagReadError(f'{f} is missing')
        self.complete = True      # False once a scan met an unfinished file
        self.unread_bytes = 0     # bytes after the last complete record of an unfinished file

    # ---- messages
    def messages(self, topics: Optional[Iterable[str]] = None) -> Iterator[BagMessage]:
        """Every message of the bag in file order (= receive order for our recordings)."""
        wanted = set(topics) if topics is not None else None
        for path in self.files:
            yield from self._scan(path, wanted)

    def _scan(self, path: str, wanted) -> Iterator[BagMessage]:
        schemas: Dict[int, Schema] = {}
        channels: Dict[int, Channel] = {}
        finished = False
        with open(path, 'rb') as f:
            size = os.fstat(f.fileno()).st_size
            records = StreamReader(f, skip_magic=False).records
            while True:
                try:
                    record = next(records)
                except StopIteration:
                    break
                except Exception:  # noqa: BLE001  (a truncated tail: McapError, struct.error,
                    # EOFError, zlib.error... from the incomplete record; keep what was complete)
                    self.complete = False
                    self.unread_bytes += max(0, size - f.tell())
                    break
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    channel = channels.get(record.channel_id)
                    if channel is None or (wanted is not None and channel.topic not in wanted):
                        continue
                    schema = schemas.get(channel.schema_id)
                    yield BagMessage(channel.topic, schema.name if schema else '', record.data,
                                     record.log_time, record.publish_time, record.sequence,
                                     channel, schema)
                elif isinstance(record, Footer):
                    finished = True
        if not finished:
            self.complete = False

    def decoded_messages(self, topics: Optional[Iterable[str]] = None):
        """(BagMessage, ROS-like message object) decoded with mcap_ros2 (no rclpy needed)."""
        from mcap_ros2.decoder import DecoderFactory
        factory = DecoderFactory()
        decoders = {}
        for m in self.messages(topics):
            decoder = decoders.get(m.channel.id)
            if decoder is None:
                decoder = decoders[m.channel.id] = factory.decoder_for('cdr', m.schema)
            yield m, decoder(m.data)

    def rosbag2_metadata_records(self) -> List[Metadata]:
        out = []
        for path in self.files:
            with open(path, 'rb') as f:
                try:
                    out += [m for m in make_reader(f).iter_metadata() if m.name == 'rosbag2']
                except McapError:
                    pass
        return out

    # ---- summary
    def topics(self) -> Dict[str, TopicSummary]:
        """Per topic: type, count, first/last log time, QoS (a full scan of the files)."""
        out: Dict[str, TopicSummary] = {}
        for m in self.messages():
            t = out.get(m.topic)
            if t is None:
                t = out[m.topic] = TopicSummary(
                    m.topic, m.type, m.channel.message_encoding,
                    offered_qos_profiles=_channel_qos(m.channel),
                    type_hash=m.channel.metadata.get('topic_type_hash', ''))
            t.count += 1
            if t.first is None or m.log_time < t.first:
                t.first = m.log_time
            if t.last is None or m.log_time > t.last:
                t.last = m.log_time
        # Topics registered but without messages come from metadata.yaml.
        for entry in (self.metadata or {}).get('topics_with_message_count') or []:
            meta = entry.get('topic_metadata', {})
            if meta.get('name') and meta['name'] not in out:
                out[meta['name']] = TopicSummary(
                    meta['name'], meta.get('type', ''), meta.get('serialization_format', ''),
                    offered_qos_profiles=meta.get('offered_qos_profiles') or [],
                    type_hash=meta.get('type_description_hash', ''))
        return out

    def info(self) -> dict:
        topics = self.topics()
        starts = [t.first for t in topics.values() if t.first is not None]
        ends = [t.last for t in topics.values() if t.last is not None]
        start = min(starts) if starts else 0
        end = max(ends) if ends else 0
        return {
            'path': self.path,
            'files': [os.path.basename(f) for f in self.files],
            'size': sum(os.path.getsize(f) for f in self.files),
            'storage': 'mcap',
            'start': start, 'end': end, 'duration': end - start,
            'messages': sum(t.count for t in topics.values()),
            'topics': topics,
            'complete': self.complete,
            'has_metadata_yaml': self.metadata is not None,
        }
