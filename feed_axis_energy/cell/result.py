"""Per-job results: the energy side of a job, the whole result, and the store of the last N.

:class:`EnergyReport` is what the energy side knows at a job's end (energy per axis and
total, peak power, samples, electrical energy where drives are declared);
:class:`JobResult` adds what the job was (program and its SHA-256, machine, load) and how it
ended (status, message, lost samples). Their ``to_dict`` forms are the JSON payloads of
``job/energy`` and ``job/result`` (docs/nodes.md: a contract); ``from_dict`` checks every key
and type, and every number is finite (``DataError`` otherwise), so no NaN ever leaves.
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
import math
from typing import Any, Mapping

from ..errors import DataError, describe, JobError
from .spec import JobSpec
from .states import JobState

__all__ = ['EnergyReport', 'JobResult', 'ResultStore', 'RESULT_STATUSES', 'ELECTRICAL_KEYS']

RESULT_STATUSES = tuple(s.value for s in (JobState.ENDED, JobState.ABORTED, JobState.FAILED))
ELECTRICAL_KEYS = ('measured_at', 'motor_energy_j', 'supply_energy_j', 'returned_j')
"""Keys of a result's ``electrical`` object (``None`` when the machine declares no drive)."""


def _number(d: Mapping[str, Any], key: str, *, where: str, minimum: float | None = None,
            prefix: str = '') -> float:
    name = prefix + str(key)
    if key not in d:
        msg = f'key {key!r} is missing'
        raise DataError(msg, file=where, column=name)
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        msg = f'must be a finite number, got {describe(v)}'
        raise DataError(msg, file=where, column=name)
    if minimum is not None and v < minimum:
        msg = f'must be >= {minimum:g}, got {v!r}'
        raise DataError(msg, file=where, column=name)
    return float(v)


def _count(d: Mapping[str, Any], key: str, *, where: str) -> int:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, int) or v < 0:
        msg = f'must be a whole number >= 0, got {describe(v)}'
        raise DataError(msg, file=where, column=key)
    return v


def _text(d: Mapping[str, Any], key: str, *, where: str, limit: int = 4096) -> str:
    v = d.get(key)
    if not isinstance(v, str) or len(v) > limit:
        msg = f'must be text of at most {limit} characters, got {describe(v)}'
        raise DataError(msg, file=where, column=key)
    return v


def _per_axis(d: Mapping[str, Any], key: str, *, where: str) -> dict[str, float]:
    v = d.get(key)
    if not isinstance(v, Mapping) or 'total' not in v or len(v) > 64:
        msg = f'must be an object of numbers per axis with "total", got {describe(v)}'
        raise DataError(msg, file=where, column=key)
    return {str(k): _number(v, k, where=where, prefix=f'{key}.') for k in v}


def _electrical(d: Mapping[str, Any], *, where: str) -> dict[str, Any] | None:
    e = d.get('electrical')
    if e is None:
        return None
    if not isinstance(e, Mapping):
        msg = f'must be an object or null, got {describe(e)}'
        raise DataError(msg, file=where, column='electrical')
    return {'measured_at': _text(e, 'measured_at', where=where, limit=16),
            'motor_energy_j': _per_axis(e, 'motor_energy_j', where=where),
            'supply_energy_j': _per_axis(e, 'supply_energy_j', where=where),
            'returned_j': _number(e, 'returned_j', where=where, minimum=0.0)}


def _finite(values: Mapping[str, float], what: str) -> dict[str, float]:
    out = {str(k): float(v) for k, v in values.items()}
    bad = [k for k, v in out.items() if not math.isfinite(v)]
    if bad:
        msg = f'{what}: not finite for {", ".join(bad)}'
        raise DataError(msg, file='job result', column=what)
    return out


