"""
Read a bag directory (or one ``.mcap`` file).

Messages in file order, and a summary like ``ros2 bag info``.

Two kinds of trouble are told apart:
- an unfinished file (the recorder was killed: no summary, a record cut off at the end) is read
  up to its last complete record; ``BagReader.complete`` then says False. Not an error.
- damaged bytes: a chunk whose CRC (of its uncompressed records) does not match, that does not
  decompress or parse, a record running past the data section of a finished file, a data-section
  or summary CRC that does not match. By default ``messages()`` raises BagDamagedError at the
  damage and ``topics()``/``info()`` raise it after a full scan (naming each damaged chunk, its
  log time range and message count, and how many messages are readable); with
  ``BagReader(path, salvage=True)`` every readable message is read, the damaged chunks are
  skipped and listed in ``BagReader.damage``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import glob
import io
import os
import re
import struct
from typing import Callable, Dict, Iterable, Iterator, List, Optional
import zlib

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.records import Channel, ChunkIndex, Schema, Statistics
import yaml

MAGIC = b'\x89MCAP0\r\n'
_RECORD = struct.Struct('<BQ')            # opcode, body length
_FOOTER = struct.Struct('<BQQQI')         # opcode, length, summary start, offsets start, CRC
_CHUNK = struct.Struct('<QQQI')           # start time, end time, uncompressed size, CRC
_MESSAGE = struct.Struct('<HIQQ')         # channel id, sequence, log time, publish time
_U32, _U64 = struct.Struct('<I'), struct.Struct('<Q')
_FOOTER_OP, _SCHEMA, _CHANNEL, _MESSAGE_OP, _CHUNK_OP = 0x02, 0x03, 0x04, 0x05, 0x06
_MESSAGE_INDEX, _CHUNK_INDEX, _STATISTICS, _DATA_END = 0x07, 0x08, 0x0B, 0x0F
_SPLIT_FILE = re.compile(r'(.*)_(\d+)\.mcap')
_MAX_CHUNK = 1 << 32     # larger uncompressed sizes are damage, not allocations to try


class BagReadError(OSError):
    """Not a bag, or not readable (the message says which and why)."""


class BagDamagedError(BagReadError):
    """Bytes of the bag are damaged (not merely cut off at the end); ``damage`` lists where."""

    def __init__(self, message: str, damage: List['Damage']):
        super().__init__(message)
        self.damage = damage


class BagDecodeError(BagReadError):
    """A message's bytes do not decode with its schema (the message names topic and message)."""


def stamp(ns: Optional[int]) -> str:
    """Ns since the epoch as seconds.nanoseconds (or n/a)."""
    if ns is None:
        return 'n/a'
    return f'{ns // 1_000_000_000}.{ns % 1_000_000_000:09d}'


@dataclass
class Damage:
    """
    One damaged place of a file.

    A chunk (``chunk`` = its number, from 1), or another part of the file (``chunk`` None: a
    record, the data section, the summary).
    """

    file: str
    offset: Optional[int]                 # where in the file (None: not one place)
    reason: str
    chunk: Optional[int] = None
    chunks: Optional[int] = None          # chunks in the file (when its summary says)
    start: Optional[int] = None           # log time range of the chunk (index or chunk record)
    end: Optional[int] = None
    messages: Optional[int] = None        # messages lost with it, if known
    topics: List[str] = field(default_factory=list)

    def describe(self) -> str:
        if self.chunk is None:
            where = os.path.basename(self.file)
            if self.offset is not None:
                where += f' at offset {self.offset}'
        else:
            of = f' of {self.chunks}' if self.chunks else ''
            where = f'{os.path.basename(self.file)} chunk {self.chunk}{of} (offset {self.offset}'
            if self.start is not None:
                where += f', log time {stamp(self.start)} .. {stamp(self.end)}'
            if self.messages is not None:
                where += f', {self.messages} messages'
                if self.topics:
                    where += ' of ' + ', '.join(sorted(self.topics))
            where += ')'
        return f'{where}: {self.reason}'


@dataclass
class BagMessage:
    topic: str
    type: str  # noqa: A003
    data: bytes
    log_time: int        # ns since the epoch: when the recorder received it
    publish_time: int    # ns since the epoch: when it was sent (log_time if unknown)
    sequence: int
    channel: Channel
    schema: Optional[Schema]


@dataclass
class TopicSummary:
    name: str
    type: str  # noqa: A003
    serialization_format: str
    count: int = 0
    first: Optional[int] = None
    last: Optional[int] = None
    offered_qos_profiles: List[dict] = field(default_factory=list)
    type_hash: str = ''

    @property
    def rate(self) -> float:
        """Mean message rate in Hz over this topic's own span."""
        if self.count < 2 or self.first is None or self.last is None or self.last == self.first:
            return 0.0
        return (self.count - 1) * 1e9 / (self.last - self.first)


