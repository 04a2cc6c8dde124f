"""saw_ros.ros.guard: what a guarded callback does with a message it refuses, in one process."""
import pytest
from saw_ros.interface.message_checks import Refused

pytestmark = pytest.mark.ros


def test_refusals_are_counted_warned_once_and_reported(ros_context, capfd):
    """Refused and unreadable messages: counted, one warning a topic; NodeFailure goes through."""
    from diagnostic_msgs.msg import DiagnosticStatus
    from rclpy.node import Node
    from saw_ros.ros.guard import InputGuard
    from saw_ros.ros.runtime import NodeFailure

    node = Node('guarded', context=ros_context)
    guard = InputGuard(node)
    taken = []

    def callback(msg):
        if msg == 'nan':
            raise Refused('not finite', 'x has nan')
        if msg == 'short':
            raise ValueError('buffer too short')      # what a parser raises: 'unreadable'
        if msg == 'stop':
            raise NodeFailure('the node decided to stop')
        taken.append(msg)

    on_message = guard.guarded('/in', callback)
    try:
        assert guard.status().level == DiagnosticStatus.OK and guard.refused == 0
        for msg in ('ok', 'nan', 'nan', 'short', 'nan', 'ok'):
            on_message(msg)
        assert taken == ['ok', 'ok']
        assert guard.counts == {('/in', 'not finite'): 3, ('/in', 'unreadable'): 1}
        status = guard.status()
        assert status.level == DiagnosticStatus.WARN and status.name == 'guarded: inputs'
        assert status.message == '4 messages refused'
        assert {kv.key: kv.value for kv in status.values} == {'/in: not finite': '3',
                                                              '/in: unreadable': '1'}
        with pytest.raises(NodeFailure):
            on_message('stop')
        guard.refuse('/other', 'empty image', '0x720')      # another topic: its own warning
    finally:
        node.destroy_node()
    err = capfd.readouterr().err
    assert err.count('message on /in refused') == 1, err          # throttled: 4 refused, 1 said
    assert 'message on /in refused, not used: not finite: x has nan' in err
    assert 'message on /other refused, not used: empty image: 0x720' in err
    assert 'Traceback' not in err
