"""
Damaged bytes are reported as damage, unless salvaging.

The report says which chunk, its log time range, how many messages are lost and readable (``saw-ros
bag info`` exits 1, BagReader raises); a file cut short (the recorder killed) is unfinished, not
damaged; decode failures name topic and message.
"""
import os
import shutil
import struct

from mcap.reader import make_reader
from mcap_ros2._dynamic import serialize_dynamic
import pytest

from saw_ros.bag import BagReader, BagWriter, qos_profile_dict
from saw_ros.bag.reader import BagDamagedError, BagDecodeError, BagReadError, stamp
from saw_ros.bag.schema import message_definition
from saw_ros.cli.main import main

POSE = 'geometry_msgs/msg/PoseStamped'
CLOCK = 'rosgraph_msgs/msg/Clock'
T0 = 1_700_000_000_000_000_000
N = 1500     # per topic: 3000 messages, ~10 chunks of 8 KiB


def encoder(type_name):
    return serialize_dynamic(type_name, message_definition(type_name))[type_name]


def pose_bytes(i):
    return encoder(POSE)({'header': {'stamp': {'sec': i // 1000, 'nanosec': (i % 1000) * 10**6},
                                     'frame_id': 'surface'},
                          'pose': {'position': {'x': i * 0.001, 'y': 0.0, 'z': 0.0},
                                   'orientation': {'x': 0.0, 'y': 0.0, 'z': 0.0, 'w': 1.0}}})


@pytest.fixture(scope='module')
def pristine(tmp_path_factory):
    """Return a finished bag: /clock and /saw/pose at 1 kHz, 1.5 s, 8 KiB chunks."""
    directory = tmp_path_factory.mktemp('pristine') / 'bag'
    bag = BagWriter(str(directory), chunk_size=8192, compression='zstd')
    bag.add_topic('/clock', CLOCK, [qos_profile_dict()])
    bag.add_topic('/saw/pose', POSE, [qos_profile_dict()])
    clock = encoder(CLOCK)
    for i in range(N):
        t = T0 + i * 10**6
        bag.write('/clock', clock({'clock': {'sec': i // 1000, 'nanosec': (i % 1000) * 10**6}}),
                  t, t)
        bag.write('/saw/pose', pose_bytes(i), t + 1000, t)
    bag.close()
    return directory


def copy(pristine, tmp_path, keep_metadata=True):
    directory = tmp_path / 'bag'
    shutil.copytree(pristine, directory)
    if not keep_metadata:
        os.remove(directory / 'metadata.yaml')
    return directory, directory / 'bag_0.mcap'


def chunk_indexes(path):
    with open(path, 'rb') as f:
        return sorted(make_reader(f).get_summary().chunk_indexes,
                      key=lambda c: c.chunk_start_offset)


def flip(path, offset, mask=0x10):
    with open(path, 'r+b') as f:
        f.seek(offset)
        byte = f.read(1)[0]
        f.seek(offset)
        f.write(bytes([byte ^ mask]))


def compressed_data_offset(chunk):
    """Offset of the middle of a chunk's compressed bytes."""
    head = 9 + 8 + 8 + 8 + 4 + 4 + len(chunk.compression) + 8
    return chunk.chunk_start_offset + head + chunk.compressed_size // 2


def chunk_messages(pristine, chunk):
    return [m for m in BagReader(str(pristine)).messages()
            if chunk.message_start_time <= m.log_time <= chunk.message_end_time]


def info(capsys, *args):
    code = main(['bag', 'info', *map(str, args)])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize('mask', [0x10, 0x01, 0xFF])
def test_flipped_byte_in_a_chunk_is_damage_with_chunk_and_time_range(
        pristine, tmp_path, capsys, mask):
    directory, path = copy(pristine, tmp_path)
    chunks = chunk_indexes(path)
    assert len(chunks) >= 6
    bad = chunks[3]
    flip(path, compressed_data_offset(bad), mask)
    lost = len(chunk_messages(pristine, bad))
    assert lost > 50

    code, out, err = info(capsys, directory)
    assert code == 1 and out == ''
    assert 'is damaged' in err and 'unfinished' not in err
    assert f'chunk 4 of {len(chunks)}' in err
    assert f'log time {stamp(bad.message_start_time)} .. {stamp(bad.message_end_time)}' in err
    assert f'{lost} messages of /clock, /saw/pose' in err
    assert f'{2 * N - lost} of {2 * N} messages readable' in err
    assert '--salvage' in err

    code, out, err = info(capsys, '--salvage', directory)
    assert code == 0
    assert f'Messages:          {2 * N - lost}' in out
    assert f'State:             DAMAGED, salvaged: {2 * N - lost} of {2 * N} messages read' in out
    assert f'Damaged:           bag_0.mcap chunk 4 of {len(chunks)}' in out

    # BagReader consumers (the player reads topics() first) get an error, not fewer messages.
    with pytest.raises(BagDamagedError) as exc:
        BagReader(str(directory)).topics()
    assert exc.value.damage[0].chunk == 4 and exc.value.damage[0].messages == lost
    assert isinstance(exc.value, BagReadError)
    strict = BagReader(str(directory)).messages()
    before = []
    with pytest.raises(BagDamagedError):
        for m in strict:
            before.append(m.log_time)
    assert before and max(before) < bad.message_start_time
    # Salvage reads everything else, in order.
    salvaged = BagReader(str(directory), salvage=True)
    got = [(m.topic, m.log_time, m.data) for m in salvaged.messages()]
    skipped = {(m.topic, m.log_time) for m in chunk_messages(pristine, bad)}
    expected = [(m.topic, m.log_time, m.data) for m in BagReader(str(pristine)).messages()
                if (m.topic, m.log_time) not in skipped]
    assert got == expected
    assert [d.chunk for d in salvaged.damage] == [4]


def test_truncated_file_is_unfinished_not_damaged(pristine, tmp_path, capsys):
    directory, path = copy(pristine, tmp_path, keep_metadata=False)   # as after kill -9
    chunks = chunk_indexes(path)
    cut = chunks[5]
    with open(path, 'r+b') as f:
        f.truncate(cut.chunk_start_offset + cut.chunk_length // 2)
    code, out, err = info(capsys, directory)
    assert code == 0 and err == ''
    assert 'unfinished file (recorder killed?)' in out and 'DAMAGED' not in out
    complete = [m for m in BagReader(str(pristine)).messages()
                if m.log_time < cut.message_start_time]
    assert f'Messages:          {len(complete)}' in out
    reader = BagReader(str(directory))
    assert len(list(reader.messages())) == len(complete)
    assert not reader.complete and reader.damage == []
    assert reader.unread_bytes == cut.chunk_length // 2

    # Cut short AND damaged before the cut: damaged (exit 1), and unfinished as well.
    flip(path, compressed_data_offset(chunks[1]))
    code, out, err = info(capsys, directory)
    assert code == 1 and 'chunk 2 (offset' in err and 'is damaged' in err


def test_file_cut_after_10_bytes_has_no_start(pristine, tmp_path, capsys):
    (tmp_path / 'cut').mkdir()
    with open(pristine / 'bag_0.mcap', 'rb') as f:
        (tmp_path / 'cut' / 'cut_0.mcap').write_bytes(f.read(10))
    code, out, err = info(capsys, tmp_path / 'cut')
    assert code == 0, err
    assert 'Start:             n/a' in out and 'End:               n/a' in out
    assert 'Messages:          0' in out and '1970' not in out
    assert 'unfinished' in out


def test_not_an_mcap_file_is_refused(tmp_path, capsys):
    (tmp_path / 'x.mcap').write_bytes(b'PK\x03\x04 not a bag at all')
    code, _, err = info(capsys, tmp_path / 'x.mcap')
    assert code == 2 and 'not an MCAP file' in err


def test_damaged_chunk_length_in_a_finished_file_is_skipped_by_its_index(pristine, tmp_path,
                                                                         capsys):
    directory, path = copy(pristine, tmp_path)
    chunks = chunk_indexes(path)
    flip(path, chunks[2].chunk_start_offset + 1 + 6, 0x40)   # a high byte of the record length
    code, _, err = info(capsys, directory)
    assert code == 1
    assert f'chunk 3 of {len(chunks)}' in err and 'runs past the data section' in err
    lost = len(chunk_messages(pristine, chunks[2]))
    salvaged = BagReader(str(directory), salvage=True)
    assert len(list(salvaged.messages())) == 2 * N - lost


def test_damage_outside_the_chunks_fails_the_data_section_crc(pristine, tmp_path, capsys):
    directory, path = copy(pristine, tmp_path)
    index = chunk_indexes(path)[2]
    flip(path, index.message_index_offsets[2] + 9 + 2 + 4 + 3)   # in a message index record
    code, _, err = info(capsys, directory)
    assert code == 1 and 'data section CRC mismatch' in err
    assert f'{2 * N} of {2 * N} messages readable' in err
    assert len(list(BagReader(str(directory), salvage=True).messages())) == 2 * N


def test_decode_failure_names_topic_and_message(tmp_path):
    bag = BagWriter(str(tmp_path / 'bad'))
    bag.add_topic('/saw/pose', POSE, [qos_profile_dict()])
    for i in range(5):
        data = pose_bytes(i)
        bag.write('/saw/pose', data[:30] if i == 2 else data, T0 + i, T0 + i, i + 1)
    bag.close()
    decoded = BagReader(str(tmp_path / 'bad')).decoded_messages()
    assert next(decoded)[1].pose.position.x == 0.0
    next(decoded)
    with pytest.raises(BagDecodeError) as exc:
        next(decoded)
    text = str(exc.value)
    assert '/saw/pose' in text and POSE in text and 'message 3 of the topic' in text
    assert 'sequence 3' in text and '30 bytes' in text


def test_message_record_layout_is_what_the_reader_assumes():
    # The reader parses Message records itself (channel u16, sequence u32, two u64 times).
    assert struct.calcsize('<HIQQ') == 22
