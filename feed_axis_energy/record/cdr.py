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

import functools
from typing import Iterator, NamedTuple, Sequence

import numpy as np

__all__ = ['joint_trajectory_cdr', 'joint_trajectory_rows', 'MessageRows',
           'diagnostic_array_cdr', 'block_energy_cdr', 'block_energy_cdr_array',
           'BLOCK_ENERGY_PER_MESSAGE']

_NS = 1_000_000_000
BLOCK_ENERGY_PER_MESSAGE = 10_000   # statuses per /block_energy message
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


def _point_groups(offsets: np.ndarray) -> list[tuple[int, int, int]]:
    """Split the points into groups of equal layout: ``[(first, period, count)]``.

    Everything is 4-byte aligned and values 8-byte aligned, so a point's layout depends only
    on its start offset modulo 8: from the second point on the layouts repeat every one or
    two points (the first may differ). Points ``first, first + period, ...`` (``count`` of
    them) have the same layout shifted by a constant step.
    """
    n = offsets.shape[0]

    def repeats(lo: int, period: int) -> bool:
        steps = offsets[lo + period:] - offsets[lo:n - period]
        return steps.shape[0] == 0 or bool(np.all(steps == steps[0]))

    for lo in (0, 1):
        for period in (1, 2):
            if lo < n and repeats(lo, period):
                head = [(0, 1, 1)] if lo else []
                return head + [(lo + r, period, len(range(lo + r, n, period)))
                               for r in range(min(period, n - lo))]
    msg = 'JointTrajectory point layout does not repeat'   # see above: cannot happen
    raise AssertionError(msg)


def _parts(value) -> tuple[np.ndarray, ...]:
    """A field's column blocks: a 2-D array, or a tuple of them (columns side by side)."""
    return value if isinstance(value, tuple) else (value,)


def _strided(view: np.ndarray, col: int, shape: tuple[int, ...], step: int) -> np.ndarray:
    """A writable view of ``view`` (2-D, rows = messages) from column ``col``: rows, then
    elements ``step`` apart, then (for a 3-D shape) consecutive elements."""
    base = view[:, col:]
    item = view.itemsize
    strides = (view.strides[0], step * item) + ((item,) if len(shape) == 3 else ())
    return np.lib.stride_tricks.as_strided(base, shape=shape, strides=strides, writeable=True)


