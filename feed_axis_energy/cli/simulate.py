"""``feed-axis-energy simulate``: one NC program on one machine, energy per axis and per block."""
from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import sys
from pathlib import Path

from feed_axis_energy.cli.common import add_machine_options
from feed_axis_energy.core.errors import ConfigError, shorten

# plottopics' constant, repeated so that --help does not import numpy (a test compares them)
DEFAULT_PLOT_RATE_HZ = 20.0

__all__ = ['add_parser', 'run', 'bag_bytes_per_sample']

# Recorded bytes per sample (all three topics, MCAP without compression; an upper bound of
# the zstd-compressed size, which varies with the data) with k axes:
# /setpoints 3 arrays of k doubles, /axis_state 4 arrays of 2k, /power 2 arrays of k + 1,
# plus per-point lengths and stamps; measured 228 B (1 axis) and 437 B (3 axes), see README.
_BAG_BYTES_AXIS = 105
_BAG_BYTES_BASE = 125
# The plot topics (one /plot/power and one /plot/axes JointState per kept sample, record and
# index included): about 214 + 56 bytes per axis, rounded up
_PLOT_BYTES_AXIS = 60
_PLOT_BYTES_BASE = 220
_DISK_RESERVE = 1.1      # refuse when the estimate exceeds 1 / 1.1 of the free space
BLOCK_TEXT_CHARS = 60    # block text shown in top_blocks (cut with '...')
# the per-block breakdown costs 8 (axes + causes) bytes per program line; kept when the
# program's lines need at most this much, or when an export needs the per-block table
BLOCK_BREAKDOWN_BYTES = 16 << 20


def bag_bytes_per_sample(n_axes: int, *, plot_rate_hz: float | None = None,
                         rate_hz: float = 1000.0) -> float:
    """Estimated recording size per sample [bytes] for ``n_axes`` axes (see README).

    With ``plot_rate_hz`` the plot topics are counted at their largest share: per display
    interval at most ``2 * n_axes + 3`` kept samples (the first and each power column's
    extremes), all samples at 0 Hz.
    """
    k = int(n_axes)
    size = float(_BAG_BYTES_BASE + _BAG_BYTES_AXIS * k)
    if plot_rate_hz is not None:
        share = 1.0 if plot_rate_hz <= 0 else min(1.0, (2 * k + 3) * plot_rate_hz / rate_hz)
        size += share * (_PLOT_BYTES_BASE + _PLOT_BYTES_AXIS * k)
    return size


def _plot_rate(text: str) -> float:
    """``--plot-rate-hz``: a finite number >= 0 (a usage error otherwise)."""
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not math.isfinite(value) or value < 0:
        msg = f'expected a number of hertz >= 0 (0: every sample), got {text[:60]!r}'
        raise argparse.ArgumentTypeError(msg)
    return value


def _start_time(text: str) -> int:
    """``--start-time``: ``now`` or ISO-8601 -> ns since the epoch (a usage error otherwise)."""
    from feed_axis_energy.core.starttime import parse_start_time
    try:
        return parse_start_time(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


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
    rate.add_argument('--decimate', type=_positive_int, default=None, metavar='N',
                      help='exported time series: every N-th sample (default 1: all)')
    rate.add_argument('--export-rate-hz', type=_positive_float, default=None, metavar='HZ',
                      help='exported time series: about HZ samples per second (every '
                           'round(rate/HZ)-th sample)')
    p.add_argument('--plot-rate-hz', type=_plot_rate, default=DEFAULT_PLOT_RATE_HZ,
                   metavar='HZ',
                   help='display rate of the --out recording\'s plot topics /plot/power and '
                        '/plot/axes (one sample per message; per interval of 1/HZ the first '
                        'sample and those of each power and torque minimum and maximum, so '
                        f'no peak is lost); 0: every sample (default {DEFAULT_PLOT_RATE_HZ:g})')
    p.add_argument('--start-time', type=_start_time, default=None, metavar='now|ISO-8601',
                   help='stamp the --out recording in wall-clock time from this start (e.g. '
                        '2026-11-23T14:00:00Z; no offset: UTC) instead of simulation time '
                        'from 0 (the default)')
    p.add_argument('--json', action='store_true',
                   help='print one JSON object instead of the table (keys in README)')
    p.add_argument('--top', type=int, default=5, metavar='N',
                   help='number of most energetic blocks to list (default: 5)')
    p.add_argument('--max-samples', type=int, default=0, metavar='N',
                   help='refuse programs that need more than N samples (default 0: no limit); '
                        'the count is known from the plan before any sample is computed')
    p.add_argument('--quiet', action='store_true', help='no progress indication')
    p.set_defaults(run=run)


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f'expected an integer >= 1, got {shorten(text)!r}')
    return value


