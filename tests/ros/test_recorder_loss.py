"""
The recorder says what it lost.

Per topic, from gaps in the publication sequence numbers, in its final line and in metadata.yaml's
custom_data.
"""
import json
import os
import re
import signal

import pytest
from saw_ros.bag import BagReader
from saw_ros.bench.loadgen import published_counts
from saw_ros.graph.process import ManagedProcess, node_command, wait_for
from saw_ros.ros.nodes.recorder import LossCounter
import yaml


def test_loss_counter_counts_gaps_per_publisher():
    c = LossCounter()
    for s in (1, 2, 3, 6, 7, 10):            # 4, 5, 8, 9 lost
        c.add('/a', s)
    for s in (5, 6, 9):                      # first seen at 5: 1-4 lost at the start; 7, 8
        c.add('/b', s)
    c.add('/b', 0)                           # no sequence number: not counted
    assert c.lost == {'/a': 4, '/b': 6} and c.at_start == {'/a': 0, '/b': 4}
    assert c.text() == 'lost 10 (/a: 4, /b: 6), 4 of them at the start (/b: 4)'
    # Two publishers on one topic, numbered independently and interleaved.
    c = LossCounter()
    for s in (100, 1, 101, 2, 103, 3, 104, 5):   # 1-99 at the start, 102 and 4 lost
        c.add('/c', s)
    assert c.lost == {'/c': 101} and c.at_start == {'/c': 99}
    assert LossCounter().text() == 'lost 0'
    # A latched topic's late subscriber gets the last message by design: no loss at the start.
    c = LossCounter()
    c.latched.add('/l')
    for s in (7, 8, 10):
        c.add('/l', s)
    assert c.lost == {'/l': 1} and c.at_start == {'/l': 0}


