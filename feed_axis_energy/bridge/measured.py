"""Live measured drive data arriving over MQTT: checked, counted, handed on or dropped.

One message per sample on ``<prefix>/<machine>/measured/<axis>``::

    {"stamp": 1764280000.125, "value": 41.5, "quantity": "power_w"}

``stamp`` is the sample's wall-clock time [s since the UNIX epoch], ``value`` a finite
number in the unit that ``quantity`` names (:data:`QUANTITIES`). Anything else is dropped
and counted under one of :data:`DROP_REASONS`; nothing a publisher sends can raise out of
:meth:`MeasuredInput.handle`, and its memory does not grow with the stream (a token bucket
bounds the rate, payloads above :data:`MAX_PAYLOAD_BYTES` are not decoded).
"""
from __future__ import annotations

from dataclasses import dataclass
import json
import logging
import math
import time
from typing import Any, Callable, Collection

from ..errors import describe, RequestError, shorten
from .logbound import BoundedLog

__all__ = ['DROP_REASONS', 'MAX_PAYLOAD_BYTES', 'MeasuredInput', 'MeasuredSample',
           'parse_measured', 'QUANTITIES']

_log = logging.getLogger(__name__)

MAX_PAYLOAD_BYTES = 64 * 1024
"""Largest measured-data message decoded [bytes]."""

QUANTITIES = {
    'power_w': 'W', 'current_a': 'A', 'torque_nm': 'N m', 'force_n': 'N', 'velocity_m_s': 'm/s',
    'speed_rad_s': 'rad/s', 'position_m': 'm', 'acceleration_m_s2': 'm/s^2', 'energy_j': 'J',
}
"""Accepted ``quantity`` names -> their unit (the name ends in it)."""

DROP_REASONS = ('too_large', 'not_utf8', 'bad_json', 'not_object', 'missing_key',
                'wrong_type', 'non_finite', 'unknown_quantity', 'bad_stamp', 'unknown_axis',
                'rate_limited', 'callback_error')
"""Why a message was dropped: the keys of :attr:`MeasuredInput.drops`."""

_MAX_STAMP_S = 9.2e9    # int64 nanoseconds end in 2262


@dataclass(frozen=True)
class MeasuredSample:
    """One measured value of one axis.

    Attributes
    ----------
    axis
        The axis the topic names.
    quantity
        One of :data:`QUANTITIES`.
    value
        The value in the quantity's unit.
    stamp_ns
        Wall-clock time of the sample [ns since the UNIX epoch].
    """

    axis: str
    quantity: str
    value: float
    stamp_ns: int


def _refuse(message: str, *, topic: str, code: str, key: str = '') -> RequestError:
    return RequestError(message, request=topic, field=key, code=code)


def _constant(name: str) -> Any:
    raise _refuse(f'{name} is not a finite number', topic='', code='non_finite')


def _number(data: dict[str, Any], key: str, *, topic: str) -> float:
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _refuse(f'expected a number, got {describe(value)}', topic=topic,
                      code='wrong_type', key=key)
    number = float(value)  # a huge integer becomes inf here
    if not math.isfinite(number):
        raise _refuse(f'expected a finite number, got {describe(value)}', topic=topic,
                      code='non_finite', key=key)
    return number