def _positive_float(text: str) -> float:
    import math
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f'expected a number > 0, got {shorten(text)!r}')
    return value


def _usage_error(text: str) -> SystemExit:
    """Print a usage error as argparse does; the caller raises the result (exit 2)."""
    print(f'usage: feed-axis-energy simulate ... (see --help)\n'
          f'feed-axis-energy simulate: error: {text}', file=sys.stderr)
    return SystemExit(2)


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    # imported here: ``feed-axis-energy --help`` must not pay for the simulation's imports
    from feed_axis_energy.cli.common import (load_machine_and_options, print_summary,
                                             program_text_lines)
    from feed_axis_energy.cli.progress import Progress
    from feed_axis_energy.core.simstream import streamable

    machine, options = load_machine_and_options(args)
    if args.out is not None:
        from feed_axis_energy.core.outputs import check_target, is_bag_directory
        # refused before any sample is computed, not after
        check_target(args.out, option='--out', force=args.force, kind='directory',
                     replaceable=is_bag_directory)
    if args.report is not None:
        from feed_axis_energy.core.outputs import check_target, marked_or_empty
        from feed_axis_energy.report import MARKER
        check_target(args.report, option='--report', force=args.force, kind='directory',
                     replaceable=marked_or_empty(MARKER))
    exports = _export_targets(args, options.rate_hz)
    if args.max_samples < 0:
        msg = f'--max-samples must be >= 0, got {args.max_samples}'
        raise ConfigError(msg, file='command line', key='max-samples')
    progress = Progress('simulate', enabled=not args.quiet)
    trajectory = args.program.suffix.lower() == '.csv'
    warnings: list[str] = []
    trace = _trace(args)
    new_bag = args.out is not None and not os.path.lexists(args.out)
    # the bag, the exports and the report or none of them: a new bag is removed if an export
    # or the report fails (one that replaced an earlier bag with --force cannot be brought
    # back); the exports are staged and only renamed into place at the end
    if args.out is not None or args.report is not None or exports:
        from feed_axis_energy.core.outputs import Rollback
        guard = Rollback()
    else:                                   # nothing to write: no output machinery imported
        guard = contextlib.nullcontext()
    with guard as written, _Exports(args, exports) as export:
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
        lines = [b['line'] for b in summary['top_blocks']]
        texts = {} if trajectory else program_text_lines(args.program, lines)
        for block in summary['top_blocks']:
            block['text'] = shorten(texts.get(block['line'], '').strip(),
                                    limit=BLOCK_TEXT_CHARS)
        if args.report is not None:
            summary['report'] = str(args.report / 'index.html')
            _write_report(args, summary, trace, blocks, trajectory=trajectory)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print_summary(summary, source_lines=texts)
        if args.out is not None:
            print(f'recording: {args.out} (topics /setpoints, /axis_state, /power, '
                  '/block_energy; plot-ready /plot/power, /plot/axes, /plot/block_energy; '
                  'units in README)')
        for fmt, path in exports.items():
            print(f'{fmt}: {path} (timeseries.{fmt}, blocks.{fmt}; columns in README)')
    return 0


