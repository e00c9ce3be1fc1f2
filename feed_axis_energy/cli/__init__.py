"""The ``feed-axis-energy`` command: subcommands are thin shells over :mod:`feed_axis_energy.core`.

Every subcommand module defines ``add_parser(subparsers)`` and ``run(args) -> int``.
Exit codes: 0 success, 1 bad input or failed job (message on stderr), 2 usage error.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from feed_axis_energy import __version__
from feed_axis_energy.core.errors import FeedAxisError
from feed_axis_energy.core.outputs import terminate_on_signals

__all__ = ['main', 'build_parser']

# Order is the order shown in --help.
SUBCOMMANDS = ('simulate', 'demo', 'compare', 'launch', 'import', 'fit-loss', 'rig',
               'analyze')
# Subcommands whose module is not named after them ('import' is a Python keyword).
_MODULES = {'import': 'import_run'}


def build_parser() -> argparse.ArgumentParser:
    """Return the top-level argument parser with every subcommand registered."""
    parser = argparse.ArgumentParser(
        prog='feed-axis-energy',
        description='Virtual ball-screw feed axis: actual power and energy of each feed axis '
                    'from an NC program (method of the paper in README), compared with '
                    'measured runs.')
    parser.add_argument('--version', action='version', version=f'%(prog)s {__version__}')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True)
    for name in SUBCOMMANDS:
        module_name = _MODULES.get(name, name.replace('-', '_'))
        module = importlib.import_module(f'feed_axis_energy.cli.{module_name}')
        module.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        # SIGTERM raises SystemExit(143) inside the command so that staged outputs are
        # removed (core/outputs.py); SIGINT raises KeyboardInterrupt as usual.
        with terminate_on_signals():
            return int(args.run(args) or 0)
    except FeedAxisError as err:
        print(f'error: {err}', file=sys.stderr)
        return 1
    except (OSError, FileExistsError) as err:
        print(f'error: {err}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130
