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


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog='saw-ros', description='SAW wave robot between flexible surfaces (Shachaf, Katz, '
        'Zarrouk, Biomimetics 2023): simulation, vision, comparison, bags and figures.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True)
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f'{commands.__name__}.{info.name}')
        name = getattr(module, 'NAME', info.name)
        p = sub.add_parser(name, help=module.HELP, description=(module.__doc__ or '').lstrip('\n'),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
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
