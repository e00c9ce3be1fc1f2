"""``feed-axis-energy demo``: the paper's demonstrator campaign (3 loads x 5 feeds), simulated.

Loads and feeds are those of the paper's verification (section 3): clamped loads 0, 17.336
and 22.711 kg; feeds 100 ... 500 mm/s on a reciprocating 400 mm stroke with 1 s dwells.
"""
from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from feed_axis_energy.cli.common import format_table
from feed_axis_energy.cli.progress import Progress
from feed_axis_energy.core.errors import ConfigError
from feed_axis_energy.core.gcode import load_gcode
from feed_axis_energy.core.machine import load_machine
from feed_axis_energy.core.recording import write_simulation_bag
from feed_axis_energy.core.simulate import simulate_program, summarize
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
                   help='directory for the recordings (default: out/demonstrator; replaced '
                        'if it holds an earlier demo)')
    p.add_argument('--no-bags', action='store_true', help='do not write recordings')
    p.add_argument('--json', action='store_true', help='print the summaries as JSON')
    p.add_argument('--quiet', action='store_true', help='no progress indication')
    p.set_defaults(run=run)


def _prepare_out(out: Path) -> None:
    if out.exists():
        if not (out / _MARKER).exists():
            msg = (f'{out} exists and was not written by "feed-axis-energy demo"; '
                   'choose another --out')
            raise ConfigError(msg, file='command line', key='out')
        shutil.rmtree(out)
    out.mkdir(parents=True)
    (out / _MARKER).write_text('written by feed-axis-energy demo\n')


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    machine = load_machine(args.machine if args.machine is not None else default_machine())
    options = machine.planner.options()
    if not args.no_bags:
        _prepare_out(args.out)
    runs = [(feed, load) for feed in PAPER_FEEDS_MM_S for load in PAPER_LOADS_KG]
    progress = Progress('demo', enabled=not args.quiet, delay_s=0.0)
    summaries = []
    programs = {feed: load_gcode(program_path(f'demonstrator_f{feed}.nc'),
                                 **machine.gcode_keywords())
                for feed in PAPER_FEEDS_MM_S}
    for i, (feed, load) in enumerate(runs):
        result = simulate_program(programs[feed], machine, load_kg=load, options=options)
        summary = summarize(result, top_blocks=0)
        summary['feed_mm_s'] = feed
        if not args.no_bags:
            bag = args.out / f'f{feed}_load{load:g}kg'
            write_simulation_bag(bag, result, summary=summary)
            summary['bag'] = str(bag)
        summaries.append(summary)
        progress((i + 1) / len(runs))
    progress.done()
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
