"""Campaigns: many independent simulations (programs x machines x loads) as plain jobs.

A job (:class:`BatchJob`) is plain, picklable data: paths as text and numbers, never a
machine object, so that it crosses process and host boundaries unchanged. :func:`run_job` is
a top-level function that loads the machine and the program itself and runs one
:func:`.stream.simulate_stream` (or the whole-record path for trajectory CSVs and
declared effects that need the whole record, as ``simulate`` does). A job that fails (a
program the parser or planner refuses, a missing file) returns a :class:`JobResult` with the
error instead of raising, so one bad program does not end a campaign.

:func:`.bundle.run_batch` runs many of them on any executor.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
from typing import Any

from ..errors import ConfigError, FeedAxisError, PlanningError, shorten

__all__ = ['MAX_JOBS', 'PROFILES', 'COMPRESSIONS', 'BatchJob', 'JobResult', 'run_job',
           'job_machine', 'job_options', 'failed_result', 'finish_result']

MAX_JOBS = 100_000
"""Most jobs one batch may hold (the results are kept in memory: about 2 kB each)."""
PROFILES = ('jerk', 'trapezoid')
COMPRESSIONS = ('zstd', 'none')
_MAX_WARNINGS = 5          # warnings kept per job (a program may warn on every line)
_ERROR_CHARS = 300         # longest error text kept from an unexpected exception


@dataclass(frozen=True)
class BatchJob:
    """One simulation of a campaign, as plain data.

    Attributes
    ----------
    index
        0-based position in the batch; results are returned in this order.
    program
        The program as the user named it (shown in tables and in the summary).
    program_path
        Absolute path the worker opens (G-code, or a trajectory CSV ending in ``.csv``).
    machine
        The machine config as the user named it (shown).
    machine_path
        Absolute path of the machine YAML the worker loads.
    load_kg
        Workpiece mass [kg], 0 to 1e6.
    rate_hz
        Sample rate [Hz] (0, 1e6], or ``None`` for the machine's.
    profile
        ``'jerk'``, ``'trapezoid'`` or ``None`` for the machine's.
    top_blocks
        Source lines listed in the summary's ``top_blocks``.
    max_samples
        Refuse (as a failed job) a program needing more samples; 0: no limit.
    out
        Absolute path of the job's recording (a rosbag2 directory, as ``simulate --out``),
        or ``''`` for none. Built under a hidden temporary name and renamed when complete;
        a job that fails leaves nothing.
    force
        Replace an existing recording at ``out`` (only a bag directory).
    compression
        MCAP chunk compression of the recording: ``'zstd'`` or ``'none'``.
    overrides
        Changes of the machine config, ``(dotted key, value, relative)`` as in
        :func:`.sweep.apply_overrides` (a what-if variant); empty: the file as it is.
    feed_override, rapid_override
        Factors on the programmed feed and on the rapid speed (:func:`.sweep.override_moves`).
    method
        ``'phases'`` (default): the summary by phase (:func:`.phasesum.summarize_phases`)
        where the machine is covered, as ``simulate``; ``'samples'``: over the samples.
    figures
        With the summary by phase: ``'all'`` (default) or ``'energy'``, the figures a
        sweep compares only (:data:`.phasesum.FIGURES`; cheaper).
    strict_tools, allow_no_feed, subroutine_path
        How the program is read, on top of the machine config's ``gcode`` settings
        (:func:`..gcode.with_program_options`; ``--strict-tools``, ``--allow-no-feed``,
        ``--subroutine-path``): the flags turn the config's on, the directories (absolute)
        are searched after the config's.
    """

    index: int
    program: str
    program_path: str
    machine: str
    machine_path: str
    load_kg: float = 0.0
    rate_hz: float | None = None
    profile: str | None = None
    top_blocks: int = 0
    max_samples: int = 0
    out: str = ''
    force: bool = False
    compression: str = 'zstd'
    overrides: tuple[tuple[str, Any, bool], ...] = ()
    feed_override: float = 1.0
    rapid_override: float = 1.0
    strict_tools: bool = False
    allow_no_feed: bool = False
    subroutine_path: tuple[str, ...] = ()
    method: str = 'phases'
    figures: str = 'all'

    def __post_init__(self) -> None:
        where = f'job {self.index + 1}'
        if self.method not in ('phases', 'samples'):
            msg = f'method must be phases or samples, got {shorten(str(self.method))!r}'
            raise ConfigError(msg, file=where, key='method')
        if self.figures not in ('all', 'energy'):
            msg = f'figures must be all or energy, got {shorten(str(self.figures))!r}'
            raise ConfigError(msg, file=where, key='figures')
        if not 0.0 <= self.load_kg <= 1.0e6:      # also refuses nan and inf
            msg = f'load must be a number of 0 to 1e6 kg, got {self.load_kg!r}'
            raise ConfigError(msg, file=where, key='load_kg')
        if self.rate_hz is not None and not 0.0 < self.rate_hz <= 1.0e6:
            msg = f'rate must be > 0 and <= 1e6 Hz, got {self.rate_hz!r}'
            raise ConfigError(msg, file=where, key='rate_hz')
        if self.profile is not None and self.profile not in PROFILES:
            msg = f'profile must be one of {", ".join(PROFILES)}, got {shorten(self.profile)!r}'
            raise ConfigError(msg, file=where, key='profile')
        if self.top_blocks < 0 or self.max_samples < 0:
            msg = 'top_blocks and max_samples must be >= 0'
            raise ConfigError(msg, file=where, key='top_blocks')
        if self.compression not in COMPRESSIONS:
            msg = (f'compression must be one of {", ".join(COMPRESSIONS)}, got '
                   f'{shorten(self.compression)!r}')
            raise ConfigError(msg, file=where, key='compression')
        if not (0.0 < self.feed_override <= 10.0 and 0.0 < self.rapid_override <= 1.0):
            msg = (f'feed override must be > 0 and <= 10, rapid override > 0 and <= 1, got '
                   f'{self.feed_override!r} and {self.rapid_override!r}')
            raise ConfigError(msg, file=where, key='override')


@dataclass(frozen=True)
class JobResult:
    """What one job produced: the simulation summary, or the error that ended it.

    Attributes
    ----------
    job
        The job.
    summary
        The keys of :func:`.simulate.summarize` (``program`` is ``job.program``), or ``None``
        when the job failed.
    error
        Empty on success; else the message (names file and line/column where known).
    error_type
        Name of the error type (``GcodeError``, ``PlanningError``, ... ``WorkerError`` when the
        executor lost the job, ``InternalError`` for an unexpected exception).
    warnings
        The first warnings of the program (parser warnings), at most 5 plus a count.
    """

    job: BatchJob
    summary: dict[str, Any] | None
    error: str = ''
    error_type: str = ''
    warnings: tuple[str, ...] = field(default=())

    @property
    def ok(self) -> bool:
        """True when the job produced a summary."""
        return self.summary is not None

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able values: the job's inputs, status and summary or error."""
        job = self.job
        out: dict[str, Any] = {
            'job': job.index + 1, 'program': job.program, 'machine': job.machine,
            'load_kg': job.load_kg, 'status': 'ok' if self.ok else 'failed'}
        if self.ok:
            out['summary'] = self.summary
        else:
            out['error'] = self.error
            out['error_type'] = self.error_type
        if self.warnings:
            out['warnings'] = list(self.warnings)
        return out


