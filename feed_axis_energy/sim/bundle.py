"""Running a campaign: :func:`run_batch` on any executor, and bundles of the jobs of one
program that share its reading (issue 23, part 3).

:func:`run_batch` runs the jobs (:class:`.batch.BatchJob`, one run each:
:func:`.batch.run_job`) in this process or on any ``concurrent.futures``-style executor
(``ProcessPoolExecutor``, ``ThreadPoolExecutor``, ``distributed.Client(...)
.get_executor()``) and returns the results in job order, whatever order they complete in:
the same jobs give the same results, serially or in parallel, bundled or not.

Jobs of one program whose machines read it the same way (the same ``gcode`` settings) form
a bundle: the program is interpreted once, its moves go to one planner per **plan** (axis
limits, planner options, feed and rapid override: what decides the motion), and each
planned window's pieces and the motion at their quadrature rows
(:func:`.quadrature.window_rows`) are evaluated on every variant with that plan
(:class:`.quadrature.WindowEvaluator`: the variant's dynamics, its own cuts where a sign
changes). A variant that changes only the load, masses, inertias, losses or efficiencies
re-evaluates the phases; one that changes an override or a limit is planned again; none
reads the program again. Each variant's summary is the one :func:`.phasesum.summarize_phases`
gives for it alone, bit for bit (the same rows, the same operations).

A job shares when it asks for the summary by phase of an NC program on a machine the phases
cover (:func:`.quadrature.phase_covered`), without a recording or a sample limit; the others
run alone (:func:`.batch.run_job`). :func:`bundle_jobs` cuts each program's sharing jobs
into at most ``tasks`` bundles (one per worker), sorted by plan so that a plan's variants
stay together.

Memory: the planned windows of every plan in the bundle (at most :data:`MAX_PLANS` plans,
two or three windows each) and the rows of one window at a time; the moves between the
slowest and the fastest planner (they advance window by window, in turn); per variant its
accumulators (per source line only where ``top_blocks`` asks for the lines).
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
import concurrent.futures as cf
from dataclasses import dataclass
from itertools import tee
from typing import Any

from ..errors import ConfigError, FeedAxisError
from .batch import (BatchJob, failed_result, finish_result, job_machine, job_options,
                    JobResult, MAX_JOBS, run_job)

__all__ = ['run_batch', 'bundle_jobs', 'run_bundle', 'MAX_PLANS']

MAX_PLANS = 4
"""Most plans one bundle advances side by side (each holds its planned windows: about 16 MB
for a dense contour; more plans are more bundles, each reading the program)."""


def _shares(job: Any) -> bool:
    """True when the job may run in a bundle (checked without loading anything)."""
    return (job.method == 'phases' and not job.out and not job.max_samples
            and not job.program_path.lower().endswith('.csv'))


def bundle_jobs(jobs: Sequence[Any], tasks: int) -> list[list[int]]:
    """The jobs' indices in bundles: per program and way of reading it, the jobs that share
    (:func:`run_bundle`) cut into at most ``tasks`` bundles of near-equal size, each sorted
    by plan; every other job alone. Bundles come in the order of their first job.

    A machine that fails to load makes its job run alone (it then fails with its own
    error, as in :func:`.batch.run_job`).
    """
    from .quadrature import phase_covered
    groups: dict[tuple[str, str], list[tuple[str, int]]] = {}
    alone: list[list[int]] = []
    for i, job in enumerate(jobs):
        machine = None
        if _shares(job):
            try:
                machine = job_machine(job)
            except FeedAxisError:
                machine = None
        if machine is None or not phase_covered(machine):
            alone.append([i])
            continue
        read = (job.program_path, repr(sorted(machine.gcode_keywords().items())))
        groups.setdefault(read, []).append((_plan_key(job, machine, job_options(job, machine)),
                                            i))
    bundles = list(alone)
    tasks = max(int(tasks), 1)
    for members in groups.values():
        members.sort()                     # by plan, then by job index
        n = min(tasks, len(members))
        for part in range(n):
            lo, hi = part * len(members) // n, (part + 1) * len(members) // n
            bundles.extend(_by_plans(members[lo:hi]))
    bundles.sort(key=min)
    return bundles


def _by_plans(members: list[tuple[str, int]]) -> list[list[int]]:
    """``members`` (sorted by plan) in near-equal runs of at most :data:`MAX_PLANS` plans."""
    keys = sorted({key for key, _ in members})
    runs = -(-len(keys) // MAX_PLANS)
    cut = {key: (j * runs) // len(keys) for j, key in enumerate(keys)}
    out: list[list[int]] = [[] for _ in range(runs)]
    for key, i in members:
        out[cut[key]].append(i)
    return out


def _plan_key(job: Any, machine: Any, options: Any) -> str:
    """What decides the motion of a job: the axis limits, the planner options and the
    overrides (as text: equal text, equal plan)."""
    return repr((sorted(machine.limits().items()), options, job.feed_override,
                 job.rapid_override))


@dataclass
class _Plan:
    """One planner of a bundle and the variants evaluated on its windows."""

    members: list[int]                 # indices into the bundle's jobs
    windows: Iterator[Any] | None = None


class _Source:
    """The program's moves, noting an error of the read (it fails every job)."""

    def __init__(self, stream: Iterable[Any]) -> None:
        self.stream = stream
        self.error: BaseException | None = None

    def __iter__(self) -> Iterator[Any]:
        try:
            yield from self.stream
        except Exception as err:  # noqa: B902 - every job of the bundle gets it
            self.error = err
            raise


