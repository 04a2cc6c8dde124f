"""
The player's ``ros2 bag play`` features through real topics and services.

loop, start_offset, remapping, start_paused, and the pause / resume / toggle_paused / is_paused /
play_next services. The bags are tests/bag/test_bag_format.write_bag's: /clock and /saw/pose at
1 kHz, pose i stamped i ms. The player runs as a subprocess in the run's isolated DDS domain.
"""
import os
import sys
import time

import pytest

from saw_ros.graph.process import ManagedProcess, node_command, wait_for

pytestmark = [pytest.mark.ros]

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'bag'))
from test_bag_format import write_bag  # noqa: E402, I100


class Listener:
    """Poses received on a topic (their stamps in ms), and Trigger calls to the player."""

    def __init__(self, context, *topics):
        from geometry_msgs.msg import PoseStamped
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        self.node = Node('player_listener', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.got = {t: [] for t in topics}
        for t in topics:
            self.node.create_subscription(
                PoseStamped, t, lambda m, t=t: self.got[t].append(
                    m.header.stamp.sec * 1000 + m.header.stamp.nanosec // 10**6), 1000)

    def spin(self, timeout):
        self.executor.spin_once(timeout_sec=timeout)

    def wait(self, condition, timeout=20.0):
        return wait_for(condition, timeout, spin=self.spin)

    def quiet_for(self, quiet_s, timeout):
        """Wait until ``quiet_s`` pass with no message on any topic; False after ``timeout``."""
        counts = [sum(len(v) for v in self.got.values())]
        last_change = [time.monotonic()]

        def settled():
            n = sum(len(v) for v in self.got.values())
            if n != counts[0]:
                counts[0], last_change[0] = n, time.monotonic()
            return time.monotonic() - last_change[0] >= quiet_s
        return self.wait(settled, timeout)

    def call(self, service):
        from std_srvs.srv import Trigger
        client = self.node.create_client(Trigger, f'/player/{service}')
        try:
            assert client.wait_for_service(timeout_sec=20.0), f'no /player/{service}'
            future = client.call_async(Trigger.Request())
            assert self.wait(future.done, 10.0), f'/player/{service}: no answer'
            return future.result()
        finally:
            self.node.destroy_client(client)

    def close(self):
        self.executor.shutdown(timeout_sec=1)
        self.node.destroy_node()


def start_player(tmp_path, *ros_args, **params):
    return ManagedProcess('player', node_command('player', *ros_args, params=params),
                          os.environ, tmp_path / 'logs')


def test_loop_from_a_start_offset_onto_a_remapped_topic(tmp_path, ros_context):
    write_bag(tmp_path / 'bag', n=200)
    listener = Listener(ros_context, '/replay/pose', '/saw/pose')
    player = start_player(tmp_path, '-r', '/saw/pose:=/replay/pose', bag=str(tmp_path / 'bag'),
                          topics=['/saw/pose'], clock=False, loop=True, start_offset=0.1,
                          wait_for_subscribers=1)
    try:
        got = listener.got['/replay/pose']
        assert listener.wait(lambda: len(got) >= 250, 30.0), (len(got), player.output())
    finally:
        assert player.stop(timeout=10) == 0, player.output()
        listener.close()
    # From 100 ms into the bag (pose 100), to its end (199), then again from 100: twice at least.
    assert got[:200] == list(range(100, 200)) * 2, got[:5]
    assert got[200:250] == list(range(100, 150))
    assert listener.got['/saw/pose'] == []            # remapped: nothing on the recorded name
    assert 'looping' in player.output() and 'from 0.1 s' in player.output()


def test_start_paused_then_step_resume_pause_and_toggle(tmp_path, ros_context):
    write_bag(tmp_path / 'bag', n=50)
    listener = Listener(ros_context, '/saw/pose')
    got = listener.got['/saw/pose']
    # rate 0.05: the 50 ms bag plays in 1 s, long enough to pause it half-way.
    player = start_player(tmp_path, bag=str(tmp_path / 'bag'), topics=['/saw/pose'],
                          clock=False, rate=0.05, start_paused=True, wait_for_subscribers=1)
    try:
        assert listener.call('is_paused').message == 'paused'
        assert not listener.wait(lambda: got, 0.5), 'played while paused'
        for i in range(3):
            answer = listener.call('play_next')
            assert answer.success and answer.message == 'published a message on /saw/pose'
            assert listener.wait(lambda: len(got) == i + 1, 10.0), got
        assert got == [0, 1, 2]
        assert listener.call('resume').message == 'playing'
        answer = listener.call('play_next')
        assert not answer.success and answer.message.startswith('not paused')
        assert listener.wait(lambda: len(got) >= 10, 10.0), got
        assert listener.call('pause').message == 'paused'
        # What the player published before it paused may still be on its way (a busy machine
        # delivered one 0.26 s late): wait until 0.3 s pass without one, then nothing more may
        # come. Playing, 0.8 s would have brought 40.
        settled = listener.quiet_for(0.3, 10.0)
        assert settled, ('still receiving 10 s after the pause', got)
        held = len(got)
        assert not listener.wait(lambda: len(got) > held, 0.5), 'played on while paused'
        held = len(got)
        assert listener.call('play_next').success
        assert listener.wait(lambda: len(got) == held + 1, 10.0)
        assert listener.call('toggle_paused').message == 'playing'
        assert listener.wait(lambda: player.returncode is not None, 20.0), player.output()
        assert player.returncode == 0, player.output()
        listener.wait(lambda: len(got) == 50, 5.0)
    finally:
        player.stop(timeout=10)
        listener.close()
    assert got == list(range(50))        # every message once, in order, whatever the pauses
