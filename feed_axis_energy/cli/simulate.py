"""``feed-axis-energy simulate``: one NC program on one machine, energy per axis and per block."""
from __future__ import annotations

import argparse
import contextlib
import gc
from itertools import chain
import json
import os
import sys
from pathlib import Path

from feed_axis_energy.cli.common import (add_machine_options, add_quiet_option, METHOD_HELP,
                                         plot_rate_option, positive_float, positive_int,
                                         start_time_option)
from feed_axis_energy.cli.simulate_out import (check_cost, check_start, consumers, export_targets,
                                               Exports, report_trace, staged_out, write_report)
from feed_axis_energy.errors import ConfigError, shorten

# plottopics' constant, repeated so that --help does not import numpy (a test compares them)
DEFAULT_PLOT_RATE_HZ = 20.0

__all__ = ['add_parser', 'run']

BLOCK_TEXT_CHARS = 60    # block text shown in top_blocks (cut with '...')
# the per-block breakdown costs 8 (axes + causes) bytes per program line; kept when the
# program's lines need at most this much, or when an export needs the per-block table
BLOCK_BREAKDOWN_BYTES = 16 << 20
GC_THRESHOLD = 20_000   # first-generation threshold of the collector while streaming


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
                        'must not exist unless --force; built in a hidden temporary '
                        'directory and renamed into place when complete')
    p.add_argument('--report', type=Path, metavar='DIR',
                   help='write a report: one self-contained index.html (plots embedded, '
                        'opens offline, prints on A4) and its PNG images: power and '
                        'cumulative energy over time, energy by cause and per block, path '
                        'and bounding box; must not exist unless --force')
    p.add_argument('--force', action='store_true',
                   help='replace an existing --out bag directory (only a rosbag2 directory, '
                        'never a symbolic link), --report directory (only an earlier '
                        'report or an empty directory) or --csv/--parquet directory (one this '
                        'command wrote, or empty) once the new one is complete')
    p.add_argument('--compression', choices=('none', 'zstd'), default='zstd',
                   help='MCAP chunk compression of the --out recording (default zstd at the '
                        'fast level -1: about 5x smaller for 1.2-1.5x the writer\'s CPU time)')
    p.add_argument('--csv', type=Path, metavar='DIR',
                   help='write timeseries.csv (time series) and blocks.csv (per block: line, '
                        'text, duration, energy per axis and per cause) into DIR; must not '
                        'exist unless --force; built in a hidden temporary and renamed into '
                        'place when complete')
    p.add_argument('--parquet', type=Path, metavar='DIR',
                   help='the same tables as --csv as Parquet files (needs pyarrow)')
    rate = p.add_mutually_exclusive_group()
    rate.add_argument('--decimate', type=positive_int, default=None, metavar='N',
                      help='exported time series: every N-th sample (default 1: all)')
    rate.add_argument('--export-rate-hz', type=positive_float, default=None, metavar='HZ',
                      help='exported time series: about HZ samples per second (every '
                           'round(rate/HZ)-th sample)')
    p.add_argument('--plot-rate-hz', type=plot_rate_option, default=DEFAULT_PLOT_RATE_HZ,
                   metavar='HZ',
                   help='display rate of the --out recording\'s plot topics /plot/power and '
                        '/plot/axes (one sample per message; per interval of 1/HZ the first '
                        'sample and those of each power and torque minimum and maximum, so '
                        f'no peak is lost); 0: every sample (default {DEFAULT_PLOT_RATE_HZ:g})')
    p.add_argument('--start-time', type=start_time_option, default=None, metavar='now|ISO-8601',
                   help='stamp the --out recording in wall-clock time from this start (e.g. '
                        '2026-11-23T14:00:00Z; no offset: UTC) instead of simulation time '
                        'from 0 (the default)')
    p.add_argument('--json', action='store_true',
                   help='print one JSON object instead of the table (keys in README)')
    p.add_argument('--top', type=int, default=5, metavar='N',
                   help='number of most energetic blocks to list (default: 5)')
    p.add_argument('--method', choices=('phases', 'samples'), default='phases',
                   help=(METHOD_HELP + '. Recordings, exports and the report\'s curves '
                         'are samples either way'))
    p.add_argument('--max-samples', type=int, default=0, metavar='N',
                   help='refuse programs that need more than N samples (default 0: no limit); '
                        'the count is known from the plan before any sample is computed')
    add_quiet_option(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    # imported here: ``feed-axis-energy --help`` must not pay for the simulation's imports
    from feed_axis_energy.cli.common import (load_machine_and_options, print_summary,
                                             program_text_lines)
    from feed_axis_energy.cli.progress import Progress
    from feed_axis_energy.sim import streamable

    machine, options = load_machine_and_options(args)
    if args.out is not None:
        from feed_axis_energy.outputs import check_target, is_bag_directory
        # refused before any sample is computed, not after
        check_target(args.out, option='--out', force=args.force, kind='directory',
                     replaceable=is_bag_directory)
    if args.report is not None:
        from feed_axis_energy.outputs import check_target, marked_or_empty
        from feed_axis_energy.report import MARKER
        check_target(args.report, option='--report', force=args.force, kind='directory',
                     replaceable=marked_or_empty(MARKER))
    exports = export_targets(args, options.rate_hz)
    if args.max_samples < 0:
        msg = f'--max-samples must be >= 0, got {args.max_samples}'
        raise ConfigError(msg, file='command line', key='max-samples')
    progress = Progress('simulate', enabled=not args.quiet)
    trajectory = args.program.suffix.lower() == '.csv'
    warnings: list[str] = []
    trace = report_trace(args)
    new_bag = args.out is not None and not os.path.lexists(args.out)
    # the bag, the exports and the report or none of them: a new bag is removed if an export
    # or the report fails (one that replaced an earlier bag with --force cannot be brought
    # back); the exports are staged and only renamed into place at the end
    if args.out is not None or args.report is not None or exports:
        from feed_axis_energy.outputs import Rollback
        guard = Rollback()
    else:                                   # nothing to write: no output machinery imported
        guard = contextlib.nullcontext()
    with guard as written, Exports(args, exports) as export:
        if trajectory or not streamable(machine):
            summary, blocks = _run_whole(args, machine, options, progress,
                                         trajectory=trajectory, warnings=warnings, trace=trace,
                                         export=export)
        else:
            summary, warnings, blocks = _run_stream(args, machine, options, progress,
                                                    trace=trace, export=export)
        if new_bag:
            written.add(args.out)
        summary['warnings'] = warnings
        if args.out is not None:
            summary['bag'] = str(args.out)
        for fmt, path in exports.items():
            summary[fmt] = str(path)
        export.write_rollups(summary)
        lines = [b['line'] for b in summary['top_blocks']]
        texts = {} if trajectory else program_text_lines(args.program, lines)
        for block in summary['top_blocks']:
            block['text'] = shorten(texts.get(block['line'], '').strip(),
                                    limit=BLOCK_TEXT_CHARS)
        if args.report is not None:
            summary['report'] = str(args.report / 'index.html')
            write_report(args, summary, trace, blocks, trajectory=trajectory)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print_summary(summary, source_lines=texts)
        if args.out is not None:
            print(f'recording: {args.out} (topics /setpoints, /axis_state, /power, '
                  '/block_energy; plot-ready /plot/power, /plot/axes, /plot/block_energy; '
                  'units in README)')
        rollups = ', rollups.{fmt}' if summary.get('rollups') else ''
        for fmt, path in exports.items():
            print(f'{fmt}: {path} (timeseries.{fmt}, blocks.{fmt}{rollups.format(fmt=fmt)}; '
                  'columns in README)')
    return 0


class _Moves:
    """One pass over the program's moves, streamed from the file (memory: one batch of
    moves, not the program), feeding the sanity checks and reporting progress by line."""

    def __init__(self, args: argparse.Namespace, machine, *, check: bool,
                 progress=None, n_lines: int = 0) -> None:
        from feed_axis_energy.cli.common import program_keywords
        from feed_axis_energy.gcode import iter_moves, sanity_checker
        self.stream = iter_moves(args.program, **program_keywords(machine, args))
        self.file = self.stream.file
        self.checker = sanity_checker(args.program, machine) if check else None
        self.progress = progress if n_lines > 0 else None
        self.n_lines = n_lines

    def __iter__(self):
        # the moves of the checked batches, chained in C: no generator step per move
        return chain.from_iterable(self.batches())

    def batches(self):
        """The moves in the interpreter's batches (lists), each checked before it is given
        (:meth:`.gcode.MoveStream.batches`)."""
        progress, n_lines = self.progress, self.n_lines
        for batch in self.stream.batches():
            if not batch:
                continue
            self._check(batch)
            if progress is not None:
                progress(min(batch[-1].line / n_lines, 1.0))
            yield batch

    def _check(self, batch: list) -> None:
        if self.checker is not None and batch:
            self.checker.add_many(batch)

    def warnings(self, args: argparse.Namespace) -> list[str]:
        """Print the parser's and ``check``'s warnings on stderr (after the pass); return
        them."""
        from feed_axis_energy.gcode import checked_warning_texts
        texts = checked_warning_texts(args.program, self.stream.warnings, self.checker)
        for text in texts:
            print(f'warning: {text}', file=sys.stderr)
        return texts


def _count_lines(path: Path) -> int:
    """Lines of a file (for progress), counted in 1 MiB blocks; 0 if unreadable."""
    n = 0
    try:
        with open(path, 'rb') as fh:
            while block := fh.read(1 << 20):
                n += block.count(b'\n') + block.count(b'\r') - block.count(b'\r\n')
    except OSError:
        return 0
    return n + 1


def _run_stream(args, machine, options, progress, *, trace=None,
                export=None) -> tuple[dict, list[str], object]:
    """Parse, plan, simulate and record chunk by chunk: memory holds one batch of moves and
    one chunk of samples, never the program. With ``--out`` or ``--max-samples`` a first
    pass over the moves (parsing and planning without samples) gives the cost and the
    warnings before any output; otherwise the single pass checks as it goes and the
    warnings follow the simulation."""
    # the moves (a tracked object each) live for a batch: with the default first threshold
    # (700 allocations) the collector walks them again and again (about 2 % of a contour's
    # instructions); cycles are still collected, less often
    threshold = gc.get_threshold()
    gc.set_threshold(max(threshold[0], GC_THRESHOLD), *threshold[1:])
    try:
        return _run_stream_gc(args, machine, options, progress, trace=trace, export=export)
    finally:
        gc.set_threshold(*threshold)


def _run_stream_gc(args, machine, options, progress, *, trace=None,
                   export=None) -> tuple[dict, list[str], object]:
    from feed_axis_energy.plan import estimate_plan
    from feed_axis_energy.sim import phase_covered, simulate_stream
    limits = machine.limits()
    duration = None
    warnings = None
    if args.method == 'phases' and phase_covered(machine):
        return _run_phases(args, machine, options, progress, trace=trace, export=export)
    if args.max_samples or args.out is not None:
        first = _Moves(args, machine, check=True)
        estimate = estimate_plan(first, limits, options=options, file=first.file)
        warnings = first.warnings(args)
        check_cost(args, estimate, n_axes=len(limits), rate_hz=options.rate_hz,
                   file=first.file)
        duration = estimate.duration_s
        check_start(args, duration)
        moves = _Moves(args, machine, check=False)
    else:
        moves = _Moves(args, machine, check=True, progress=progress,
                       n_lines=_count_lines(args.program))
    top = args.top
    n_lines = moves.n_lines or _count_lines(args.program)
    kw = dict(file=moves.file, load_kg=args.load_kg, options=options, top_blocks=top,
              duration_s=duration, progress=progress if duration else None, limits=limits,
              block_breakdown=_breakdown_per_block(args, machine, export, n_lines),
              rollup=True, context=moves.stream.context)
    if args.out is None:
        # chunk_gaps: the report's trace takes the chunks as computed (dwells left out: their
        # power is constant, so a plot is the same); the exports get them at full rate
        summary, blocks = simulate_stream(
            moves, machine, chunk_gaps=True,
            on_chunk=consumers(None, trace, export, options.rate_hz), **kw)
    else:
        with staged_out(args) as staged, _bag_writer(args, staged, options) as writer:
            # chunk_gaps: the writer takes the left-out dwell samples as they are (record.thinning)
            summary, blocks = simulate_stream(moves, machine,
                                              on_chunk=consumers(writer, trace, export,
                                                                 options.rate_hz),
                                              chunk_gaps=True, **kw)
            writer.finish(blocks, summary=summary, stamp_s=summary['duration_s'])
            if export:
                # inside the staged bag: a failure here leaves no bag either
                export.write_blocks(blocks)
    if export and args.out is None:
        export.write_blocks(blocks)
    progress.done()
    if warnings is None:
        warnings = moves.warnings(args)
    summary['method'] = 'samples'
    return summary, warnings, blocks


def _bag_writer(args, staged, options):
    """The ``--out`` recording's writer into the staged directory."""
    from feed_axis_energy.record import SimulationBagWriter
    return SimulationBagWriter(staged, compression=args.compression, rate_hz=options.rate_hz,
                               plot_rate_hz=args.plot_rate_hz,
                               start_ns=args.start_time or 0)


def _breakdown_per_block(args, machine, export, n_lines: int) -> bool:
    """Keep the per-block breakdown: when an export needs it or it fits the byte budget."""
    columns = len(machine.limits()) + 8 + len(machine.effects)
    if machine.electrical:
        # the electrical side's own per-line table: axes and causes with the drives' four
        columns *= 2
        columns += 4
    return bool(export) or 8 * columns * n_lines <= BLOCK_BREAKDOWN_BYTES


def _run_phases(args, machine, options, progress, *, trace=None,
                export=None) -> tuple[dict, list[str], object]:
    """The summary by phase (:func:`feed_axis_energy.sim.summarize_phases`: no samples);
    samples only for the recording, the exports and the report's curves, in a second pass
    that reads the program again."""
    from types import SimpleNamespace
    from feed_axis_energy.plan import grid_samples
    from feed_axis_energy.sim import sample_chunks, summarize_phases
    n_lines = _count_lines(args.program)
    outputs = args.out is not None or trace is not None or bool(export)
    moves = _Moves(args, machine, check=True, progress=progress, n_lines=n_lines)
    summary, blocks = summarize_phases(
        moves, machine, file=moves.file, load_kg=args.load_kg, options=options,
        top_blocks=args.top, block_breakdown=_breakdown_per_block(args, machine, export, n_lines),
        rollup=True, context=moves.stream.context)
    progress.done()
    warnings = moves.warnings(args)
    duration = summary['duration_s']
    estimate = SimpleNamespace(duration_s=duration,
                               samples=grid_samples(duration, options.rate_hz))
    check_cost(args, estimate, n_axes=len(machine.limits()), rate_hz=options.rate_hz,
               file=moves.file)
    if not outputs:
        return summary, warnings, blocks
    check_start(args, duration)
    from feed_axis_energy.cli.progress import Progress
    progress = Progress('simulate samples', enabled=progress.enabled)
    again = _Moves(args, machine, check=False)
    # the chunks as computed (dwells left out; the exporter expands them, see consumers)
    chunks = sample_chunks(again, machine, file=again.file, load_kg=args.load_kg,
                           options=options, duration_s=duration, progress=progress)
    if args.out is None:
        take = consumers(None, trace, export, options.rate_hz)
        for chunk in chunks:
            take(chunk)
        if export:
            export.write_blocks(blocks)
    else:
        with staged_out(args) as staged, _bag_writer(args, staged, options) as writer:
            take = consumers(writer, trace, export, options.rate_hz)
            for chunk in chunks:
                take(chunk)
            writer.finish(blocks, summary=summary, stamp_s=duration)
            if export:
                export.write_blocks(blocks)
    progress.done()
    return summary, warnings, blocks


def _warn(args, program, machine) -> list[str]:
    """Print the parser's and ``check``'s sanity warnings on stderr; return them."""
    from feed_axis_energy.gcode import warning_texts
    texts = warning_texts(args.program, program, machine)
    for text in texts:
        print(f'warning: {text}', file=sys.stderr)
    return texts


def _run_whole(args, machine, options, progress, *, trajectory: bool,
               warnings: list[str], trace=None, export=None) -> tuple[dict, list]:
    """Whole-record path: trajectory CSVs and declared effects that need the whole record."""
    from feed_axis_energy.cli.common import program_keywords
    from feed_axis_energy.cli.progress import Progress
    from feed_axis_energy.gcode import load_gcode
    from feed_axis_energy.sim import (load_trajectory_csv, simulate_motion, simulate_program,
                                      summarize)
    from feed_axis_energy.record import write_simulation_bag
    from feed_axis_energy.physics import energy_by_line
    if trajectory:
        motion = load_trajectory_csv(args.program, axes=machine.axis_names)
        result = simulate_motion(motion, machine, load_kg=args.load_kg)
    else:
        program = load_gcode(args.program, **program_keywords(machine, args))
        warnings.extend(_warn(args, program, machine))
        result = simulate_program(program, machine, load_kg=args.load_kg, options=options,
                                  progress=progress)
    progress.done()
    # A trajectory has no source lines to attribute energy to.
    summary = summarize(result, top_blocks=0 if trajectory else args.top)
    summary['method'] = 'samples'

    if export:
        from feed_axis_energy.sim import line_table
        export.series.write(result)
        export.write_blocks(line_table(result))
    if args.out is not None:
        check_start(args, summary['duration_s'])
        with staged_out(args) as staged:
            write_simulation_bag(staged, result, summary=summary,
                                 progress=Progress('write bag', enabled=not args.quiet),
                                 compression=args.compression,
                                 plot_rate_hz=args.plot_rate_hz,
                                 start_ns=args.start_time or 0)
    blocks: list = []
    if trace is not None:
        trace.add(result)
        blocks = [] if trajectory else energy_by_line(result.power)
    return summary, blocks
