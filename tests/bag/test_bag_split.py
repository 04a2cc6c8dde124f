"""
Split bags, as ``ros2 bag record --max-bag-size / --max-bag-duration`` writes them.

Each file a finished MCAP that mcap's seeking reader opens alone (summary, indexes), named
``<bag>_<n>.mcap``; metadata.yaml lists every file with its start, duration and message count;
our reader, rosbags' reader and reindexing read the files as one bag, nothing lost or repeated
at the seams.
"""
import os

from mcap.reader import make_reader
from mcap_ros2._dynamic import serialize_dynamic
import pytest
from saw_ros.bag import BagReader, BagWriter, qos_profile_dict
from saw_ros.bag.reindex import reindex, SUFFIX
from saw_ros.bag.schema import message_definition
from saw_ros.cli.main import main
import yaml

CLOCK = 'rosgraph_msgs/msg/Clock'
T0 = 1_700_000_000_000_000_000
MS = 10**6
S = 10**9
DATA = serialize_dynamic(CLOCK, message_definition(CLOCK))[CLOCK]({'clock': {'sec': 1,
                                                                             'nanosec': 2}})


def write(directory, stamps, close=True, topics=('/clock', '/other'), **options):
    """Write each topic at each log time (ns after T0), sequence numbers from 1."""
    options.setdefault('chunk_size', 4096)
    bag = BagWriter(str(directory), idle_flush_s=None, **options)
    for topic in topics:
        bag.add_topic(topic, CLOCK, [qos_profile_dict()])
    for i, t in enumerate(stamps):
        for k, topic in enumerate(topics):
            bag.write(topic, DATA, T0 + t + k, T0 + t, i + 1)
    if close:
        bag.close()
    else:                       # as kill -9 leaves it: what reached the files stays
        bag.flush_until(1 << 63)
        bag._stream.close()
    return bag


def metadata(directory):
    with open(directory / 'metadata.yaml') as f:
        return yaml.safe_load(f)['rosbag2_bagfile_information']


def standard(path):
    """Return (log times, sequences) of one file, read by mcap's seeking reader (its summary)."""
    with open(path, 'rb') as f:
        reader = make_reader(f)
        assert type(reader).__name__ == 'SeekingReader'
        summary = reader.get_summary()
        assert summary is not None and summary.chunk_indexes
        rows = [(m.log_time, m.sequence, c.topic) for _, c, m in reader.iter_messages()]
        assert summary.statistics.message_count == len(rows)
    return rows


def assert_whole(directory, topics=('/clock', '/other'), n=None):
    """
    Every message once, in order, whether read file by file or as one bag.

    Returns the files' rows.
    """
    meta = metadata(directory)
    names = meta['relative_file_paths']
    assert [f['path'] for f in meta['files']] == names
    assert names == [f'{directory.name}_{i}.mcap' for i in range(len(names))]
    assert sorted(os.listdir(directory)) == sorted(names + ['metadata.yaml'])
    per_file = [standard(directory / name) for name in names]
    for rows, entry in zip(per_file, meta['files']):
        times = [r[0] for r in rows]
        assert entry['message_count'] == len(rows)
        assert entry['starting_time']['nanoseconds_since_epoch'] == times[0]
        assert entry['duration']['nanoseconds'] == times[-1] - times[0]
    everything = [r for rows in per_file for r in rows]
    assert [r[0] for r in everything] == sorted(r[0] for r in everything)
    assert meta['message_count'] == len(everything)
    for topic in topics:
        sequences = [r[1] for r in everything if r[2] == topic]
        assert sequences == list(range(1, len(sequences) + 1)), topic   # none lost or twice
        if n is not None:
            assert len(sequences) == n
    ours = [(m.log_time, m.sequence, m.topic) for m in BagReader(str(directory)).messages()]
    assert ours == everything
    return per_file


def test_duration_limit_keeps_a_message_at_the_limit_and_splits_one_ns_past_it(tmp_path):
    # /clock at 0, 1 s (exactly the limit after the file's first) and 1 s + 1 ns: rosbag2's
    # test (later than the first by more than the limit) splits before the third only.
    write(tmp_path / 'edge', [0, S, S + 1], topics=('/clock',), max_bag_duration_ns=S)
    files = assert_whole(tmp_path / 'edge', topics=('/clock',), n=3)
    assert [[r[0] - T0 for r in rows] for rows in files] == [[0, S], [S + 1]]