# rosbag2 before Jazzy (metadata versions up to 8) wrote the policies as rmw's enum numbers; Jazzy
# and our writer write their names. The player reads names.
_POLICY_NAMES = {'history': {0: 'system_default', 1: 'keep_last', 2: 'keep_all', 3: 'unknown'},
                 'reliability': {0: 'system_default', 1: 'reliable', 2: 'best_effort',
                                 3: 'unknown', 4: 'best_available'},
                 'durability': {0: 'system_default', 1: 'transient_local', 2: 'volatile',
                                3: 'unknown', 4: 'best_available'},
                 'liveliness': {0: 'system_default', 1: 'automatic', 3: 'manual_by_topic',
                                4: 'unknown', 5: 'best_available'}}


def qos_profiles(value) -> List[dict]:
    """
    Return offered QoS profiles as a list of mappings with policy names.

    ``value`` as rosbag2 keeps them: YAML text (a channel's metadata, and metadata.yaml up to
    version 8) or a list (metadata.yaml since version 9); [] if it is neither.
    """
    if isinstance(value, str):
        try:
            value = yaml.safe_load(value) if value else []
        except yaml.YAMLError:
            return []
    if not isinstance(value, list):
        return []
    profiles = []
    for profile in value:
        if isinstance(profile, dict):
            profile = dict(profile)
            for policy, names in _POLICY_NAMES.items():
                if isinstance(profile.get(policy), int):
                    profile[policy] = names.get(profile[policy], 'unknown')
            profiles.append(profile)
    return profiles


def channel_qos(channel: Channel) -> List[dict]:
    """Return the offered QoS profiles a channel's metadata holds (rosbag2's YAML text)."""
    return qos_profiles(channel.metadata.get('offered_qos_profiles', ''))


def _one_line(text) -> str:
    return ' '.join(str(text).split())


# What metadata.yaml's fields must be, where the reader uses them (None: may be absent or ~).
_METADATA_TYPES = (('relative_file_paths', list, 'a list of file names'),
                   ('message_count', int, 'an integer'),
                   ('topics_with_message_count', list, 'a list'),
                   ('starting_time', dict, 'a mapping'),
                   ('duration', dict, 'a mapping'),
                   ('custom_data', dict, 'a mapping'))


def read_metadata(meta_path: str) -> dict:
    """
    Return the ``rosbag2_bagfile_information`` mapping of a metadata.yaml, its fields checked.

    BagReadError (one line naming the file and what is wrong) if it is not YAML, not a mapping,
    or a field the reader uses has the wrong type; a metadata.yaml that is a link out of its bag
    is refused like any file outside the bag.
    """
    inside(os.path.dirname(meta_path), os.path.basename(meta_path), meta_path)
    try:
        with open(meta_path, encoding='utf-8') as f:
            doc = yaml.safe_load(f)
    except (OSError, UnicodeDecodeError) as exc:
        raise BagReadError(f'{meta_path} cannot be read: {_one_line(exc)}') from None
    except yaml.YAMLError as exc:
        where = getattr(exc, 'problem_mark', None)
        at = f' (line {where.line + 1})' if where is not None else ''
        raise BagReadError(f'{meta_path} is not YAML{at}: '
                           f'{_one_line(getattr(exc, "problem", None) or exc)}') from None
    if not isinstance(doc, dict):
        raise BagReadError(f'{meta_path} is not a rosbag2 metadata file: a '
                           f'{type(doc).__name__} where a mapping with '
                           'rosbag2_bagfile_information should be')
    info = doc.get('rosbag2_bagfile_information')
    if not isinstance(info, dict):
        raise BagReadError(f'{meta_path} has no rosbag2_bagfile_information mapping')
    for key, kind, what in _METADATA_TYPES:
        value = info.get(key)
        if value is not None and (not isinstance(value, kind) or isinstance(value, bool)):
            raise BagReadError(f'{meta_path}: {key} must be {what}, '
                               f'not {_one_line(value)[:200]!r}')
    if not all(isinstance(n, str) and n for n in info.get('relative_file_paths') or []):
        raise BagReadError(f'{meta_path}: relative_file_paths must be a list of file names')
    for entry in info.get('topics_with_message_count') or []:
        meta = entry.get('topic_metadata') if isinstance(entry, dict) else None
        if not (isinstance(meta, dict) and isinstance(meta.get('name'), str)
                and isinstance(entry.get('message_count', 0), int)
                and all(isinstance(meta.get(k, ''), str)
                        for k in ('type', 'serialization_format', 'type_description_hash'))
                # rosbag2 wrote the QoS as YAML text up to metadata version 8, as a list from 9
                and isinstance(meta.get('offered_qos_profiles') or [], (list, str))):
            raise BagReadError(f'{meta_path}: topics_with_message_count entries must be '
                               'mappings with topic_metadata (name, type...) and message_count, '
                               f'not {_one_line(entry)[:200]!r}')
    return info


