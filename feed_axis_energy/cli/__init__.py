"""The ``feed-axis-energy`` command: subcommands are thin shells over :mod:`feed_axis_energy.core`.

Every subcommand module defines ``add_parser(subparsers)`` and ``run(args) -> int``.
Exit codes: 0 success, 1 bad input or failed job (message on stderr), 2 usage error.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from feed_axis_energy import __version__
from feed_axis_energy.errors import FeedAxisError
from feed_axis_energy.interrupt import Terminated, terminate_on_signals

__all__ = ['main', 'build_parser']

# Order is the order shown in --help; the one-line help of each subcommand is listed here so
# that ``--help`` imports no subcommand module (each module's add_parser uses the same text,
# a test checks it).
SUBCOMMANDS = {
    'simulate': 'predict power and energy of every feed axis for an NC program',
    'check': 'list the errors and warnings of NC programs on a machine (no simulation)',
    'batch': 'simulate many programs x machines x loads in parallel; one table, JSON or CSV',
    'sweep': 'what-if: energy against cycle time on variants of the machine and run',
    'demo': "simulate the paper's demonstrator at its 3 loads and 5 feeds",
    'compare': 'compare measured runs of a campaign with the simulation (Table 1)',
    'launch': 'run the ROS 2 node graph on an NC program (separate processes)',
    'serve': 'run the node graph as a job service with an OPC UA server (and MQTT)',
    'cell-client': 'run programs as jobs on a serve over OPC UA; print the results',
    'import': 'turn the measured runs of a campaign into rosbag2/MCAP bags',
    'fit-loss': 'fit the loss function y = a*x^b from no-load runs at several feeds',
    'rig': 'write a virtual measured campaign (truth model + instrument artefacts)',
    'analyze': 'find the catalog effect(s) the model misses; error before/after',
}
# Subcommands whose module is not named after them ('import' is a Python keyword; the
# machine cell's commands live in cli/cell/).
_MODULES = {'import': 'import_run', 'serve': 'cell.serve', 'cell-client': 'cell.client'}


def _chosen(argv: list[str]) -> str | None:
    """The subcommand named in ``argv`` (top-level options take no values)."""
    for arg in argv:
        if not arg.startswith('-'):
            return arg if arg in SUBCOMMANDS else None
    return None


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """Return the top-level argument parser.

    Only the subcommand named in ``argv`` is imported and gets its full parser; the others
    are listed with their one-line help (start-up time: a subcommand's imports are paid only
    when it runs). ``argv=None`` imports and registers every subcommand.
    """
    parser = argparse.ArgumentParser(
        prog='feed-axis-energy',
        description='Virtual ball-screw feed axis: actual power and energy of each feed axis '
                    'from an NC program (method of the paper in README), compared with '
                    'measured runs.')
    parser.add_argument('--version', action='version', version=f'%(prog)s {__version__}')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True)
    chosen = None if argv is None else _chosen(argv)
    for name, summary in SUBCOMMANDS.items():
        if argv is None or name == chosen:
            module_name = _MODULES.get(name, name.replace('-', '_'))
            module = importlib.import_module(f'feed_axis_energy.cli.{module_name}')
            module.add_parser(sub)
        else:
            sub.add_parser(name, help=summary)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the process exit code."""
    if argv is None:
        argv = sys.argv[1:]
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    try:
        # SIGTERM and SIGINT raise Terminated inside the command so that staged outputs
        # are removed (outputs.py); the handlers are restored afterwards.
        with terminate_on_signals():
            return int(args.run(args) or 0)
    except FeedAxisError as err:
        print(f'error: {err}', file=sys.stderr)
        return 1
    except OSError as err:
        print(f'error: {err}', file=sys.stderr)
        return 1
    except Terminated as err:
        print(f'terminated by signal {err.signum}; no partial output left', file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130
