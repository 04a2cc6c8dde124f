"""
Bags written by another writer than ours open in our reader and player (issue 34).

The writer is rosbags (pip install rosbags, pinned in requirements.txt): an independent,
maintained implementation of rosbag2's MCAP storage, so these bags have what the real rosbag2
writes and our writer does not: metadata.yaml of versions 8 (QoS as YAML text with rmw's enum
numbers) and 9 (QoS as a list of names), message definitions in ros2msg and in ros2idl, file and
message compression (zstd), and several files in one bag. Bags of the real rosbag2 (its own test
bags) were checked by hand: docs/measurements.md.
"""
from pathlib import Path
import shutil

import pytest
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from saw_ros.bag.reader import BagReader, BagReadError
from std_msgs.msg import String

rosbags = pytest.importorskip('rosbags', reason='rosbags (requirements.txt) writes these bags')
from rosbags.interfaces import (  # noqa: E402, I100
    Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime)
from rosbags.rosbag2 import (  # noqa: E402
    CompressionFormat, CompressionMode, StoragePlugin, Writer)
from rosbags.typesys import get_typestore, Stores  # noqa: E402

TYPES = get_typestore(Stores.ROS2_JAZZY)
STRING = 'std_msgs/msg/String'
FOREVER = QosTime(sec=0, nsec=0)
LATCHED = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
              FOREVER, FOREVER, QosLiveliness.AUTOMATIC, FOREVER, False)
STREAM = Qos(QosHistory.KEEP_LAST, 10, QosReliability.BEST_EFFORT, QosDurability.VOLATILE,
             FOREVER, FOREVER, QosLiveliness.AUTOMATIC, FOREVER, False)
# rosbag2's ros2idl: each definition after a line of 80 '=' and 'IDL: <type>'.
STRING_IDL = ('=' * 80 + '\nIDL: std_msgs/msg/String\n'
              'module std_msgs {\n  module msg {\n    struct String {\n      string data;\n'
              '    };\n  };\n};\n')


def _string(text: str) -> bytes:
    msg = TYPES.types[STRING](data=text)
    return bytes(TYPES.serialize_cdr(msg, STRING))


def write(path: Path, version: int, compression=None, idl: bool = False, first: int = 0,
          count: int = 6) -> Path:
    """Write a bag with rosbags: /chatter (a stream) and /latched (transient local)."""
    writer = Writer(path, version=version, storage_plugin=StoragePlugin.MCAP)
    if compression is not None:
        writer.set_compression(compression, CompressionFormat.ZSTD)
    with writer:
        definition = ({'msgdef': STRING_IDL, 'rihs01': TYPES.hash_rihs01(STRING)} if idl
                      else {'typestore': TYPES})
        chatter = writer.add_connection('/chatter', STRING, offered_qos_profiles=[STREAM],
                                        **definition)
        latched = writer.add_connection('/latched', STRING, offered_qos_profiles=[LATCHED],
                                        typestore=TYPES)
        writer.write(latched, 1_000_000 * first, _string('set once'))
        for i in range(first, first + count):
            writer.write(chatter, 1_000_000 * (i + 1), _string(f'hello {i}'))
    return path


def _read(path: Path):
    reader = BagReader(str(path))
    return reader, [(m.topic, m.log_time, deserialize_message(bytes(m.data), String).data)
                    for m in reader.messages()]


EXPECTED = [('/latched', 0, 'set once')] + [('/chatter', 1_000_000 * (i + 1), f'hello {i}')
                                            for i in range(6)]


@pytest.mark.parametrize('version', [8, 9])
@pytest.mark.parametrize('compression', [None, CompressionMode.FILE, CompressionMode.MESSAGE],
                         ids=['plain', 'file-zstd', 'message-zstd'])
def test_every_message_of_a_rosbags_bag_reads_back_with_its_topic_and_qos(tmp_path, version,
                                                                          compression):
    path = write(tmp_path / 'bag', version, compression)
    reader, messages = _read(path)
    assert messages == EXPECTED
    topics = reader.topics()
    assert {name: (t.type, t.serialization_format, t.count) for name, t in topics.items()} == {
        '/chatter': (STRING, 'cdr', 6), '/latched': (STRING, 'cdr', 1)}
    # Version 8 wrote the policies as numbers, 9 as names: both read as rosbag2's names, and the
    # player offers what was recorded (its QoS for /latched keeps late subscribers).
    from saw_ros.ros.nodes.player import offered_qos
    (latched,) = topics['/latched'].offered_qos_profiles
    assert (latched['reliability'], latched['durability']) == ('reliable', 'transient_local')
    qos = offered_qos(topics['/latched'].offered_qos_profiles, 10)
    assert qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert offered_qos(topics['/chatter'].offered_qos_profiles, 10).reliability == \
        ReliabilityPolicy.BEST_EFFORT
    assert reader.info()['messages'] == 7


def test_a_ros2idl_message_definition_is_read_as_its_type(tmp_path):
    reader, messages = _read(write(tmp_path / 'bag', 9, idl=True))
    assert messages == EXPECTED
    chatter = next(m for m in reader.messages(['/chatter']))
    assert (chatter.type, chatter.schema.encoding) == (STRING, 'ros2idl')
    assert chatter.schema.data.decode().startswith('=' * 80 + '\nIDL: std_msgs/msg/String')


def test_a_bag_of_several_files_reads_them_in_the_order_metadata_lists_them(tmp_path):
    """rosbag2 splits a recording into files (--max-bag-size); metadata.yaml lists them all."""
    import yaml
    one = write(tmp_path / 'one', 9, count=3)
    two = write(tmp_path / 'two', 9, first=3, count=3)
    info = yaml.safe_load((one / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    more = yaml.safe_load((two / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    shutil.move(str(two / 'two.mcap'), str(one / 'two.mcap'))
    info['relative_file_paths'].append('two.mcap')
    info['files'] += more['files']
    info['message_count'] += more['message_count']
    for entry, other in zip(info['topics_with_message_count'], more['topics_with_message_count']):
        entry['message_count'] += other['message_count']
    (one / 'metadata.yaml').write_text(yaml.safe_dump({'rosbag2_bagfile_information': info}))
    reader, messages = _read(one)
    assert [m for m in messages if m[0] == '/chatter'] == EXPECTED[1:]
    assert reader.topics()['/latched'].count == 2 and reader.info()['messages'] == 8


def test_a_compressed_file_that_is_not_zstd_is_refused_in_one_line(tmp_path):
    path = write(tmp_path / 'bag', 9, CompressionMode.FILE)
    (zstd_file,) = path.glob('*.mcap.zstd')
    zstd_file.write_bytes(b'not zstd at all')
    with pytest.raises(BagReadError, match='does not decompress as zstd') as err:
        _read(path)
    assert '\n' not in str(err.value)
