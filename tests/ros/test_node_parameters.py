"""
Start-up refusals and run-time parameter changes of the comparison, recorder and player nodes.

Invalid values end the node at start with one line of reason (exit 1, no traceback); parameters
read only at start are read-only, so `ros2 param set` is refused with the reason while the node
runs on.
"""
import os
import signal
import sys

import pytest

from saw_ros.graph.process import ManagedProcess, node_command, wait_for
from saw_ros.interface import topics as table

pytestmark = pytest.mark.ros


def start(tmp_path, name, **params):
    return ManagedProcess(name, node_command(name, params=params), os.environ, tmp_path / 'logs')


def refused_at_start(proc, *texts):
    """Return the node exits 1 with a one-line reason containing ``texts`` and no traceback."""
    assert proc.wait(30) == 1, proc.output()
    out = proc.output()
    assert 'Traceback' not in out, out
    for text in texts:
        assert text in out, out
    return out


class ParameterClient:
    """set_parameters / get_parameters on another node, from the test's own node."""

    def __init__(self, context, target):
        from rcl_interfaces.srv import GetParameters, SetParameters
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        self.node = Node('parameter_test_client', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.set_client = self.node.create_client(SetParameters, f'/{target}/set_parameters')
        self.get_client = self.node.create_client(GetParameters, f'/{target}/get_parameters')

    def _call(self, client, request):
        assert wait_for(client.service_is_ready, 30, spin=self.spin)
        # service_is_ready says the request can reach the server, not that its reply can reach
        # us (the reply's writer may match our reader later; a reply sent before is lost, a
        # known DDS race of ROS 2 services). Asking again is what a client does then; the
        # requests here are idempotent (get, or a set the node refuses).
        for _ in range(6):
            future = client.call_async(request)
            if wait_for(future.done, 5, spin=self.spin):
                return future.result()
            client.remove_pending_request(future)
        raise AssertionError(f'no reply from {client.srv_name} in 6 tries of 5 s')

    def spin(self, t):
        self.executor.spin_once(timeout_sec=t)

    def set(self, name, value):  # noqa: A003
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter
        request = SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()])
        return self._call(self.set_client, request).results[0]

    def get(self, name):
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import parameter_value_to_python
        values = self._call(self.get_client, GetParameters.Request(names=[name])).values
        return parameter_value_to_python(values[0])

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()


def assert_read_only(client, proc, name, value):
    before = client.get(name)
    result = client.set(name, value)
    assert not result.successful
    assert 'read-only' in result.reason and name in result.reason, result.reason
    assert client.get(name) == before
    assert proc.returncode is None, proc.output()       # runs on


# -- comparison ------------------------------------------------------------------------------
@pytest.mark.parametrize('content, expected', [
    (None, 'does not exist'),
    ('a,b\n1,2\n', 'needs columns slope_deg, voltage_V'),
    ('slope_deg,voltage_V,speed_cm_s\n0,6,fast\n', 'row 2 is not valid'),
    (b'\xff\xfe\x00\x01', 'is not a reference CSV'),
])
def test_comparison_refuses_a_missing_or_unreadable_reference_file(tmp_path, content, expected):
    path = tmp_path / 'reference.csv'
    if isinstance(content, str):
        path.write_text(content)
    elif isinstance(content, bytes):
        path.write_bytes(content)
    out = refused_at_start(start(tmp_path, 'comparison', reference_file=str(path)),
                           'invalid parameters: reference_file', str(path), expected,
                           'leave reference_file out')
    assert len([line for line in out.splitlines() if line.strip()]) == 1, out


def test_comparison_refuses_non_positive_periods_at_start(tmp_path):
    refused_at_start(start(tmp_path, 'comparison', report_period=0.0),
                     'report_period = 0 is out of range: allowed (0, inf) s')
    # an integer for a double is taken as the double, and checked as one
    refused_at_start(start(tmp_path, 'comparison', steady_threshold=-1),
                     'steady_threshold = -1 is out of range: allowed (0, inf)')


def test_comparison_start_up_parameters_are_read_only_and_live_ones_validated(
        tmp_path, ros_context):
    proc = start(tmp_path, 'comparison', reference_file='msg_config/reference_paper.csv')
    client = ParameterClient(ros_context, 'comparison')
    try:
        assert_read_only(client, proc, 'steady_threshold', 0.5)
        assert_read_only(client, proc, 'report_period', 0.1)
        assert_read_only(client, proc, 'reference_file', '/nonexistent.csv')
        assert_read_only(client, proc, 'simulator_node', 'other')
        bad = client.set('idle_timeout', -1.0)
        assert not bad.successful and 'idle_timeout = -1 is out of range' in bad.reason, \
            bad.reason
        assert client.set('idle_timeout', 3.0).successful
        assert client.get('idle_timeout') == 3.0
        assert proc.returncode is None, proc.output()
    finally:
        client.close()
        code = proc.stop()
    assert code == 0, proc.output()
    assert 'Traceback' not in proc.output()


