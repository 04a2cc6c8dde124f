"""
Hostile or cut-short bags: one clear line, nothing read outside the bag, what is missing said.

A malformed metadata.yaml, file names that leave the bag directory (``..``, absolute, a link),
a gigabyte of zeros after a valid header, and a copy cut short whose metadata.yaml still holds
the counts.
"""
import os
from pathlib import Path
import shutil

from mcap_ros2._dynamic import serialize_dynamic
import pytest
from saw_ros.bag import BagReader, BagWriter, qos_profile_dict
from saw_ros.bag.reader import BagDamagedError, BagReadError, MAGIC, stamp
from saw_ros.bag.schema import message_definition
from saw_ros.cli.main import main
import yaml

CLOCK = 'rosgraph_msgs/msg/Clock'
T0 = 1_700_000_000_000_000_000
N = 1000     # per topic, 1 kHz: 1 s


@pytest.fixture(scope='module')
def pristine(tmp_path_factory):
    """Return a finished bag: /clock and /other at 1 kHz for 1 s, 4 KiB chunks."""
    directory = tmp_path_factory.mktemp('pristine') / 'bag'
    clock = serialize_dynamic(CLOCK, message_definition(CLOCK))[CLOCK]
    bag = BagWriter(str(directory), chunk_size=4096, compression='zstd')
    bag.add_topic('/clock', CLOCK, [qos_profile_dict()])
    bag.add_topic('/other', CLOCK, [qos_profile_dict()])
    for i in range(N):
        t = T0 + i * 10**6
        data = clock({'clock': {'sec': i // 1000, 'nanosec': (i % 1000) * 10**6}})
        bag.write('/clock', data, t, t, i + 1)
        bag.write('/other', data, t + 1, t, i + 1)
    bag.close()
    return directory


@pytest.fixture
def bag(pristine, tmp_path):
    directory = tmp_path / 'bag'
    shutil.copytree(pristine, directory)
    return directory


def info(capsys, *args):
    code = main(['bag', 'info', *map(str, args)])
    out = capsys.readouterr()
    return code, out.out, out.err


def one_line_refusal(capsys, directory, *words):
    """Check that bag info and BagReader (player, track) refuse with one line naming ``words``."""
    code, out, err = info(capsys, directory)
    assert code != 0 and out == ''
    assert 'Traceback' not in err and len(err.strip().splitlines()) == 1, err
    for word in words:
        assert word in err, err
    with pytest.raises(BagReadError):
        BagReader(str(directory)).topics()
    return err


def set_metadata(directory, text):
    (directory / 'metadata.yaml').write_text(text)


def metadata_with(directory, **fields):
    doc = yaml.safe_load((directory / 'metadata.yaml').read_text())
    doc['rosbag2_bagfile_information'].update(fields)
    set_metadata(directory, yaml.safe_dump(doc))


@pytest.mark.parametrize('text,words', [
    ('rosbag2_bagfile_information: {version: 9\n  relative_file_paths: [', ['not YAML']),
    ('just a string\n', ['not a rosbag2 metadata file', 'str']),
    ('- 1\n- 2\n', ['not a rosbag2 metadata file', 'list']),
    ('rosbag2_bagfile_information: 7\n', ['no rosbag2_bagfile_information mapping']),
    ('\x00\xff\xfe', ['metadata.yaml']),
])
def test_malformed_metadata_is_one_line(bag, capsys, text, words):
    set_metadata(bag, text)
    one_line_refusal(capsys, bag, 'metadata.yaml', *words)


@pytest.mark.parametrize('fields,words', [
    ({'relative_file_paths': 'bag_0.mcap'}, ['relative_file_paths must be a list']),
    ({'relative_file_paths': [5]}, ['relative_file_paths must be a list of file names']),
    ({'message_count': 'many'}, ['message_count must be an integer']),
    ({'topics_with_message_count': [1, 2]}, ['topics_with_message_count entries']),
    ({'topics_with_message_count': [{'topic_metadata': {'name': 3}}]},
     ['topics_with_message_count entries']),
    ({'starting_time': 12}, ['starting_time must be a mapping']),
])
def test_metadata_fields_of_the_wrong_type_are_one_line(bag, capsys, fields, words):
    metadata_with(bag, **fields)
    one_line_refusal(capsys, bag, *words)


@pytest.fixture
def outside(pristine, tmp_path):
    """Return a readable bag file outside the bag under test (what an escape would open)."""
    target = tmp_path / 'elsewhere' / 'secret.mcap'
    target.parent.mkdir()
    shutil.copy(pristine / 'bag_0.mcap', target)
    return target


def test_dot_dot_out_of_the_bag_is_refused(bag, outside, capsys):
    metadata_with(bag, relative_file_paths=['../elsewhere/secret.mcap'])
    one_line_refusal(capsys, bag, "'../elsewhere/secret.mcap' leads outside the bag directory")
    metadata_with(bag, relative_file_paths=['../../../../../../../../etc/hostname'])
    one_line_refusal(capsys, bag, 'outside the bag directory')


def test_absolute_path_is_refused(bag, outside, capsys):
    metadata_with(bag, relative_file_paths=[str(outside)])
    one_line_refusal(capsys, bag, 'is an absolute path')


def test_links_out_of_the_bag_are_refused(bag, outside, capsys):
    os.symlink(outside, bag / 'link.mcap')
    metadata_with(bag, relative_file_paths=['link.mcap'])
    one_line_refusal(capsys, bag, "'link.mcap' is a link outside the bag directory")
    # Without metadata.yaml the bag's *.mcap files are read: a link among them is refused too.
    os.remove(bag / 'metadata.yaml')
    one_line_refusal(capsys, bag, 'link.mcap', 'outside the bag directory')
    # And a metadata.yaml that is itself a link out.
    os.remove(bag / 'link.mcap')
    (outside.parent / 'metadata.yaml').write_text((bag.parent / 'x').as_posix())
    os.symlink(outside.parent / 'metadata.yaml', bag / 'metadata.yaml')
    one_line_refusal(capsys, bag, 'metadata.yaml', 'outside the bag directory')


def test_a_link_inside_the_bag_is_read(bag):
    os.rename(bag / 'bag_0.mcap', bag / 'data.mcap')
    os.symlink('data.mcap', bag / 'bag_0.mcap')
    assert BagReader(str(bag)).info()['messages'] == 2 * N


def test_gigabyte_of_zeros_after_a_valid_header_is_damage_at_its_start(tmp_path, capsys):
    directory = tmp_path / 'zeros'
    directory.mkdir()
    path = directory / 'zeros_0.mcap'
    header = b'\x01' + (4 + 4 + 4 + 4).to_bytes(8, 'little') + b'\x04\x00\x00\x00ros2' \
        + b'\x04\x00\x00\x00test'
    path.write_bytes(MAGIC + header)
    with open(path, 'r+b') as f:
        f.truncate(len(MAGIC) + len(header) + (1 << 30))     # sparse: no disk used
    start = len(MAGIC) + len(header)
    code, out, err = info(capsys, directory)
    assert code == 1 and out == ''
    assert f'zeros_0.mcap at offset {start}: zero bytes where a record should start' in err
    assert f'the {1 << 30} bytes from there on are not read' in err
    reader = BagReader(str(directory), salvage=True)
    assert list(reader.messages()) == [] and len(reader.damage) == 1
    with pytest.raises(BagDamagedError):
        BagReader(str(directory)).topics()


def cut(directory, fraction):
    path = directory / 'bag_0.mcap'
    with open(path, 'r+b') as f:
        f.truncate(int(os.path.getsize(path) * fraction))


def test_copy_cut_short_says_what_is_missing_from_its_metadata(bag, pristine, capsys):
    cut(bag, 0.5)
    reader = BagReader(str(bag))
    topics = reader.topics()
    read = {name: t.count for name, t in topics.items()}
    last = max(t.last for t in topics.values())
    assert 0 < sum(read.values()) < 2 * N
    text = reader.shortfall()
    assert f'{sum(read.values())} messages readable of {2 * N} (metadata.yaml)' in text
    assert f'missing {2 * N - sum(read.values())}' in text
    assert f'/clock: {N - read["/clock"]}' in text and f'/other: {N - read["/other"]}' in text
    end = T0 + (N - 1) * 10**6 + 1
    assert f'log time {stamp(last)} .. {stamp(end)} ({(end - last) / 1e9:.3f} s) lost' in text
    assert 'saw-ros bag reindex' in text
    code, out, _ = info(capsys, bag)
    assert code == 0 and f'Missing:           {text}' in out
    assert BagReader(str(pristine)).shortfall() is None


def test_killed_recording_says_where_the_readable_part_ends(bag, capsys):
    os.remove(bag / 'metadata.yaml')
    cut(bag, 0.7)
    reader = BagReader(str(bag))
    last = max(t.last for t in reader.topics().values())
    text = reader.shortfall()
    assert f'whatever came after log time {stamp(last)} is lost' in text
    assert 'no metadata.yaml' in text


REFERENCE_CAMERA = Path(__file__).resolve().parents[2] / 'bags' / 'reference_camera'


def test_track_warns_on_a_killed_recording_and_refuses_hostile_metadata(tmp_path, capsys):
    directory = tmp_path / 'camera'
    shutil.copytree(REFERENCE_CAMERA, directory)
    os.remove(directory / 'metadata.yaml')                # as after kill -9
    path = next(directory.glob('*.mcap'))
    with open(path, 'r+b') as f:
        f.truncate(os.path.getsize(path) // 2)
    code = main(['track', str(directory), '--px-per-m', '1200', '--quiet'])
    err = capsys.readouterr().err
    assert code == 0, err
    assert 'saw-ros track: warning:' in err and 'is unfinished' in err and 'Traceback' not in err
    set_metadata(directory, '[1, 2')
    code = main(['track', str(directory), '--px-per-m', '1200', '--quiet'])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and 'not YAML' in err, err


@pytest.mark.ros
def test_player_refuses_hostile_metadata_in_one_line(bag, outside, tmp_path):
    from saw_ros.graph.process import ManagedProcess, node_command
    metadata_with(bag, relative_file_paths=['../elsewhere/secret.mcap'])
    player = ManagedProcess('player', node_command('player', params={'bag': str(bag)}),
                            os.environ, tmp_path / 'logs')
    assert player.wait(60) == 1
    out = player.output()
    assert 'leads outside the bag directory' in out and 'Traceback' not in out, out