def run_bundle(jobs: Sequence[Any]) -> list[Any]:
    """Run jobs that share a program (from :func:`bundle_jobs`); one result per job, in
    order. A failure is returned, never raised: an error of the read fails every job, a
    planner's error the jobs of that plan, an evaluation's error its job.

    A top-level function of plain data, like :func:`.batch.run_job`.
    """
    from ..heap import keep_freed_memory
    jobs = list(jobs)
    if len(jobs) == 1:
        return [run_job(jobs[0])]
    keep_freed_memory()
    results: list[Any] = [None] * len(jobs)
    try:
        _run(jobs, results)
    except Exception as err:  # noqa: B902 - one bad bundle must not end the campaign
        for i, job in enumerate(jobs):
            if results[i] is None:
                results[i] = failed_result(job, err)
    return results


def _run(jobs: list[Any], results: list[Any]) -> None:
    """Fill ``results`` (None where a job is still to finish)."""
    from ..gcode import iter_moves
    from ..plan import iter_window_motions
    from .phasesum import PhaseSummary
    from .quadrature import PHASE_ORDER, window_rows, WindowEvaluator
    from .sweep import override_moves
    machines: list[Any] = []
    options: list[Any] = []
    accs: list[Any] = []
    evals: list[Any] = [None] * len(jobs)
    for job in jobs:
        machine = job_machine(job)
        machines.append(machine)
        options.append(job_options(job, machine))
    plans: dict[str, _Plan] = {}
    for i, job in enumerate(jobs):
        plans.setdefault(_plan_key(job, machines[i], options[i]), _Plan([])).members.append(i)
    first = machines[0]
    stream = iter_moves(jobs[0].program_path, **first.gcode_keywords())
    source = _Source(stream)
    branches = tee(source, len(plans)) if len(plans) > 1 else (iter(source),)
    for i, job in enumerate(jobs):
        accs.append(PhaseSummary(machines[i], file=stream.file, load_kg=job.load_kg,
                                 options=options[i], top_blocks=job.top_blocks,
                                 rollup=True, context=stream.context,
                                 lines=job.top_blocks > 0, figures=job.figures))
    for plan, branch in zip(plans.values(), branches):
        lead = plan.members[0]
        job, machine = jobs[lead], machines[lead]
        limits = machine.limits()
        moves: Iterable[Any] = override_moves(branch, feed=job.feed_override,
                                              rapid=job.rapid_override, limits=limits)
        for i in plan.members:
            moves = accs[i].wrap(moves)
            try:
                evals[i] = WindowEvaluator(machines[i], load_kg=jobs[i].load_kg,
                                           order=PHASE_ORDER, every_sign=accs[i].every_sign)
            except FeedAxisError as err:
                results[i] = failed_result(jobs[i], err)
        plan.windows = iter_window_motions(moves, limits, options=options[lead],
                                           file=stream.file)
    active = list(plans.values())
    while active:
        for plan in list(active):
            try:
                at = next(plan.windows)            # type: ignore[arg-type]
            except StopIteration:
                active.remove(plan)
                continue
            except Exception as err:  # noqa: B902 - the read's error fails every job
                if source.error is not None:
                    raise
                active.remove(plan)
                for i in plan.members:
                    if results[i] is None:
                        results[i] = failed_result(jobs[i], err)
                continue
            rows = window_rows(at, PHASE_ORDER)
            for i in plan.members:
                if results[i] is not None:
                    continue
                try:
                    accs[i].add(evals[i](at, rows))
                except FeedAxisError as err:
                    results[i] = failed_result(jobs[i], err)
    warnings = list(stream.warnings)
    for i, job in enumerate(jobs):
        if results[i] is None:
            summary, _ = accs[i].result()
            results[i] = finish_result(job, summary, warnings)


