"""
What every saw_ros node shares.

The main() shape and signal handling (the QoS profiles are ``saw_ros.ros.qos``).

main() follows ros2/demos: init, build the node, spin, and on SIGINT/SIGTERM or an external
shutdown destroy the node and exit 0 without a traceback. A node that must exit with an error
(a diverging simulation) raises ``NodeFailure``: its message is logged and the exit code is 1.

Stopping (``run_node``): SIGINT and SIGTERM only request the stop (rclpy's own handlers are not
installed); the spin loop returns between two 0.1 s slices, ``close()`` finishes the node's work,
the node is destroyed, and only then the context shut down. Why: docs/measurements.md.
"""
from __future__ import annotations

import signal
import sys
import time
from typing import Callable, List, Optional


# s a stopping node waits, in all, for reliable subscribers to acknowledge its last messages.
FLUSH_TIMEOUT = 5.0


# glibc's malloc: blocks of at least MMAP_THRESHOLD bytes get pages of their own from the kernel,
# and free memory above TRIM_THRESHOLD at the heap's top goes back to it. Its defaults (128 kB,
# adapting upwards) give each 2.7 MB frame fresh pages: ~900 page faults, 3 of the 7 ms a
# JPEG decode took in the vision node here (measured with getrusage's minor faults). Frames and
# buffers below 64 MB come from the heap instead and their pages are reused.
MMAP_THRESHOLD = 64 << 20
TRIM_THRESHOLD = 256 << 20


def keep_freed_memory() -> bool:
    """Tune glibc's malloc as above (True), or leave another C library's as it is (False)."""
    import ctypes
    import ctypes.util
    try:
        libc = ctypes.CDLL(ctypes.util.find_library('c') or 'libc.so.6')
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3        # glibc's <malloc.h>
    return bool(mallopt(m_mmap_threshold, MMAP_THRESHOLD)) and \
        bool(mallopt(m_trim_threshold, TRIM_THRESHOLD))


class NodeFailure(RuntimeError):
    """The node cannot go on (the reason is the message): log it and exit with status 1."""


def make_executor(context=None):
    """
    Return rclpy's EventsExecutor where available, else the SingleThreadedExecutor.

    The EventsExecutor is C++ (Jazzy: rclpy.experimental). The events
    executor takes and dispatches a message for a fraction of the SingleThreadedExecutor's
    per-message cost (it does not rebuild a wait set each time), which is most of what a Python
    node at 1 kHz spends.
    """
    try:
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    except ImportError:
        from rclpy.executors import SingleThreadedExecutor
        return SingleThreadedExecutor(context=context)


class _StopRequest:
    """
    SIGINT/SIGTERM seen by ``run_node``'s handler (on the main thread, between bytecodes).

    ``interrupt``: also raise KeyboardInterrupt, as Python's own Ctrl-C does. Only while a node's
    own loop runs on the main thread outside any executor (the player's ``play()``, loadgen's
    ``run()``): there nothing is half-done in rclpy, and the context stays valid for ``close()``.
    Never in an executor's callbacks, never while the node is built or closed.
    """

    requested = False
    interrupt = False


_STOP = _StopRequest()


def _on_stop_signal(signum, frame) -> None:
    _STOP.requested = True
    if _STOP.interrupt:
        _STOP.interrupt = False     # once: a second signal must not break the clean-up
        raise KeyboardInterrupt


def take_stop_signals() -> dict:
    """
    Make SIGINT and SIGTERM request a stop (``_STOP``) from now on; return the handlers replaced.

    A request made before ``run_node`` starts is kept by it (it then starts nothing).
    """
    return {sig: signal.signal(sig, _on_stop_signal) for sig in (signal.SIGINT, signal.SIGTERM)}


def spin_node(node, until: Optional[Callable[[], bool]] = None, executor=None,
              pause: float = 0.0) -> None:
    """
    Spin ``node`` on ``executor`` (default: ``make_executor()``) until a stop is requested.

    (SIGINT, SIGTERM), its context is shut down or ``until()`` holds.

    Spins in 0.1 s slices: the stop request and ``until`` are checked at least that often, and
    between callbacks only (the signal handler just sets the request). ``pause`` s of sleep after
    each round let messages gather, for a node whose callbacks take every waiting message at
    once (the recorder): fewer, fuller rounds of the executor.
    """
    if executor is None:
        executor = make_executor(node.context)
    executor.add_node(node)
    interrupt, _STOP.interrupt = _STOP.interrupt, False
    try:
        while not _STOP.requested and node.context.ok() and not (until is not None and until()):
            executor.spin_once(timeout_sec=0.1)
            if pause:
                time.sleep(pause)
    finally:
        _STOP.interrupt = interrupt and not _STOP.requested
        try:
            executor.remove_node(node)
        finally:
            executor.shutdown(timeout_sec=0)


