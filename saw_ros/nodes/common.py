"""What every saw_ros node shares: the main() shape, signal handling and QoS profiles.

main() follows ros2/demos: init, build the node, spin, and on SIGINT/SIGTERM or an external
shutdown destroy the node and exit 0 without a traceback. A node that must exit with an error
(a diverging simulation) raises ``NodeFailure``: its message is logged and the exit code is 1.
"""
from __future__ import annotations

import signal
import sys
from typing import Callable, Optional

from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy)

# Every 1 kHz stream must arrive complete (tests and bags count stamps): reliable, and a queue
# deep enough to ride out a subscriber's scheduling hiccup of a few tens of milliseconds.
STREAM_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=200,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)
# /clock as rosgraph expects it from a simulator: reliable, shallow.
CLOCK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
# Camera images: reliable so that recordings and accuracy figures see every frame; 60 Hz of
# 1280x720 images is light next to the 1 kHz streams.
IMAGE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=30,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
# Low-rate reports (comparison, status): late joiners get the last one.
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)


class NodeFailure(RuntimeError):
    """The node cannot go on (the reason is the message): log it and exit with status 1."""


def run_node(make_node: Callable[[], 'object'], args=None,
             spin: Optional[Callable[[object], None]] = None) -> int:
    """Build and spin a node until Ctrl-C, SIGTERM, shutdown or NodeFailure; return exit code."""
    import rclpy
    from rclpy.executors import ExternalShutdownException

    rclpy.init(args=args)
    # SIGTERM (kill, systemd, our own supervisor) stops the node like Ctrl-C does.
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    node = None
    code = 0
    try:
        node = make_node()
        if spin is not None:
            spin(node)
        else:
            rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except NodeFailure as exc:
        logger = node.get_logger() if node is not None else rclpy.logging.get_logger('saw_ros')
        logger.fatal(str(exc))
        code = 1
    finally:
        if node is not None:
            close = getattr(node, 'close', None)
            if close is not None:
                close()
            node.destroy_node()
        rclpy.try_shutdown()
    return code


def exit_with(code: int) -> None:
    sys.exit(code)
