"""
A rosbag2 bag directory written with the ``mcap`` library.

What ``ros2 bag record`` makes with its MCAP storage (metadata.yaml version 9, ``ros2`` profile,
``ros2msg`` schemas, channels with ``offered_qos_profiles`` and ``topic_type_hash``, a ``rosbag2``
Metadata record, zstd chunks).

Messages go into the file in log_time order, as rosbag2 writes them (receive order), although
the recorder hands them over in bursts per subscription: its callbacks take everything waiting on
one subscription, then on the next, so arrival order steps back in log time across topics
(measured before this buffer: up to 4 ms between the 1 kHz topics, 149 ms with camera images on
their own participant). A reorder buffer (a queue per topic, each in log_time order as its
subscription receives it) holds each message until one ``reorder_window_ns`` (default 0.5 s)
newer has arrived, or until the buffer holds ``max_buffer_bytes`` (default 128 MiB: then the
oldest go first); every 20 ms of log time the messages due are merged into the file (ties in
arrival order).

A message that arrives after a later one was written (later than the window) is never dropped:
it is written with its log_time raised to the last written one, so the file stays ordered (its
receive time is off by its lateness; publish_time and sequence are kept), and counted in
``late_messages`` and ``max_lateness_ns``. Chunks then never overlap in time: a message with the
log_time of the last one of the chunk just closed (a tie, or a late one) goes 1 ns later, as
mcap counts chunks that share a time as overlapping. ``flush_until(t)`` writes what is older than
t at once.

Every chunk goes to the file as soon as it fills, unbuffered, so a process killed with SIGKILL
leaves its complete chunks readable (what was lost: the open chunk and the reorder buffer, i.e.
the last ~0.5 s plus up to one chunk); ``close()`` (idempotent) writes the buffer, the summary and
metadata.yaml. Chunks carry a CRC of their uncompressed records, and the data section a CRC in
DataEnd, so that a reader can tell damaged bytes from a file cut short.
Not thread-safe: one thread writes (the recorder gives it a thread of its own).
"""
from __future__ import annotations

import bisect
from collections import deque
import os
import threading
import time
from typing import Dict, List, Optional, Tuple

from mcap.writer import CompressionType, Writer
from saw_ros.bag.schema import message_definition, type_hash
import yaml

# rosbag2's MCAP default (mcap::McapWriterOptions: 768 KiB chunks, zstd).
DEFAULT_CHUNK_SIZE = 768 * 1024
# Reorder buffer (see above): how far in log time a message may arrive after a newer one and still
# be written in order, and the memory it may take (at 166 MB/s of images, 0.5 s is ~83 MB).
DEFAULT_REORDER_WINDOW_NS = 500_000_000
DEFAULT_MAX_BUFFER_BYTES = 128 * 1024 * 1024
# The buffer is emptied in batches, each time the newest log time has advanced this much: one
# merge per ~100 messages at 6 kHz instead of one per message.
_FLUSH_BATCH_NS = 20_000_000
# Once no message has come for this long, the buffer goes to the file (the publishers stopped:
# a kill -9 now loses only the open chunk, as without the buffer).
DEFAULT_IDLE_FLUSH_S = 1.0
# A limit never reached (int, so that the split test in _add is two integer comparisons).
_NO_LIMIT = 1 << 63
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


def bag_metadata(files, topics, custom_data: Optional[Dict[str, str]]) -> dict:
    """
    Return the ``rosbag2_bagfile_information`` mapping (metadata.yaml version 9).

    ``files``: (file name, log time of its first message, of its last, message count) each, in
    the order they were written (start and end None: no message); ``topics``: (name, type,
    serialization format, offered QoS profiles, type hash, message count) each.
    """
    starts = [f[1] for f in files if f[1] is not None]
    ends = [f[2] for f in files if f[2] is not None]
    first = min(starts) if starts else time.time_ns()
    duration = max(ends) - first if starts and ends else 0
    return {
        'version': 9,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': duration},
        'starting_time': {'nanoseconds_since_epoch': first},
        'message_count': sum(t[5] for t in topics),
        'topics_with_message_count': [
            {'topic_metadata': {'name': name, 'type': type_name,
                                'serialization_format': serialization_format,
                                'offered_qos_profiles': qos,
                                'type_description_hash': hash_string},
             'message_count': n}
            for name, type_name, serialization_format, qos, hash_string, n in topics],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [f[0] for f in files],
        'files': [{'path': name,
                   'starting_time': {'nanoseconds_since_epoch': (
                       start if start is not None else first)},
                   'duration': {'nanoseconds': (
                       end - start if start is not None and end is not None else 0)},
                   'message_count': count}
                  for name, start, end, count in files],
        'custom_data': custom_data,
        'ros_distro': ROS_DISTRO,
    }


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
    """
    What mcap's Writer needs of a stream (write, tell), straight to the OS.

    What the writer hands over (whole records, whole chunks) is in the file even if the process
    dies next.
    """

    def __init__(self, path: str):
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        self.position = 0

    def write(self, data) -> int:
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]
            self.position += n
        return len(data)

    def tell(self) -> int:
        return self.position

    def flush(self) -> None:
        pass

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