def spin_events(node, until: Optional[Callable[[], bool]] = None) -> None:
    """``spin_node`` on the EventsExecutor (``make_executor()``)."""
    spin_node(node, until)


def _context_gone(exc: BaseException, node) -> bool:
    """
    ``exc`` is rcl refusing to work because the context was shut down.

    (an external shutdown, or another process' signal handling): a stop, not a failure.
    """
    from rclpy.exceptions import InvalidHandle
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    if not isinstance(exc, (_rclpy.RCLError, InvalidHandle)):
        return False
    import rclpy
    context = node.context if node is not None else rclpy.get_default_context()
    return not context.ok()


def run_node(make_node: Callable[[], 'object'], args=None,
             spin: Optional[Callable[[object], None]] = None, events: bool = False) -> int:
    """
    Build and spin a node until Ctrl-C, SIGTERM, shutdown or NodeFailure; return exit code.

    ``spin(node)`` replaces the default spinning (a loop of its own or ``spin_node``); else
    ``spin_node`` on the EventsExecutor (``events``) or the SingleThreadedExecutor. Either way
    SIGINT and SIGTERM end spinning (module docstring), then ``node.close()`` runs (if the node
    has one: finish files, stop the node's threads), subscribers get up to FLUSH_TIMEOUT to
    acknowledge the last messages (``flush``), the node is destroyed and the context shut
    down, in that order; exit code 0.
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    # No rclpy signal handlers (they would shut the context down under a running callback):
    # ours only request the stop, from before rcl starts (checked once the node is built).
    previous = take_stop_signals()
    # A request made while the executable was starting stands (saw_ros.ros.nodes took the
    # signals then); one left by an earlier run in this process (tests) does not.
    _STOP.requested = _STOP.requested and all(h is _on_stop_signal for h in previous.values())
    _STOP.interrupt = False
    keep_freed_memory()
    node = None
    code = 0
    try:
        if _STOP.requested:
            return code               # stopped before it started: nothing to finish
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        node = make_node()
        if _STOP.requested:
            pass                      # stopped while the node was being built
        elif spin is not None:
            _STOP.interrupt = True    # a loop of its own; spin_node turns this off
            try:
                if not _STOP.requested:   # (a signal just before interrupt was set)
                    spin(node)
            finally:
                _STOP.interrupt = False
        else:
            spin_node(node, executor=None if events else SingleThreadedExecutor(
                context=node.context))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except NodeFailure as exc:
        logger = node.get_logger() if node is not None else rclpy.logging.get_logger('saw_ros')
        logger.fatal(str(exc))
        code = 1
    except Exception as exc:  # noqa: BLE001  (re-raised unless the context went away)
        if not _context_gone(exc, node):
            raise
    finally:
        _STOP.interrupt = False
        try:
            if node is not None:
                _close(node)
        finally:
            rclpy.try_shutdown()
            for sig, handler in previous.items():
                signal.signal(sig, handler)
    return code


def flush(node, timeout: float = FLUSH_TIMEOUT) -> List[str]:
    """
    Wait, ``timeout`` s at most in all.

    Until every reliable subscriber has acknowledged what ``node``'s publishers published; warn
    about and return the topics where one did not.

    Exiting at once would drop what a lagging reliable subscriber has not received yet; the
    bound keeps a stalled or vanished subscriber from holding the node (docs/measurements.md).
    """
    from rclpy.duration import Duration
    deadline = time.monotonic() + timeout
    late = []
    for pub in list(node.publishers):
        left = max(0.0, deadline - time.monotonic())
        if not pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9))):
            late.append(pub.topic_name)
    if late:
        node.get_logger().warning(
            f'not acknowledged by every subscriber within {timeout:g} s: {", ".join(late)} (a '
            f'subscriber stalled or is gone; it may have missed the last messages)')
    return late


def _close(node) -> None:
    """
    Call the node's ``close()`` (if any: it may still publish), ``flush()``, ``destroy_node()``.

    The context is still valid unless something else shut it down (then what failed because of it
    is a stop, not an error).
    """
    try:
        close = getattr(node, 'close', None)
        if close is not None:
            close()
        if node.context.ok():
            flush(node)
    except Exception as exc:  # noqa: BLE001  (re-raised unless the context went away)
        if not _context_gone(exc, node):
            raise
    finally:
        node.destroy_node()


def run_module(main: Callable[[], int], yaml_file: Optional[Callable[[], str]] = None) -> None:
    """
    Run a node module as ``python -m saw_ros.ros.nodes.<node>``.

    ``--write-yaml PATH`` writes the node's parameter file (``yaml_file()``) instead of running
    it: how every ``msg_config/<node>.yaml`` is made.
    """
    if yaml_file is not None and len(sys.argv) == 3 and sys.argv[1] == '--write-yaml':
        with open(sys.argv[2], 'w') as f:
            f.write(yaml_file())
        raise SystemExit(0)
    raise SystemExit(main())
