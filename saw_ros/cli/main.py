"""
``saw-ros``: the offline command.

Each subcommand lives in ``saw_ros/cli/commands/<name>.py`` with ``HELP`` (one line),
``add_arguments(parser)`` and ``run(args) -> int``; they are found there, so adding a command is
adding a file.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from saw_ros.cli import commands
from saw_ros.cli.errors import UserError
from saw_ros.core.params import ParameterError
from saw_ros.core.pool import PoolError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='saw-ros', description='SAW wave robot between flexible surfaces (Shachaf, Katz, '
        'Zarrouk, Biomimetics 2023): simulation, vision, comparison, bags and figures.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True)
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f'{commands.__name__}.{info.name}')
        name = getattr(module, 'NAME', info.name)
        p = sub.add_parser(name, help=module.HELP, description=module.__doc__.lstrip('\n'),
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
    except KeyboardInterrupt:
        print(f'saw-ros {args.command}: interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())