def inside(directory: str, name: str, source: str) -> str:
    """
    Return the path of file ``name`` of the bag ``directory``, refusing any that leaves it.

    An absolute name, a ``..`` out of it or a symbolic link that resolves outside it is a
    BagReadError naming ``source`` (where the name comes from): a bag never reads or writes
    outside its own directory, whatever its metadata.yaml says.
    """
    if os.path.isabs(name):
        raise BagReadError(f'{source}: file {name!r} is an absolute path; the files of a bag '
                           'are inside its directory')
    root = os.path.realpath(directory)
    target = os.path.realpath(os.path.join(directory, name))
    if os.path.commonpath([root, target]) != root or target == root:
        how = 'leads' if '..' in name.split('/') else 'is a link'
        raise BagReadError(f'{source}: file {name!r} {how} outside the bag directory '
                           f'({target}); refused')
    return os.path.join(directory, name)


class _Short(ValueError):
    pass


class _Exact(io.BytesIO):
    """
    A record body for mcap's record parsers.

    A read past its end is an error (mcap's ReadDataStream would return the short bytes).
    """

    def read(self, n=-1):
        data = super().read(n)
        if n is not None and n >= 0 and len(data) != n:
            raise _Short(f'record ends {n - len(data)} bytes early')
        return data


def _parse(cls, body):
    return cls.read(ReadDataStream(_Exact(bytes(body))))


def _decompress(compression: str, data, size: int) -> bytes:
    if compression == 'zstd':
        import zstandard
        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    if compression == 'lz4':
        import lz4.frame
        return lz4.frame.decompress(data)
    if compression == '':
        return bytes(data)
    raise ValueError(f'unknown compression {compression!r}')


def _learn(opcode: int, body, schemas: dict, channels: dict) -> bool:
    """Keep a Schema or Channel record by its id (summary and chunks alike); True if it was one."""
    if opcode == _SCHEMA:
        schema = _parse(Schema, body)
        schemas[schema.id] = schema
    elif opcode == _CHANNEL:
        channel = _parse(Channel, body)
        channels[channel.id] = channel
    else:
        return False
    return True


def _records(data) -> Iterator[tuple]:
    """(opcode, body) of every record in ``data`` (a chunk's records); ValueError if cut."""
    view, pos, n = memoryview(data), 0, len(data)
    while pos < n:
        if n - pos < 9:
            raise ValueError(f'{n - pos} stray bytes at the end of the records')
        opcode, length = _RECORD.unpack_from(data, pos)
        pos += 9
        if length > n - pos:
            raise ValueError(f'a record (opcode {opcode:#04x}) runs {length - (n - pos)} bytes '
                             'past the end of the records')
        yield opcode, view[pos:pos + length]
        pos += length


class _Summary:
    """What a finished file's footer and summary section say (empty for an unfinished file)."""

    def __init__(self):
        self.finished = False
        self.data_end = None        # offset where the summary (or the footer) starts
        self.schemas: Dict[int, Schema] = {}
        self.channels: Dict[int, Channel] = {}
        self.chunks: Dict[int, ChunkIndex] = {}   # by chunk start offset
        self.message_count: Optional[int] = None


def _read_summary(f, size: int, path: str, damage: List[Damage]) -> _Summary:
    out = _Summary()
    if size < len(MAGIC) * 2 + _FOOTER.size:
        return out
    f.seek(size - len(MAGIC) - _FOOTER.size)
    tail = f.read(_FOOTER.size + len(MAGIC))
    if tail[-len(MAGIC):] != MAGIC:
        return out
    opcode, length, summary_start, _, summary_crc = _FOOTER.unpack_from(tail)
    footer_at = size - len(MAGIC) - _FOOTER.size
    if opcode != _FOOTER_OP or length != 20 or summary_start > footer_at:
        return out
    out.finished = True
    out.data_end = summary_start or footer_at
    if not summary_start:
        return out
    f.seek(summary_start)
    data = f.read(footer_at - summary_start)
    if summary_crc and zlib.crc32(tail[:25], zlib.crc32(data)) != summary_crc:
        damage.append(Damage(path, summary_start, 'summary section (schemas, channels, chunk and '
                                                  'message indexes) CRC mismatch; not used',
                             messages=0))
        return out
    try:
        for opcode, body in _records(data):
            if _learn(opcode, body, out.schemas, out.channels):
                continue
            if opcode == _CHUNK_INDEX:
                index = _parse(ChunkIndex, body)
                out.chunks[index.chunk_start_offset] = index
            elif opcode == _STATISTICS:
                out.message_count = _parse(Statistics, body).message_count
    except (ValueError, struct.error, UnicodeDecodeError, McapError) as exc:
        damage.append(Damage(path, summary_start, f'summary section unreadable ({exc}); not used',
                             messages=0))
        return _finished_only(out)
    return out


def _finished_only(summary: _Summary) -> _Summary:
    out = _Summary()
    out.finished, out.data_end = summary.finished, summary.data_end
    return out


