"""A rosbag2 bag directory written with the ``mcap`` library: what ``ros2 bag record`` makes with
its MCAP storage (metadata.yaml version 9, ``ros2`` profile, ``ros2msg`` schemas, channels with
``offered_qos_profiles`` and ``topic_type_hash``, a ``rosbag2`` Metadata record, zstd chunks).

Every chunk goes to the file as soon as it fills, unbuffered, so a process killed with SIGKILL
leaves its complete chunks readable; ``close()`` (idempotent) writes the summary and metadata.yaml.
Chunks carry a CRC of their uncompressed records, and the data section a CRC in DataEnd, so that a
reader can tell damaged bytes from a file cut short.
Not thread-safe: one thread writes (the recorder gives it a thread of its own).
"""
from __future__ import annotations

import os
import time
from typing import Dict, List, Optional

import yaml
from mcap.writer import CompressionType, Writer

from .schema import message_definition, type_hash

# rosbag2's MCAP default (mcap::McapWriterOptions: 768 KiB chunks, zstd).
DEFAULT_CHUNK_SIZE = 768 * 1024
# RMW_DURATION_INFINITE as rosbag2 writes it.
INFINITE = {'sec': 9223372036, 'nsec': 854775807}
ROS_DISTRO = 'jazzy'


class BagWriteError(OSError):
    """The bag cannot be written (where and why are in the message)."""


class BagExistsError(BagWriteError, FileExistsError):
    """The output directory exists already: a recording is never overwritten."""


def qos_profile_dict(history='unknown', depth=0, reliability='reliable', durability='volatile',
                     deadline=None, lifespan=None, liveliness='automatic',
                     liveliness_lease_duration=None, avoid_ros_namespace_conventions=False):
    """One offered QoS profile as rosbag2 stores it (version 9: policies as strings)."""
    return {'history': history, 'depth': int(depth), 'reliability': reliability,
            'durability': durability, 'deadline': dict(deadline or INFINITE),
            'lifespan': dict(lifespan or INFINITE), 'liveliness': liveliness,
            'liveliness_lease_duration': dict(liveliness_lease_duration or INFINITE),
            'avoid_ros_namespace_conventions': bool(avoid_ros_namespace_conventions)}


class _IndentedDumper(yaml.SafeDumper):
    """Lists indented under their key, as yaml-cpp (rosbag2) writes them."""

    def increase_indent(self, flow=False, indentless=False):
        return super().increase_indent(flow, False)


def _represent_none(dumper, _):
    return dumper.represent_scalar('tag:yaml.org,2002:null', '~')


_IndentedDumper.add_representer(type(None), _represent_none)


def dump_yaml(data) -> str:
    return yaml.dump(data, Dumper=_IndentedDumper, sort_keys=False, default_flow_style=False,
                     width=1 << 16)


def check_writable_target(directory: str) -> None:
    """Raise BagWriteError unless ``directory`` is new and can be created; touches nothing."""
    directory = os.path.abspath(directory)
    if os.path.lexists(directory):
        raise BagExistsError(f'{directory} exists already; choose another output (a recording '
                             'is never overwritten)')
    parent = os.path.dirname(directory)
    while not os.path.exists(parent):
        parent = os.path.dirname(parent)
    if not os.path.isdir(parent):
        raise BagWriteError(f'cannot create {directory}: {parent} is not a directory')
    if not os.access(parent, os.W_OK | os.X_OK):
        raise BagWriteError(f'cannot create {directory}: {parent} is not writable')


class _UnbufferedFile:
    """What mcap's Writer needs of a stream (write, tell), straight to the OS: what the writer
    hands over (whole records, whole chunks) is in the file even if the process dies next."""

    def __init__(self, path: str):
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        self._pos = 0

    def write(self, data) -> int:
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]
            self._pos += n
        return len(data)

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        pass

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


class _Topic:
    __slots__ = ('name', 'type', 'serialization_format', 'qos', 'hash', 'channel_id', 'count')

    def __init__(self, name, type_name, serialization_format, qos, hash_string, channel_id):
        self.name, self.type, self.serialization_format = name, type_name, serialization_format
        self.qos, self.hash, self.channel_id, self.count = qos, hash_string, channel_id, 0