@dataclass(frozen=True)
class EnergyReport:
    """What the energy side reports at a job's end (payload of ``job/energy``).

    Attributes
    ----------
    job_id
        The job.
    samples
        Samples integrated.
    duration_s
        Time from the first to the last sample integrated [s].
    energy_j, peak_power_w
        Per axis and ``total``: energy (eq. 2) [J] and the largest power [W] after the
        braking rule (and declared effects), as ``simulate``'s ``energy_j``/``peak_power_w``.
    braking_returned_j
        Energy the axes returned while braking, ``-integral min(M·omega, 0) dt`` [J]
        (``simulate``'s ``regenerated_energy_j``).
    electrical
        ``None`` without declared drives; else ``measured_at``, ``motor_energy_j`` and
        ``supply_energy_j`` (per axis, ``total``; the supply side with ``cabinet``) [J] and
        ``returned_j`` (what the drives return to the supply) [J].
    """

    job_id: str
    samples: int
    duration_s: float
    energy_j: dict[str, float]
    peak_power_w: dict[str, float]
    braking_returned_j: float
    electrical: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (``job/energy``)."""
        return {'job_id': self.job_id, 'samples': self.samples, 'duration_s': self.duration_s,
                'energy_j': dict(self.energy_j), 'peak_power_w': dict(self.peak_power_w),
                'braking_returned_j': self.braking_returned_j,
                'electrical': None if self.electrical is None else dict(self.electrical)}

    @classmethod
    def from_dict(cls, d: Any, *, where: str = 'job/energy') -> 'EnergyReport':
        """Inverse of :meth:`to_dict`; ``DataError`` naming the key on anything else."""
        if not isinstance(d, Mapping):
            msg = f'must be a JSON object, got {describe(d)}'
            raise DataError(msg, file=where)
        job_id = _text(d, 'job_id', where=where, limit=64)
        return cls(job_id=job_id, samples=_count(d, 'samples', where=where),
                   duration_s=_number(d, 'duration_s', where=where, minimum=0.0),
                   energy_j=_per_axis(d, 'energy_j', where=where),
                   peak_power_w=_per_axis(d, 'peak_power_w', where=where),
                   braking_returned_j=_number(d, 'braking_returned_j', where=where,
                                              minimum=0.0),
                   electrical=_electrical(d, where=where))


@dataclass(frozen=True)
class JobResult:
    """The result of one job (payload of ``job/result``; docs/nodes.md lists the keys).

    ``status`` is ``ended``, ``aborted`` or ``failed``; ``lost_samples`` counts samples the
    planner sent that the energy side did not integrate (0 in a healthy graph); the energy
    figures cover what was integrated, so an aborted job's energy is that of the samples run
    before the abort.
    """

    job_id: str
    status: str
    message: str
    program: str
    program_sha256: str
    machine: str
    load_kg: float
    duration_s: float
    samples: int
    lost_samples: int
    energy_j: dict[str, float] = field(default_factory=dict)
    peak_power_w: dict[str, float] = field(default_factory=dict)
    braking_returned_j: float = 0.0
    electrical: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        if self.status not in RESULT_STATUSES:
            msg = f'status must be one of {RESULT_STATUSES}, got {describe(self.status)}'
            raise DataError(msg, file='job result', column='status')
        object.__setattr__(self, 'energy_j', _finite(self.energy_j, 'energy_j'))
        object.__setattr__(self, 'peak_power_w', _finite(self.peak_power_w, 'peak_power_w'))
        for name in ('load_kg', 'duration_s', 'braking_returned_j'):
            if not math.isfinite(getattr(self, name)):
                msg = f'{name} is not finite'
                raise DataError(msg, file='job result', column=name)

    @classmethod
    def build(cls, spec: JobSpec, report: EnergyReport | None, *, status: str,
              message: str = '', sent_samples: int = 0) -> 'JobResult':
        """The result of ``spec`` from the energy side's ``report`` (``None``: nothing was
        integrated, e.g. a job that failed while planning)."""
        if report is not None and report.job_id != spec.job_id:
            msg = f'energy report of job {report.job_id!r} given for job {spec.job_id!r}'
            raise JobError(msg, field='state', job_id=spec.job_id)
        samples = report.samples if report is not None else 0
        return cls(job_id=spec.job_id, status=status, message=message,
                   program=str(spec.program), program_sha256=spec.program_sha256,
                   machine=str(spec.machine), load_kg=spec.load_kg,
                   duration_s=report.duration_s if report is not None else 0.0,
                   samples=samples, lost_samples=max(0, sent_samples - samples),
                   energy_j=dict(report.energy_j) if report is not None else {},
                   peak_power_w=dict(report.peak_power_w) if report is not None else {},
                   braking_returned_j=report.braking_returned_j if report is not None else 0.0,
                   electrical=report.electrical if report is not None else None)

    @property
    def energy_total_j(self) -> float:
        """Total mechanical energy [J] (0 when nothing ran)."""
        return self.energy_j.get('total', 0.0)

    @property
    def peak_total_w(self) -> float:
        """Peak total power [W] (0 when nothing ran)."""
        return self.peak_power_w.get('total', 0.0)

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (``job/result``)."""
        return {'job_id': self.job_id, 'status': self.status, 'message': self.message,
                'program': self.program, 'program_sha256': self.program_sha256,
                'machine': self.machine, 'load_kg': self.load_kg,
                'duration_s': self.duration_s, 'samples': self.samples,
                'lost_samples': self.lost_samples, 'energy_j': dict(self.energy_j),
                'peak_power_w': dict(self.peak_power_w),
                'braking_returned_j': self.braking_returned_j,
                'electrical': None if self.electrical is None else dict(self.electrical)}

    @classmethod
    def from_dict(cls, d: Any, *, where: str = 'job/result') -> 'JobResult':
        """Inverse of :meth:`to_dict`; ``DataError`` naming the key on anything else."""
        if not isinstance(d, Mapping):
            msg = f'must be a JSON object, got {describe(d)}'
            raise DataError(msg, file=where)
        status = _text(d, 'status', where=where, limit=16)
        if status not in RESULT_STATUSES:
            msg = f'must be one of {RESULT_STATUSES}, got {describe(status)}'
            raise DataError(msg, file=where, column='status')
        energy = d.get('energy_j')
        ran = isinstance(energy, Mapping) and bool(energy)
        return cls(job_id=_text(d, 'job_id', where=where, limit=64), status=status,
                   message=_text(d, 'message', where=where),
                   program=_text(d, 'program', where=where),
                   program_sha256=_text(d, 'program_sha256', where=where, limit=64),
                   machine=_text(d, 'machine', where=where),
                   load_kg=_number(d, 'load_kg', where=where, minimum=0.0),
                   duration_s=_number(d, 'duration_s', where=where, minimum=0.0),
                   samples=_count(d, 'samples', where=where),
                   lost_samples=_count(d, 'lost_samples', where=where),
                   energy_j=_per_axis(d, 'energy_j', where=where) if ran else {},
                   peak_power_w=_per_axis(d, 'peak_power_w', where=where) if ran else {},
                   braking_returned_j=_number(d, 'braking_returned_j', where=where,
                                              minimum=0.0),
                   electrical=_electrical(d, where=where))