@functools.lru_cache(maxsize=64)
def _template(names: tuple[str, ...], frame_id: str, points: int, widths: tuple[int, ...],
              lead: int) -> tuple[np.ndarray, int, tuple]:
    """The bytes every message of this layout shares, and where the rest goes (cached).

    Returns ``(template row, payload column, (value_at, time_at, point groups, message
    length))``; the
    arrays are read-only.
    """
    prefix = _prefix(names, frame_id)
    begin = len(prefix) + 4                       # after the points count
    count_at, value_at, time_at, end = _layout(begin, points, list(widths))
    # the payload (after the 4-byte encapsulation) starts 8-aligned: float64 views fit
    payload = lead + 4 + (-(lead + 4) % 8)
    width = payload + end + (-end % 8)
    template = np.zeros(width, np.uint8)
    template[payload - 4:payload] = np.frombuffer(_ENCAPSULATION, np.uint8)
    template[payload:payload + len(prefix)] = np.frombuffer(prefix, np.uint8)
    t32 = template[payload:].view('<u4')
    t32[(begin - 4) // 4] = points
    for f, w in enumerate(widths):
        t32[count_at[:, f] // 4] = w
    groups = _point_groups(np.column_stack((count_at, value_at, time_at)))
    for arr in (template, value_at, time_at):
        arr.flags.writeable = False
    return template, payload, (value_at, time_at, groups, end + 4)


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
    full = n // batch
    out: list[tuple[int, bytes]] = []
    parts = [(0, full, batch)] if full else []
    if n > full * batch:
        parts.append((full * batch, 1, n - full * batch))
    for row0, n_msgs, n_points in parts:
        block = joint_trajectory_rows(t_ns[row0:row0 + n_msgs * n_points], names,
                                      [None if v is None else v[row0:] for v in values],
                                      points=n_points, frame_id=frame_id)
        stop = block.start + block.length
        stamps = block.stamps.tolist()
        out += [(stamps[i], block.rows[i, block.start:stop].tobytes()) for i in range(n_msgs)]
    return out


class MessageRows(NamedTuple):
    """Messages of one layout as rows of a byte array (see :func:`joint_trajectory_rows`).

    Attributes
    ----------
    stamps
        Header stamp of every message [ns], ``(m,)`` int64.
    rows
        ``(m, width)`` uint8; message ``i`` is ``rows[i, start:start + length]``.
    start, length
        Column of the first CDR byte (the encapsulation header) and the message size [bytes].
    """

    stamps: np.ndarray
    rows: np.ndarray
    start: int
    length: int


def joint_trajectory_rows(t_ns: np.ndarray, names: tuple[str, ...],
                          values: list[np.ndarray | None], *, points: int,
                          frame_id: str = '', lead: int = 0) -> MessageRows:
    """JointTrajectory messages of exactly ``points`` points each, one row per message.

    The messages of a row block all have the same size, so a container's record headers can
    be written into the ``lead`` spare bytes before each message and the records taken as one
    slice (:mod:`.mcapstream`): no Python object per message.

    Parameters
    ----------
    t_ns
        Sample times [ns], ``(m * points,)`` int64, non-negative.
    names, frame_id
        Joint names and ``header.frame_id``.
    values
        As for :func:`joint_trajectory_cdr`, or a field as a tuple of 2-D arrays whose
        columns follow one another (no joined copy needed); rows beyond ``m * points`` are
        ignored.
    points
        Points per message.
    lead
        Spare bytes wanted before the first CDR byte of each row.

    Returns
    -------
    MessageRows
        The rows; unused bytes are zero.
    """
    if points < 1 or t_ns.shape[0] % points:
        msg = f'joint_trajectory_rows: {t_ns.shape[0]} samples are not messages of {points}'
        raise ValueError(msg)
    n_msgs = t_ns.shape[0] // points
    widths = [0 if v is None else len(names) for v in values]
    for v in values:
        if v is not None and sum(p.shape[1] for p in _parts(v)) != len(names):
            msg = f'joint_trajectory_rows: columns do not match the {len(names)} joint names'
            raise ValueError(msg)
    template, payload, (value_at, time_at, groups, length) = _template(
        tuple(names), frame_id, points, tuple(widths), lead)
    width = template.shape[0]
    rows = np.empty((n_msgs, width), np.uint8)
    rows[:] = template
    u32 = rows[:, payload:].view('<u4')
    f64 = rows[:, payload:].view('<f8')
    stamps = t_ns.reshape(n_msgs, points)
    first = stamps[:, 0]
    u32[:, 0] = (first // _NS).astype('<u4')
    u32[:, 1] = (first % _NS).astype('<u4')
    rel = stamps - first[:, None]
    for first_point, period, n_r in groups:
        idx = slice(first_point, first_point + period * n_r, period)
        step = (int(time_at[first_point + period] - time_at[first_point]) if n_r > 1
                else 8)
        at = int(time_at[first_point]) // 4
        _strided(u32, at, (n_msgs, n_r), step // 4)[...] = rel[:, idx] // _NS
        _strided(u32, at + 1, (n_msgs, n_r), step // 4)[...] = rel[:, idx] % _NS
        for f, w in enumerate(widths):
            if not w:
                continue
            # column by column: numpy copies long strided rows fast, short ones slowly
            col = int(value_at[first_point, f]) // 8
            for part in _parts(values[f]):
                for j in range(part.shape[1]):
                    # a column is a view in either memory order (C or Fortran)
                    src = part[:n_msgs * points, j].reshape(n_msgs, points)
                    _strided(f64, col, (n_msgs, n_r), step // 8)[...] = src[:, idx]
                    col += 1
    return MessageRows(stamps=first.copy(), rows=rows, start=payload - 4, length=length)


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


def block_energy_cdr_array(stamp_ns: int, program: str, lines: np.ndarray,
                           energy_j: np.ndarray, duration_s: np.ndarray, *,
                           frame_id: str = '') -> bytes:
    """The ``/block_energy`` DiagnosticArray of many source lines, laid out with numpy.

    Equal to :func:`diagnostic_array_cdr` of the statuses ``(0, f'{program}:{line}',
    'block energy', '', (('line', str(line)), ('energy_j', repr(e)), ('duration_s',
    repr(d))))`` (a test compares them) at a few microseconds per line instead of tens.

    Every string starts 4-aligned (its length prefix), so the distance from one string's
    start to the next element's is ``ceil4(5 + bytes)`` (length, bytes, NUL, padding), or
    ``ceil4(6 + bytes)`` when a status's level byte sits in between: all offsets are one
    cumulative sum, and the string bytes are scattered into place in one assignment.
    """
    lines = np.asarray(lines, np.int64)
    n = int(lines.shape[0])
    head = bytearray(_ENCAPSULATION)
    _put_u32(head, stamp_ns // _NS)
    _put_u32(head, stamp_ns % _NS)
    _put_string(head, frame_id)
    _put_u32(head, n)
    if n == 0:
        return bytes(head)
    line_txt = list(map(str, lines.tolist()))
    e_txt = list(map(repr, np.asarray(energy_j, float).tolist()))
    d_txt = list(map(repr, np.asarray(duration_s, float).tolist()))
    prefix = f'{program}:'
    # per status, the strings in order: name, message, hardware id, then key, value x 3
    fixed = [None, 'block energy', '', 'line', None, 'energy_j', None, 'duration_s', None]
    lens = np.empty((n, 9), np.int64)
    digits = np.fromiter(map(len, line_txt), np.int64, n)
    lens[:, 0] = len(prefix.encode('utf-8')) + digits
    for j, text in enumerate(fixed):
        if text is not None:
            lens[:, j] = len(text.encode('utf-8'))
    lens[:, 4] = digits
    lens[:, 6] = np.fromiter(map(len, e_txt), np.int64, n)
    lens[:, 8] = np.fromiter(map(len, d_txt), np.int64, n)
    # slots from each element's (aligned) start to the next element's; the values count
    # (u32 3) follows the hardware id
    slot = np.empty((n, 10), np.int64)
    slot[:, :3] = (5 + lens[:, :3] + 3) // 4 * 4
    slot[:, 3] = 4
    slot[:, 4:] = (5 + lens[:, 3:] + 3) // 4 * 4
    slot[:-1, 9] = (6 + lens[:-1, 8] + 3) // 4 * 4      # the next status's level byte
    p0 = len(head) - 4 + 4           # payload offset of the first name: after level byte + pad
    starts = p0 + np.concatenate(([0], np.cumsum(slot.ravel())[:-1])).reshape(n, 10)
    end = int(starts[-1, 9]) + 5 + int(lens[-1, 8])
    payload = np.zeros(end + (-end % 4), np.uint8)
    payload[:len(head) - 4] = np.frombuffer(bytes(head[4:]), np.uint8)
    u32 = payload.view('<u4')
    str_starts = np.delete(starts, 3, axis=1)            # (n, 9): the strings' starts
    u32[str_starts.ravel() // 4] = (lens + 1).ravel()
    u32[starts[:, 3] // 4] = 3
    text = ''.join(f'{prefix}{a}block energyline{a}energy_j{b}duration_s{c}'
                   for a, b, c in zip(line_txt, e_txt, d_txt)).encode('utf-8')
    flat = lens.ravel()
    src0 = np.concatenate(([0], np.cumsum(flat)[:-1]))
    dest = np.repeat(str_starts.ravel() + 4 - src0, flat) + np.arange(int(flat.sum()))
    payload[dest] = np.frombuffer(text, np.uint8)
    return _ENCAPSULATION + payload[:end].tobytes()


def block_energy_cdr(blocks: Sequence[tuple[int, float, float]], *, stamp_s: float = 0.0,
                     stamp_ns: int | None = None,
                     program: str = '') -> Iterator[tuple[int, bytes]]:
    """``(stamp_ns, CDR)`` of the ``/block_energy`` DiagnosticArrays (one status per line).

    At most :data:`BLOCK_ENERGY_PER_MESSAGE` statuses per message, all at ``stamp_s``
    (:func:`.bagio.read_block_energy` joins them), laid out with numpy
    (:func:`block_energy_cdr_array`), so a program of a million lines costs a few
    megabytes at a time, not a million message objects. ``blocks`` may be a
    :class:`feed_axis_energy.physics.breakdown.LineEnergy` (its arrays are used directly).
    ``stamp_ns``, when given, replaces ``stamp_s`` (a wall-clock stamp does not fit a float to
    the nanosecond).
    """
    stamp = int(round(stamp_s * _NS)) if stamp_ns is None else int(stamp_ns)
    columns = getattr(blocks, 'lines', None) is not None
    total = len(blocks)
    step = BLOCK_ENERGY_PER_MESSAGE
    for lo in range(0, max(total, 1), step):
        if columns:
            lines = blocks.lines[lo:lo + step]
            energy, duration = blocks.energy_j[lo:lo + step], blocks.duration_s[lo:lo + step]
        else:
            rows = np.array([(int(a), float(b), float(c)) for a, b, c in blocks[lo:lo + step]],
                            dtype=[('l', np.int64), ('e', float), ('d', float)])
            lines, energy, duration = rows['l'], rows['e'], rows['d']
        yield stamp, block_energy_cdr_array(stamp, program, lines, energy, duration)
