"""``feed-axis-energy check``: every problem of every program, without simulating it.

The shell: options, output and exit code; the checking is
:func:`feed_axis_energy.gcode.program_problems`.
"""
from __future__ import annotations

import argparse
from dataclasses import replace
import json
import math
from pathlib import Path
import sys
from typing import Any

__all__ = ['add_parser', 'run']

HELP = 'list the errors and warnings of NC programs on a machine (no simulation)'


def _max_dwell(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0.0):
        msg = f'must be a number of seconds > 0, got {text[:60]!r}'
        raise argparse.ArgumentTypeError(msg)
    return value


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    from feed_axis_energy.cli.common import (add_program_options, add_quiet_option,
                                             add_tool_option, axes_option)
    from feed_axis_energy.gcode import DEFAULT_MAX_DWELL_S, DIALECTS
    p = sub.add_parser(
        'check', help=HELP,
        description='Parse each PROGRAM as `simulate` would and list its problems: the '
                    'error that stops the parser (file:line:column and the offending text; '
                    'checking goes on with the next program), the parser\'s warnings, and '
                    'sanity warnings from the parsed moves: moves beyond the machine\'s '
                    'travel (axes.<A>.travel_m), feeds above an axis\'s velocity limit, '
                    'dwells longer than --max-dwell-s, programs that never move.',
        epilog='Exit status: 0 no program has an error (warnings allowed), 1 at least one '
               'program has an error (or the machine config is bad), 2 usage error.')
    p.add_argument('programs', type=Path, nargs='+', metavar='PROGRAM',
                   help='NC program (G-code) files')
    p.add_argument('--machine', type=Path, metavar='YAML', default=None,
                   help='machine config: travel and velocity limits, tool table, G28 position, '
                        'default dialect (default: config/demonstrator.yaml)')
    add_tool_option(p)
    add_program_options(p)
    p.add_argument('--ignore-axes', type=axes_option, default=(), metavar='A,B',
                   help='drop the words of these axes (A, B, C, U, V, W) with one warning '
                        'each; without it a program moving such an axis is an error')
    p.add_argument('--dialect', default=None, choices=DIALECTS,
                   help='G-code dialect (default: the machine config\'s gcode.dialect)')
    p.add_argument('--max-dwell-s', type=_max_dwell, default=DEFAULT_MAX_DWELL_S, metavar='S',
                   help=f'report dwells longer than S seconds (default {DEFAULT_MAX_DWELL_S:g} '
                        's)')
    p.add_argument('--json', action='store_true',
                   help='print one JSON object (keys in README) instead of the list')
    add_quiet_option(p, help_text='no progress on stderr')
    p.set_defaults(run=run)


def _parse_keywords(machine: Any, args: argparse.Namespace) -> dict[str, Any]:
    """Keywords for ``load_gcode``: tools, G28 position, dialect, axes to ignore."""
    from feed_axis_energy.cli.common import program_keywords
    kw = program_keywords(machine, args)
    kw['dialect'] = args.dialect if args.dialect is not None else machine.gcode.dialect
    return kw


def _stats_dict(s: Any) -> dict[str, Any] | None:
    if s is None:
        return None
    return dict(feed_moves=s.n_feed_moves, traverses=s.n_traverses, arcs=s.n_arcs,
                dwells=s.n_dwells, feed_length_m=s.feed_length_m,
                traverse_length_m=s.traverse_length_m, dwell_s=s.dwell_s,
                final_position_m=list(s.final_position),
                bbox_min_m=None if s.bbox_min is None else list(s.bbox_min),
                bbox_max_m=None if s.bbox_max is None else list(s.bbox_max))


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    from feed_axis_energy.gcode import program_problems
    from feed_axis_energy.machine import load_machine
    from feed_axis_energy.paths import default_machine
    machine = load_machine(args.machine if args.machine is not None else default_machine())
    if args.tool:
        from feed_axis_energy.gcode import with_tools
        machine = replace(machine, gcode=with_tools(machine.gcode, dict(args.tool)))
    from feed_axis_energy.cli.common import apply_program_options
    machine = apply_program_options(machine, args)
    keywords = _parse_keywords(machine, args)
    results = []
    n = len(args.programs)
    for i, path in enumerate(args.programs, 1):
        if not args.quiet and n > 1:
            print(f'check: [{i}/{n}] {path}', file=sys.stderr, flush=True)
        problems, stats = program_problems(path, machine=machine, keywords=keywords,
                                           max_dwell_s=args.max_dwell_s)
        results.append((path, problems, stats))
    n_err = sum(1 for _, ps, _ in results for p in ps if p.severity == 'error')
    n_warn = sum(1 for _, ps, _ in results for p in ps if p.severity == 'warning')
    if args.json:
        doc = dict(machine=machine.name, errors=n_err, warnings=n_warn, programs=[
            dict(program=str(path), ok=not any(p.severity == 'error' for p in ps),
                 errors=[p.as_dict() for p in ps if p.severity == 'error'],
                 warnings=[p.as_dict() for p in ps if p.severity == 'warning'],
                 summary=_stats_dict(stats)) for path, ps, stats in results])
        print(json.dumps(doc, indent=2))
    else:
        for path, problems, stats in results:
            for p in problems:
                print(p)
            print(_program_line(path, problems, stats))
        bad = sum(1 for _, ps, _ in results if any(p.severity == 'error' for p in ps))
        print(f'checked {n} program{"s" if n != 1 else ""} on {machine.name}: {bad} with '
              f'errors, {n_err} error{"s" if n_err != 1 else ""}, {n_warn} '
              f'warning{"s" if n_warn != 1 else ""}')
    return 1 if n_err else 0


def _program_line(path: Path, problems: list[Any], stats: Any) -> str:
    errs = sum(1 for p in problems if p.severity == 'error')
    warns = len(problems) - errs
    head = f'{path}: {"refused" if errs else "ok"}, {warns} warning{"s" if warns != 1 else ""}'
    if stats is None:
        return head
    rotary = (f', rotary travel {stats.rotary_travel_deg:.3f} deg in {stats.n_rotary_moves} '
              'moves' if stats.n_rotary_moves else '')
    return (f'{head}; {stats.n_feed_moves} feed moves, {stats.n_arcs} arcs, '
            f'{stats.n_traverses} traverses, {stats.n_dwells} dwells; feed path '
            f'{stats.feed_length_m * 1e3:.3f} mm, traverse path '
            f'{stats.traverse_length_m * 1e3:.3f} mm, dwell {stats.dwell_s:.3f} s{rotary}')
