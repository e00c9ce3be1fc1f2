"""The MQTT topic tree of the cell bridge and the JSON it publishes (docs/cell.md).

Under ``<prefix>/<machine>`` (:class:`TopicTree`)::

    status             {"online", "stamp"}                       retained, QoS 1, last will
    job/state          {"job_id", "state", "stamp"}              retained, QoS 1
    job/result         the job's result (RESULT_KEYS and more)   retained, QoS 1
    power              {"job_id", "stamp", "predicted", "power_w", "energy_j",
                        "energy_import_j", "energy_export_j"}    QoS 0, one per live sample
    measured/<axis>    {"stamp", "value", "quantity"}            subscribed (:mod:`.measured`)

Keys carry their unit (``_w`` watts, ``_j`` joules, ``_s`` seconds); ``stamp`` is wall-clock
time in seconds since the UNIX epoch (a JSON number). The power and energy objects hold one
key per axis and ``total``. A number that is not finite is written as ``null``, never as
``NaN``.
"""
from __future__ import annotations

from dataclasses import dataclass
import json
import math
from typing import Any, Mapping

from ..errors import ConfigError, RequestError
from .service import AxisPower, LiveSample

__all__ = ['DEFAULT_PREFIX', 'MAX_LEVEL_CHARS', 'POWER_KEYS', 'power_payload',
           'result_payload', 'RETAINED', 'STATE_KEYS', 'state_payload', 'STATUS_KEYS',
           'status_payload', 'TopicTree']

DEFAULT_PREFIX = 'feed_axis_energy'
MAX_LEVEL_CHARS = 64
"""Longest topic level (prefix, machine, axis) accepted [characters]."""

STATUS_KEYS = ('online', 'stamp')
STATE_KEYS = ('job_id', 'state', 'stamp')
POWER_KEYS = ('job_id', 'stamp', 'predicted', 'power_w', 'energy_j', 'energy_import_j',
              'energy_export_j')
RETAINED = ('status', 'job/state', 'job/result')
"""Topics (below ``<prefix>/<machine>``) published retained, for late subscribers."""


def _check_level(value: str, key: str, *, slashes: bool = False) -> str:
    bad = '+#\x00' if slashes else '/+#\x00'
    if (not isinstance(value, str) or not value or len(value) > 4 * MAX_LEVEL_CHARS
            or not value.isprintable() or any(c in bad for c in value)
            or (not slashes and len(value) > MAX_LEVEL_CHARS)
            or value.startswith('/') or value.endswith('/') or '//' in value
            or value.startswith('$')):
        msg = (f'expected a topic level of 1 to {MAX_LEVEL_CHARS} printable characters '
               f'without {" ".join(repr(c) for c in bad if c != chr(0))}, leading "$" or '
               f'"/", got {value!r}')
        raise ConfigError(msg, file='<mqtt>', key=key)
    return value


@dataclass(frozen=True)
class TopicTree:
    """The topics of one machine.

    Attributes
    ----------
    prefix
        First levels, shared by a cell (``feed_axis_energy`` or ``plant/cell3``).
    machine
        The machine's name, one level.
    """

    prefix: str = DEFAULT_PREFIX
    machine: str = 'machine'

    def __post_init__(self) -> None:
        _check_level(self.prefix, 'prefix', slashes=True)
        _check_level(self.machine, 'machine')

    @property
    def base(self) -> str:
        """``<prefix>/<machine>``."""
        return f'{self.prefix}/{self.machine}'

    @property
    def status(self) -> str:
        """Whether the bridge is connected (retained; the last will says offline)."""
        return f'{self.base}/status'

    @property
    def job_state(self) -> str:
        """The job state (retained)."""
        return f'{self.base}/job/state'

    @property
    def job_result(self) -> str:
        """The last job's result (retained)."""
        return f'{self.base}/job/result'

    @property
    def power(self) -> str:
        """Live predicted power and energy so far."""
        return f'{self.base}/power'

    def measured(self, axis: str) -> str:
        """Where live measured data of ``axis`` arrive."""
        return f'{self.base}/measured/{_check_level(axis, "axis")}'

    @property
    def measured_filter(self) -> str:
        """The subscription that receives every axis's measured data."""
        return f'{self.base}/measured/+'

    def axis_of(self, topic: str) -> str | None:
        """The axis a measured-data topic names, or None for any other topic."""
        head = f'{self.base}/measured/'
        if not topic.startswith(head):
            return None
        axis = topic[len(head):]
        return axis if axis and '/' not in axis else None


def _number(value: float) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None


def _dumps(data: Mapping[str, Any]) -> bytes:
    return json.dumps(data, allow_nan=False, separators=(',', ':')).encode()


def status_payload(*, online: bool, stamp_ns: int) -> bytes:
    """The ``status`` message."""
    return _dumps({'online': online, 'stamp': stamp_ns / 1e9})


def state_payload(*, job_id: str, state: str, stamp_ns: int) -> bytes:
    """The ``job/state`` message."""
    return _dumps({'job_id': job_id, 'state': state, 'stamp': stamp_ns / 1e9})


def power_payload(sample: LiveSample) -> bytes:
    """The ``power`` message of one live sample (per axis and ``total``)."""
    parts: dict[str, AxisPower] = {**sample.axes, 'total': sample.total}
    return _dumps({
        'job_id': sample.job_id, 'stamp': sample.stamp_ns / 1e9, 'predicted': True,
        'power_w': {k: _number(v.power_w) for k, v in parts.items()},
        'energy_j': {k: _number(v.energy_import_j - v.energy_export_j)
                     for k, v in parts.items()},
        'energy_import_j': {k: _number(v.energy_import_j) for k, v in parts.items()},
        'energy_export_j': {k: _number(v.energy_export_j) for k, v in parts.items()},
    })


def result_payload(result: Mapping[str, Any], *, stamp_ns: int) -> bytes:
    """The ``job/result`` message: the service's result with the publication ``stamp``.

    Raises
    ------
    RequestError
        The result holds a value JSON cannot carry (NaN, infinity, an object).
    """
    data = dict(result)
    data['stamp'] = stamp_ns / 1e9
    try:
        return _dumps(data)
    except (TypeError, ValueError) as exc:
        msg = f'cannot be published as JSON: {exc}'
        raise RequestError(msg, request='job result', code='bad_result') from exc
