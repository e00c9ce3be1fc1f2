"""The JSON of ``measured/live`` (in) and ``measured/comparison`` (out): the node's contract.

``measured/live`` (docs/nodes.md, "measured_live") carries one sample per message::

    {"axis": "X", "stamp": 1764280000.1, "quantity": "power_w", "value": 41.5}

or a batch of such objects, ``{"samples": [{...}, ...]}`` (at most :data:`MAX_BATCH`).
``stamp`` is wall-clock time [s since the UNIX epoch]; ``value`` a finite number in the unit
the quantity names; ``quantity`` may be left out: it is then ``power_w`` (what the contract
carried first; publishers of power need not name it). :func:`parse_live` never raises: what
it cannot use it counts under one of :data:`REJECTS`.
"""
from __future__ import annotations

from dataclasses import dataclass
import json
import math
from typing import Any

from ..comparison import json_clean
from .monitor import LIVE_QUANTITIES

__all__ = ['ALARM_KEYS', 'alarm_text', 'COMPARISON_KEYS', 'comparison_text',
           'DEFAULT_QUANTITY', 'JobLive',
           'LiveSample', 'MAX_BATCH', 'MAX_TEXT_CHARS', 'parse_job_live', 'parse_live', 'REJECTS']

DEFAULT_QUANTITY = 'power_w'
"""The quantity of a sample that names none."""
MAX_BATCH = 10_000
"""Most samples in one batch message."""
MAX_TEXT_CHARS = 4 * 1024 * 1024
"""Longest message parsed [characters]."""
REJECTS = ('too_large', 'bad_json', 'not_object', 'bad_sample', 'batch_too_long')
"""Why (part of) a message was not used."""
_MAX_STAMP_S = 9.2e9    # int64 nanoseconds end in 2262

COMPARISON_KEYS = ('job_id', 'source', 'stamp', 'axes', 'elapsed_s', 'measured_power_w',
                   'predicted_power_w', 'residual_power_w', 'measured_energy_j',
                   'predicted_energy_j', 'energy_error_j', 'energy_error_pct', 'lag', 'alarm',
                   'rows', 'final', 'measures', 'signal', 'counters')
"""Top-level keys of a ``measured/comparison`` message, in order."""

ALARM_KEYS = ('job_id', 'stamp', 'active', 'count', 'residual_w', 'band_w', 'band_source')
"""Keys of a ``measured/alarm`` message."""

LiveSample = tuple[str, str, int, float]
"""``(axis, quantity, stamp_ns, value)``."""


def _constant(name: str) -> Any:
    raise ValueError(f'{name} is not a number')


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _sample(item: Any) -> LiveSample | None:
    if not isinstance(item, dict):
        return None
    axis, quantity = item.get('axis'), item.get('quantity', DEFAULT_QUANTITY)
    stamp, value = item.get('stamp'), item.get('value')
    if not (isinstance(axis, str) and 0 < len(axis) <= 16 and axis.isprintable()):
        return None
    if not (isinstance(quantity, str) and quantity in LIVE_QUANTITIES):
        return None
    if not (_is_number(stamp) and _is_number(value)):
        return None
    assert isinstance(stamp, (int, float)) and isinstance(value, (int, float))
    try:
        stamp_f, value_f = float(stamp), float(value)
    except OverflowError:
        return None
    if not (math.isfinite(value_f) and 0.0 < stamp_f < _MAX_STAMP_S):
        return None
    whole = math.floor(stamp_f)     # seconds and fraction apart: ns exact as far as the float
    stamp_ns = int(whole) * 1_000_000_000 + round((stamp_f - whole) * 1e9)
    return axis, quantity, stamp_ns, value_f


def parse_live(text: str) -> tuple[list[LiveSample], dict[str, int]]:
    """The samples of one ``measured/live`` message, and what was rejected.

    Parameters
    ----------
    text
        The message's ``data``.

    Returns
    -------
    samples, rejects
        The usable samples in message order; counts by :data:`REJECTS` key (only those
        that occurred).
    """
    if len(text) > MAX_TEXT_CHARS:
        return [], {'too_large': 1}
    try:
        data = json.loads(text, parse_constant=_constant)
    except (ValueError, RecursionError):
        return [], {'bad_json': 1}
    if not isinstance(data, dict):
        return [], {'not_object': 1}
    if 'samples' not in data:
        one = _sample(data)
        return ([one], {}) if one is not None else ([], {'bad_sample': 1})
    items = data['samples']
    if not isinstance(items, list):
        return [], {'bad_sample': 1}
    rejects: dict[str, int] = {}
    if len(items) > MAX_BATCH:
        rejects['batch_too_long'] = 1
        return [], rejects
    out = []
    for item in items:
        got = _sample(item)
        if got is None:
            rejects['bad_sample'] = rejects.get('bad_sample', 0) + 1
        else:
            out.append(got)
    return out, rejects


def comparison_text(comparison: dict[str, Any]) -> str:
    """One ``measured/comparison`` message: strict JSON, NaN as null, keys in order."""
    ordered = {k: comparison[k] for k in COMPARISON_KEYS}
    return json.dumps(json_clean(ordered), allow_nan=False, separators=(',', ':'))


@dataclass(frozen=True)
class JobLive:
    """What ``measured_live`` takes from one ``job/live`` message (docs/nodes.md, "Jobs").

    Attributes
    ----------
    job_id
        The job.
    stamp_ns
        Time of the batch's last sample [ns].
    clock
        ``wall`` (real-time mode) or ``simulation``.
    power_w
        That sample's power per axis and ``total`` [W].
    """

    job_id: str
    stamp_ns: int
    clock: str
    power_w: dict[str, float]


def parse_job_live(text: str) -> JobLive | None:
    """The prediction in one ``job/live`` message, or None when it is not usable."""
    if len(text) > MAX_TEXT_CHARS:
        return None
    try:
        data = json.loads(text, parse_constant=_constant)
    except (ValueError, RecursionError):
        return None
    if not isinstance(data, dict):
        return None
    job_id, stamp, clock, power = (data.get('job_id'), data.get('stamp_ns'), data.get('clock'),
                                   data.get('power_w'))
    if not (isinstance(job_id, str) and isinstance(clock, str) and isinstance(power, dict)
            and isinstance(stamp, int) and not isinstance(stamp, bool) and stamp > 0):
        return None
    values = {k: float(v) for k, v in power.items()
              if isinstance(k, str) and _is_number(v) and math.isfinite(float(v))}
    return JobLive(job_id, stamp, clock, values)


def alarm_text(comparison: dict[str, Any]) -> str:
    """One ``measured/alarm`` message (:data:`ALARM_KEYS`) from a comparison."""
    alarm = comparison['alarm']
    body = {'job_id': comparison['job_id'], 'stamp': comparison['stamp'],
            'active': alarm['active'], 'count': alarm['count'],
            'residual_w': alarm['residual_w'], 'band_w': alarm['band_w'],
            'band_source': alarm['band_source']}
    return json.dumps(json_clean(body), allow_nan=False, separators=(',', ':'))
