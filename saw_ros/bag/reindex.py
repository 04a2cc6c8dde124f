"""
Make an unfinished bag a finished one: ``saw-ros bag reindex BAG`` (rosbag2's ``reindex``).

A recorder killed (or a disk full, a copy cut short) leaves MCAP files without their summary:
our reader reads them up to the last complete record, but the standard ``mcap`` reader's seeking
reader needs the summary's chunk indexes, and ``ros2 bag`` needs metadata.yaml. Reindexing
copies every readable message (damaged chunks skipped, as ``--salvage`` reads) into a new file
with the same schemas, channels, times and sequence numbers, finishes it (chunk and message
indexes, statistics, the rosbag2 Metadata record) and writes metadata.yaml.

Nothing is lost by doing it and nothing leaves the bag directory: each file is written under a
temporary name beside it and moved into place only when complete; the original is kept beside it
as ``<file>.unfinished`` (no longer a ``.mcap``: readers skip it; delete it once satisfied).
metadata.yaml's ``custom_data`` keeps what it held (the recorder's loss counts, for a copy cut
short) and says what the reindexing found missing (``saw_ros.reindexed``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import os
from typing import Dict, List, Optional

from mcap.writer import CompressionType, Writer
from saw_ros.bag.reader import BagReader, BagReadError, channel_qos, inside
from saw_ros.bag.writer import bag_metadata, DEFAULT_CHUNK_SIZE, dump_yaml
SUFFIX = '.unfinished'


@dataclass
class Reindexed:
    """What ``reindex`` did: per topic the messages now in the finished bag."""

    path: str
    counts: Dict[str, int] = field(default_factory=dict)
    kept: List[str] = field(default_factory=list)    # the originals, renamed
    missing: Optional[str] = None                     # what the unfinished bag lacked
    already_finished: bool = False

    @property
    def messages(self) -> int:
        return sum(self.counts.values())

    def describe(self) -> str:
        if self.already_finished:
            return (f'{self.path} is a finished bag (summary and metadata.yaml): nothing to '
                    'reindex')
        counts = ', '.join(f'{t}: {n}' for t, n in sorted(self.counts.items()))
        text = (f'{self.path} reindexed: {self.messages} messages ({counts}); summary and '
                f'metadata.yaml written; the original kept as {", ".join(self.kept)}')
        return text + (f'. {self.missing}' if self.missing else '')


def reindex(path: str) -> Reindexed:
    """
    Rewrite the unfinished bag directory ``path`` as a finished one; return what it holds.

    BagReadError (one line) when ``path`` is no bag directory, or an earlier reindexing left its
    ``.unfinished`` copy there.
    """
    directory = os.path.abspath(path)
    if not os.path.isdir(directory):
        raise BagReadError(f'{path} is not a bag directory (reindex rewrites a bag directory; '
                           'put a lone .mcap file in a directory of its own)')
    reader = BagReader(directory, salvage=True)
    reader.info()                                   # a full scan: complete? damaged?
    result = Reindexed(directory)
    if reader.complete and not reader.damage and reader.metadata is not None:
        result.already_finished = True
        return result
    result.missing = reader.shortfall(hint=False) or ('damaged: ' + '; '.join(
        d.describe() for d in reader.damage))
    for path_ in reader.files:
        if os.path.lexists(path_ + SUFFIX):
            raise BagReadError(f'{path_ + SUFFIX} exists (an earlier reindex kept the original '
                               'there): move it away first')
    topics: Dict[str, list] = {}
    files = []
    for path_ in reader.files:
        # A split bag's files finished before the recorder was killed stay as they are.
        finished = reader.finished(path_)
        files.append((os.path.basename(path_),) + _rewrite(path_, topics, copy=not finished))
        if not finished:
            result.kept.append(os.path.basename(path_) + SUFFIX)
    # Topics metadata.yaml listed without a message left keep their entry.
    for entry in (reader.metadata or {}).get('topics_with_message_count') or []:
        meta = entry['topic_metadata']
        topics.setdefault(meta['name'], [
            meta['name'], meta.get('type', ''), meta.get('serialization_format', 'cdr'),
            meta.get('offered_qos_profiles') or [], meta.get('type_description_hash', ''), 0])
    custom = dict((reader.metadata or {}).get('custom_data') or {})
    custom['saw_ros.reindexed'] = result.missing
    info = bag_metadata(files, [tuple(t) for t in topics.values()], custom)
    _write_metadata(directory, info)
    result.counts = {name: t[5] for name, t in topics.items()}
    return result


def _rewrite(path: str, topics: Dict[str, list], copy: bool = True):
    """
    Copy the readable messages of ``path`` into a finished file put in its place.

    ``topics`` gains each topic's metadata.yaml entry and count; returns the file's first and
    last log time and its message count. ``copy`` False only counts (a file already finished).
    """
    if not copy:
        return _tally(BagReader(path).messages(), topics)
    directory = os.path.dirname(path)
    temporary = inside(directory, f'.{os.path.basename(path)}.reindexing', directory)
    if os.path.lexists(temporary):          # left by an interrupted reindex: ours to replace
        os.remove(temporary)
    with open(temporary, 'xb') as stream:
        writer = Writer(stream, chunk_size=DEFAULT_CHUNK_SIZE, compression=CompressionType.ZSTD,
                        enable_data_crcs=True)
        writer.start(profile='ros2', library='saw_ros reindex (mcap-python)')
        schemas: Dict[int, int] = {}
        channels: Dict[int, int] = {}
        file_topics: Dict[str, list] = {}

        def copied():
            for m in BagReader(path, salvage=True).messages():
                channel = channels.get(m.channel.id)
                if channel is None:
                    schema = 0
                    if m.schema is not None:
                        known = schemas.get(m.schema.id)
                        if known is None:
                            known = schemas[m.schema.id] = writer.register_schema(
                                m.schema.name, m.schema.encoding, m.schema.data)
                        schema = known
                    channel = channels[m.channel.id] = writer.register_channel(
                        m.topic, m.channel.message_encoding, schema, dict(m.channel.metadata))
                writer.add_message(channel, m.log_time, m.data, m.publish_time, m.sequence)
                yield m

        first, last, count = _tally(copied(), file_topics)
        for name, entry in file_topics.items():
            topics.setdefault(name, entry[:5] + [0])[5] += entry[5]
        writer.add_metadata('rosbag2', {'serialized_metadata': dump_yaml(bag_metadata(
            [(os.path.basename(path), first, last, count)],
            [tuple(t) for t in file_topics.values()], None))})
        writer.finish()
        stream.flush()
        os.fsync(stream.fileno())
    os.replace(path, path + SUFFIX)
    os.replace(temporary, path)
    return first, last, count


def _tally(messages, topics: Dict[str, list]):
    """Count ``messages`` per topic into ``topics``; return their first, last log time, count."""
    first = last = None
    count = 0
    for m in messages:
        entry = topics.get(m.topic)
        if entry is None:
            entry = topics[m.topic] = [
                m.topic, m.type, m.channel.message_encoding, channel_qos(m.channel),
                m.channel.metadata.get('topic_type_hash', ''), 0]
        entry[5] += 1
        first = m.log_time if first is None else first
        last = m.log_time
        count += 1
    return first, last, count


def _write_metadata(directory: str, info: dict) -> None:
    """Write metadata.yaml under a temporary name, then move it into place (never half)."""
    temporary = inside(directory, '.metadata.yaml.reindexing', directory)
    if os.path.lexists(temporary):          # left by an interrupted reindex: ours to replace
        os.remove(temporary)
    with open(temporary, 'x', encoding='utf-8') as f:
        f.write(dump_yaml({'rosbag2_bagfile_information': info}))
    os.replace(temporary, os.path.join(directory, 'metadata.yaml'))