def _trace(args: argparse.Namespace):
    """The decimated series for ``--report`` (None without it)."""
    if args.report is None:
        return None
    from feed_axis_energy.report.decimate import PowerTrace
    return PowerTrace()


def _write_report(args: argparse.Namespace, summary: dict, trace, blocks, *,
                  trajectory: bool) -> None:
    """Write the ``--report`` directory (all or nothing)."""
    from feed_axis_energy.cli.common import program_text_lines
    from feed_axis_energy.report.sim_report import write_sim_report

    def text(lines: list[int]) -> dict[int, str]:
        return {} if trajectory else program_text_lines(args.program, lines)

    if not args.quiet:
        print('simulate: writing the report', file=sys.stderr)
    write_sim_report(summary, trace, blocks, args.report, block_text=text, force=args.force)


def _export_targets(args: argparse.Namespace, rate_hz: float) -> dict:
    """``{'csv': DIR, 'parquet': DIR}`` of the requested exports, checked before any work
    (and the decimation from ``--decimate`` / ``--export-rate-hz`` in ``args.decimate``)."""
    from feed_axis_energy.core.exports import EXPORT_MARKER
    from feed_axis_energy.core.outputs import check_target, marked_or_empty
    exports = {fmt: getattr(args, fmt) for fmt in ('csv', 'parquet')
               if getattr(args, fmt) is not None}
    if (args.decimate or args.export_rate_hz) and not exports:
        raise _usage_error('--decimate and --export-rate-hz apply to --csv or --parquet, '
                           'neither given')
    if len({Path(p).resolve() for p in exports.values()}) < len(exports):
        raise _usage_error('--csv and --parquet name the same directory')
    if args.export_rate_hz is not None:
        hz = args.export_rate_hz
        if hz > rate_hz:
            msg = (f'--export-rate-hz {hz:g} Hz is above the sample rate {rate_hz:g} Hz; '
                   'give at most the sample rate')
            raise ConfigError(msg, file='command line', key='export-rate-hz')
        args.decimate = max(1, round(rate_hz / hz))
    if 'parquet' in exports:
        from feed_axis_energy.core.exports import require_pyarrow
        require_pyarrow('--parquet')        # before any work: a clear error if missing
    for fmt, path in exports.items():
        check_target(path, option=f'--{fmt}', force=args.force, kind='directory',
                     replaceable=marked_or_empty(EXPORT_MARKER))
    return exports


class _Exports:
    """The ``--csv``/``--parquet`` directories, staged (hidden temporaries renamed into
    place when the command succeeds, removed when it fails), and their time series."""

    def __init__(self, args: argparse.Namespace, targets: dict) -> None:
        self.args = args
        self.targets = targets
        self.series = None
        self.dirs: dict = {}
        self._stack = None

    def __bool__(self) -> bool:
        return bool(self.targets)

    def __enter__(self) -> '_Exports':
        if not self.targets:                # no export: nothing staged, nothing imported
            return self
        from feed_axis_energy.core.exports import EXPORT_MARKER, SeriesExporter
        from feed_axis_energy.core.outputs import marked_or_empty, staged_directory
        self._stack = contextlib.ExitStack()
        try:
            for fmt, path in self.targets.items():
                inner = self._stack.enter_context(staged_directory(
                    path, option=f'--{fmt}', force=self.args.force,
                    replaceable=marked_or_empty(EXPORT_MARKER)))
                inner.mkdir()
                (inner / EXPORT_MARKER).write_text('feed-axis-energy simulate export\n',
                                                   encoding='utf-8')
                self.dirs[fmt] = inner
            if self.dirs:
                self.series = SeriesExporter(self.dirs, decimate=self.args.decimate or 1)
        except BaseException:
            self._stack.__exit__(*sys.exc_info())
            raise
        return self

    def write_blocks(self, blocks) -> None:
        """The per-block tables (needs the per-block breakdown)."""
        from feed_axis_energy.core.exports import write_blocks
        if self.dirs:
            write_blocks(self.dirs, blocks, program=self.args.program)

    def __exit__(self, exc_type, exc, tb):
        if self.series is not None:
            self.series.close()
        if self._stack is None:
            return False
        return self._stack.__exit__(exc_type, exc, tb)


