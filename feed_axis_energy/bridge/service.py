"""The job service the cell bridges stand on: a narrow interface, not an implementation.

The OPC UA server and the MQTT bridge speak to the machine's job machinery only through
:class:`JobService`, a :class:`typing.Protocol`: the ROS graph's job interface implements it
(a thin node adapts its services and topics), a test double implements it in ``test/bridge``.
Nothing here imports ROS or the job core.

Conventions of the interface (docs/cell.md):

* a job's state is one of :data:`JOB_STATES`; :data:`FINAL_STATES` end a job;
* live data arrive as :class:`LiveSample` (predicted mechanical power per axis and in total
  [W], energy drawn and returned so far [J]) and state changes as :class:`StateChange`, both
  stamped in wall-clock time (integer ns since the UNIX epoch), handed to every listener
  given to :meth:`JobService.subscribe`, possibly from another thread;
* a job's result is a mapping with at least the keys of :data:`RESULT_KEYS`
  (:func:`result_summary` checks them).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Callable, Mapping, Protocol, Sequence, Union

from ..errors import describe, RequestError

__all__ = ['AxisPower', 'FINAL_STATES', 'JOB_STATES', 'JobService', 'Listener', 'LiveSample',
           'RESULT_KEYS', 'ResultSummary', 'result_summary', 'ServiceEvent', 'StateChange']

JOB_STATES = ('idle', 'planning', 'running', 'ended', 'aborted', 'failed')
"""Every state a job service reports, in the order a job passes through them."""

FINAL_STATES = ('ended', 'aborted', 'failed')
"""The states that end a job (its result exists)."""

RESULT_KEYS = ('job_id', 'status', 'energy_j', 'duration_s', 'peak_power_w')
"""Keys every job result carries: ``energy_j`` is the total mechanical energy [J] (the figure
of ``simulate``'s ``energy_j.total``), ``duration_s`` [s], ``peak_power_w`` [W], ``status``
one of :data:`FINAL_STATES`."""


@dataclass(frozen=True)
class AxisPower:
    """Predicted power of one axis (or of all axes) and its energy so far.

    Attributes
    ----------
    power_w
        Mechanical power at this instant [W] (negative while braking).
    energy_import_j
        Energy drawn since the job started [J] (>= 0).
    energy_export_j
        Energy returned while braking since the job started [J] (>= 0).
    """

    power_w: float
    energy_import_j: float
    energy_export_j: float


@dataclass(frozen=True)
class LiveSample:
    """One instant of a running job's prediction.

    Attributes
    ----------
    job_id
        The job it belongs to.
    stamp_ns
        Wall-clock time of the sample [ns since the UNIX epoch].
    axes
        Axis name -> its power and energy so far.
    total
        The sum over the axes.
    """

    job_id: str
    stamp_ns: int
    axes: Mapping[str, AxisPower]
    total: AxisPower


@dataclass(frozen=True)
class StateChange:
    """A job service's state changed to ``state`` (one of :data:`JOB_STATES`)."""

    job_id: str
    state: str
    stamp_ns: int


ServiceEvent = Union[LiveSample, StateChange]
Listener = Callable[[ServiceEvent], None]


class JobService(Protocol):
    """What a cell bridge needs from the machine's job machinery.

    Every method returns promptly (no planning in the caller's thread) and never raises for
    a refused request: ``start_job`` and ``abort_job`` answer ``(accepted, message)``, the
    message saying why when refused (a program outside the program root, a job already
    running: the service's own words).
    """

    def axes(self) -> Sequence[str]:
        """Names of the machine's feed axes, fixed for the service's life."""
        ...

    def start_job(self, job_id: str, program: str, load_kg: float) -> tuple[bool, str]:
        """Start a job; ``program`` is a path the service resolves and checks."""
        ...

    def abort_job(self, job_id: str) -> tuple[bool, str]:
        """Abort the running job ``job_id``."""
        ...

    def state(self) -> str:
        """The current state, one of :data:`JOB_STATES`."""
        ...

    def active_job(self) -> str:
        """The id of the job planning or running, or of the last job; '' before any."""
        ...

    def active_line(self) -> int:
        """The program line being executed (1-based), 0 when none."""
        ...

    def progress(self) -> float:
        """Fraction of the running job done, 0 to 1."""
        ...

    def last_result(self) -> Mapping[str, Any] | None:
        """The result of the last job that ended, or None."""
        ...

    def result(self, job_id: str) -> Mapping[str, Any] | None:
        """The result of job ``job_id`` among the last jobs the service keeps, or None."""
        ...

    def subscribe(self, listener: Listener) -> Callable[[], None]:
        """Hand every later event to ``listener``; returns the call that unsubscribes it."""
        ...


@dataclass(frozen=True)
class ResultSummary:
    """The fields of a job result that the bridges show as values of their own."""

    job_id: str
    status: str
    energy_j: float
    duration_s: float
    peak_power_w: float


def _finite(result: Mapping[str, Any], key: str) -> float:
    value = result.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value):
        msg = f'expected a finite number, got {describe(value)}'
        raise RequestError(msg, request='job result', field=key)
    return float(value)


def result_summary(result: Mapping[str, Any]) -> ResultSummary:
    """Check a job result's :data:`RESULT_KEYS` and return them as a :class:`ResultSummary`.

    Parameters
    ----------
    result
        A result as :meth:`JobService.result` returns it.

    Returns
    -------
    ResultSummary
        The checked fields.

    Raises
    ------
    RequestError
        A key missing, a number not finite, a status that is not a final state.
    """
    job_id = result.get('job_id')
    if not isinstance(job_id, str):
        msg = f'expected the job id as text, got {describe(job_id)}'
        raise RequestError(msg, request='job result', field='job_id')
    status = result.get('status')
    if status not in FINAL_STATES:
        msg = f'expected one of {", ".join(FINAL_STATES)}, got {describe(status)}'
        raise RequestError(msg, request='job result', field='status')
    return ResultSummary(job_id=job_id, status=str(status),
                         energy_j=_finite(result, 'energy_j'),
                         duration_s=_finite(result, 'duration_s'),
                         peak_power_w=_finite(result, 'peak_power_w'))