def _open_chunk(body) -> bytes:
    """Return the uncompressed records of a chunk record's body, their CRC checked."""
    _, _, size, crc = _CHUNK.unpack_from(body)
    pos = _CHUNK.size
    name_length, = _U32.unpack_from(body, pos)
    compression = bytes(body[pos + 4:pos + 4 + name_length]).decode('utf-8')
    pos += 4 + name_length
    data_length, = _U64.unpack_from(body, pos)
    pos += 8
    if data_length > len(body) - pos:
        raise ValueError(f'its data ({data_length} bytes) runs past the chunk record')
    if size > _MAX_CHUNK:
        raise ValueError(f'its uncompressed size ({size} bytes) is implausible')
    try:
        records = _decompress(compression, memoryview(body)[pos:pos + data_length], size)
    except ValueError:
        raise
    except Exception as exc:  # noqa: BLE001  (zstandard.ZstdError, lz4's RuntimeError)
        raise ValueError(f'its {compression} data do not decompress ({exc})') from None
    if len(records) != size:
        raise ValueError(f'it decompresses to {len(records)} bytes, not the {size} it states')
    if crc and zlib.crc32(records) != crc:
        raise ValueError(f'CRC mismatch of its uncompressed records (stored {crc:#010x}, '
                         f'computed {zlib.crc32(records):#010x})')
    return records


class _Scan:
    """What the scan of one file's data section carries from one record to the next."""

    def __init__(self, path: str, size: int, summary: _Summary):
        self.path, self.size, self.summary = path, size, summary
        self.schemas: Dict[int, Schema] = dict(summary.schemas)
        self.channels: Dict[int, Channel] = dict(summary.channels)
        self.data_end = summary.data_end if summary.finished else size
        self.crc: Optional[int] = zlib.crc32(MAGIC)   # of the data section so far (None: lost)
        self.pos = len(MAGIC)
        self.chunk_number = 0
        self.lost: Optional[Damage] = None   # the damaged chunk whose message indexes follow
        self.orphans: Dict[int, int] = {}    # channel id: messages whose channel is unknown
        self.chunk_offsets = sorted(summary.chunks)
        self.ordinal = {offset: i + 1 for i, offset in enumerate(self.chunk_offsets)}


def split_order(name: str) -> tuple:
    """
    Sort key putting a split bag's files in the order written: ``run_2.mcap`` before ``run_10``.

    rosbag2 names them ``<bag>_<n>.mcap``, n from 0; other names sort by name, after them.
    """
    match = _SPLIT_FILE.fullmatch(os.path.basename(name))
    return (0, match.group(1), int(match.group(2))) if match else (1, name, 0)