def _check_cost(args: argparse.Namespace, estimate, *, n_axes: int, rate_hz: float,
                file: str) -> None:
    """Refuse, before any sample is computed, a run beyond a documented limit."""
    from feed_axis_energy.core.errors import PlanningError
    samples, duration = estimate.samples, estimate.duration_s
    what = f'{samples:,} samples ({duration / 3600.0:.2f} h at {rate_hz:g} Hz)'
    if args.max_samples and samples > args.max_samples:
        rate = args.max_samples / max(duration, 1e-9)
        msg = (f'the run needs {what}, more than --max-samples {args.max_samples:,}; '
               f'lower the rate (--rate-hz {max(rate, 1e-3):.3g} fits) or raise the limit')
        raise PlanningError(msg, file=file)
    if args.out is not None:
        import shutil
        per_sample = bag_bytes_per_sample(n_axes, plot_rate_hz=args.plot_rate_hz,
                                          rate_hz=rate_hz)
        need = samples * per_sample
        parent = args.out.resolve().parent
        free = shutil.disk_usage(parent).free if parent.is_dir() else None
        if free is not None and need * _DISK_RESERVE > free:
            rate = free / _DISK_RESERVE / per_sample / max(duration, 1e-9)
            msg = (f'the recording of {what} needs about {need / 1e9:.2f} GB but {parent} '
                   f'has {free / 1e9:.2f} GB free; lower the rate (--rate-hz '
                   f'{max(rate, 1e-3):.3g} fits) or write elsewhere')
            raise PlanningError(msg, file=file)


def _staged_out(args: argparse.Namespace):
    """The ``--out`` bag directory, built in a hidden temporary and renamed when complete."""
    from feed_axis_energy.core.outputs import is_bag_directory, staged_directory
    return staged_directory(args.out, option='--out', force=args.force,
                            replaceable=is_bag_directory)


