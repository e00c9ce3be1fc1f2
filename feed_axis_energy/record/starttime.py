"""``--start-time now|ISO-8601``: the wall-clock time a recording's stamps start from.

By default a recording is stamped in simulation time (the program starts at 0 ns, 1970 in
a viewer). With a start time every stamp (log time and header stamp) is the start plus the
simulation time, so a simulated run overlays a live machine's recording of the same program
in Foxglove or PlotJuggler. ISO-8601 text goes through :meth:`datetime.fromisoformat`
(``2026-11-23T14:00:00Z``, ``2026-11-23 14:00:00+01:00``, ``2026-11-23``); a time without
an offset is UTC. ROS 2 stamps hold seconds as int32, so the last stamp must fall before
2038-01-19 03:14:08 UTC.
"""
from __future__ import annotations

from datetime import datetime, timezone
import math
import struct
import time

from ..errors import DataError, shorten

__all__ = ['parse_start_time', 'check_end', 'restamp', 'MAX_STAMP_NS']

_NS = 1_000_000_000
MAX_STAMP_NS = (2 ** 31) * _NS - 1     # builtin_interfaces/Time.sec is int32


def parse_start_time(text: str, *, now_ns: int | None = None) -> int:
    """The start time [ns since the Unix epoch] of ``'now'`` or an ISO-8601 date and time.

    Raises
    ------
    ValueError
        Not ``now`` nor ISO-8601, before 1970 or not before 2038-01-19 (the message quotes at
        most 60 characters of ``text``).
    """
    value = str(text).strip()
    if value.lower() == 'now':
        return int(time.time_ns() if now_ns is None else now_ns)
    try:
        when = datetime.fromisoformat(value)
    except ValueError:
        msg = (f'expected "now" or an ISO-8601 date and time such as 2026-11-23T14:00:00Z, '
               f'got {shorten(value, limit=60)!r}')
        raise ValueError(msg) from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=timezone.utc)
    delta = when - datetime(1970, 1, 1, tzinfo=timezone.utc)
    ns = (delta.days * 86_400 + delta.seconds) * _NS + delta.microseconds * 1000
    if not 0 <= ns <= MAX_STAMP_NS:
        msg = (f'{shorten(value, limit=60)} is outside the ROS 2 time range '
               '(1970-01-01 to 2038-01-19 03:14:07 UTC)')
        raise ValueError(msg)
    return ns


def check_end(start_ns: int, duration_s: float) -> str | None:
    """Why stamps from ``start_ns`` over ``duration_s`` do not fit a ROS 2 time, or None."""
    if not math.isfinite(duration_s):
        return f'the program duration {duration_s} s is not finite'
    end = start_ns + int(math.ceil(duration_s * _NS))
    if end > MAX_STAMP_NS:
        return ('the recording would end after 2038-01-19 03:14:07 UTC, the last time a ROS 2 '
                'stamp holds; choose an earlier --start-time')
    return None


_STAMP = struct.Struct('<iI')


def restamp(cdr: bytes, stamp_ns: int) -> bytes:
    """A serialized message whose first field is a header (or a ``Time``, as
    ``rosgraph_msgs/Clock``) with that stamp set to ``stamp_ns`` (little-endian CDR).

    Raises
    ------
    DataError
        Data too short or not little-endian CDR, or a stamp outside the ROS 2 time range.
    """
    if len(cdr) < 12 or cdr[1] != 1:
        msg = 'expected little-endian CDR with a header stamp'
        raise DataError(msg, file='<cdr>')
    if not 0 <= stamp_ns <= MAX_STAMP_NS:
        msg = f'stamp {stamp_ns} ns is outside the ROS 2 time range'
        raise DataError(msg, file='<cdr>')
    out = bytearray(cdr)
    _STAMP.pack_into(out, 4, stamp_ns // _NS, stamp_ns % _NS)
    return bytes(out)