def _record(tmp_path, rec_params, gen_params):
    out = tmp_path / 'bag'
    rec = ManagedProcess('recorder', node_command('recorder', params=dict(
        output=str(out), **rec_params)), os.environ, tmp_path / 'logs')
    assert wait_for(lambda: 'recording to' in rec.output(), 30), rec.output()
    gen = ManagedProcess('loadgen',
                         node_command('loadgen', params=gen_params, package='saw_ros.bench'),
                         os.environ, tmp_path / 'logs')
    assert gen.wait(90) == 0, gen.output()
    rec.signal(signal.SIGINT)
    assert rec.wait(30) == 0, rec.output()
    final = [line for line in rec.output().splitlines() if 'finished:' in line]
    assert len(final) == 1, rec.output()
    meta = yaml.safe_load((out / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    lost = json.loads(meta['custom_data']['saw_ros.lost_messages'])
    published = published_counts(gen.output())
    return final[0], lost, published, BagReader(str(out))


@pytest.mark.ros
def test_recorder_reports_zero_loss(tmp_path):
    final, lost, published, reader = _record(
        tmp_path, {}, {'rate': 200.0, 'duration': 1.0, 'streams': 2})
    counts = {n: t.count for n, t in reader.topics().items()}
    assert counts == published
    assert final.endswith('; lost 0'), final
    assert lost == dict.fromkeys(published, 0)


@pytest.mark.ros
@pytest.mark.slow
def test_recorder_that_cannot_keep_up_reports_its_loss_per_topic(tmp_path):
    # A one-message subscription queue against 6 x 3 kHz: messages are overwritten before the
    # recorder takes them.
    final, lost, published, reader = _record(
        tmp_path, {'queue_depth': 1}, {'rate': 3000.0, 'duration': 1.0, 'streams': 6})
    assert sum(lost.values()) > 0, final
    seqs = {}
    for m in reader.messages():
        seqs.setdefault(m.topic, []).append(m.sequence)
    for topic, s in seqs.items():
        # what arrived + what was lost = every number from 1 to the last received
        assert len(s) + lost[topic] == s[-1], (topic, len(s), lost[topic])
        assert s[-1] <= published[topic]
    match = re.search(r'; lost (\d+) \(([^)]*)\)(, \d+ of them at the start \(.*\))?$', final)
    assert match, final
    assert int(match.group(1)) == sum(lost.values())
    reported = dict(part.rsplit(': ', 1) for part in match.group(2).split(', '))
    assert {t: int(n) for t, n in reported.items()} == {t: n for t, n in lost.items() if n}


@pytest.mark.ros
def test_recorder_reports_what_was_published_before_it_matched(tmp_path, ros_context):
    # The publisher runs before the recorder exists: its first messages cannot be in the bag,
    # and the recorder says how many from the first sequence number it receives.
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rosgraph_msgs.msg import Clock
    gen = ManagedProcess('loadgen', node_command('loadgen', params={
        'rate': 500.0, 'duration': 6.0, 'streams': 2, 'wait_subscribers': 0},
        package='saw_ros.bench'), os.environ, tmp_path / 'logs')
    node = Node('probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    heard = []
    node.create_subscription(Clock, '/clock', heard.append, 10)
    assert wait_for(lambda: heard, 30, spin=lambda t: executor.spin_once(timeout_sec=t)), \
        gen.output()
    out = tmp_path / 'bag'
    rec = ManagedProcess('recorder', node_command('recorder', params={'output': str(out)}),
                         os.environ, tmp_path / 'logs')
    assert gen.wait(90) == 0, gen.output()
    rec.signal(signal.SIGINT)
    assert rec.wait(30) == 0, rec.output()
    published = published_counts(gen.output())
    meta = yaml.safe_load((out / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    lost = json.loads(meta['custom_data']['saw_ros.lost_messages'])
    at_start = json.loads(meta['custom_data']['saw_ros.lost_at_start'])
    first, counts = {}, {}
    for m in BagReader(str(out)).messages():
        first.setdefault(m.topic, m.sequence)
        counts[m.topic] = counts.get(m.topic, 0) + 1
    assert set(first) == set(published), (first, published)
    for topic, n in published.items():
        assert at_start[topic] == first[topic] - 1 >= 1, (topic, first, at_start)
        assert counts[topic] + lost[topic] == n, (topic, counts, lost, n)
    final = [line for line in rec.output().splitlines() if 'finished:' in line][0]
    assert f', {sum(at_start.values())} of them at the start (' in final, final
    assert 'published before the subscriptions matched' in rec.output()
    node.destroy_node()


def test_close_records_what_the_subscriptions_still_hold(tmp_path, ros_context):
    """
    The messages that came after the executor's last round are written at close, not dropped.

    The recorder is never spun here: every message is still in its subscription's queue when
    ``close`` drains it (that drain took nothing before: the handle's ``with`` gives None).
    """
    from rclpy.duration import Duration
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from saw_ros.ros.nodes.recorder import Recorder
    from std_msgs.msg import String
    topic = '/saw/drain_check'
    talker = Node('drain_talker', context=ros_context)
    publisher = talker.create_publisher(
        String, topic, QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    recorder = Recorder(context=ros_context, parameter_overrides=[
        Parameter('output', value=str(tmp_path / 'bag')), Parameter('topics', value=[topic])])
    try:
        # Discovery by hand (its timer is the executor's): subscribed once the topic is seen.
        assert wait_for(lambda: recorder._discover() or (
            recorder._subs.get(topic) and publisher.get_subscription_count() > 0), 20)
        for i in range(20):
            publisher.publish(String(data=str(i)))
        assert publisher.wait_for_all_acked(Duration(seconds=20))
        recorder.close()
    finally:
        recorder.destroy_node()
        talker.destroy_node()
    got = [m.data for _, m in BagReader(str(tmp_path / 'bag')).decoded_messages([topic])]
    assert got == [str(i) for i in range(20)]
    meta = yaml.safe_load((tmp_path / 'bag' / 'metadata.yaml').read_text())
    assert json.loads(meta['rosbag2_bagfile_information']['custom_data'][
        'saw_ros.lost_messages']) == {topic: 0}
