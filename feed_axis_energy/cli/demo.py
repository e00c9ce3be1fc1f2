"""``feed-axis-energy demo``: the paper's demonstrator campaign (3 loads x 5 feeds), simulated.

Loads and feeds are those of the paper's verification (section 3): clamped loads 0, 17.336
and 22.711 kg; feeds 100 ... 500 mm/s on a reciprocating 400 mm stroke with 1 s dwells.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from feed_axis_energy.cli.common import add_quiet_option, format_table
from feed_axis_energy.cli.progress import Progress
from feed_axis_energy.gcode import load_gcode
from feed_axis_energy.machine import load_machine
from feed_axis_energy.outputs import marked_or_empty, staged_directory
from feed_axis_energy.record import write_simulation_bag
from feed_axis_energy.sim import simulate_program, summarize
from feed_axis_energy.paths import default_machine, program_path

__all__ = ['add_parser', 'run', 'PAPER_LOADS_KG', 'PAPER_FEEDS_MM_S']

PAPER_LOADS_KG = (0.0, 17.336, 22.711)
PAPER_FEEDS_MM_S = (100, 200, 300, 400, 500)
_MARKER = '.feed_axis_energy_demo'


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    p = sub.add_parser(
        'demo', help="simulate the paper's demonstrator at its 3 loads and 5 feeds",
        description="Simulate the paper's ball-screw test stand (config/demonstrator.yaml) "
                    'on the reciprocating 400 mm stroke at 100..500 mm/s with clamped loads '
                    'of 0, 17.336 and 22.711 kg; print the energy table and keep one '
                    'rosbag2/MCAP recording per run.')
    p.add_argument('--machine', type=Path, default=None, metavar='YAML',
                   help='machine config (default: config/demonstrator.yaml)')
    p.add_argument('--out', type=Path, default=Path('out/demonstrator'), metavar='DIR',
                   help='directory for the recordings (default: out/demonstrator); must not '
                        'exist unless --force; built in a hidden temporary directory and '
                        'renamed into place when complete')
    p.add_argument('--force', action='store_true',
                   help='replace an existing --out directory if it holds an earlier demo '
                        '(or is empty); never a symbolic link or another directory')
    p.add_argument('--no-bags', action='store_true', help='do not write recordings')
    p.add_argument('--json', action='store_true', help='print the summaries as JSON')
    add_quiet_option(p)
    p.set_defaults(run=run)


def _simulate_all(args: argparse.Namespace, machine, staged: Path | None) -> list[dict]:
    """Simulate every run; with ``staged``, write its bag there (named as under --out)."""
    options = machine.planner.options()
    runs = [(feed, load) for feed in PAPER_FEEDS_MM_S for load in PAPER_LOADS_KG]
    progress = Progress('demo', enabled=not args.quiet, delay_s=0.0)
    summaries = []
    programs = {feed: load_gcode(program_path(f'demonstrator_f{feed}.nc'),
                                 **machine.gcode_keywords())
                for feed in PAPER_FEEDS_MM_S}
    if staged is not None:
        staged.mkdir()
        (staged / _MARKER).write_text('written by feed-axis-energy demo\n')
    for i, (feed, load) in enumerate(runs):
        result = simulate_program(programs[feed], machine, load_kg=load, options=options)
        summary = summarize(result, top_blocks=0)
        summary['feed_mm_s'] = feed
        if staged is not None:
            name = f'f{feed}_load{load:g}kg'
            write_simulation_bag(staged / name, result, summary=summary)
            summary['bag'] = str(args.out / name)
        summaries.append(summary)
        progress((i + 1) / len(runs))
    progress.done()
    return summaries


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    machine = load_machine(args.machine if args.machine is not None else default_machine())
    runs = [(feed, load) for feed in PAPER_FEEDS_MM_S for load in PAPER_LOADS_KG]
    if args.no_bags:
        summaries = _simulate_all(args, machine, None)
    else:
        # all 15 bags or none: built in a hidden temporary directory, renamed at the end
        with staged_directory(args.out, option='--out', force=args.force,
                              replaceable=marked_or_empty(_MARKER)) as staged:
            summaries = _simulate_all(args, machine, staged)
    if args.json:
        print(json.dumps(summaries, indent=2))
        return 0
    by_key = {(s['feed_mm_s'], s['load_kg']): s for s in summaries}
    header = (['feed [mm/s]', 'duration [s]']
              + [f'E @ {load:g} kg [J]' for load in PAPER_LOADS_KG]
              + [f'peak P @ {load:g} kg [W]' for load in PAPER_LOADS_KG])
    rows = []
    for feed in PAPER_FEEDS_MM_S:
        runs_at = [by_key[(feed, load)] for load in PAPER_LOADS_KG]
        rows.append([str(feed), f'{runs_at[0]["duration_s"]:.3f}']
                    + [f'{s["energy_j"]["total"]:.1f}' for s in runs_at]
                    + [f'{s["peak_power_w"]["total"]:.1f}' for s in runs_at])
    source = default_machine() if args.machine is None else args.machine
    try:
        source = source.resolve().relative_to(Path.cwd().resolve())
    except ValueError:
        pass  # outside the working directory: keep the full path
    print(f'machine: {machine.name} ({source}), braking: {machine.braking}')
    print('program: reciprocating 400 mm stroke, 1 s dwell (config/programs/demonstrator_f*.nc)')
    print()
    print(format_table(header, rows))
    if not args.no_bags:
        print()
        print(f'recordings: {args.out}/ ({len(runs)} rosbag2/MCAP directories, topics '
              '/setpoints /axis_state /power /block_energy)')
    return 0