def run_batch(jobs: Iterable[BatchJob], *, executor: cf.Executor | None = None,
              progress: Callable[[int, int, JobResult], None] | None = None,
              share: int = 0) -> list[JobResult]:
    """Run every job; return the results in job order.

    Parameters
    ----------
    jobs
        The jobs, at most :data:`MAX_JOBS`.
    executor
        Anything with the ``concurrent.futures.Executor.submit`` interface whose futures
        ``concurrent.futures.as_completed`` accepts: a ``ProcessPoolExecutor``, or a Dask
        ``Client.get_executor()``. ``None`` runs the jobs one after the other in this process.
        The executor is not shut down here.
    progress
        Called after each job with ``(jobs done, jobs in all, that job's result)`` (the
        jobs of a bundle when it ends).
    share
        0: every job on its own. ``N > 0``: the jobs of one program that can share a read
        of it run in at most ``N`` bundles per program (:func:`.bundle.bundle_jobs`; give
        the number of workers): the same results, the program read and planned once per
        bundle rather than once per job.

    Returns
    -------
    list of JobResult
        ``results[i]`` belongs to ``jobs[i]``; a job the executor lost (a worker that died)
        is a failed result with ``error_type`` ``'WorkerError'``.

    Raises
    ------
    ConfigError
        More than :data:`MAX_JOBS` jobs.
    """
    jobs = list(jobs)
    total = len(jobs)
    if total > MAX_JOBS:
        msg = f'{total:,} jobs are more than the {MAX_JOBS:,} a batch may hold; split it'
        raise ConfigError(msg, file='batch')
    bundles = bundle_jobs(jobs, share) if share > 0 else [[i] for i in range(total)]
    results: list[JobResult | None] = [None] * total
    done = 0

    def take(members: list[int], got: list[JobResult]) -> None:
        nonlocal done
        for i, result in zip(members, got):
            results[i] = result
            done += 1
            if progress is not None:
                progress(done, total, result)

    def task(members: list[int]) -> tuple[Callable[..., Any], Any]:
        # a job alone is submitted as itself (run_job, as executors have always seen it)
        if len(members) == 1:
            return run_job, jobs[members[0]]
        return run_bundle, tuple(jobs[i] for i in members)

    if executor is None:
        for members in bundles:
            take(members, run_bundle(tuple(jobs[i] for i in members)))
        return results  # type: ignore[return-value]
    pending = {}
    for members in bundles:
        fn, arg = task(members)
        pending[executor.submit(fn, arg)] = members
    try:
        for future in cf.as_completed(pending):
            members = pending[future]
            try:
                got = future.result()
                got = [got] if isinstance(got, JobResult) else list(got)
            except Exception as err:  # noqa: B902 - a worker died or the executor failed
                got = [failed_result(jobs[i], err, kind='WorkerError') for i in members]
            take(members, got)
    except BaseException:
        for future in pending:
            future.cancel()
        raise
    return results  # type: ignore[return-value]
