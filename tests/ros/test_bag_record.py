"""Recorder and player end to end through real topics in an isolated DDS domain."""
import os
import signal
import sys

import pytest

from saw_ros.bag import BagReader
from saw_ros.bench.loadgen import published_counts
from saw_ros.graph.process import ManagedProcess, node_command, wait_for

pytestmark = [pytest.mark.ros, pytest.mark.slow]
SIM_TOPICS = ['/clock', '/saw/pose', '/saw/twist', '/saw/contacts', '/saw/contact_wrench',
              '/saw/joint_states']


def start_recorder(tmp_path, output, **params):
    params.setdefault('output', str(output))
    return ManagedProcess('recorder', node_command('recorder', params=params), os.environ,
                          tmp_path / 'logs')


def run_loadgen(tmp_path, **params):
    proc = ManagedProcess('loadgen',
                          node_command('loadgen', params=params, package='saw_ros.bench'),
                          os.environ, tmp_path / 'logs')
    assert proc.wait(60) == 0, proc.output()
    return published_counts(proc.output())


def recording(rec):
    return wait_for(lambda: 'recording to' in rec.output(), 20)


def bag_counts(path):
    return {name: t.count for name, t in BagReader(str(path)).topics().items()}


@pytest.mark.parametrize('stop', [signal.SIGTERM, signal.SIGINT])
def test_counts_equal_published_and_signals_finish_the_bag(tmp_path, stop):
    out = tmp_path / 'bag'
    rec = start_recorder(tmp_path, out)
    assert recording(rec), rec.output()
    published = run_loadgen(tmp_path, rate=1000.0, duration=2.0, streams=6)
    rec.signal(stop)
    assert rec.wait(30) == 0, rec.output()
    assert (out / 'metadata.yaml').is_file(), rec.output()
    reader = BagReader(str(out))
    assert bag_counts(out) == published
    assert reader.complete
    assert reader.info()['messages'] == sum(published.values())


def test_images_and_streams_recorded(tmp_path):
    out = tmp_path / 'bag'
    # The raw frames are excluded by default (record_topics.yaml): ask for them.
    rec = start_recorder(tmp_path, out, exclude_topics=[''])
    published = run_loadgen(tmp_path, rate=1000.0, duration=2.0, streams=6, image_fps=60.0,
                            start_delay=1.5)
    assert rec.stop(20) == 0, rec.output()
    # Every message published is in the bag: 1 kHz on the 6 simulator topics plus 60 fps
    # 1280x720 images (loadgen: 1 s publisher histories like the simulator's, images from a
    # participant of their own like the camera's, 2 s of image history; docs/bags.md "Loss").
    assert bag_counts(out) == published


def test_kill_9_leaves_complete_chunks_readable(tmp_path):
    out = tmp_path / 'bag'
    rec = start_recorder(tmp_path, out, chunk_size=16384)
    published = run_loadgen(tmp_path, rate=1000.0, duration=1.0, streams=3)

    def size():
        return os.path.getsize(out / 'bag_0.mcap') if (out / 'bag_0.mcap').exists() else 0
    assert wait_for(lambda: size() > 50_000, 10)
    rec.signal(signal.SIGKILL)
    assert rec.wait(10) == -signal.SIGKILL
    assert not (out / 'metadata.yaml').exists()
    reader = BagReader(str(out))
    msgs = list(reader.messages())
    assert not reader.complete
    assert 0.8 * sum(published.values()) < len(msgs) <= sum(published.values())


def test_refuses_existing_output_without_touching_it(tmp_path):
    out = tmp_path / 'taken'
    out.mkdir()
    (out / 'mine.txt').write_text('keep')
    rec = start_recorder(tmp_path, out)
    assert rec.wait(30) == 1
    assert 'exists already' in rec.output()
    assert os.listdir(out) == ['mine.txt']


def test_player_republishes_with_timing_and_clock(tmp_path, ros_context):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rosgraph_msgs.msg import Clock
    from geometry_msgs.msg import PoseStamped
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'bag'))
    from test_bag_format import write_bag
    write_bag(tmp_path / 'src', n=500)  # 0.5 s of /clock + /saw/pose at 1 kHz
    node = Node('listener', context=ros_context)
    got = {'/saw/pose': [], '/clock': []}
    import time
    node.create_subscription(PoseStamped, '/saw/pose',
                             lambda m: got['/saw/pose'].append(time.monotonic()), 1000)
    node.create_subscription(Clock, '/clock', lambda m: got['/clock'].append(m.clock), 1000)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    player = ManagedProcess('player', node_command('player', params={
        'bag': str(tmp_path / 'src'), 'rate': 0.5, 'wait_for_subscribers': 2}), os.environ,
        tmp_path / 'logs')
    assert wait_for(lambda: player.returncode is not None and len(got['/saw/pose']) >= 500,
                    30, spin=lambda t: ex.spin_once(timeout_sec=t)), player.output()
    assert player.wait(10) == 0, player.output()
    assert len(got['/saw/pose']) == 500 and len(got['/clock']) == 500
    span = got['/saw/pose'][-1] - got['/saw/pose'][0]
    # 0.499 s of bag at rate 0.5: about 1 s; the bound above allows the receipt times of a test
    # process that a loaded machine (two CPU hogs beside the suite) delays by up to a second.
    assert 0.8 < span < 2.5
    assert got['/clock'][-1].nanosec == 499 * 10**6
    ex.shutdown()
    node.destroy_node()