class ResultStore:
    """The results of the last ``capacity`` jobs, by job id (oldest dropped first).

    Parameters
    ----------
    capacity
        Number of results kept (``>= 1``).
    """

    def __init__(self, capacity: int = 100) -> None:
        if isinstance(capacity, bool) or not isinstance(capacity, int) or capacity < 1:
            msg = f'result store capacity must be a whole number >= 1, got {describe(capacity)}'
            raise JobError(msg, field='request')
        self.capacity = capacity
        self._results: OrderedDict[str, JobResult] = OrderedDict()

    def __len__(self) -> int:
        return len(self._results)

    def __contains__(self, job_id: object) -> bool:
        return job_id in self._results

    def add(self, result: JobResult) -> None:
        """Keep ``result`` (a job id is stored once: a second result for it is refused)."""
        if result.job_id in self._results:
            msg = 'a result for this job id is stored already'
            raise JobError(msg, field='job_id', job_id=result.job_id)
        self._results[result.job_id] = result
        while len(self._results) > self.capacity:
            self._results.popitem(last=False)

    def get(self, job_id: str) -> JobResult:
        """The result of ``job_id``; ``JobError`` if it is unknown or no longer kept."""
        try:
            return self._results[job_id]
        except KeyError:
            msg = (f'no result for this job id (the last {self.capacity} jobs are kept; '
                   f'{len(self._results)} stored)')
            raise JobError(msg, field='job_id', job_id=str(job_id)) from None

    def last(self) -> JobResult | None:
        """The newest result, or ``None``."""
        return next(reversed(self._results.values())) if self._results else None

    def job_ids(self) -> list[str]:
        """Stored job ids, oldest first."""
        return list(self._results)
