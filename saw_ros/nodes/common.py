"""What every saw_ros node shares: the main() shape, signal handling and QoS profiles.

main() follows ros2/demos: init, build the node, spin, and on SIGINT/SIGTERM or an external
shutdown destroy the node and exit 0 without a traceback. A node that must exit with an error
(a diverging simulation) raises ``NodeFailure``: its message is logged and the exit code is 1.
"""
from __future__ import annotations

import signal
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


def with_depth(qos: QoSProfile, depth: int) -> QoSProfile:
    """``qos`` with another history depth: the same contract (depth does not take part in QoS
    matching), a longer queue on this side."""
    return QoSProfile(history=qos.history, depth=depth, reliability=qos.reliability,
                      durability=qos.durability)


# A subscriber of the 1 kHz streams in a busy graph: 1 s of queue (like the recorder's) rides out
# a few hundred ms without CPU on two shared cores (200, STREAM_QOS's depth, did not).
INPUT_DEPTH = 1000
# Publishers of camera images and infos keep 1 s of history at 60 fps: a reliable reader that
# falls behind is repaired from the writer's history (cf. the simulator's PUBLISHER_DEPTH).
IMAGE_PUBLISHER_DEPTH = 60


def image_publisher_qos() -> QoSProfile:
    """IMAGE_QOS offered transient-local with IMAGE_PUBLISHER_DEPTH of history: compatible
    with every volatile reader, and a recorder (which asks for transient-local when all
    publishers offer it) that matches late still gets the last second of frames (the recorder's
    image participant matched 0.1-0.5 s after the simulator had started: first frames lost)."""
    return QoSProfile(history=IMAGE_QOS.history, depth=IMAGE_PUBLISHER_DEPTH,
                      reliability=IMAGE_QOS.reliability,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
# Low-rate reports (comparison, status): late joiners get the last one.
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)


class NodeFailure(RuntimeError):
    """The node cannot go on (the reason is the message): log it and exit with status 1."""


def make_executor(context=None):
    """rclpy's EventsExecutor (C++; Jazzy: rclpy.experimental) where available, else the
    SingleThreadedExecutor. The events executor takes and dispatches a message for a fraction of
    the SingleThreadedExecutor's per-message cost (it does not rebuild a wait set each time),
    which is most of what a Python node at 1 kHz spends."""
    try:
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    except ImportError:
        from rclpy.executors import SingleThreadedExecutor
        return SingleThreadedExecutor(context=context)


def spin_events(node, until: Optional[Callable[[], bool]] = None) -> None:
    """Spin ``node`` on ``make_executor()`` until shutdown or ``until()`` holds.

    Spins in 0.1 s slices: Python signal handlers (SIGTERM here) run between slices, and
    ``until`` is checked at least that often."""
    import rclpy
    executor = make_executor(node.context)
    executor.add_node(node)
    try:
        while rclpy.ok(context=node.context) and not (until is not None and until()):
            executor.spin_once(timeout_sec=0.1)
    finally:
        try:
            executor.remove_node(node)
        finally:
            executor.shutdown(timeout_sec=0)


def run_node(make_node: Callable[[], 'object'], args=None,
             spin: Optional[Callable[[object], None]] = None, events: bool = False) -> int:
    """Build and spin a node until Ctrl-C, SIGTERM, shutdown or NodeFailure; return exit code.

    ``spin(node)`` replaces the default spinning; ``events``: spin on the EventsExecutor
    (``spin_events``) instead of ``rclpy.spin``'s SingleThreadedExecutor."""
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
        elif events:
            spin_events(node)
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
