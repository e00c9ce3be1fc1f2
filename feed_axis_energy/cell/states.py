"""The job state machine: which state may follow which, and why a command is refused.

```
idle --start--> planning --planned--> running --finished--> ended
                   |                     |------abort------> aborted
                   |--abort--> aborted   |------fault------> failed
                   |--fault--> failed
ended | aborted | failed --start--> planning
```

One job at a time: ``start`` is legal only when no job is planning or running; ``abort``
only while one is. The terminal states keep the last job's id until the next start.
"""
from __future__ import annotations

from enum import Enum

from ..errors import JobError

__all__ = ['JobState', 'TRANSITIONS', 'TERMINAL', 'ACTIVE', 'check_transition']


class JobState(str, Enum):
    """State of the graph's job (the ``state`` of ``job/state``)."""

    IDLE = 'idle'
    PLANNING = 'planning'
    RUNNING = 'running'
    ENDED = 'ended'
    ABORTED = 'aborted'
    FAILED = 'failed'

    def __str__(self) -> str:
        return self.value


TERMINAL = frozenset((JobState.ENDED, JobState.ABORTED, JobState.FAILED))
"""States a job ends in (its result exists)."""
ACTIVE = frozenset((JobState.PLANNING, JobState.RUNNING))
"""States in which a job holds the graph (start refused, abort allowed)."""

TRANSITIONS: dict[JobState, frozenset[JobState]] = {
    JobState.IDLE: frozenset((JobState.PLANNING,)),
    JobState.PLANNING: frozenset((JobState.RUNNING, JobState.ABORTED, JobState.FAILED)),
    JobState.RUNNING: frozenset((JobState.ENDED, JobState.ABORTED, JobState.FAILED)),
    JobState.ENDED: frozenset((JobState.PLANNING,)),
    JobState.ABORTED: frozenset((JobState.PLANNING,)),
    JobState.FAILED: frozenset((JobState.PLANNING,)),
}
"""Legal successors of every state."""


def check_transition(old: JobState, new: JobState, *, job_id: str = '') -> JobState:
    """``new`` if the state machine allows ``old -> new``, else ``JobError`` (field
    ``state``) saying what is allowed."""
    if new not in TRANSITIONS[old]:
        allowed = ', '.join(sorted(s.value for s in TRANSITIONS[old]))
        msg = f'cannot go from {old.value} to {new.value} (from {old.value}: {allowed})'
        raise JobError(msg, field='state', job_id=job_id)
    return new