class _Topic:
    __slots__ = ('name', 'type', 'serialization_format', 'qos', 'hash', 'channel_id', 'count',
                 'pending', 'channel_metadata')

    def __init__(self, name, type_name, serialization_format, qos, hash_string, channel_id,
                 channel_metadata):
        self.name, self.type, self.serialization_format = name, type_name, serialization_format
        self.qos, self.hash, self.channel_id, self.count = qos, hash_string, channel_id, 0
        self.channel_metadata = channel_metadata
        # Reorder buffer of this topic, in log_time order: (log_time, arrival number, channel id,
        # data, publish_time, sequence).
        self.pending: deque = deque()


class BagWriter:
    """
    Write one bag directory ``<directory>/metadata.yaml`` + ``<name>_0.mcap`` (+ ``_1``...).

    Split as ``ros2 bag record --max-bag-size / --max-bag-duration`` splits: before a message
    whose file already holds ``max_bag_size`` bytes (0: no limit), or whose log time is more than
    ``max_bag_duration_ns`` after the file's first message (0: no limit), the file is finished
    (summary, indexes, rosbag2 Metadata record) and ``<name>_<n+1>.mcap`` started with every
    schema and channel registered again (same ids). mcap's Writer keeps an index entry per chunk
    until it finishes a file, so a limit bounds the memory a long recording takes.

    >>> bag = BagWriter('bags/run')                              # doctest: +SKIP
    >>> bag.add_topic('/saw/pose', 'geometry_msgs/msg/PoseStamped', [qos_profile_dict()])
    >>> bag.write('/saw/pose', cdr_bytes, log_time_ns, publish_time_ns)
    >>> bag.close()
    """

    def __init__(self, directory: str, chunk_size: int = DEFAULT_CHUNK_SIZE,
                 compression: str = 'zstd', custom_data: Optional[Dict[str, str]] = None,
                 reorder_window_ns: int = DEFAULT_REORDER_WINDOW_NS,
                 max_buffer_bytes: int = DEFAULT_MAX_BUFFER_BYTES,
                 idle_flush_s: Optional[float] = DEFAULT_IDLE_FLUSH_S,
                 max_bag_size: int = 0, max_bag_duration_ns: int = 0):
        if compression not in ('zstd', 'none', ''):
            raise ValueError(f'compression must be zstd or none, not {compression!r}')
        if reorder_window_ns < 0 or max_buffer_bytes < 0:
            raise ValueError('reorder_window_ns and max_buffer_bytes must be >= 0')
        if max_bag_size < 0 or max_bag_duration_ns < 0:
            raise ValueError('max_bag_size and max_bag_duration_ns must be >= 0 (0: no limit)')
        check_writable_target(directory)
        self.directory = os.path.abspath(directory)
        self.name = os.path.basename(self.directory.rstrip('/'))
        self._chunk_size = chunk_size
        self._compression = (CompressionType.ZSTD if compression == 'zstd'
                             else CompressionType.NONE)
        self.max_bag_size = int(max_bag_size) or _NO_LIMIT
        self.max_bag_duration_ns = int(max_bag_duration_ns) or _NO_LIMIT
        # Files finished so far: (name, first log time, last log time, message count).
        self.files: List[Tuple[str, Optional[int], Optional[int], int]] = []
        self._schemas: Dict[str, int] = {}
        self._schema_data: Dict[str, bytes] = {}
        self._topics: Dict[str, _Topic] = {}
        try:
            os.makedirs(self.directory)
        except OSError as exc:
            raise BagWriteError(f'cannot create {self.directory}: {exc}') from exc
        self._open_file()
        self.message_count = 0
        self.custom_data = custom_data
        self.closed = False
        # Reorder buffer: the topics' pending queues.
        self.reorder_window_ns = int(reorder_window_ns)
        self.max_buffer_bytes = int(max_buffer_bytes)
        self.buffered = 0             # messages in the buffer (not in the file yet)
        self._arrivals = 0
        self._buffered_bytes = 0
        self._newest = -(1 << 63)     # newest log time handed to write()
        self._next_flush = -(1 << 63)  # flush once a log time passes this
        self._written = -(1 << 63)    # log time of the last message written to the file
        self._position = 0            # file position after that message was added
        self._chunk_closed = False    # and whether adding it closed a chunk
        self.late_messages = 0        # arrived after a later message had been written
        self.max_lateness_ns = 0
        # The idle flush runs on a thread of its own; the lock keeps it apart from the writer.
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._idle_error: Optional[BaseException] = None   # raised by the next write or close
        self._idle_thread = None
        if idle_flush_s:
            self._idle_thread = threading.Thread(target=self._idle_flush,
                                                 args=(float(idle_flush_s),),
                                                 name='bag-idle-flush', daemon=True)
            self._idle_thread.start()

    # ---- files
    def _open_file(self) -> None:
        """Start ``<name>_<n>.mcap``, n the files finished so far; register what is known."""
        self.file_name = f'{self.name}_{len(self.files)}.mcap'
        try:
            self._stream = _UnbufferedFile(os.path.join(self.directory, self.file_name))
        except OSError as exc:
            raise BagWriteError(f'cannot create {self.file_name} in {self.directory}: '
                                f'{exc}') from exc
        # (mcap's stub asks for an IO; its Writer calls write and tell only, which we have)
        self._mcap = Writer(self._stream, chunk_size=self._chunk_size,  # type: ignore[arg-type]
                            compression=self._compression, enable_data_crcs=True)
        self._mcap.start(profile='ros2', library='saw_ros (mcap-python)')
        self._file_start: Optional[int] = None
        self._file_end: Optional[int] = None
        self._file_count = 0
        # Registered in the order of the first file, so the ids are the same in every file.
        for type_name, schema_id in self._schemas.items():
            again = self._mcap.register_schema(name=type_name, encoding='ros2msg',
                                               data=self._schema_data[type_name])
            assert again == schema_id, (type_name, again, schema_id)
        for topic in self._topics.values():
            again = self._mcap.register_channel(
                topic=topic.name, message_encoding=topic.serialization_format,
                schema_id=self._schemas[topic.type], metadata=topic.channel_metadata)
            assert again == topic.channel_id, (topic.name, again, topic.channel_id)

    def _finish_file(self) -> None:
        """Finish the open file: rosbag2 Metadata record (the bag so far), summary, indexes."""
        self.files.append((self.file_name, self._file_start, self._file_end, self._file_count))
        try:
            self._mcap.add_metadata('rosbag2', {'serialized_metadata': dump_yaml(
                self._metadata(self.files))})
            self._mcap.finish()
        finally:
            self._stream.close()

    def _split(self) -> None:
        self._finish_file()
        self._open_file()

    # ---- topics and messages
    def add_topic(self, name: str, type_name: str, offered_qos_profiles: List[dict],
                  serialization_format: str = 'cdr') -> int:
        """Register a topic (schema once per type, one channel per topic); returns channel id."""
        with self._lock:
            return self._add_topic(name, type_name, offered_qos_profiles, serialization_format)

    def _add_topic(self, name, type_name, offered_qos_profiles, serialization_format) -> int:
        if name in self._topics:
            return self._topics[name].channel_id
        schema_id = self._schemas.get(type_name)
        if schema_id is None:
            data = message_definition(type_name).encode('utf-8')
            schema_id = self._mcap.register_schema(name=type_name, encoding='ros2msg', data=data)
            self._schemas[type_name], self._schema_data[type_name] = schema_id, data
        hash_string = type_hash(type_name)
        qos = [dict(p) for p in offered_qos_profiles]
        metadata = {'offered_qos_profiles': dump_yaml(qos).rstrip('\n') if qos else '',
                    'topic_type_hash': hash_string}
        channel_id = self._mcap.register_channel(
            topic=name, message_encoding=serialization_format, schema_id=schema_id,
            metadata=metadata)
        self._topics[name] = _Topic(name, type_name, serialization_format, qos, hash_string,
                                    channel_id, metadata)
        return channel_id

    def write(self, topic: str, data: bytes, log_time: int, publish_time: Optional[int] = None,
              sequence: int = 0) -> None:
        """
        One serialised message (bytes as received), times in ns since the epoch.

        It reaches the file in log_time order, once the reorder window has passed it (or on close).
        """
        entry = self._topics[topic]
        if publish_time is None:
            publish_time = log_time
        with self._lock:
            if self._idle_error is not None:
                self._raise_idle_error()
            if log_time < self._written:  # later than the window: in order, a little late
                lateness = self._written - log_time
                self.late_messages += 1
                if lateness > self.max_lateness_ns:
                    self.max_lateness_ns = lateness
                log_time = self._written
            item = (log_time, self._arrivals, entry.channel_id, data, publish_time, sequence)
            pending = entry.pending
            if pending and log_time < pending[-1][0]:
                bisect.insort(pending, item)   # out of order within its topic (two publishers)
            else:
                pending.append(item)
            self._arrivals += 1
            self.buffered += 1
            self._buffered_bytes += len(data)
            entry.count += 1
            self.message_count += 1
            if log_time > self._newest:
                self._newest = log_time
                if log_time > self._next_flush:
                    self._next_flush = log_time + _FLUSH_BATCH_NS
                    self._flush_until(log_time - self.reorder_window_ns)
            if self._buffered_bytes > self.max_buffer_bytes:
                self._flush_until(self._newest - self.reorder_window_ns)

    def flush_until(self, log_time: int) -> None:
        """
        Write the buffered messages with log times up to ``log_time``.

        While the buffer holds more than ``max_buffer_bytes``, the oldest others go too.
        """
        with self._lock:
            self._flush_until(log_time)

    def _idle_flush(self, idle_s: float) -> None:
        """
        Write the whole buffer once no message has arrived for ``idle_s``.

        The recording went quiet: what is buffered would otherwise wait for the next message or
        close().
        """
        period = min(0.25, idle_s / 2)
        seen, quiet = -1, 0.0
        while not self._stop.wait(period):
            if self._arrivals != seen:
                seen, quiet = self._arrivals, 0.0
                continue
            quiet += period
            if quiet >= idle_s and self.buffered:
                with self._lock:
                    if not self.closed and self._arrivals == seen:
                        try:
                            self._flush_until(1 << 63)
                        except Exception as exc:  # noqa: BLE001  (disk full...): raised in
                            self._idle_error = exc  # the writing thread by its next call
                            return

    def _raise_idle_error(self) -> None:
        exc, self._idle_error = self._idle_error, None
        raise BagWriteError(f'writing {self.directory} failed: {exc}') from exc

    def _flush_until(self, log_time: int) -> None:
        batch = []
        for topic in self._topics.values():
            pending = topic.pending
            while pending and pending[0][0] <= log_time:
                batch.append(pending.popleft())
        batch.sort()
        self._add(batch)
        while self._buffered_bytes > self.max_buffer_bytes:
            oldest = min((t.pending for t in self._topics.values() if t.pending),
                         key=lambda pending: pending[0])
            self._add([oldest.popleft()])

    def _add(self, items) -> None:
        """
        Hand messages (in log_time order, none older than the last written) to mcap.

        A message past the open file's size or duration limit goes to a new file.
        """
        add, stream = self._mcap.add_message, self._stream
        written, position, closed = self._written, self._position, self._chunk_closed
        size_limit = self.max_bag_size
        stamp_limit = (_NO_LIMIT if self._file_start is None
                       else self._file_start + self.max_bag_duration_ns)
        size = in_file = 0
        for stamp, _, channel_id, data, publish_time, sequence in items:
            before = stream.position
            if stamp <= written:
                # A tie with the last written message (or a late one raised to it): if a chunk
                # was closed after that one, 1 ns later (chunks sharing a time overlap for mcap)
                stamp = written + (closed or before != position)
            if (before >= size_limit or stamp > stamp_limit) and (in_file or self._file_count):
                self._file_count += in_file
                self._file_end = written
                self._split()
                add, stream, in_file = self._mcap.add_message, self._stream, 0
                before = position = stream.position
                stamp_limit = _NO_LIMIT
            if self._file_start is None:
                self._file_start = stamp
                stamp_limit = stamp + self.max_bag_duration_ns
            add(channel_id, stamp, data, publish_time, sequence)
            position = stream.position
            closed = position != before
            written = stamp
            size += len(data)
            in_file += 1
        if items:
            self._file_count += in_file
            self._file_end = written
            self._written, self._position, self._chunk_closed = written, position, closed
            self._buffered_bytes -= size
            self.buffered -= len(items)

    # ---- metadata
    def metadata(self) -> dict:
        """Return the ``rosbag2_bagfile_information`` mapping (metadata.yaml version 9)."""
        files = self.files if self.closed and self.files else self.files + [
            (self.file_name, self._file_start, self._file_end, self._file_count)]
        return self._metadata(files)

    def _metadata(self, files) -> dict:
        return bag_metadata(
            files, [(t.name, t.type, t.serialization_format, t.qos, t.hash, t.count)
                    for t in self._topics.values()], self.custom_data)

    def close(self) -> None:
        """
        Finish the MCAP file (rosbag2 Metadata record, summary, indexes) and write metadata.yaml.

        Safe to call twice.
        """
        self._stop.set()
        with self._lock:
            if self.closed:
                return
            self.closed = True
        if self._idle_thread is not None:
            self._idle_thread.join()
        if self._idle_error is not None:
            self._stream.close()
            self._raise_idle_error()
        try:
            self._flush_until(1 << 63)
        except BaseException:
            self._stream.close()
            raise
        self._finish_file()
        info = self._metadata(self.files)
        tmp = os.path.join(self.directory, '.metadata.yaml.tmp')
        with open(tmp, 'w', encoding='utf-8') as f:
            f.write(dump_yaml({'rosbag2_bagfile_information': info}))
        os.replace(tmp, os.path.join(self.directory, 'metadata.yaml'))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
