"""The job board: one job at a time, its state, and the results of the last N jobs.

:class:`JobBoard` is what a shell talks to: the ROS node ``gcode_trajectory`` (topics
``job/command``, ``job/state``, ``job/result``), and later an OPC UA or MQTT bridge, call
the same five operations without knowing about ROS:

* :meth:`JobBoard.start` (a request mapping) -> the checked :class:`JobSpec`, state
  ``planning``; refused with a ``JobError`` (``field`` = ``state``) while a job is planning
  or running, or naming the request field at fault;
* :meth:`JobBoard.abort` (job id) -> marks the running job for abort; the runner stops
  streaming and reports through :meth:`JobBoard.finish` with status ``aborted``;
* :attr:`JobBoard.snapshot` -> the current :class:`JobSnapshot` (state, job id, message);
* :meth:`JobBoard.result` (job id) -> its :class:`JobResult` from the last ``keep`` jobs;
* the runner's side: :meth:`JobBoard.planned` (planning -> running),
  :meth:`JobBoard.finish` (a result ends the job: ``ended``, ``aborted`` or ``failed``).

Every state change is also handed to the ``on_change`` callbacks (a bridge publishes it).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from ..errors import JobError
from .result import JobResult, ResultStore
from .spec import JobLimits, JobSpec, parse_job_request
from .states import ACTIVE, check_transition, JobState

__all__ = ['JobBoard', 'JobSnapshot']


@dataclass(frozen=True)
class JobSnapshot:
    """The job state as published on ``job/state`` (docs/nodes.md).

    Attributes
    ----------
    state
        One of :class:`JobState`.
    job_id
        The current or last job ('' before the first).
    message
        Why the state was entered (a failure's reason, ``abort requested`` ...).
    spec
        The job's spec while it is planning or running (and after, until the next), or
        ``None`` before the first job.
    sequence
        Number of state changes so far (a reader can tell a repeated state from a new one).
    planned_samples
        Samples the running job's plan holds (0 before it is planned): a client's progress
        is the samples integrated (``job/live``) over this.
    """

    state: JobState
    job_id: str = ''
    message: str = ''
    spec: JobSpec | None = None
    sequence: int = 0
    planned_samples: int = 0

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (``job/state``)."""
        return {'state': self.state.value, 'job_id': self.job_id, 'message': self.message,
                'sequence': self.sequence, 'planned_samples': self.planned_samples,
                'spec': None if self.spec is None else self.spec.to_dict()}


class JobBoard:
    """One job at a time through the state machine of :mod:`.states`; the last results.

    Parameters
    ----------
    limits
        Where programs and machines may come from, and the largest load and program.
    keep
        Number of results kept for :meth:`result`.
    """

    def __init__(self, limits: JobLimits, *, keep: int = 100) -> None:
        self.limits = limits
        self.results = ResultStore(keep)
        self._snapshot = JobSnapshot(JobState.IDLE)
        self._abort_requested = False
        self.on_change: list[Callable[[JobSnapshot], None]] = []

    @property
    def snapshot(self) -> JobSnapshot:
        """The current state."""
        return self._snapshot

    @property
    def state(self) -> JobState:
        """The current state's name."""
        return self._snapshot.state

    @property
    def current(self) -> JobSpec | None:
        """The spec of the job that is planning or running (``None`` otherwise)."""
        return self._snapshot.spec if self._snapshot.state in ACTIVE else None

    @property
    def abort_requested(self) -> bool:
        """Whether the running job has been asked to stop."""
        return self._abort_requested

    def _enter(self, state: JobState, *, message: str = '', spec: JobSpec | None = None,
               planned_samples: int | None = None) -> JobSnapshot:
        old = self._snapshot
        check_transition(old.state, state, job_id=spec.job_id if spec else old.job_id)
        if planned_samples is None:     # kept through the job's end; a new job starts at 0
            planned_samples = 0 if spec is not None else old.planned_samples
        spec = spec if spec is not None else old.spec
        self._snapshot = JobSnapshot(state, job_id=spec.job_id if spec else '',
                                     message=message, spec=spec, sequence=old.sequence + 1,
                                     planned_samples=planned_samples)
        for callback in list(self.on_change):
            callback(self._snapshot)
        return self._snapshot

    def start(self, request: Any) -> JobSpec:
        """Check ``request`` and make it the current job (state ``planning``).

        Raises
        ------
        JobError
            ``field`` = ``state`` while another job is planning or running; ``job_id`` for
            an id whose result is still kept; else the request field at fault.
        """
        if self.state in ACTIVE:
            cur = self._snapshot.job_id
            msg = (f'job {cur!r} is {self.state.value}; abort it or wait for its end '
                   'before starting another')
            raise JobError(msg, field='state', job_id=_requested_id(request))
        spec = parse_job_request(request, self.limits)
        if spec.job_id in self.results:
            msg = 'this job id was used already (its result is kept); choose a new one'
            raise JobError(msg, field='job_id', job_id=spec.job_id)
        self._abort_requested = False
        self._enter(JobState.PLANNING, spec=spec, message='planning')
        return spec

    def planned(self, job_id: str, *, samples: int = 0) -> None:
        """The runner has planned the job (``samples`` in its plan) and streams it:
        ``planning -> running``."""
        self._check_current(job_id)
        self._enter(JobState.RUNNING, message='running', planned_samples=max(0, int(samples)))

    def abort(self, job_id: str) -> None:
        """Ask the running (or planning) job ``job_id`` to stop.

        Raises
        ------
        JobError
            ``field`` = ``state`` when no job is planning or running, or ``job_id`` is not
            the current job.
        """
        if self.state not in ACTIVE:
            msg = f'no job is running (state {self.state.value}); nothing to abort'
            raise JobError(msg, field='state', job_id=str(job_id))
        self._check_current(job_id)
        self._abort_requested = True

    def finish(self, result: JobResult) -> None:
        """End the current job with ``result`` (its ``status`` is the new state) and keep
        the result."""
        self._check_current(result.job_id)
        if result.status == JobState.ENDED.value and self.state is not JobState.RUNNING:
            msg = f'a job cannot end from {self.state.value}'
            raise JobError(msg, field='state', job_id=result.job_id)
        self.results.add(result)
        self._abort_requested = False
        self._enter(JobState(result.status), message=result.message or result.status)

    def result(self, job_id: str) -> JobResult:
        """The result of ``job_id`` (``JobError`` if unknown or no longer kept)."""
        return self.results.get(job_id)

    def _check_current(self, job_id: str) -> None:
        cur = self.current
        if cur is None or cur.job_id != job_id:
            running = f'the current job is {cur.job_id!r}' if cur else 'no job is running'
            msg = f'not the current job ({running}, state {self.state.value})'
            raise JobError(msg, field='state', job_id=str(job_id))


def _requested_id(request: Any) -> str:
    job_id = request.get('job_id') if isinstance(request, dict) else None
    return job_id[:64] if isinstance(job_id, str) and job_id.isprintable() else ''
