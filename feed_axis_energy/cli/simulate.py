"""``feed-axis-energy simulate``: one NC program on one machine, energy per axis and per block."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from feed_axis_energy.cli.common import add_machine_options
from feed_axis_energy.core.errors import ConfigError

__all__ = ['add_parser', 'run', 'bag_bytes_per_sample']

# Recorded bytes per sample (all three topics, MCAP without compression; an upper bound of
# the zstd-compressed size, which varies with the data) with k axes:
# /setpoints 3 arrays of k doubles, /axis_state 4 arrays of 2k, /power 2 arrays of k + 1,
# plus per-point lengths and stamps; measured 228 B (1 axis) and 437 B (3 axes), see README.
_BAG_BYTES_AXIS = 105
_BAG_BYTES_BASE = 125
_DISK_RESERVE = 1.1      # refuse when the estimate exceeds 1 / 1.1 of the free space


def bag_bytes_per_sample(n_axes: int) -> int:
    """Estimated recording size per sample [bytes] for ``n_axes`` axes (see README)."""
    return _BAG_BYTES_BASE + _BAG_BYTES_AXIS * int(n_axes)


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
    p.add_argument('--force', action='store_true',
                   help='replace an existing --out bag directory (only a rosbag2 directory, '
                        'never a symbolic link) once the new one is complete')
    p.add_argument('--compression', choices=('none', 'zstd'), default='zstd',
                   help='MCAP chunk compression of the --out recording (default zstd at the '
                        'fast level -1: about 5x smaller for 1.2-1.5x the writer\'s CPU time)')
    p.add_argument('--json', action='store_true',
                   help='print one JSON object instead of the table (keys in README)')
    p.add_argument('--top', type=int, default=5, metavar='N',
                   help='number of most energetic blocks to list (default: 5)')
    p.add_argument('--max-samples', type=int, default=0, metavar='N',
                   help='refuse programs that need more than N samples (default 0: no limit); '
                        'the count is known from the plan before any sample is computed')
    p.add_argument('--quiet', action='store_true', help='no progress indication')
    p.set_defaults(run=run)


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
    if args.max_samples < 0:
        msg = f'--max-samples must be >= 0, got {args.max_samples}'
        raise ConfigError(msg, file='command line', key='max-samples')
    progress = Progress('simulate', enabled=not args.quiet)
    trajectory = args.program.suffix.lower() == '.csv'
    warnings: list[str] = []
    if trajectory or not streamable(machine):
        summary = _run_whole(args, machine, options, progress, trajectory=trajectory,
                             warnings=warnings)
    else:
        summary, warnings = _run_stream(args, machine, options, progress)
    summary['warnings'] = warnings
    if args.out is not None:
        summary['bag'] = str(args.out)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        lines = [b['line'] for b in summary['top_blocks']]
        print_summary(summary, source_lines=program_text_lines(args.program, lines))
        if args.out is not None:
            print(f'recording: {args.out} (topics /setpoints, /axis_state, /power, '
                  '/block_energy; units in README)')
    return 0


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
        need = samples * bag_bytes_per_sample(n_axes)
        parent = args.out.resolve().parent
        free = shutil.disk_usage(parent).free if parent.is_dir() else None
        if free is not None and need * _DISK_RESERVE > free:
            rate = free / _DISK_RESERVE / bag_bytes_per_sample(n_axes) / max(duration, 1e-9)
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


def _run_stream(args, machine, options, progress) -> tuple[dict, list[str]]:
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
        moves = _Moves(args, machine, check=False)
    else:
        moves = _Moves(args, machine, check=True, progress=progress,
                       n_lines=_count_lines(args.program))
    top = args.top
    kw = dict(file=moves.file, load_kg=args.load_kg, options=options, top_blocks=top,
              duration_s=duration, progress=progress if duration else None, limits=limits)
    if args.out is None:
        summary, _ = simulate_stream(moves, machine, **kw)
    else:
        from feed_axis_energy.core.recording import SimulationBagWriter
        with _staged_out(args) as staged, \
                SimulationBagWriter(staged, compression=args.compression,
                                    rate_hz=options.rate_hz) as writer:
            # chunk_gaps: the writer takes the left-out dwell samples as they are (recthin)
            summary, blocks = simulate_stream(moves, machine, on_chunk=writer.write,
                                              chunk_gaps=True, **kw)
            writer.finish(blocks, summary=summary, stamp_s=summary['duration_s'])
    progress.done()
    if warnings is None:
        warnings = moves.warnings(args)
    return summary, warnings


def _warn(args, program, machine) -> list[str]:
    """Print the parser's and ``check``'s sanity warnings on stderr; return them."""
    from feed_axis_energy.cli.check import warning_texts
    texts = warning_texts(args.program, program, machine)
    for text in texts:
        print(f'warning: {text}', file=sys.stderr)
    return texts


def _run_whole(args, machine, options, progress, *, trajectory: bool,
               warnings: list[str]) -> dict:
    """Whole-record path: trajectory CSVs and declared effects that need the whole record."""
    from feed_axis_energy.cli.common import program_keywords
    from feed_axis_energy.cli.progress import Progress
    from feed_axis_energy.core.gcode import load_gcode
    from feed_axis_energy.core.measured.trajcsv import load_trajectory_csv
    from feed_axis_energy.core.recording import write_simulation_bag
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
    if args.out is not None:
        with _staged_out(args) as staged:
            write_simulation_bag(staged, result, summary=summary,
                                 progress=Progress('write bag', enabled=not args.quiet),
                                 compression=args.compression)
    return summary
