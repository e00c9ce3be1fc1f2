"""What ``simulate`` writes beside its summary: the recording (its cost checked before any
sample, built in a hidden temporary), the ``--csv``/``--parquet`` exports, the ``--report``
page, and the one list of consumers that takes each simulated chunk to them.
"""
from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from feed_axis_energy.errors import ConfigError

__all__ = ['bag_bytes_per_sample', 'check_cost', 'check_start', 'consumers', 'export_targets',
           'Exports', 'report_trace', 'staged_out', 'usage_error', 'write_report']


def usage_error(text: str) -> SystemExit:
    """Print a usage error as argparse does; the caller raises the result (exit 2)."""
    print(f'usage: feed-axis-energy simulate ... (see --help)\n'
          f'feed-axis-energy simulate: error: {text}', file=sys.stderr)
    return SystemExit(2)


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


def report_trace(args: argparse.Namespace):
    """The decimated series for ``--report`` (None without it)."""
    if args.report is None:
        return None
    from feed_axis_energy.report import PowerTrace
    return PowerTrace()


def write_report(args: argparse.Namespace, summary: dict, trace, blocks, *,
                 trajectory: bool) -> None:
    """Write the ``--report`` directory (all or nothing)."""
    from feed_axis_energy.cli.common import program_text_lines
    from feed_axis_energy.report import write_sim_report

    def text(lines: list[int]) -> dict[int, str]:
        return {} if trajectory else program_text_lines(args.program, lines)

    if not args.quiet:
        print('simulate: writing the report', file=sys.stderr)
    write_sim_report(summary, trace, blocks, args.report, block_text=text, force=args.force)


def export_targets(args: argparse.Namespace, rate_hz: float) -> dict:
    """``{'csv': DIR, 'parquet': DIR}`` of the requested exports, checked before any work
    (and the decimation from ``--decimate`` / ``--export-rate-hz`` in ``args.decimate``)."""
    from feed_axis_energy.sim import EXPORT_MARKER
    from feed_axis_energy.outputs import check_target, marked_or_empty
    exports = {fmt: getattr(args, fmt) for fmt in ('csv', 'parquet')
               if getattr(args, fmt) is not None}
    if (args.decimate or args.export_rate_hz) and not exports:
        raise usage_error('--decimate and --export-rate-hz apply to --csv or --parquet, '
                          'neither given')
    if len({Path(p).resolve() for p in exports.values()}) < len(exports):
        raise usage_error('--csv and --parquet name the same directory')
    if args.export_rate_hz is not None:
        hz = args.export_rate_hz
        if hz > rate_hz:
            msg = (f'--export-rate-hz {hz:g} Hz is above the sample rate {rate_hz:g} Hz; '
                   'give at most the sample rate')
            raise ConfigError(msg, file='command line', key='export-rate-hz')
        args.decimate = max(1, round(rate_hz / hz))
    if 'parquet' in exports:
        from feed_axis_energy.sim import require_pyarrow
        require_pyarrow('--parquet')        # before any work: a clear error if missing
    for fmt, path in exports.items():
        check_target(path, option=f'--{fmt}', force=args.force, kind='directory',
                     replaceable=marked_or_empty(EXPORT_MARKER))
    return exports


class Exports:
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

    def __enter__(self) -> 'Exports':
        if not self.targets:                # no export: nothing staged, nothing imported
            return self
        from feed_axis_energy.sim import EXPORT_MARKER, SeriesExporter
        from feed_axis_energy.outputs import marked_or_empty, staged_directory
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
        from feed_axis_energy.sim import write_blocks
        if self.dirs:
            write_blocks(self.dirs, blocks, program=self.args.program)

    def write_rollups(self, summary: dict) -> None:
        """The roll-ups per operation, subroutine, tool and axis (when the summary has them)."""
        from feed_axis_energy.sim import write_rollups
        if self.dirs:
            write_rollups(self.dirs, summary.get('rollups'))

    def __exit__(self, exc_type, exc, tb):
        if self.series is not None:
            self.series.close()
        if self._stack is None:
            return False
        return self._stack.__exit__(exc_type, exc, tb)


def check_cost(args: argparse.Namespace, estimate, *, n_axes: int, rate_hz: float,
               file: str) -> None:
    """Refuse, before any sample is computed, a run beyond a documented limit."""
    from feed_axis_energy.errors import PlanningError
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


def staged_out(args: argparse.Namespace):
    """The ``--out`` bag directory, built in a hidden temporary and renamed when complete."""
    from feed_axis_energy.outputs import is_bag_directory, staged_directory
    return staged_directory(args.out, option='--out', force=args.force,
                            replaceable=is_bag_directory)


def consumers(writer, trace, export, rate: float):
    """``on_chunk`` for the bag writer and the report's trace (compact dwells, as computed)
    and the exports (full rate); ``None`` when nothing takes the chunks."""
    takers = []
    if writer is not None:
        takers.append(writer.write)
    if trace is not None:
        takers.append(trace.add)
    if export:
        from feed_axis_energy.sim import expand_gaps

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


def check_start(args, duration_s: float) -> None:
    """Refuse a ``--start-time`` whose recording would end past the ROS 2 time range."""
    if args.out is None or args.start_time is None:
        return
    from feed_axis_energy.record import check_end
    why = check_end(args.start_time, duration_s)
    if why is not None:
        raise ConfigError(why, file='command line', key='start-time')
