"""
``saw-ros``: the offline command.

Each subcommand lives in ``saw_ros/cli/commands/<name>.py`` with ``HELP`` (one line),
``add_arguments(parser)`` and ``run(args) -> int``; they are found there, so adding a command is
adding a file.
"""
from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
from typing import Optional

# Our own message says why a video cannot be read: FFmpeg's and OpenCV's log lines to the
# terminal ("moov atom not found") would be a second, cryptic line.
os.environ.setdefault('OPENCV_FFMPEG_LOGLEVEL', '-8')
os.environ.setdefault('OPENCV_LOG_LEVEL', 'SILENT')

from saw_ros.cli import commands  # noqa: E402
from saw_ros.cli.errors import UserError  # noqa: E402
from saw_ros.core.params import ParameterError  # noqa: E402
from saw_ros.core.pool import PoolError  # noqa: E402


class Parser(argparse.ArgumentParser):
    """An argument parser whose mistakes are one line (usage lines are in --help)."""

    def error(self, message):
        print(f'{self.prog}: error: {message} (see {self.prog} --help)', file=sys.stderr)
        sys.exit(2)


def command_name(module_name: str) -> str:
    """Return the name users type for the command in ``commands/<module_name>.py``."""
    return module_name.replace('_', '-')


def build_parser(chosen: Optional[str] = None) -> argparse.ArgumentParser:
    """
    Return the parser of every command, or of ``chosen`` alone when it names one.

    The other commands' modules are not imported then: each pulls in what it runs on (numba's
    kernels, OpenCV, rclpy for the bench's load generator), some 0.6 s of CPU for ``saw-ros
    --help`` against 0.1 s for ``saw-ros bag info`` alone, paid by every script and test that
    calls us. Their names stay known, so a mistyped command still lists them all.
    """
    parser = Parser(
        prog='saw-ros', description='SAW wave robot between flexible surfaces (Shachaf, Katz, '
        'Zarrouk, Biomimetics 2023): simulation, vision, comparison, bags and figures.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True)
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        name = command_name(info.name)
        if chosen in COMMANDS and name != chosen:
            sub.add_parser(name)
            continue
        module = importlib.import_module(f'{commands.__name__}.{info.name}')
        p = sub.add_parser(name, help=module.HELP, description=(module.__doc__ or '').lstrip('\n'),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


COMMANDS = frozenset(command_name(info.name) for info in pkgutil.iter_modules(commands.__path__))


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    # saw-ros has no option of its own but --help: its first word that is not an option is the
    # command.
    chosen = next((word for word in argv if not word.startswith('-')), None)
    args = build_parser(chosen).parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except (ParameterError, PoolError, UserError) as exc:
        print(f'saw-ros {args.command}: error: {exc}', file=sys.stderr)
        return 2
    except BrokenPipeError:
        # stdout closed by its reader (saw-ros ... | head): stop quietly, as Unix tools do.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:
        # A file that could not be written or read after the checks (a full disk, a folder
        # removed meanwhile): the file and the reason, not a traceback.
        where = f'{exc.filename}: ' if exc.filename else ''
        print(f'saw-ros {args.command}: error: {where}{exc.strerror or exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f'saw-ros {args.command}: interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())
