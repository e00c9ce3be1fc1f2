"""Vectorised CDR serialisation of batched ``trajectory_msgs/msg/JointTrajectory`` messages.

A time series becomes messages of ``batch`` points (:func:`.bagio.series_to_messages` builds
the same messages as objects). Every full message of a series has the same layout: only the
stamp, the points' ``time_from_start`` and the float64 values differ. So the byte layout is
worked out once per message size and all messages of a chunk are filled at once with numpy
(one row of a 2-D byte array per message), instead of building and serialising one Python
object per point. The bytes equal ``typestore.serialize_cdr`` of the message objects (a
test compares them).

Layout (little-endian CDR, offsets relative to the payload after the 4-byte encapsulation
header ``00 01 00 00``): ``header.stamp`` (int32 sec, uint32 nanosec), ``header.frame_id``
(uint32 length with the terminating NUL, the bytes, NUL, padding to 4), ``joint_names``
(uint32 count, then strings as above), ``points`` (uint32 count, then per point four
float64 sequences - uint32 count aligned to 4, the values aligned to 8 when there are any -
and ``time_from_start`` as int32 sec, uint32 nanosec aligned to 4).
"""
from __future__ import annotations

import numpy as np

__all__ = ['joint_trajectory_cdr', 'diagnostic_array_cdr']

_NS = 1_000_000_000
_ENCAPSULATION = b'\x00\x01\x00\x00'
_FIELDS = ('positions', 'velocities', 'accelerations', 'effort')


def _cdr_string(text: str, offset: int) -> bytes:
    """A CDR string at payload ``offset`` (a multiple of 4), padded to 4 bytes."""
    raw = text.encode('utf-8') + b'\x00'
    out = len(raw).to_bytes(4, 'little') + raw
    return out + b'\x00' * (-(offset + len(out)) % 4)


def _prefix(names: tuple[str, ...], frame_id: str) -> bytes:
    """Payload bytes from the header to the points count (exclusive); stamp zeroed."""
    out = bytearray(8)                            # stamp, filled per message
    out += _cdr_string(frame_id, len(out))
    out += len(names).to_bytes(4, 'little')
    for name in names:
        out += _cdr_string(name, len(out))
    return bytes(out)