def parse_measured(axis: str, payload: bytes, *, topic: str) -> MeasuredSample:
    """Check one measured-data message.

    Parameters
    ----------
    axis
        The axis from the topic.
    payload
        The message as received.
    topic
        The topic, for messages.

    Returns
    -------
    MeasuredSample
        The checked sample.

    Raises
    ------
    RequestError
        With ``code`` one of :data:`DROP_REASONS`, naming the topic and the key.
    """
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise _refuse(f'{len(payload)} bytes, at most {MAX_PAYLOAD_BYTES} are read',
                      topic=topic, code='too_large')
    try:
        text = bytes(payload).decode('utf-8')
    except UnicodeDecodeError as exc:
        raise _refuse(f'not UTF-8 text: {exc.reason} at byte {exc.start}', topic=topic,
                      code='not_utf8') from exc
    try:
        data = json.loads(text, parse_constant=_constant)
    except RequestError as exc:
        raise _refuse(exc.reason, topic=topic, code='non_finite') from exc
    except (ValueError, RecursionError) as exc:
        raise _refuse(f'not JSON: {shorten(str(exc))}', topic=topic, code='bad_json') from exc
    if not isinstance(data, dict):
        raise _refuse(f'expected a JSON object, got {describe(data)}', topic=topic,
                      code='not_object')
    for key in ('stamp', 'value', 'quantity'):
        if key not in data:
            raise _refuse('missing', topic=topic, code='missing_key', key=key)
    quantity = data['quantity']
    if not isinstance(quantity, str):
        raise _refuse(f'expected text, got {describe(quantity)}', topic=topic,
                      code='wrong_type', key='quantity')
    if quantity not in QUANTITIES:
        raise _refuse(f'expected one of {", ".join(QUANTITIES)}, got {describe(quantity)}',
                      topic=topic, code='unknown_quantity', key='quantity')
    value = _number(data, 'value', topic=topic)
    stamp = _number(data, 'stamp', topic=topic)
    if not 0.0 < stamp < _MAX_STAMP_S:
        raise _refuse(f'expected seconds since 1970 (UTC), got {stamp!r}', topic=topic,
                      code='bad_stamp', key='stamp')
    whole = math.floor(stamp)   # seconds and fraction apart: ns exact as far as the float is
    return MeasuredSample(axis=axis, quantity=quantity, value=value,
                          stamp_ns=int(whole) * 1_000_000_000 + round((stamp - whole) * 1e9))


class MeasuredInput:
    """The measured stream's gate: rate limit, checks, counts, the callback.

    Parameters
    ----------
    on_sample
        Called with each accepted :class:`MeasuredSample` (in the caller's thread); an
        exception it raises is logged and counted as ``callback_error``.
    axes
        Axes accepted; empty: any.
    max_rate_hz
        Messages accepted per second on average, over all axes; a burst of one second's
        worth passes at once; more are dropped as ``rate_limited`` before being decoded.
    clock
        Monotonic time [s] (a test may pass its own).
    """

    def __init__(self, on_sample: Callable[[MeasuredSample], None], *,
                 axes: Collection[str] = (), max_rate_hz: float = 2000.0,
                 clock: Callable[[], float] = time.monotonic):
        if not (math.isfinite(max_rate_hz) and max_rate_hz > 0):
            raise ValueError(f'max_rate_hz must be a positive number, got {max_rate_hz!r}')
        self._on_sample = on_sample
        self._axes = frozenset(axes)
        self._rate = float(max_rate_hz)
        self._tokens = float(max_rate_hz)
        self._clock = clock
        self._last = clock()
        self.accepted = 0
        """Messages handed to the callback."""
        self.drops: dict[str, int] = dict.fromkeys(DROP_REASONS, 0)
        """Messages dropped, by reason."""
        self.last_error = ''
        """The message of the last drop."""
        self._log = BoundedLog(_log)

    @property
    def dropped(self) -> int:
        """All messages dropped."""
        return sum(self.drops.values())

    def _admit(self) -> bool:
        now = self._clock()
        self._tokens = min(self._rate, self._tokens + (now - self._last) * self._rate)
        self._last = now
        if self._tokens < 1.0:
            return False
        self._tokens -= 1.0
        return True

    def _drop(self, code: str, message: str) -> None:
        self.drops[code] += 1
        self.last_error = message
        self._log.log(logging.WARNING, code, f'measured data dropped: {message}')

    def handle(self, axis: str | None, topic: str, payload: bytes) -> MeasuredSample | None:
        """Check one message and hand it on; returns the sample, or None when dropped."""
        if not self._admit():
            self._drop('rate_limited', f'{shorten(topic)}: more than {self._rate:g} '
                       'messages per second')
            return None
        if axis is None or (self._axes and axis not in self._axes):
            known = ', '.join(sorted(self._axes)) or 'any'
            self._drop('unknown_axis', f'{shorten(topic)}: not an axis topic of this machine '
                       f'(axes {known})')
            return None
        try:
            sample = parse_measured(axis, payload, topic=topic)
        except RequestError as exc:
            self._drop(exc.code or 'bad_json', str(exc))
            return None
        try:
            self._on_sample(sample)
        except Exception as exc:    # the consumer's failure must not end the stream
            self._drop('callback_error', f'{shorten(topic)}: the consumer failed: {exc!r}')
            return None
        self.accepted += 1
        return sample