def job_machine(job: BatchJob):
    """The job's machine (each file and variant loaded once per process)."""
    from .sweep import variant_machine
    machine = variant_machine(job.machine_path, job.overrides)
    if job.strict_tools or job.allow_no_feed or job.subroutine_path:
        from ..gcode import with_program_options
        machine = replace(machine, gcode=with_program_options(
            machine.gcode, strict_tools=job.strict_tools, allow_no_feed=job.allow_no_feed,
            subroutine_path=tuple(job.subroutine_path)))
    return machine


def job_options(job: BatchJob, machine):
    """The job's planner options: the machine's, with the job's rate and profile."""
    options = machine.planner.options()
    if job.rate_hz is not None:
        options = replace(options, rate_hz=float(job.rate_hz))
    if job.profile is not None:
        options = replace(options, profile=job.profile)
    return options


def _all_finite(value: Any) -> bool:
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, dict):
        return all(_all_finite(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return all(_all_finite(v) for v in value)
    return True


def _simulate(job: BatchJob) -> tuple[dict[str, Any], list[str]]:
    """Run one job, with its recording when it has one; raises the core's errors."""
    if not job.out:
        return _run(job, None)
    from ..outputs import is_bag_directory, staged_directory
    with staged_directory(job.out, option='--out', force=job.force,
                          replaceable=is_bag_directory) as staged:
        summary, warnings = _run(job, staged)
    summary['bag'] = job.out
    return summary, warnings


def _run(job: BatchJob, bag) -> tuple[dict[str, Any], list[str]]:
    """Simulate one job; write its recording to the new directory ``bag`` unless None."""
    from .phasesum import summarize_phases
    from .quadrature import phase_covered
    from .stream import sample_chunks, simulate_stream, streamable
    machine = job_machine(job)
    options = job_options(job, machine)
    if job.program_path.lower().endswith('.csv'):
        if job.feed_override != 1.0 or job.rapid_override != 1.0:
            msg = ('feed and rapid overrides apply to NC programs, not to a trajectory CSV '
                   '(its motion is given)')
            raise ConfigError(msg, file=job.program_path)
        from .trajcsv import load_trajectory_csv
        from .simulate import simulate_motion, summarize
        motion = load_trajectory_csv(job.program_path, axes=machine.axis_names)
        if job.max_samples and motion.t.shape[0] > job.max_samples:
            msg = (f'the trajectory has {motion.t.shape[0]:,} samples, more than '
                   f'max_samples {job.max_samples:,}')
            raise PlanningError(msg, file=job.program_path)
        result = simulate_motion(motion, machine, load_kg=job.load_kg)
        summary = summarize(result, top_blocks=0)
        summary['method'] = 'samples'
        _record_whole(job, bag, result, summary)
        return summary, []
    from ..gcode import iter_moves, Program
    # the moves of the whole program, as simulate's streamed path reads them, with the
    # operation context of each (roll-ups per operation, subroutine and tool)
    stream = iter_moves(job.program_path, **machine.gcode_keywords())
    program = Program(moves=tuple(stream), file=stream.file, n_lines=stream.n_lines,
                      warnings=tuple(stream.warnings))
    warnings = list(program.warnings)
    limits = machine.limits()
    if job.feed_override != 1.0 or job.rapid_override != 1.0:
        from .sweep import override_moves
        # one move for one move: the context's marks (move ordinals) still hold
        program = replace(program, moves=tuple(override_moves(
            program.moves, feed=job.feed_override, rapid=job.rapid_override, limits=limits)))
    if job.max_samples:
        from ..plan import estimate_plan
        est = estimate_plan(program.moves, limits, options=options, file=program.file)
        if est.samples > job.max_samples:
            rate = job.max_samples / max(est.duration_s, 1e-9)
            msg = (f'the run needs {est.samples:,} samples ({est.duration_s / 3600.0:.2f} h at '
                   f'{options.rate_hz:g} Hz), more than max_samples {job.max_samples:,}; '
                   f'a rate of {max(rate, 1e-3):.3g} Hz fits')
            raise PlanningError(msg, file=program.file)
    if job.method == 'phases' and phase_covered(machine):
        # the figures by phase (as simulate); samples only for the recording
        summary, blocks = summarize_phases(program.moves, machine, file=program.file,
                                           load_kg=job.load_kg, options=options,
                                           top_blocks=job.top_blocks, rollup=True,
                                           context=stream.context, figures=job.figures)
        if bag is not None:
            from ..record import SimulationBagWriter
            with SimulationBagWriter(bag, compression=job.compression,
                                     rate_hz=options.rate_hz) as writer:
                for chunk in sample_chunks(program.moves, machine, file=program.file,
                                           load_kg=job.load_kg, options=options,
                                           total_moves=len(program.moves), limits=limits):
                    writer.write(chunk)
                summary['program'] = job.program
                writer.finish(blocks, summary=summary, stamp_s=summary['duration_s'])
    elif streamable(machine):
        kw = dict(file=program.file, load_kg=job.load_kg, options=options,
                  top_blocks=job.top_blocks, total_moves=len(program.moves), limits=limits,
                  rollup=True, context=stream.context)
        if bag is None:
            summary, _ = simulate_stream(program.moves, machine, **kw)
            summary['method'] = 'samples'
        else:
            from ..record import SimulationBagWriter
            with SimulationBagWriter(bag, compression=job.compression,
                                     rate_hz=options.rate_hz) as writer:
                summary, blocks = simulate_stream(program.moves, machine,
                                                  on_chunk=writer.write, chunk_gaps=True,
                                                  **kw)
                summary['method'] = 'samples'
                summary['program'] = job.program
                writer.finish(blocks, summary=summary, stamp_s=summary['duration_s'])
    else:
        from .simulate import simulate_program, summarize
        result = simulate_program(program, machine, load_kg=job.load_kg, options=options)
        summary = summarize(result, top_blocks=job.top_blocks)
        summary['method'] = 'samples'
        _record_whole(job, bag, result, summary)
    return summary, warnings


def _record_whole(job: BatchJob, bag, result, summary: dict[str, Any]) -> None:
    """The recording of a whole-record result (trajectory CSV, effects on the whole record)."""
    if bag is None:
        return
    from ..record import write_simulation_bag
    summary['program'] = job.program
    write_simulation_bag(bag, result, summary=summary, compression=job.compression)


def _kept_warnings(warnings: list[str]) -> tuple[str, ...]:
    kept = [shorten(w, limit=200) for w in warnings[:_MAX_WARNINGS]]
    if len(warnings) > _MAX_WARNINGS:
        kept.append(f'... and {len(warnings) - _MAX_WARNINGS} more warnings')
    return tuple(kept)


def failed_result(job: BatchJob, err: BaseException, *, kind: str = '') -> JobResult:
    """The result row of a job that ended in ``err``."""
    if isinstance(err, FeedAxisError):
        return JobResult(job, None, error=str(err), error_type=type(err).__name__)
    if isinstance(err, MemoryError):
        return JobResult(job, None, error=f'{job.program}: out of memory',
                         error_type='MemoryError')
    if isinstance(err, OSError):
        text = shorten(str(err), limit=_ERROR_CHARS)
        return JobResult(job, None, error=f'{job.program}: {text}', error_type='OSError')
    name = kind or 'InternalError'
    text = shorten(f'{type(err).__name__}: {err}', limit=_ERROR_CHARS)
    what = 'the executor lost the job' if kind else 'unexpected error (please report)'
    return JobResult(job, None, error=f'{job.program}: {what}: {text}', error_type=name)


def run_job(job: BatchJob) -> JobResult:
    """Simulate one job; a failure is returned as a result, never raised.

    A top-level function of plain data, so executors in other processes or on other hosts
    can run it (they need this package and the job's files at the same paths).

    Parameters
    ----------
    job
        The job.

    Returns
    -------
    JobResult
        The summary, or the error (message naming the file and line/column where known).
    """
    from ..heap import keep_freed_memory
    keep_freed_memory()
    try:
        summary, warnings = _simulate(job)
    except Exception as err:  # noqa: B902 - one bad job must not end the campaign
        return failed_result(job, err)
    return finish_result(job, summary, warnings)


def finish_result(job: BatchJob, summary: dict[str, Any], warnings: list[str]) -> JobResult:
    """The result of a job that produced ``summary``: failed if a value is not finite;
    the summary's ``program`` is the job's, the first warnings kept."""
    if not _all_finite(summary):
        msg = f'{job.program}: the simulation gave a value that is not finite'
        return JobResult(job, None, error=msg, error_type='PlanningError')
    summary['program'] = job.program
    return JobResult(job, summary, warnings=_kept_warnings(warnings))
