"""saw_ros.ros.ready: what a node's status on /saw/ready says, read back as the probe reads it."""
import pytest

pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue  # noqa: E402, I100
from saw_ros.ros.ready import main, READY_KEY, ready_nodes  # noqa: E402


def status(name, level=DiagnosticStatus.OK, value='true'):
    return DiagnosticStatus(level=level, name=name, message='ready',
                            values=[KeyValue(key=READY_KEY, value=value)])


def test_ready_nodes_takes_ok_statuses_with_ready_true():
    msg = DiagnosticArray(status=[status('camera'), status('vision', DiagnosticStatus.WARN),
                                  status('comparison', value='false')])
    assert ready_nodes(msg) == {'camera'}


def test_probe_without_nodes_is_a_usage_error():
    with pytest.raises(SystemExit) as exc:
        main([])
    assert exc.value.code == 2