# -- recorder --------------------------------------------------------------------------------
def test_recorder_parameters_are_read_only(tmp_path, ros_context):
    proc = start(tmp_path, 'recorder', output=str(tmp_path / 'bag'))
    client = ParameterClient(ros_context, 'recorder')
    try:
        assert wait_for(lambda: 'recording to' in proc.output(), 30), proc.output()
        for name, value in (('queue_depth', 5), ('topics', ['/other']), ('output', '/tmp/x'),
                            ('compression', 'none'), ('exclude_topics', ['']),
                            ('discovery_period', 1.0), ('max_bag_size', 1000),
                            ('max_bag_duration', 1.0)):
            assert_read_only(client, proc, name, value)
    finally:
        client.close()
        code = proc.stop()
    assert code == 0, proc.output()


def test_recorder_refuses_invalid_values_at_start(tmp_path):
    refused_at_start(start(tmp_path, 'recorder', output=str(tmp_path / 'bag'), queue_depth=0),
                     'queue_depth = 0 is out of range: allowed [1, inf)')
    # The split limits: 0 (no limit) is their low end; one below it is refused.
    refused_at_start(start(tmp_path, 'recorder', output=str(tmp_path / 'bag'), max_bag_size=-1),
                     'max_bag_size = -1 is out of range: allowed [0, inf) bytes')
    refused_at_start(start(tmp_path, 'recorder', output=str(tmp_path / 'bag'),
                           max_bag_duration=-0.001),
                     'max_bag_duration = -0.001 is out of range: allowed [0, inf) s')
    assert not (tmp_path / 'bag').exists()


# -- player ----------------------------------------------------------------------------------
def _bag(tmp_path, n=500):
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'bag'))
    from test_bag_format import write_bag
    write_bag(tmp_path / 'src', n=n)      # n ms of /clock + /saw/pose at 1 kHz
    return str(tmp_path / 'src')


@pytest.mark.parametrize('params, expected', [
    ({'clock_rate': 0.0}, 'clock_rate = 0 is out of range: allowed (0, 1e+06] Hz'),
    ({'clock_rate': -5.0}, 'clock_rate = -5 is out of range: allowed (0, 1e+06] Hz'),
    ({'rate': 0.0}, 'rate = 0 is out of range: allowed (0, inf)'),
    ({'rate': 'fast'}, "invalid parameters: rate = 'fast' is invalid: must be a number"),
])
def test_player_refuses_invalid_rates_at_start(tmp_path, params, expected):
    refused_at_start(start(tmp_path, 'player', bag=_bag(tmp_path), **params), expected)


def test_player_parameters_are_read_only_while_playing(tmp_path, ros_context):
    # 0.5 s of bag at rate 0.02: 25 s of playing, stopped by the test.
    proc = start(tmp_path, 'player', bag=_bag(tmp_path), rate=0.02)
    client = ParameterClient(ros_context, 'player')
    try:
        assert wait_for(lambda: 'playing' in proc.output(), 30), proc.output()
        assert_read_only(client, proc, 'rate', 2.0)
        assert_read_only(client, proc, 'clock_rate', 0.0)
        assert 'played' not in proc.output()          # still playing, unchanged
    finally:
        client.close()
        code = proc.stop()
    assert code == 0, proc.output()
    assert 'Traceback' not in proc.output()


@pytest.mark.slow
def test_player_end_does_not_wait_forever_for_a_stalled_subscriber(tmp_path):
    """
    A reliable subscriber that stops acknowledging no longer keeps the player from exiting.

    Here the subscriber is stopped (SIGSTOP): the player waits ACK_TIMEOUT, names the topic,
    exits 0.
    """
    from saw_ros.ros.runtime import FLUSH_TIMEOUT as ACK_TIMEOUT
    listener = start(tmp_path, 'comparison')          # a reliable /saw/pose subscriber
    player = None
    try:
        player = start(tmp_path, 'player', bag=_bag(tmp_path, n=1000), rate=0.5, clock=False,
                       topics=[table.POSE], wait_for_subscribers=1)
        assert wait_for(lambda: 'playing' in player.output(), 30), player.output()
        listener.signal(signal.SIGSTOP)
        assert player.wait(30 + ACK_TIMEOUT) == 0, player.output()
        out = player.output()
        assert 'played 1000 messages' in out, out
        assert 'not acknowledged by every subscriber' in out and table.POSE in out, out
    finally:
        listener.signal(signal.SIGCONT)
        listener.stop()
        if player is not None and player.returncode is None:
            player.stop()
