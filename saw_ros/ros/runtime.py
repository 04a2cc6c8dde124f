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

import ast
import functools
import os
import re
import signal
import sys
import time
from typing import Any, Callable, cast, Iterable, List, Optional


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


@functools.lru_cache(maxsize=None)
def _interruptible_executor_class() -> Any:
    from rclpy.executors import SingleThreadedExecutor

    class InterruptibleExecutor(SingleThreadedExecutor):
        # A stop (run_node's KeyboardInterrupt) may land inside __init__, before rclpy sets
        # _sigint_gc; the half-built executor's __del__ then printed a traceback on the way
        # out ("no attribute '_sigint_gc'": a recorder stopped as it started, at load).
        _sigint_gc = cast(Any, None)   # (rclpy types it as always set: so it is, but late)

    return InterruptibleExecutor


def single_threaded_executor(context=None):
    """Return rclpy's SingleThreadedExecutor, safe to stop while it is being built."""
    return _interruptible_executor_class()(context=context)


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
        return single_threaded_executor(context)


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
    Spin ``node`` on ``executor`` (default: ``make_executor()``) until it should stop.

    That is: a stop is requested (SIGINT, SIGTERM), its context is shut down or ``until()``
    holds.

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
    Return whether ``exc`` is rcl refusing to work because the context was shut down.

    That is an external shutdown, or another process' signal handling: a stop, not a failure.
    """
    from rclpy.exceptions import InvalidHandle
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    if not isinstance(exc, (_rclpy.RCLError, InvalidHandle)):
        return False
    import rclpy
    context = node.context if node is not None else rclpy.get_default_context()
    return not context.ok()


def run_node(make_node: Callable[[], Any], args=None,
             spin: Optional[Callable[[Any], None]] = None, events: bool = False,
             name: str = 'saw_ros', parameters: Optional[Callable[[], Iterable]] = None) -> int:
    """
    Build and spin a node until Ctrl-C, SIGTERM, shutdown or NodeFailure; return exit code.

    ``spin(node)`` replaces the default spinning (a loop of its own or ``spin_node``); else
    ``spin_node`` on the EventsExecutor (``events``) or the SingleThreadedExecutor. Either way
    SIGINT and SIGTERM end spinning (module docstring), then ``node.close()`` runs (if the node
    has one: finish files, stop the node's threads), subscribers get up to FLUSH_TIMEOUT to
    acknowledge the last messages (``flush``), the node is destroyed and the context shut
    down, in that order; exit code 0.

    Before anything starts, the command line (``args``, else ``sys.argv``): ``-h``/``--help``
    prints the node's ``parameters()`` (spec() entries: name, default, metadata) and returns 0;
    an unknown argument, a params file that is missing or not YAML, or ROS arguments rcl cannot
    parse end it with one FATAL line under the node's ``name`` and exit code 1. Start-up values
    for parameters the node did not declare are named in a warning.
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.signals import SignalHandlerOptions
    from saw_ros.core.params import ParameterError
    from saw_ros.ros.params import unknown_start_values

    argv = list(sys.argv if args is None else args)
    try:
        wants_help = check_command_line(argv)
    except ParameterError as exc:
        rclpy.logging.get_logger(name).fatal(str(exc))
        return 1
    if wants_help:
        try:
            print(help_text(name, parameters, getattr(sys.modules.get(
                getattr(make_node, '__module__', '')), '__doc__', None)), flush=True)
        except BrokenPipeError:
            # The reader (`| head`) stopped reading: no error of ours. Python would report
            # the broken pipe again when it flushes stdout at exit.
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0

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
        rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
        node = make_node()
        unknown = unknown_start_values(node)
        if unknown:
            node.get_logger().warning(
                f'unknown parameter{"s" if len(unknown) > 1 else ""} ignored: '
                f'{", ".join(unknown)} ({name} declares no such parameter; {name} --help '
                f'lists them)')
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
            spin_node(node, executor=None if events else single_threaded_executor(node.context))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (NodeFailure, ParameterError) as exc:
        # (a node not built yet has no logger of its own: the same name, so that the FATAL line
        # says which node refused)
        logger = node.get_logger() if node is not None else rclpy.logging.get_logger(name)
        logger.fatal(str(exc) if isinstance(exc, NodeFailure) else f'invalid parameters: {exc}')
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


HELP_FLAGS = ('-h', '--help')


def check_command_line(argv: List[str]) -> bool:
    """
    Return whether ``argv`` (with the program's name first) asks for help.

    Raises ParameterError, with one line, for what would make rcl fail or be silently ignored:
    an argument that is neither ROS's nor ``-h``/``--help``, a ``--params-file`` that is missing,
    unreadable or not YAML, and ROS arguments rcl cannot parse (its message, without its source
    locations).
    """
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    from rclpy.utilities import remove_ros_args
    from saw_ros.core.params import ParameterError
    for flag, path in zip(argv, argv[1:]):
        if flag == '--params-file':
            check_params_file(path)
    try:
        rest = remove_ros_args(argv)[1:]
    except _rclpy.RCLInvalidROSArgsError as exc:
        text = re.sub(r', at [^,]*\.c:\d+', '', str(exc)).replace('\n', ' ').strip()
        raise ParameterError(text.replace('Failed to parse ROS arguments: ',
                                          'invalid ROS arguments: ')) from None
    except _rclpy.UnknownROSArgsError as exc:
        # After --ros-args: -h and --help are ours there too; rcl names the others as a list.
        try:
            extra = [str(a) for a in ast.literal_eval(str(exc))]
        except (ValueError, SyntaxError, TypeError):
            extra = [str(exc)]
        unknown = [a for a in extra if a not in HELP_FLAGS]
        if unknown:
            raise ParameterError(f'unknown ROS argument{"s" if len(unknown) > 1 else ""} '
                                 f'{" ".join(unknown)} (--help lists the parameters)') from None
        return True
    unknown = [a for a in rest if a not in HELP_FLAGS]
    if unknown:
        raise ParameterError(f'unknown argument{"s" if len(unknown) > 1 else ""} '
                             f'{" ".join(unknown)}: parameters go after --ros-args, as -p '
                             f'NAME:=VALUE or --params-file FILE (--help lists them)')
    return any(a in HELP_FLAGS for a in rest)


def check_params_file(path: str) -> None:
    """
    Raise ParameterError (one line) unless ``path`` is a YAML file of node names.

    rcl's own refusal is two lines ("Failed to parse global arguments", then the error) and left
    the node to exit 0.
    """
    import yaml
    from saw_ros.core.params import ParameterError
    # launch_ros writes a list parameter as a tuple (``!!python/tuple``), which rcl reads as a
    # list: so does this check (safe_load refused `ros2 launch`'s recorder topics).

    class ParamsLoader(yaml.SafeLoader):
        """SafeLoader, and a !!python/tuple read as a list."""

    ParamsLoader.add_constructor('tag:yaml.org,2002:python/tuple',
                                 lambda load, node: load.construct_sequence(node))
    try:
        with open(path, encoding='utf-8') as f:
            doc = yaml.load(f, Loader=ParamsLoader)     # noqa: S506 (safe, one tag more)
    except FileNotFoundError:
        raise ParameterError(f'params file {path} does not exist') from None
    except OSError as exc:
        raise ParameterError(f'params file {path} cannot be read: {exc.strerror or exc}') \
            from None
    except UnicodeDecodeError:
        raise ParameterError(f'params file {path} is not YAML: not UTF-8 text') from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}' if mark is not None else ''
        raise ParameterError(f'params file {path} is not YAML: '
                             f'{getattr(exc, "problem", None) or exc}{where}') from None
    if not isinstance(doc, dict):
        raise ParameterError(f'params file {path} is not a ROS parameters file: expected '
                             f'"<node name>: ros__parameters: ..." at its top, found '
                             f'{type(doc).__name__ if doc is not None else "nothing"}')


