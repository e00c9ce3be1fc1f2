"""``feed-axis-energy simulate``: one NC program on one machine, energy per axis and per block."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from feed_axis_energy.cli.common import (add_machine_options, load_machine_and_options,
                                         print_summary, program_text_lines)
from feed_axis_energy.cli.progress import Progress
from feed_axis_energy.core.gcode import load_gcode
from feed_axis_energy.core.measured.trajcsv import load_trajectory_csv
from feed_axis_energy.core.recording import write_simulation_bag
from feed_axis_energy.core.simulate import simulate_motion, simulate_program, summarize

__all__ = ['add_parser', 'run']


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    p = sub.add_parser(
        'simulate', help='predict power and energy of every feed axis for an NC program',
        description='Parse PROGRAM (RS-274 G-code), plan the motion with the machine\'s '
                    'limits, compute screw torques, actual power P = sum M*omega (eq. 1) and '
                    'energy E = integral P dt (eq. 2). Prints duration, energy per axis and '
                    'total, peak power and the blocks with the most energy.')
    p.add_argument('program', type=Path,
                   help='NC program (G-code) file, or a trajectory CSV (*.csv) with a header '
                        '"time [s],X [mm],..." as the motion source instead of G-code')
    add_machine_options(p)
    p.add_argument('--out', type=Path, metavar='BAG_DIR',
                   help='write the full time series as a rosbag2 directory (MCAP storage); '
                        'must not exist yet')
    p.add_argument('--json', action='store_true',
                   help='print one JSON object instead of the table (keys in README)')
    p.add_argument('--top', type=int, default=5, metavar='N',
                   help='number of most energetic blocks to list (default: 5)')
    p.add_argument('--quiet', action='store_true', help='no progress indication')
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    machine, options = load_machine_and_options(args)
    if args.out is not None and args.out.exists():
        msg = f'{args.out} exists already; choose a new output directory'
        raise FileExistsError(msg)
    progress = Progress('simulate', enabled=not args.quiet)
    trajectory = args.program.suffix.lower() == '.csv'
    if trajectory:
        motion = load_trajectory_csv(args.program, axes=machine.axis_names)
        result = simulate_motion(motion, machine, load_kg=args.load_kg)
    else:
        program = load_gcode(args.program, home=machine.home_point())
        for warning in program.warnings:
            print(f'warning: {warning}', file=sys.stderr)
        if not program.moves:
            print(f'warning: {args.program}: the program has no motion', file=sys.stderr)
        result = simulate_program(program, machine, load_kg=args.load_kg, options=options,
                                  progress=progress)
    progress.done()
    # A trajectory has no source lines to attribute energy to.
    summary = summarize(result, top_blocks=0 if trajectory else args.top)
    if args.out is not None:
        write_simulation_bag(args.out, result, summary=summary,
                             progress=Progress('write bag', enabled=not args.quiet))
        summary['bag'] = str(args.out)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print_summary(summary, source_lines=program_text_lines(args.program))
        if args.out is not None:
            print(f'recording: {args.out} (topics /setpoints, /axis_state, /power, '
                  '/block_energy; units in README)')
    return 0
