"""
The recorder splits its bag (max_bag_duration, max_bag_size) and the player plays it as one.

Through real topics in the run's isolated DDS domain: nothing lost or repeated at the seams
(every topic's publication sequence numbers consecutive across files), a recorder killed with
SIGKILL in its second file read and repaired, a split bag played in order across its files.
"""
import os
import signal
import sys

from mcap.reader import make_reader
import pytest
from saw_ros.bag import BagReader
from saw_ros.bag.reindex import reindex
from saw_ros.bench.loadgen import published_counts
from saw_ros.graph.process import ManagedProcess, node_command, wait_for
import yaml

pytestmark = [pytest.mark.ros]

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'bag'))
from test_bag_format import write_bag  # noqa: E402, I100


def start_recorder(tmp_path, output, **params):
    return ManagedProcess('recorder', node_command('recorder', params=dict(
        output=str(output), **params)), os.environ, tmp_path / 'logs')


def loadgen(tmp_path, **params):
    return ManagedProcess('loadgen', node_command('loadgen', params=params,
                                                  package='saw_ros.bench'),
                          os.environ, tmp_path / 'logs')


def sequences(directory):
    """Per topic, the publication sequence numbers in the bag, in bag order."""
    out = {}
    for m in BagReader(str(directory)).messages():
        out.setdefault(m.topic, []).append(m.sequence)
    return out


def assert_consecutive(numbers):
    for topic, seq in numbers.items():
        assert seq == list(range(seq[0], seq[0] + len(seq))), topic


def test_recorder_splits_by_duration_and_loses_nothing_at_the_seams(tmp_path):
    out = tmp_path / 'bag'
    rec = start_recorder(tmp_path, out, max_bag_duration=0.4)
    assert wait_for(lambda: 'recording to' in rec.output(), 20), rec.output()
    gen = loadgen(tmp_path, rate=1000.0, duration=1.5, streams=3)
    assert gen.wait(60) == 0, gen.output()
    assert rec.stop(20) == 0, rec.output()
    meta = yaml.safe_load((out / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    names = meta['relative_file_paths']
    assert len(names) >= 4 and names == [f'bag_{i}.mcap' for i in range(len(names))]
    for name, entry in zip(names, meta['files']):
        with open(out / name, 'rb') as f:
            summary = make_reader(f).get_summary()
        assert summary.statistics.message_count == entry['message_count'] > 0
        assert entry['duration']['nanoseconds'] <= 400_000_000
    numbers = sequences(out)
    published = published_counts(gen.output())
    assert {t: len(s) for t, s in numbers.items() if t in published} == published
    assert_consecutive(numbers)


def test_recorder_killed_in_its_second_file_is_repaired(tmp_path):
    out = tmp_path / 'bag'
    rec = start_recorder(tmp_path, out, max_bag_size=30_000, chunk_size=8192)
    assert wait_for(lambda: 'recording to' in rec.output(), 20), rec.output()
    gen = loadgen(tmp_path, rate=1000.0, duration=3.0, streams=3)
    second = out / 'bag_1.mcap'
    assert wait_for(lambda: second.exists() and second.stat().st_size > 0, 30), rec.output()
    rec.signal(signal.SIGKILL)
    assert rec.wait(10) == -signal.SIGKILL
    gen.stop(10)
    assert not (out / 'metadata.yaml').exists()
    before = sequences(out)
    assert_consecutive(before)
    result = reindex(str(out))
    assert result.kept and all(k.endswith('.mcap.unfinished') for k in result.kept)
    assert 'bag_0.mcap.unfinished' not in result.kept     # finished before the kill
    assert sequences(out) == before
    reader = BagReader(str(out))
    assert reader.info()['complete'] and reader.metadata is not None
    assert reader.metadata['relative_file_paths'][:2] == ['bag_0.mcap', 'bag_1.mcap']


def test_player_plays_a_split_bag_across_its_files(tmp_path, ros_context):
    from geometry_msgs.msg import PoseStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    bag, _ = write_bag(tmp_path / 'split', n=500, max_bag_duration_ns=100_000_000)
    assert len(bag.files) == 5
    node = Node('split_listener', context=ros_context)
    got = []
    node.create_subscription(PoseStamped, '/saw/pose', lambda m: got.append(
        m.header.stamp.sec * 1000 + m.header.stamp.nanosec // 10**6), 1000)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    player = ManagedProcess('player', node_command('player', params={
        'bag': str(tmp_path / 'split'), 'rate': 2.0, 'wait_for_subscribers': 1}), os.environ,
        tmp_path / 'logs')
    try:
        assert wait_for(lambda: player.returncode is not None and len(got) >= 500, 30,
                        spin=lambda t: executor.spin_once(timeout_sec=t)), player.output()
        assert player.wait(10) == 0, player.output()
    finally:
        player.stop(10)
        executor.shutdown()
        node.destroy_node()
    assert got == list(range(500))
