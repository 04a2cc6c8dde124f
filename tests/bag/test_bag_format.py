"""Bag files as rosbag2 writes them, checked with independent readers (mcap, mcap_ros2)."""
import json
import os
import stat

from mcap.reader import make_reader
from mcap_ros2._dynamic import serialize_dynamic
from mcap_ros2.decoder import DecoderFactory
import pytest
from saw_ros.bag import BagExistsError, BagReader, BagWriteError, BagWriter, qos_profile_dict
from saw_ros.bag.schema import message_definition, type_hash
from saw_ros.interface.share import share_file
import yaml

POSE = 'geometry_msgs/msg/PoseStamped'
DELIM = '=' * 80 + '\n'


def share(pkg, name):
    # Installed files found beside the Python package: a colcon test without underlay has only
    # the workspace in AMENT_PREFIX_PATH (test_no_ament_env checks the lookup itself).
    with open(share_file(pkg, 'msg', name), newline='') as f:
        return f.read()


def encoder(type_name):
    return serialize_dynamic(type_name, message_definition(type_name))[type_name]


def pose_bytes(i):
    return encoder(POSE)({'header': {'stamp': {'sec': i // 1000, 'nanosec': (i % 1000) * 10**6},
                                     'frame_id': 'world'},
                          'pose': {'position': {'x': i * 0.001, 'y': 0.0, 'z': 0.0},
                                   'orientation': {'x': 0.0, 'y': 0.0, 'z': 0.0, 'w': 1.0}}})


def test_schema_text_is_rosbag2s_depth_first_concatenation():
    expected = (share('geometry_msgs', 'PoseStamped.msg')
                + '\n' + DELIM + 'MSG: geometry_msgs/Pose\n' + share('geometry_msgs', 'Pose.msg')
                + '\n' + DELIM + 'MSG: geometry_msgs/Point\n' + share('geometry_msgs', 'Point.msg')
                + '\n' + DELIM + 'MSG: geometry_msgs/Quaternion\n'
                + share('geometry_msgs', 'Quaternion.msg')
                + '\n' + DELIM + 'MSG: std_msgs/Header\n' + share('std_msgs', 'Header.msg')
                + '\n' + DELIM + 'MSG: builtin_interfaces/Time\n'
                + share('builtin_interfaces', 'Time.msg'))
    assert message_definition(POSE) == expected
    # A type without dependencies is its .msg text alone.
    assert message_definition('std_msgs/msg/String') == share('std_msgs', 'String.msg')


def test_type_hash_is_the_installed_json_hash():
    path = share_file('geometry_msgs', 'msg', 'PoseStamped.json')
    with open(path) as f:
        assert type_hash(POSE) == json.load(f)['type_hashes'][0]['hash_string']
    assert type_hash(POSE).startswith('RIHS01_')


def write_bag(directory, n=300, chunk_size=4096, close=True, **options):
    bag = BagWriter(str(directory), chunk_size=chunk_size, **options)
    bag.add_topic('/saw/pose', POSE, [qos_profile_dict(reliability='reliable')])
    bag.add_topic('/clock', 'rosgraph_msgs/msg/Clock', [qos_profile_dict()])
    clock = encoder('rosgraph_msgs/msg/Clock')
    t0 = 1_700_000_000_000_000_000
    for i in range(n):
        bag.write('/clock', clock({'clock': {'sec': i // 1000, 'nanosec': (i % 1000) * 10**6}}),
                  t0 + i * 10**6, t0 + i * 10**6 - 1000)
        bag.write('/saw/pose', pose_bytes(i), t0 + i * 10**6 + 10, t0 + i * 10**6 - 500)
    if close:
        bag.close()
        bag.close()  # idempotent
    return bag, t0


def test_round_trip_read_by_mcap_and_mcap_ros2(tmp_path):
    _, t0 = write_bag(tmp_path / 'run')
    files = sorted(os.listdir(tmp_path / 'run'))
    assert files == ['metadata.yaml', 'run_0.mcap']
    with open(tmp_path / 'run' / 'run_0.mcap', 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        assert summary.statistics.message_count == 600
        assert summary.statistics.chunk_count > 1
        assert {c.compression for c in summary.chunk_indexes} == {'zstd'}
        schemas = {s.name: s for s in summary.schemas.values()}
        assert schemas[POSE].encoding == 'ros2msg'
        assert schemas[POSE].data.decode() == message_definition(POSE)
        channels = {c.topic: c for c in summary.channels.values()}
        pose = channels['/saw/pose']
        assert pose.message_encoding == 'cdr'
        assert pose.metadata['topic_type_hash'] == type_hash(POSE)
        qos = yaml.safe_load(pose.metadata['offered_qos_profiles'])
        assert qos[0]['reliability'] == 'reliable'
        assert qos[0]['deadline'] == {'sec': 9223372036, 'nsec': 854775807}
        meta = [m for m in reader.iter_metadata() if m.name == 'rosbag2']
        assert len(meta) == 1
        inner = yaml.safe_load(meta[0].metadata['serialized_metadata'])
        assert inner['version'] == 9 and inner['message_count'] == 600
        xs = []
        for schema, channel, message, decoded in reader.iter_decoded_messages(
                topics=['/saw/pose']):
            xs.append(decoded.pose.position.x)
            assert message.publish_time == message.log_time - 510
        assert xs == pytest.approx([i * 0.001 for i in range(300)])
    # metadata.yaml, version 9
    with open(tmp_path / 'run' / 'metadata.yaml') as f:
        info = yaml.safe_load(f)['rosbag2_bagfile_information']
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    assert info['message_count'] == 600
    assert info['starting_time']['nanoseconds_since_epoch'] == t0
    assert info['duration']['nanoseconds'] == 299 * 10**6 + 10
    assert info['relative_file_paths'] == ['run_0.mcap']
    assert info['files'][0]['message_count'] == 600
    assert info['ros_distro'] == 'jazzy' and info['custom_data'] is None
    topics = {t['topic_metadata']['name']: t for t in info['topics_with_message_count']}
    assert topics['/saw/pose']['message_count'] == 300
    assert topics['/saw/pose']['topic_metadata']['type'] == POSE
    assert topics['/saw/pose']['topic_metadata']['type_description_hash'] == type_hash(POSE)
    assert isinstance(topics['/saw/pose']['topic_metadata']['offered_qos_profiles'], list)
    # our reader agrees
    ours = BagReader(str(tmp_path / 'run'))
    assert [m.data for m in ours.messages(['/saw/pose'])] == [pose_bytes(i) for i in range(300)]
    assert ours.complete and ours.info()['messages'] == 600


def test_unfinished_file_keeps_its_complete_chunks(tmp_path):
    # as after kill -9 (a 20 ms reorder window: the default 0.5 s would hold half of this 1 s)
    bag, _ = write_bag(tmp_path / 'killed', n=1000, close=False, reorder_window_ns=20_000_000)
    path = tmp_path / 'killed' / 'killed_0.mcap'
    with open(path, 'ab') as f:
        f.write(b'\x06\x40\x00\x00')  # and half a record at the end
    reader = BagReader(str(tmp_path / 'killed'))
    msgs = list(reader.messages(['/saw/pose']))
    assert not reader.complete and not reader.damage
    assert reader.unread_bytes >= 4
    assert 900 < len(msgs) < 1000  # all but the reorder buffer and the last (unflushed) chunk
    assert [m.data for m in msgs] == [pose_bytes(i) for i in range(len(msgs))]


def test_refuses_existing_or_unwritable_output(tmp_path):
    (tmp_path / 'exists').mkdir()
    (tmp_path / 'exists' / 'keep.txt').write_text('mine')
    with pytest.raises(BagExistsError):
        BagWriter(str(tmp_path / 'exists'))
    assert os.listdir(tmp_path / 'exists') == ['keep.txt']
    (tmp_path / 'file.txt').write_text('not a directory')
    with pytest.raises(BagWriteError):
        BagWriter(str(tmp_path / 'file.txt' / 'run'))
    locked = tmp_path / 'locked'
    locked.mkdir()
    locked.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        if os.access(locked, os.W_OK):
            pytest.skip('running as a user who may write anywhere (root)')
        with pytest.raises(BagWriteError):
            BagWriter(str(locked / 'run'))
        assert os.listdir(locked) == []
    finally:
        locked.chmod(stat.S_IRWXU)