class BagWriter:
    """Write one bag directory ``<directory>/metadata.yaml`` + ``<name>_0.mcap``.

    >>> bag = BagWriter('bags/run')                              # doctest: +SKIP
    >>> bag.add_topic('/saw/pose', 'geometry_msgs/msg/PoseStamped', [qos_profile_dict()])
    >>> bag.write('/saw/pose', cdr_bytes, log_time_ns, publish_time_ns)
    >>> bag.close()
    """

    def __init__(self, directory: str, chunk_size: int = DEFAULT_CHUNK_SIZE,
                 compression: str = 'zstd', custom_data: Optional[Dict[str, str]] = None):
        check_writable_target(directory)
        self.directory = os.path.abspath(directory)
        self.name = os.path.basename(self.directory.rstrip('/'))
        self.file_name = f'{self.name}_0.mcap'
        try:
            os.makedirs(self.directory)
            self._stream = _UnbufferedFile(os.path.join(self.directory, self.file_name))
        except OSError as exc:
            raise BagWriteError(f'cannot create {self.directory}: {exc}') from exc
        if compression not in ('zstd', 'none', ''):
            raise ValueError(f'compression must be zstd or none, not {compression!r}')
        self._mcap = Writer(self._stream, chunk_size=chunk_size,
                            compression=(CompressionType.ZSTD if compression == 'zstd'
                                         else CompressionType.NONE),
                            enable_data_crcs=True)
        self._mcap.start(profile='ros2', library='saw_ros (mcap-python)')
        self._schemas: Dict[str, int] = {}
        self._topics: Dict[str, _Topic] = {}
        self._start: Optional[int] = None
        self._end: Optional[int] = None
        self.message_count = 0
        self.custom_data = custom_data
        self.closed = False

    # ---- topics and messages
    def add_topic(self, name: str, type_name: str, offered_qos_profiles: List[dict],
                  serialization_format: str = 'cdr') -> int:
        """Register a topic (schema once per type, one channel per topic); returns channel id."""
        if name in self._topics:
            return self._topics[name].channel_id
        schema_id = self._schemas.get(type_name)
        if schema_id is None:
            schema_id = self._mcap.register_schema(
                name=type_name, encoding='ros2msg',
                data=message_definition(type_name).encode('utf-8'))
            self._schemas[type_name] = schema_id
        hash_string = type_hash(type_name)
        qos = [dict(p) for p in offered_qos_profiles]
        channel_id = self._mcap.register_channel(
            topic=name, message_encoding=serialization_format, schema_id=schema_id,
            metadata={'offered_qos_profiles': dump_yaml(qos).rstrip('\n') if qos else '',
                      'topic_type_hash': hash_string})
        self._topics[name] = _Topic(name, type_name, serialization_format, qos, hash_string,
                                    channel_id)
        return channel_id

    def has_topic(self, name: str) -> bool:
        return name in self._topics

    def write(self, topic: str, data: bytes, log_time: int, publish_time: Optional[int] = None,
              sequence: int = 0) -> None:
        """One serialised message (bytes as received), times in ns since the epoch."""
        entry = self._topics[topic]
        self._mcap.add_message(channel_id=entry.channel_id, log_time=log_time, data=data,
                               publish_time=log_time if publish_time is None else publish_time,
                               sequence=sequence)
        entry.count += 1
        self.message_count += 1
        if self._start is None or log_time < self._start:
            self._start = log_time
        if self._end is None or log_time > self._end:
            self._end = log_time

    # ---- metadata
    def metadata(self) -> dict:
        """The ``rosbag2_bagfile_information`` mapping (metadata.yaml version 9)."""
        start = self._start if self._start is not None else time.time_ns()
        duration = (self._end - self._start) if self._start is not None else 0
        return {
            'version': 9,
            'storage_identifier': 'mcap',
            'duration': {'nanoseconds': duration},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': self.message_count,
            'topics_with_message_count': [
                {'topic_metadata': {'name': t.name, 'type': t.type,
                                    'serialization_format': t.serialization_format,
                                    'offered_qos_profiles': t.qos,
                                    'type_description_hash': t.hash},
                 'message_count': t.count} for t in self._topics.values()],
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [self.file_name],
            'files': [{'path': self.file_name,
                       'starting_time': {'nanoseconds_since_epoch': start},
                       'duration': {'nanoseconds': duration},
                       'message_count': self.message_count}],
            'custom_data': self.custom_data,
            'ros_distro': ROS_DISTRO,
        }

    def close(self) -> None:
        """Finish the MCAP file (rosbag2 Metadata record, summary, indexes) and write
        metadata.yaml. Safe to call twice."""
        if self.closed:
            return
        self.closed = True
        info = self.metadata()
        try:
            self._mcap.add_metadata('rosbag2', {'serialized_metadata': dump_yaml(info)})
            self._mcap.finish()
        finally:
            self._stream.close()
        tmp = os.path.join(self.directory, '.metadata.yaml.tmp')
        with open(tmp, 'w', encoding='utf-8') as f:
            f.write(dump_yaml({'rosbag2_bagfile_information': info}))
        os.replace(tmp, os.path.join(self.directory, 'metadata.yaml'))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