def _type_name(value) -> str:
    """Return a parameter's ROS type name, from its default."""
    if isinstance(value, (list, tuple)):
        return _type_name(value[0] if value else '') + '[]'
    return next(n for cls, n in ((bool, 'bool'), (int, 'integer'), (float, 'double'),
                                 (str, 'string')) if isinstance(value, cls))


def help_text(name: str, parameters: Optional[Callable[[], Iterable]],
              doc: Optional[str] = None) -> str:
    """
    Return a node's ``--help``: usage, what it does (``doc``'s first line), its parameters.

    Each with its type, unit, allowed range and default, from the spec() entries the node
    declares (``parameters()``), so that the help cannot drift from the node.
    """
    import textwrap
    from saw_ros.core.params import range_text
    summary = (doc or '').replace('``', '').strip().splitlines()
    lines = [f'usage: {name} [-h] [--ros-args [-p NAME:=VALUE]... [--params-file FILE]]', '']
    if summary:
        lines += [summary[0], '']
    entries = list(parameters()) if parameters is not None else []
    lines.append('parameters (name: type [unit] in allowed range, default):' if entries
                 else "parameters: see the node's documentation")
    for pname, default, meta in entries:
        unit = meta.get('unit') or ''
        numeric = isinstance(default, (int, float)) and not isinstance(default, bool)
        allowed = (range_text(dict(meta, unit='')) if numeric and 'low' in meta
                   else 'one of ' + ', '.join(meta['choices']) if meta.get('choices') else '')
        shown = repr(default) if not isinstance(default, bool) else str(default).lower()
        head = f'  {pname}: {_type_name(default)}' + (f' [{unit}]' if unit else '') + \
            (f' in {allowed}' if allowed and not allowed.startswith('one') else
             f', {allowed}' if allowed else '') + f', default {shown}'
        lines.append(head)
        lines += textwrap.wrap(meta.get('description', ''), 95, initial_indent='      ',
                               subsequent_indent='      ')
    return '\n'.join(lines)


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
