"""
Readiness from the graph itself.

Each node says on ``/saw/ready`` (saw_ros.interface.topics READY) when it is ready, and a probe
waits for the nodes it is told.

A node's status is a diagnostic_msgs/DiagnosticArray with one DiagnosticStatus: its node name,
level OK, message 'ready' and the key ``ready`` = ``true``, published latched (transient local,
depth 1 per publisher) so that a probe that joins later still gets it. What "ready" means is the
node's: the camera and the comparison once their inputs have a publisher (from then on no input
is missed), vision once it is subscribed and its outputs are offered.

The probe (``python -m saw_ros.ros.ready --nodes camera,comparison,vision [--timeout 20]``) exits
0 once every named node has said ready, 1 on timeout (or when stopped), listing who did not;
``saw_ros.graph.pipeline`` runs it as a process, so the graph layer imports no rclpy.
"""
from __future__ import annotations

import argparse
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from saw_ros.interface.topics import READY
from saw_ros.ros.qos import LATCHED_QOS

READY_KEY = 'ready'


class Readiness:
    """
    The node's publisher on READY (created with the node, so the probe discovers it early).

    ``announce()`` publishes 'ready' once.
    """

    def __init__(self, node):
        self._node = node
        self._pub = node.create_publisher(DiagnosticArray, READY, LATCHED_QOS)
        self.announced = False

    def announce(self) -> None:
        if self.announced:
            return
        self.announced = True
        msg = DiagnosticArray()
        msg.header.stamp = self._node.get_clock().now().to_msg()
        msg.status.append(DiagnosticStatus(level=DiagnosticStatus.OK, name=self._node.get_name(),
                                           message='ready',
                                           values=[KeyValue(key=READY_KEY, value='true')]))
        self._pub.publish(msg)


def ready_nodes(msg: DiagnosticArray):
    """Names of the nodes that a READY message says are ready."""
    return {s.name for s in msg.status if s.level == DiagnosticStatus.OK
            and any(kv.key == READY_KEY and kv.value == 'true' for kv in s.values)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='python -m saw_ros.ros.ready',
                                     description='wait until the named nodes say ready on '
                                                 f'{READY}')
    parser.add_argument('--nodes', required=True, help='comma-separated node names')
    parser.add_argument('--timeout', type=float, default=20.0, help='s (default 20)')
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    wanted = {n for n in args.nodes.split(',') if n}

    import rclpy
    from saw_ros.ros.runtime import make_executor
    rclpy.init(args=[])
    seen = set()
    try:
        node = rclpy.create_node('ready_probe')
        # Transient local so that statuses published before this probe matched arrive too; a
        # queue for every node's status (one history for all publishers of the topic).
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=max(10, 2 * len(wanted)),
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        node.create_subscription(DiagnosticArray, READY,
                                 lambda msg: seen.update(ready_nodes(msg)), qos)
        executor = make_executor(node.context)
        executor.add_node(node)
        until = time.monotonic() + args.timeout
        while rclpy.ok() and not wanted <= seen and time.monotonic() < until:
            executor.spin_once(timeout_sec=0.1)
        node.destroy_node()
    except KeyboardInterrupt:
        pass
    finally:
        if rclpy.ok():
            rclpy.shutdown()
    if wanted <= seen:
        print(f"ready: {', '.join(sorted(wanted))}", flush=True)
        return 0
    print(f"not ready after {args.timeout:g} s: {', '.join(sorted(wanted - seen))}", flush=True)
    return 1


if __name__ == '__main__':
    sys.exit(main())