class _Moves:
    """One pass over the program's moves, streamed from the file (memory: one batch of
    moves, not the program), feeding the sanity checks and reporting progress by line."""

    def __init__(self, args: argparse.Namespace, machine, *, check: bool,
                 progress=None, n_lines: int = 0) -> None:
        from feed_axis_energy.cli.check import sanity_checker
        from feed_axis_energy.cli.common import program_keywords
        from feed_axis_energy.core.gcode import iter_moves
        self.stream = iter_moves(args.program, **program_keywords(machine, args))
        self.file = self.stream.file
        self.checker = sanity_checker(args.program, machine) if check else None
        self.progress = progress if n_lines > 0 else None
        self.n_lines = n_lines

    def __iter__(self):
        progress, n_lines = self.progress, self.n_lines
        count = 0
        batch: list = []                # checked 4096 at a time (add_many: arrays)
        for move in self.stream:
            batch.append(move)
            count += 1
            if not count & 4095:
                self._check(batch)
                batch = []
                if progress is not None:
                    progress(min(move.line / n_lines, 1.0))
            yield move
        self._check(batch)

    def _check(self, batch: list) -> None:
        if self.checker is not None and batch:
            self.checker.add_many(batch)

    def warnings(self, args: argparse.Namespace) -> list[str]:
        """Print the parser's and ``check``'s warnings on stderr (after the pass); return
        them."""
        from feed_axis_energy.cli.check import checked_warning_texts
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
    from feed_axis_energy.core.planstream import estimate_plan
    from feed_axis_energy.core.simstream import simulate_stream
    limits = machine.limits()
    duration = None
    warnings = None
    if args.max_samples or args.out is not None:
        first = _Moves(args, machine, check=True)
        estimate = estimate_plan(first, limits, options=options, file=first.file)
        warnings = first.warnings(args)
        _check_cost(args, estimate, n_axes=len(limits), rate_hz=options.rate_hz,
                    file=first.file)
        duration = estimate.duration_s
        _check_start(args, duration)
        moves = _Moves(args, machine, check=False)
    else:
        moves = _Moves(args, machine, check=True, progress=progress,
                       n_lines=_count_lines(args.program))
    top = args.top
    n_lines = moves.n_lines or _count_lines(args.program)
    columns = len(limits) + 8 + len(machine.effects)
    kw = dict(file=moves.file, load_kg=args.load_kg, options=options, top_blocks=top,
              duration_s=duration, progress=progress if duration else None, limits=limits,
              block_breakdown=bool(export) or 8 * columns * n_lines <= BLOCK_BREAKDOWN_BYTES,
              rollup=True, context=moves.stream.context)
    if args.out is None:
        # chunk_gaps: the report's trace takes the chunks as computed (dwells left out: their
        # power is constant, so a plot is the same); the exports get them at full rate
        summary, blocks = simulate_stream(
            moves, machine, chunk_gaps=True,
            on_chunk=_consumers(None, trace, export, options.rate_hz), **kw)
    else:
        from feed_axis_energy.core.recording import SimulationBagWriter
        with _staged_out(args) as staged, \
                SimulationBagWriter(staged, compression=args.compression,
                                    rate_hz=options.rate_hz,
                                    plot_rate_hz=args.plot_rate_hz,
                                    start_ns=args.start_time or 0) as writer:
            # chunk_gaps: the writer takes the left-out dwell samples as they are (recthin)
            summary, blocks = simulate_stream(moves, machine,
                                              on_chunk=_consumers(writer, trace, export,
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
    return summary, warnings, blocks


def _consumers(writer, trace, export, rate: float):
    """``on_chunk`` for the bag writer and the report's trace (compact dwells, as computed)
    and the exports (full rate); ``None`` when nothing takes the chunks."""
    takers = []
    if writer is not None:
        takers.append(writer.write)
    if trace is not None:
        takers.append(trace.add)
    if export:
        from feed_axis_energy.core.simstream import expand_gaps

        def to_export(chunk) -> None:
            for piece in expand_gaps(chunk, rate_hz=rate):
                export.series.write(piece)
        takers.append(to_export)
    if not takers:
        return None
    if len(takers) == 1:
        return takers[0]

    def take(chunk) -> None:
        for taker in takers:
            taker(chunk)
    return take


def _check_start(args, duration_s: float) -> None:
    """Refuse a ``--start-time`` whose recording would end past the ROS 2 time range."""
    if args.out is None or args.start_time is None:
        return
    from feed_axis_energy.core.starttime import check_end
    why = check_end(args.start_time, duration_s)
    if why is not None:
        raise ConfigError(why, file='command line', key='start-time')


def _warn(args, program, machine) -> list[str]:
    """Print the parser's and ``check``'s sanity warnings on stderr; return them."""
    from feed_axis_energy.cli.check import warning_texts
    texts = warning_texts(args.program, program, machine)
    for text in texts:
        print(f'warning: {text}', file=sys.stderr)
    return texts


def _run_whole(args, machine, options, progress, *, trajectory: bool,
               warnings: list[str], trace=None, export=None) -> tuple[dict, list]:
    """Whole-record path: trajectory CSVs and declared effects that need the whole record."""
    from feed_axis_energy.cli.common import program_keywords
    from feed_axis_energy.cli.progress import Progress
    from feed_axis_energy.core.gcode import load_gcode
    from feed_axis_energy.core.measured.trajcsv import load_trajectory_csv
    from feed_axis_energy.core.recording import write_simulation_bag
    from feed_axis_energy.core.energy import energy_by_line
    from feed_axis_energy.core.simulate import simulate_motion, simulate_program, summarize
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
    if export:
        from feed_axis_energy.core.simulate import line_table
        export.series.write(result)
        export.write_blocks(line_table(result))
    if args.out is not None:
        _check_start(args, summary['duration_s'])
        with _staged_out(args) as staged:
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