class BagReader:
    def __init__(self, path: str, salvage: bool = False):
        path = os.path.abspath(path)
        if not os.path.exists(path):
            raise BagReadError(f'no bag at {path}')
        self.path = path
        self.salvage = salvage
        self.metadata: Optional[dict] = None
        if os.path.isdir(path):
            meta_path = os.path.join(path, 'metadata.yaml')
            if os.path.lexists(meta_path):
                self.metadata = read_metadata(meta_path)
                names = self.metadata.get('relative_file_paths') or []
                self.files = [inside(path, n, meta_path) for n in names]
            else:   # a recorder killed: no metadata.yaml yet; its split files in their order
                self.files = [inside(path, os.path.basename(n), path)
                              for n in sorted(glob.glob(os.path.join(path, '*.mcap')),
                                              key=split_order)]
            if not self.files:
                raise BagReadError(f'{path} holds no .mcap file (not a bag directory)')
        else:
            self.files = [path]
        for f in self.files:
            if not os.path.isfile(f):
                raise BagReadError(f'{f} is missing')
        # rosbag2's compression (metadata.yaml): 'file' compresses each .mcap whole
        # (x.mcap.zstd), 'message' each message's bytes; none in our recordings.
        meta = self.metadata or {}
        mode = str(meta.get('compression_mode') or '').lower()
        compression = str(meta.get('compression_format') or '').lower()
        if mode not in ('', 'none', 'file', 'message'):
            raise BagReadError(f'{path}: compression_mode {mode!r} unknown (rosbag2 writes '
                               "'file' or 'message')")
        if mode in ('file', 'message') and compression != 'zstd':
            raise BagReadError(f'{path}: compression_format {compression!r} cannot be read '
                               "(rosbag2 compresses with 'zstd')")
        self._file_compressed = mode == 'file'
        self._message_compressed = mode == 'message'
        # What the last scan of each file found: bytes after its last complete record (None:
        # finished), damaged places, messages read, messages its summary counts.
        self._tail: Dict[str, Optional[int]] = {}
        self._damage: Dict[str, List[Damage]] = {}
        self._read: Dict[str, int] = {}
        self._expected: Dict[str, Optional[int]] = {}
        self._collect = False     # a full scan in progress: note damage, raise at the end
        self._topics: Dict[str, TopicSummary] = {}    # what the last topics() found

    @property
    def complete(self) -> bool:
        """Return False once a scan met an unfinished file (no summary: recorder killed)."""
        return not any(n is not None for n in self._tail.values())

    def finished(self, path: str) -> bool:
        """Return True if the last scan of file ``path`` found it finished and undamaged."""
        return path in self._tail and self._tail[path] is None and not self._damage.get(path)

    @property
    def unread_bytes(self) -> int:
        """Bytes after the last complete record of the unfinished files."""
        return sum(n for n in self._tail.values() if n is not None)

    @property
    def damage(self) -> List[Damage]:
        """Damaged places found by the scans so far (each file's last scan)."""
        return [d for f in self.files for d in self._damage.get(f, [])]

    def damage_report(self) -> str:
        """Return what is damaged (a line each) and how many messages are readable."""
        lines = [d.describe() for d in self.damage]
        read = sum(self._read.values())
        total = self.expected_messages()
        lines.append(f'{read} of {total} messages readable' if total is not None
                     else f'{read} messages readable')
        return '\n  '.join(lines)

    def expected_messages(self) -> Optional[int]:
        """
        Messages the files should hold.

        Their summaries' statistics, else metadata.yaml's count, else what was read plus what the
        damage lost (None: unknown).
        """
        expected = [n for n in self._expected.values() if n is not None]
        if self._expected and len(expected) == len(self._expected):
            return sum(expected)
        if self.metadata and self.complete and isinstance(self.metadata.get('message_count'), int):
            return self.metadata['message_count']
        lost = [d.messages for d in self.damage if d.messages is not None]
        if len(lost) == len(self.damage):
            return sum(self._read.values()) + sum(lost)
        return None

    def _damaged(self, path: str, damage: Damage) -> None:
        self._damage.setdefault(path, []).append(damage)
        if not (self.salvage or self._collect):
            raise BagDamagedError(
                f'{path} is damaged: {damage.describe()}; {self._read.get(path, 0)} messages read '
                'before it (saw-ros bag info --salvage, or BagReader(path, salvage=True), reads '
                'around the damage)', [damage])

    # ---- messages
    def messages(self, topics: Optional[Iterable[str]] = None) -> Iterator[BagMessage]:
        """
        Every message of the bag in file order (= log time order for our recordings).

        Raises BagDamagedError at damaged bytes unless the reader salvages.
        """
        wanted = set(topics) if topics is not None else None
        for path in self.files:
            yield from self._scan(path, wanted)

    def _scan(self, path: str, wanted) -> Iterator[BagMessage]:
        self._damage[path], self._read[path], self._tail[path] = [], 0, None
        found: List[Damage] = []
        with self._open(path) as f:
            size = f.seek(0, io.SEEK_END)
            f.seek(0)
            head = f.read(len(MAGIC))
            if head != MAGIC[:len(head)]:
                raise BagReadError(f'{path} is not an MCAP file (no MCAP magic at its start)')
            summary = _read_summary(f, size, path, found)
            self._expected[path] = summary.message_count
            for d in found:
                self._damaged(path, d)
            if len(head) < len(MAGIC):
                self._tail[path] = len(head)
                return
            f.seek(len(MAGIC))
            yield from self._scan_records(f, path, size, summary, wanted)

    def _open(self, path: str):
        """Open one file of the bag; a compressed one ('file' mode) decompressed in memory."""
        if not self._file_compressed:
            return open(path, 'rb')
        import zstandard
        with open(path, 'rb') as f:
            try:
                return io.BytesIO(zstandard.ZstdDecompressor().decompressobj().decompress(
                    f.read()))
            except zstandard.ZstdError as exc:
                raise BagReadError(f'{path} does not decompress as zstd (compression_mode '
                                   f'file in metadata.yaml): {exc}') from None

    def _scan_records(self, f, path, size, summary: _Summary, wanted) -> Iterator[BagMessage]:
        """
        Read the data section record by record, one handler per record type.

        Chunks and messages yield their messages; the rest update the scan's state.
        """
        scan = _Scan(path, size, summary)
        handlers = {_CHUNK_OP: self._on_chunk, _MESSAGE_OP: self._on_message_record,
                    _MESSAGE_INDEX: self._on_message_index, _SCHEMA: self._on_definition,
                    _CHANNEL: self._on_definition}
        while True:
            head = f.read(9)
            if len(head) < 9 or scan.pos + 9 > scan.data_end:
                self._on_section_end(scan)
                break
            opcode, length = _RECORD.unpack(head)
            if opcode == 0:    # no MCAP record has it: zeros (a preallocated or wiped file)
                self._on_not_a_record(scan, head)
                break
            if length > scan.data_end - scan.pos - 9:
                resume = self._on_overlong(scan, opcode, length)
                if resume is None:
                    break
                scan.crc = None                # the data-section CRC cannot be checked now
                f.seek(resume)
                scan.pos = resume
                continue
            body = f.read(length)
            before = scan.crc
            if scan.crc is not None:
                scan.crc = zlib.crc32(body, zlib.crc32(head, scan.crc))
            at = scan.pos
            scan.pos += 9 + length
            if opcode == _DATA_END:
                self._on_data_end(scan, at, body, before)
                break
            if opcode == _FOOTER_OP:
                break
            handler = handlers.get(opcode)
            if handler is not None:
                yield from handler(scan, at, opcode, body, wanted)
        if scan.orphans:
            ids = ', '.join(f'{n} on channel {c}' for c, n in sorted(scan.orphans.items()))
            count = sum(scan.orphans.values())
            self._damaged(path, Damage(path, None, f'{count} messages whose channel is defined '
                                                   f'nowhere readable ({ids}): its definition '
                                                   'was in a damaged chunk', messages=count))

    def _on_section_end(self, scan: '_Scan') -> None:
        """No whole record header left: an unfinished file ends here, a finished one is cut."""
        if scan.summary.finished:
            self._damaged(scan.path, Damage(scan.path, scan.pos, 'the data section ends without '
                                                                 'its DataEnd record'))
        else:
            self._tail[scan.path] = scan.size - scan.pos

    def _on_not_a_record(self, scan: '_Scan', head: bytes) -> None:
        """
        Stop at bytes that cannot start a record (opcode 0x00), as damage.

        Scanning on would take 9-byte steps through what may be a gigabyte of zeros (35 s for
        1 GiB), to report nothing more.
        """
        rest = scan.data_end - scan.pos
        what = 'zero bytes' if not any(head) else 'bytes that are no MCAP record (opcode 0x00)'
        self._damaged(scan.path, Damage(
            scan.path, scan.pos, f'{what} where a record should start; the {rest} bytes from '
                                 'there on are not read', messages=None))

    def _on_overlong(self, scan: '_Scan', opcode: int, length: int) -> Optional[int]:
        """
        Handle a record that claims more bytes than the data section has.

        Return where reading resumes (None: nothing after it is readable).
        """
        path, pos, summary = scan.path, scan.pos, scan.summary
        if not summary.finished:       # cut off at the end: the recorder was killed
            self._tail[path] = scan.size - pos
            return None
        index = summary.chunks.get(pos)
        later = [o for o in scan.chunk_offsets if o > pos]
        if index is not None:  # a chunk whose length field is damaged: skip it by its index
            scan.chunk_number = scan.ordinal[pos]
            scan.lost = self._chunk_damage(path, pos, scan.chunk_number, summary, index,
                                           f'its record length ({length} bytes) runs past the '
                                           'data section')
            self._damaged(path, scan.lost)
            return pos + index.chunk_length
        self._damaged(path, Damage(
            path, pos, f'a record (opcode {opcode:#04x}) claims {length} bytes, past the data '
            'section' + ('' if later else '; nothing after it is readable')))
        return later[0] if later else None

    def _on_chunk(self, scan: '_Scan', at: int, _opcode, body, wanted) -> Iterator[BagMessage]:
        path, summary = scan.path, scan.summary
        scan.chunk_number = scan.ordinal.get(at, scan.chunk_number + 1)
        scan.lost = None
        try:
            records = _open_chunk(body)
        except Exception as exc:  # noqa: BLE001  (zstd and lz4 raise their own types)
            scan.lost = self._chunk_damage(path, at, scan.chunk_number, summary,
                                           summary.chunks.get(at), str(exc), body)
            self._damaged(path, scan.lost)
            return
        batch = []
        try:
            for op, rec in _records(records):
                if op == _MESSAGE_OP:
                    batch.append(_MESSAGE.unpack_from(rec) + (rec,))
                else:
                    _learn(op, rec, scan.schemas, scan.channels)
        except (ValueError, struct.error, UnicodeDecodeError, McapError) as exc:
            scan.lost = self._chunk_damage(path, at, scan.chunk_number, summary,
                                           summary.chunks.get(at),
                                           f'its records do not parse ({exc})', body)
            self._damaged(path, scan.lost)
            return
        for channel_id, sequence, log_time, publish_time, rec in batch:
            message = self._message(scan, wanted, channel_id, sequence, log_time, publish_time,
                                    bytes(rec[_MESSAGE.size:]))
            if message is not None:
                yield message

    def _on_message_record(self, scan: '_Scan', _at, _opcode, body,
                           wanted) -> Iterator[BagMessage]:
        """Yield a message record found outside chunks (other writers)."""
        channel_id, sequence, log_time, publish_time = _MESSAGE.unpack_from(body)
        message = self._message(scan, wanted, channel_id, sequence, log_time, publish_time,
                                body[_MESSAGE.size:])
        if message is not None:
            yield message

    def _on_message_index(self, scan: '_Scan', _at, _opcode, body, _wanted) -> Iterable:
        """Count the messages of a damaged chunk from the message indexes after it."""
        lost = scan.lost
        if lost is not None and len(body) >= 6:
            channel_id, = struct.unpack_from('<H', body)
            count = _U32.unpack_from(body, 2)[0] // 16
            lost.messages = (lost.messages or 0) + count
            channel = scan.channels.get(channel_id)
            name = channel.topic if channel is not None else f'channel {channel_id}'
            if name not in lost.topics:
                lost.topics.append(name)
        return ()

    def _on_definition(self, scan: '_Scan', at: int, opcode: int, body, _wanted) -> Iterable:
        """Keep a schema or channel record found outside chunks (other writers)."""
        kind, cls, table = (('schema', Schema, scan.schemas) if opcode == _SCHEMA
                            else ('channel', Channel, scan.channels))
        try:
            record = _parse(cls, body)
        except (ValueError, struct.error, UnicodeDecodeError, McapError) as exc:
            self._damaged(scan.path, Damage(scan.path, at, f'a {kind} record does not parse '
                                                           f'({exc})'))
            return ()
        table[record.id] = record
        return ()

    def _on_data_end(self, scan: '_Scan', at: int, body, before: Optional[int]) -> None:
        """Check the data section's CRC (unless damaged chunks explain a mismatch already)."""
        stored = _U32.unpack_from(body)[0] if len(body) >= 4 else 0
        if before is not None and stored and stored != before \
                and not self._damage.get(scan.path):
            self._damaged(scan.path, Damage(
                scan.path, at, f'data section CRC mismatch (stored {stored:#010x}, computed '
                f'{before:#010x}): bytes outside the chunks (message indexes...) are damaged',
                messages=0))

    def _message(self, scan: '_Scan', wanted, channel_id, sequence, log_time, publish_time,
                 data: bytes) -> Optional[BagMessage]:
        """
        Return one message record as a BagMessage, counted as read.

        None when its topic is not wanted, or when its channel is unknown (then it is counted in
        the scan's ``orphans``: its definition was in a damaged chunk).
        """
        channel = scan.channels.get(channel_id)
        if channel is None:
            scan.orphans[channel_id] = scan.orphans.get(channel_id, 0) + 1
            return None
        self._read[scan.path] += 1
        if wanted is not None and channel.topic not in wanted:
            return None
        schema = scan.schemas.get(channel.schema_id)
        if self._message_compressed:
            data = self._decompress_message(scan.path, channel.topic, log_time, data)
        return BagMessage(channel.topic, schema.name if schema else '', data, log_time,
                          publish_time, sequence, channel, schema)

    @staticmethod
    def _decompress_message(path: str, topic: str, log_time: int, data) -> bytes:
        """Return a message of a 'message'-compressed bag, decompressed (zstd frame)."""
        import zstandard
        try:
            return zstandard.ZstdDecompressor().decompressobj().decompress(bytes(data))
        except zstandard.ZstdError as exc:
            raise BagReadError(f'{path}: the {topic} message at {stamp(log_time)} does not '
                               f'decompress as zstd (compression_mode message in '
                               f'metadata.yaml): {exc}') from None

    @staticmethod
    def _chunk_damage(path, offset, number, summary: _Summary, index: Optional[ChunkIndex],
                      reason: str, body=None) -> Damage:
        """
        Return a damaged chunk, with its log time range.

        The range comes from the summary's chunk index, else from the chunk record itself.
        """
        start = end = None
        if index is not None:
            start, end = index.message_start_time, index.message_end_time
        elif body is not None and len(body) >= 16:
            start, end = struct.unpack_from('<QQ', body)
        return Damage(path, offset, reason, chunk=number, chunks=len(summary.chunks) or None,
                      start=start, end=end)

    def decoded_messages(self, topics: Optional[Iterable[str]] = None):
        """(BagMessage, ROS-like message object) decoded with mcap_ros2 (no rclpy needed)."""
        from mcap_ros2.decoder import DecoderFactory
        factory = DecoderFactory()
        decoders: Dict[int, Callable[[bytes], object]] = {}
        numbers: Dict[str, int] = {}
        for m in self.messages(topics):
            number = numbers[m.topic] = numbers.get(m.topic, 0) + 1
            decoder = decoders.get(m.channel.id)
            if decoder is None:
                try:
                    decoder = factory.decoder_for(m.channel.message_encoding, m.schema)
                except Exception as exc:  # noqa: BLE001  (mcap_ros2's schema parser errors)
                    raise BagDecodeError(f'{m.topic} [{m.type or "no schema"}]: no decoder from '
                                         f'its schema: {type(exc).__name__}: {exc}') from exc
                if decoder is None:
                    raise BagDecodeError(f'{m.topic}: no decoder for encoding '
                                         f'{m.channel.message_encoding!r} with schema '
                                         f'{m.type or "(none)"}')
                decoders[m.channel.id] = decoder
            try:
                decoded = decoder(m.data)
            except Exception as exc:  # noqa: BLE001  (struct.error, IndexError... on bad bytes)
                raise BagDecodeError(
                    f'{m.topic} [{m.type}] message {number} of the topic (log time '
                    f'{stamp(m.log_time)}, sequence {m.sequence}, {len(m.data)} bytes) does not '
                    f'decode: {type(exc).__name__}: {exc}') from exc
            yield m, decoded

    # ---- summary
    def topics(self) -> Dict[str, TopicSummary]:
        """
        Per topic: type, count, first/last log time, QoS (a full scan of the files).

        Raises BagDamagedError, listing all the damage, unless the reader salvages.
        """
        out: Dict[str, TopicSummary] = {}
        self._collect = True
        try:
            for m in self.messages():
                t = out.get(m.topic)
                if t is None:
                    t = out[m.topic] = TopicSummary(
                        m.topic, m.type, m.channel.message_encoding,
                        offered_qos_profiles=channel_qos(m.channel),
                        type_hash=m.channel.metadata.get('topic_type_hash', ''))
                t.count += 1
                if t.first is None or m.log_time < t.first:
                    t.first = m.log_time
                if t.last is None or m.log_time > t.last:
                    t.last = m.log_time
        finally:
            self._collect = False
        if self.damage and not self.salvage:
            raise BagDamagedError(f'{self.path} is damaged:\n  {self.damage_report()}\n'
                                  '(saw-ros bag info --salvage, or BagReader(path, '
                                  'salvage=True), reads the rest)', self.damage)
        # Topics registered but without messages come from metadata.yaml.
        for entry in (self.metadata or {}).get('topics_with_message_count') or []:
            meta = entry.get('topic_metadata', {})
            if meta.get('name') and meta['name'] not in out:
                out[meta['name']] = TopicSummary(
                    meta['name'], meta.get('type', ''), meta.get('serialization_format', ''),
                    offered_qos_profiles=qos_profiles(meta.get('offered_qos_profiles')),
                    type_hash=meta.get('type_description_hash', ''))
        self._topics = out
        return out

    def shortfall(self, hint: bool = True) -> Optional[str]:
        """
        Say in one line what an unfinished bag lacks; None when the scan found it complete.

        After a full scan (``topics()``, ``info()``). Where metadata.yaml is there (a copy cut
        short) its counts give what is missing per topic and its end the log time range lost;
        without it (the recorder was killed) only where the readable part ends is known. ``hint``
        adds the command that makes it a finished bag.
        """
        if self.complete:
            return None
        topics = self._topics
        read = sum(t.count for t in topics.values())
        ends = [t.last for t in topics.values() if t.last is not None]
        last = max(ends) if ends else None
        text = (f'{self.path} is unfinished (no summary: the recorder was killed or the copy is '
                f'cut short); {read} messages readable')
        meta = self.metadata or {}
        expected = meta.get('message_count')
        if isinstance(expected, int):
            missing = []
            for entry in meta.get('topics_with_message_count') or []:
                name = entry['topic_metadata']['name']
                got = topics[name].count if name in topics else 0
                if entry.get('message_count', 0) > got:
                    missing.append(f'{name}: {entry["message_count"] - got}')
            text += (f' of {expected} (metadata.yaml); missing {max(expected - read, 0)}'
                     + (f' ({", ".join(missing)})' if missing else ''))
            start = (meta.get('starting_time') or {}).get('nanoseconds_since_epoch')
            length = (meta.get('duration') or {}).get('nanoseconds')
            if isinstance(start, int) and isinstance(length, int) and last is not None \
                    and start + length > last:
                text += (f', log time {stamp(last)} .. {stamp(start + length)} '
                         f'({(start + length - last) / 1e9:.3f} s) lost')
        else:
            text += (f'; whatever came after log time {stamp(last)} is lost (no metadata.yaml '
                     'says how much: a killed recorder loses what it had not yet written, about '
                     'its last 0.5 s and one chunk)' if last is not None else '')
        return text + (f'; saw-ros bag reindex {self.path} makes it a finished bag' if hint
                       else '')

    def info(self) -> dict:
        topics = self.topics()
        starts = [t.first for t in topics.values() if t.first is not None]
        ends = [t.last for t in topics.values() if t.last is not None]
        start = min(starts) if starts else None
        end = max(ends) if ends else None
        return {
            'path': self.path,
            'files': [os.path.basename(f) for f in self.files],
            'size': sum(os.path.getsize(f) for f in self.files),
            'storage': 'mcap',
            'start': start, 'end': end,
            'duration': end - start if start is not None and end is not None else 0,
            'messages': sum(t.count for t in topics.values()),
            'topics': topics,
            'complete': self.complete,
            'unread_bytes': self.unread_bytes,
            'damage': self.damage,
            'expected_messages': self.expected_messages(),
            'has_metadata_yaml': self.metadata is not None,
            'shortfall': self.shortfall(),
        }