def test_split_by_duration_at_1_khz(tmp_path):
    # 2.5 s of two topics at 1 kHz, files of 1 s: three files, the seams at 1 s and 2 s.
    stamps = [i * MS for i in range(2500)]
    bag = write(tmp_path / 'run', stamps, max_bag_duration_ns=S)
    files = assert_whole(tmp_path / 'run', n=2500)
    assert len(files) == 3 and len(bag.files) == 3
    starts = [rows[0][0] - T0 for rows in files]
    # The first message more than 1 s after its file's first: /other at 1 s (1 ns after /clock),
    # then /clock at 2.001 s (/other at 2 s + 1 ns is exactly 1 s after it).
    assert starts == [0, S + 1, 2 * S + MS]
    for rows in files:
        assert rows[-1][0] - rows[0][0] <= S


def test_split_by_size(tmp_path):
    limit = 20_000
    write(tmp_path / 'run', [i * MS for i in range(3000)], compression='none',
          max_bag_size=limit)
    files = assert_whole(tmp_path / 'run', n=3000)
    assert len(files) >= 5
    for name in metadata(tmp_path / 'run')['relative_file_paths'][:-1]:
        # Split once the chunks written reach the limit: past it by less than a chunk and the
        # summary (4 KiB chunks here).
        assert limit <= os.path.getsize(tmp_path / 'run' / name) < limit + 16_384


def test_no_limit_is_one_file_and_negative_limits_are_refused(tmp_path):
    write(tmp_path / 'one', [i * MS for i in range(2000)], max_bag_size=0,
          max_bag_duration_ns=0)
    assert len(assert_whole(tmp_path / 'one', n=2000)) == 1
    for option in ('max_bag_size', 'max_bag_duration_ns'):
        with pytest.raises(ValueError, match='must be >= 0'):
            BagWriter(str(tmp_path / option), **{option: -1})
        assert not (tmp_path / option).exists()


def test_a_one_byte_limit_puts_each_message_in_a_file_of_its_own(tmp_path):
    # Twelve files: the reader puts run_10 and run_11 after run_9, also without metadata.yaml.
    write(tmp_path / 'run', [i * MS for i in range(12)], topics=('/clock',), max_bag_size=1)
    files = assert_whole(tmp_path / 'run', topics=('/clock',), n=12)
    assert [len(rows) for rows in files] == [1] * 12
    os.remove(tmp_path / 'run' / 'metadata.yaml')
    assert [m.sequence for m in BagReader(str(tmp_path / 'run')).messages()] == list(
        range(1, 13))


def test_a_recorder_killed_in_its_second_file_is_read_and_repaired(tmp_path, capsys):
    directory = tmp_path / 'killed'
    stamps = [i * MS for i in range(1800)]
    write(directory, stamps, close=False, max_bag_duration_ns=S)
    assert sorted(os.listdir(directory)) == ['killed_0.mcap', 'killed_1.mcap']
    first = (directory / 'killed_0.mcap').read_bytes()
    reader = BagReader(str(directory))
    before = [(m.log_time, m.sequence, m.topic) for m in reader.messages()]
    assert not reader.complete
    # The first file whole, the second up to its last complete chunk.
    assert 1001 * 2 < len(before) < 1800 * 2
    assert [r[1] for r in before if r[2] == '/clock'] == list(range(1, len(before) // 2 + 1))
    assert main(['bag', 'info', str(directory)]) == 0
    out = capsys.readouterr().out
    assert 'Files:             killed_0.mcap, killed_1.mcap' in out
    assert f'Messages:          {len(before)}' in out and 'unfinished file' in out

    result = reindex(str(directory))
    assert result.kept == ['killed_1.mcap' + SUFFIX]        # the finished file left as it was
    assert main(['bag', 'reindex', str(directory)]) == 0    # then a finished bag: left alone
    assert 'nothing to reindex' in capsys.readouterr().out
    assert (directory / 'killed_0.mcap').read_bytes() == first
    os.rename(directory / ('killed_1.mcap' + SUFFIX), tmp_path / 'original')
    files = assert_whole(directory)
    assert [r for rows in files for r in rows] == before
    assert [f['message_count'] for f in metadata(directory)['files']] == [
        len(files[0]), len(files[1])]
    assert len(files[0]) == 2001                 # /clock and /other from 0 to 1 s, /clock at 1 s
    assert result.messages == len(before)


def test_rosbags_reads_a_split_bag_as_one(tmp_path):
    rosbags = pytest.importorskip('rosbags.rosbag2', reason='rosbags (requirements.txt)')
    write(tmp_path / 'run', [i * MS for i in range(2500)], max_bag_duration_ns=S)
    with rosbags.Reader(tmp_path / 'run') as reader:
        assert [f['path'] for f in reader.storage.files] == [f'run_{i}.mcap' for i in range(3)]
        rows = [(c.topic, t) for c, t, _ in reader.messages()]
        assert reader.message_count == 5000
    assert rows == [(m.topic, m.log_time) for m in BagReader(str(tmp_path / 'run')).messages()]