def _layout(start: int, n_points: int,
            widths: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Offsets of the points' counts, values and times for ``n_points`` from ``start``.

    Returns ``(count_at (n, 4), value_at (n, 4), time_at (n,), end)``: payload offsets of
    each field's count and first value (-1 without values) and of ``time_from_start``.
    """
    count_at = np.empty((n_points, 4), np.int64)
    value_at = np.full((n_points, 4), -1, np.int64)
    time_at = np.empty(n_points, np.int64)
    o = start
    for i in range(n_points):
        for f, width in enumerate(widths):
            o += -o % 4
            count_at[i, f] = o
            o += 4
            if width:
                o += -o % 8
                value_at[i, f] = o
                o += 8 * width
        o += -o % 4
        time_at[i] = o
        o += 8
    return count_at, value_at, time_at, o


def joint_trajectory_cdr(t_ns: np.ndarray, names: tuple[str, ...],
                         values: list[np.ndarray | None], *, batch: int,
                         frame_id: str = '') -> list[tuple[int, bytes]]:
    """Serialised JointTrajectory messages of ``batch`` points (the last may be shorter).

    Parameters
    ----------
    t_ns
        Sample times [ns], ``(n,)`` int64, non-negative.
    names
        Joint names.
    values
        ``positions``, ``velocities``, ``accelerations``, ``effort``: arrays ``(n, len(names))``
        or ``None`` (empty in every point).
    batch
        Points per message.
    frame_id
        ``header.frame_id``.

    Returns
    -------
    list of (int, bytes)
        ``(stamp_ns, CDR bytes)`` per message; the stamp is the first point's time.
    """
    n = int(t_ns.shape[0])
    k = len(names)
    widths = [0 if v is None else k for v in values]
    prefix = _prefix(tuple(names), frame_id)
    out: list[tuple[int, bytes]] = []
    full = n // batch
    if full:
        out += _messages(t_ns[:full * batch], values, 0, full, batch, widths, prefix)
    if n > full * batch:
        rest = n - full * batch
        out += _messages(t_ns[full * batch:], values, full * batch, 1, rest, widths, prefix)
    return out


def _messages(t_ns: np.ndarray, values: list[np.ndarray | None], row0: int, n_msgs: int,
              n_points: int, widths: list[int], prefix: bytes) -> list[tuple[int, bytes]]:
    """``n_msgs`` messages of ``n_points`` points each, from sample ``row0`` of ``values``."""
    start = len(prefix) + 4                       # after the points count
    count_at, value_at, time_at, end = _layout(start, n_points, widths)
    # a row: 4 spare bytes, the encapsulation, then the payload at column 8 (8-aligned)
    width = 8 + end + (-end % 8)
    rows = np.zeros((n_msgs, width), np.uint8)
    rows[:, 4:8] = np.frombuffer(_ENCAPSULATION, np.uint8)
    rows[:, 8:8 + len(prefix)] = np.frombuffer(prefix, np.uint8)
    u32 = rows[:, 8:].view('<u4')
    f64 = rows[:, 8:].view('<f8')
    u32[:, (start - 4) // 4] = n_points
    for f, w in enumerate(widths):
        u32[:, count_at[:, f] // 4] = w
    stamps = t_ns.reshape(n_msgs, n_points)
    first = stamps[:, 0]
    u32[:, 0] = (first // _NS).astype('<u4')
    u32[:, 1] = (first % _NS).astype('<u4')
    rel = stamps - first[:, None]
    u32[:, time_at // 4] = (rel // _NS).astype('<u4')
    u32[:, time_at // 4 + 1] = (rel % _NS).astype('<u4')
    for f, w in enumerate(widths):
        if not w:
            continue
        cols = (value_at[:, f] // 8)[:, None] + np.arange(w)       # (n_points, w)
        block = np.asarray(values[f][row0:row0 + n_msgs * n_points], dtype='<f8')
        f64[:, cols] = block.reshape(n_msgs, n_points, w)
    stamps_list = first.tolist()
    return [(stamps_list[i], rows[i, 4:8 + end].tobytes()) for i in range(n_msgs)]


def _put_string(buf: bytearray, text: str) -> None:
    """Append a CDR string to ``buf`` (whose first 4 bytes are the encapsulation header)."""
    buf += b'\x00' * (-(len(buf) - 4) % 4)
    raw = text.encode('utf-8')
    buf += (len(raw) + 1).to_bytes(4, 'little')
    buf += raw
    buf += b'\x00'


def _put_u32(buf: bytearray, value: int) -> None:
    buf += b'\x00' * (-(len(buf) - 4) % 4)
    buf += int(value).to_bytes(4, 'little')


def diagnostic_array_cdr(stamp_ns: int, count: int, statuses, *,
                         frame_id: str = '') -> bytearray:
    """Serialised ``diagnostic_msgs/msg/DiagnosticArray`` without building message objects.

    Parameters
    ----------
    stamp_ns
        Header stamp [ns], >= 0.
    count
        Number of statuses.
    statuses
        Iterable (e.g. a generator: memory is the bytes only) of ``count`` tuples
        ``(level, name, message, hardware_id, [(key, value), ...])``.
    frame_id
        ``header.frame_id``.

    Returns
    -------
    bytearray
        The CDR bytes (equal to ``typestore.serialize_cdr`` of the message object).
    """
    buf = bytearray(_ENCAPSULATION)
    _put_u32(buf, stamp_ns // _NS)
    _put_u32(buf, stamp_ns % _NS)
    _put_string(buf, frame_id)
    _put_u32(buf, count)
    written = 0
    for level, name, message, hardware_id, values in statuses:
        buf.append(int(level) & 0xFF)
        _put_string(buf, name)
        _put_string(buf, message)
        _put_string(buf, hardware_id)
        _put_u32(buf, len(values))
        for key, value in values:
            _put_string(buf, key)
            _put_string(buf, value)
        written += 1
    if written != count:
        msg = f'diagnostic_array_cdr: {written} statuses given, {count} announced'
        raise ValueError(msg)
    return buf
