"""Every conversion between ROS messages and numpy arrays / :class:`bagio.Series`.

Streams (``trajectory_msgs/JointTrajectory`` batches) are encoded to and decoded from CDR
bytes with numpy, without building one Python object per point: rclpy publishes ``bytes`` as
an already serialized message and ``raw=True`` subscriptions deliver ``bytes``. Building and
serializing a 100-point JointTrajectory through the rclpy message classes costs about 2 ms; the
numpy codec is more than ten times faster, which is what lets the graph run far faster than
real time. The bytes are identical to what rosbags writes for the same series (tested), so a
graph recording and an offline ``simulate --out`` bag hold the same CDR data.

Low-rate messages (block energy, end marker, clock) use the rclpy message classes.
"""
from __future__ import annotations

from dataclasses import dataclass
import struct
from typing import Iterable, Sequence

import numpy as np

from feed_axis_energy.record import bagio
from feed_axis_energy.errors import DataError
from feed_axis_energy.graph import NS_PER_S, ProgramEnd, seconds_to_ns

__all__ = ['FIELDS', 'TrajectoryBatch', 'encode_trajectory', 'decode_trajectory',
           'series_to_cdr', 'cdr_to_series', 'batch_to_series', 'series_to_msg',
           'msg_to_series', 'block_energy_msg', 'block_energy_from_msg', 'program_end_msg',
           'program_end_from_msg', 'lines_to_cdr', 'lines_from_cdr', 'clock_msg', 'stamp_msg',
           'time_to_ns']

FIELDS = ('positions', 'velocities', 'accelerations', 'effort')
_U32 = struct.Struct('<I')
_STAMP = struct.Struct('<iI')
_ENCAPSULATION = b'\x00\x01\x00\x00'  # CDR, little endian


@dataclass(frozen=True)
class TrajectoryBatch:
    """A decoded JointTrajectory: stamps in integer nanoseconds.

    Attributes
    ----------
    stamp_ns
        ``header.stamp``.
    t_ns
        Absolute stamp of every point, ``(n,)`` (``stamp + time_from_start``).
    names
        ``joint_names``.
    fields
        ``{field: (n, m) float64 array or None}`` for ``positions`` ... ``effort``.
    frame_id
        ``header.frame_id``.
    """

    stamp_ns: int
    t_ns: np.ndarray
    names: tuple[str, ...]
    fields: dict[str, np.ndarray | None]
    frame_id: str = ''


def _point_layout(start: int, counts: Sequence[int]) -> tuple[list[tuple[int, int]], int]:
    """Offsets (relative to ``start``) of each field's count and data, and the point size.

    CDR aligns each primitive to its own size, counted from the end of the encapsulation
    header; an empty sequence is just its 4-byte length, with no padding for its elements.
    """
    pos = start
    out = []
    for m in counts:
        pos += (-pos) % 4
        count_at = pos
        pos += 4
        if m:
            pos += (-pos) % 8
        out.append((count_at - start, pos - start))
        pos += 8 * m
    pos += (-pos) % 4
    out.append((pos - start, pos - start))  # time_from_start
    pos += 8
    return out, pos - start


def _point_offsets(first: int, n: int, counts: Sequence[int]) -> tuple[np.ndarray, list, int]:
    """Start offset of every point (their padding depends only on the start modulo 8)."""
    layouts = {phase: _point_layout(phase, counts) for phase in (0, 4)}
    starts = np.empty(n, dtype=np.int64)
    pos = first
    for i in range(n):
        starts[i] = pos
        pos += layouts[pos % 8][1]
    return starts, layouts, pos


def _string(out: bytearray, text: str) -> None:
    data = text.encode()
    out.extend(b'\x00' * ((-(len(out) - 4)) % 4))
    out.extend(_U32.pack(len(data) + 1))
    out.extend(data)
    out.append(0)


def encode_trajectory(stamp_ns: int, rel_ns: np.ndarray, names: Sequence[str],
                      fields: dict[str, np.ndarray | None], *, frame_id: str = '') -> bytes:
    """Serialize one JointTrajectory batch to CDR bytes.

    Parameters
    ----------
    stamp_ns
        Header stamp [ns] (>= 0).
    rel_ns
        ``time_from_start`` of every point [ns], ``(n,)``.
    names
        Joint names.
    fields
        ``{field: (n, len(names)) array or None}``; missing or ``None`` fields are empty.
    frame_id
        ``header.frame_id``.
    """
    rel_ns = np.asarray(rel_ns, dtype=np.int64)
    n = rel_ns.shape[0]
    arrays = [fields.get(f) for f in FIELDS]
    counts = [0 if a is None else int(np.shape(a)[1]) for a in arrays]
    head = bytearray(_ENCAPSULATION)
    head.extend(_STAMP.pack(stamp_ns // NS_PER_S, stamp_ns % NS_PER_S))
    _string(head, frame_id)
    head.extend(b'\x00' * ((-(len(head) - 4)) % 4))
    head.extend(_U32.pack(len(names)))
    for name in names:
        _string(head, name)
    head.extend(b'\x00' * ((-(len(head) - 4)) % 4))
    head.extend(_U32.pack(n))
    first = len(head) - 4
    starts, layouts, end = _point_offsets(first, n, counts)
    buf = np.zeros(end + 4, dtype=np.uint8)
    buf[:len(head)] = np.frombuffer(bytes(head), dtype=np.uint8)
    if n:
        phase = starts % 8
        for j, (arr, m) in enumerate(zip(arrays + [None], counts + [0])):
            count_rel = np.where(phase == 0, layouts[0][0][j][0], layouts[4][0][j][0])
            data_rel = np.where(phase == 0, layouts[0][0][j][1], layouts[4][0][j][1])
            base = 4 + starts
            if j == len(FIELDS):  # time_from_start: int32 sec, uint32 nanosec
                tfs = np.empty(n, dtype=[('sec', '<i4'), ('nsec', '<u4')])
                tfs['sec'] = rel_ns // NS_PER_S
                tfs['nsec'] = rel_ns % NS_PER_S
                idx = (base + count_rel)[:, None] + np.arange(8)
                buf[idx] = tfs.view(np.uint8).reshape(n, 8)
                continue
            if m == 0:
                continue  # a zero count is already zero bytes
            idx = (base + count_rel)[:, None] + np.arange(4)
            buf[idx] = np.frombuffer(_U32.pack(m), dtype=np.uint8)
            values = np.ascontiguousarray(arr, dtype='<f8').reshape(n, m)
            idx = (base + data_rel)[:, None] + np.arange(8 * m)
            buf[idx] = values.view(np.uint8).reshape(n, 8 * m)
    return buf.tobytes()


def _read_string(data: bytes, pos: int) -> tuple[str, int]:
    pos += (-(pos - 4)) % 4
    (length,) = _U32.unpack_from(data, pos)
    pos += 4
    text = data[pos:pos + length - 1].decode()
    return text, pos + length


def decode_trajectory(data: bytes | memoryview) -> TrajectoryBatch:
    """Deserialize CDR bytes of a JointTrajectory whose points all have the same field sizes.

    Raises
    ------
    DataError
        Not little-endian CDR, truncated, or points with differing field sizes.
    """
    data = bytes(data)
    try:
        if data[:2] != b'\x00\x01':
            msg = 'expected little-endian CDR (encapsulation 00 01)'
            raise DataError(msg, file='<JointTrajectory>')
        sec, nsec = _STAMP.unpack_from(data, 4)
        frame_id, pos = _read_string(data, 12)
        pos += (-(pos - 4)) % 4
        (n_names,) = _U32.unpack_from(data, pos)
        pos += 4
        names = []
        for _ in range(n_names):
            name, pos = _read_string(data, pos)
            names.append(name)
        pos += (-(pos - 4)) % 4
        (n,) = _U32.unpack_from(data, pos)
        pos += 4
        counts = []
        probe = pos
        for _ in FIELDS:
            probe += (-(probe - 4)) % 4
            (m,) = _U32.unpack_from(data, probe) if n else (0,)
            probe += 4
            if m:
                probe += (-(probe - 4)) % 8
            probe += 8 * m
            counts.append(int(m))
    except struct.error as err:
        msg = f'truncated JointTrajectory ({len(data)} bytes)'
        raise DataError(msg, file='<JointTrajectory>') from err
    starts, layouts, end = _point_offsets(pos - 4, n, counts)
    if end + 4 > len(data):
        msg = (f'JointTrajectory of {len(data)} bytes is shorter than its {n} points need '
               '(points with differing field sizes are not supported)')
        raise DataError(msg, file='<JointTrajectory>')
    buf = np.frombuffer(data, dtype=np.uint8)
    phase = starts % 8
    base = 4 + starts
    out: dict[str, np.ndarray | None] = {}
    rel = np.zeros(n, dtype=np.int64)
    for j in range(len(FIELDS) + 1):
        count_rel = np.where(phase == 0, layouts[0][0][j][0], layouts[4][0][j][0])
        data_rel = np.where(phase == 0, layouts[0][0][j][1], layouts[4][0][j][1])
        if j == len(FIELDS):
            raw = buf[(base + count_rel)[:, None] + np.arange(8)].copy()
            tfs = raw.view([('sec', '<i4'), ('nsec', '<u4')]).reshape(n)
            rel = tfs['sec'].astype(np.int64) * NS_PER_S + tfs['nsec'].astype(np.int64)
            continue
        m = counts[j]
        got = buf[(base + count_rel)[:, None] + np.arange(4)].copy().view('<u4').reshape(n)
        if np.any(got != m):
            msg = f'JointTrajectory points differ in the size of {FIELDS[j]}'
            raise DataError(msg, file='<JointTrajectory>')
        if m == 0:
            out[FIELDS[j]] = None
            continue
        raw = buf[(base + data_rel)[:, None] + np.arange(8 * m)].copy()
        out[FIELDS[j]] = raw.view('<f8').reshape(n, m).astype(np.float64)
    stamp = sec * NS_PER_S + nsec
    return TrajectoryBatch(stamp_ns=stamp, t_ns=stamp + rel, names=tuple(names), fields=out,
                           frame_id=frame_id)


def batch_to_series(batch: TrajectoryBatch) -> bagio.Series:
    """A decoded batch as a :class:`bagio.Series` (times in float seconds)."""
    m = len(batch.names)
    fields = {f: (a if a is not None and a.shape[1] == m else None)
              for f, a in batch.fields.items()}
    return bagio.Series(t=batch.t_ns / NS_PER_S, names=batch.names, **fields)


def series_to_cdr(series: bagio.Series, *, batch: int = 100,
                  frame_id: str = '') -> list[tuple[int, bytes]]:
    """Cut a series into serialized JointTrajectory batches: ``[(stamp_ns, cdr), ...]``.

    Same batching and stamps as :func:`bagio.series_to_messages`.
    """
    if batch < 1:
        msg = f'batch must be >= 1, got {batch}'
        raise ValueError(msg)
    t_ns = seconds_to_ns(series.t) + np.int64(series.t0_ns)
    out = []
    for i0 in range(0, t_ns.shape[0], batch):
        i1 = min(i0 + batch, t_ns.shape[0])
        stamp = int(t_ns[i0])
        fields = {f: (None if getattr(series, f) is None else getattr(series, f)[i0:i1])
                  for f in FIELDS}
        out.append((stamp, encode_trajectory(stamp, t_ns[i0:i1] - stamp, series.names, fields,
                                             frame_id=frame_id)))
    return out


def cdr_to_series(data: bytes | memoryview) -> bagio.Series:
    """Decode one serialized JointTrajectory into a :class:`bagio.Series`."""
    return batch_to_series(decode_trajectory(data))


def time_to_ns(stamp) -> int:
    """``builtin_interfaces/Time`` (or Duration) to integer nanoseconds."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def _time(ns: int):
    from builtin_interfaces.msg import Time
    return Time(sec=int(ns // NS_PER_S), nanosec=int(ns % NS_PER_S))


def series_to_msg(series: bagio.Series, *, frame_id: str = ''):
    """A whole series as one rclpy ``JointTrajectory`` (object path; slow, for small data)."""
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    t_ns = seconds_to_ns(series.t) + np.int64(series.t0_ns)
    stamp = int(t_ns[0]) if t_ns.shape[0] else 0
    msg = JointTrajectory()
    msg.header.stamp = _time(stamp)
    msg.header.frame_id = frame_id
    msg.joint_names = list(series.names)
    points = []
    for i in range(t_ns.shape[0]):
        p = JointTrajectoryPoint()
        for f in FIELDS:
            arr = getattr(series, f)
            if arr is not None:
                setattr(p, f, arr[i].tolist())
        r = int(t_ns[i] - stamp)
        p.time_from_start = Duration(sec=r // NS_PER_S, nanosec=r % NS_PER_S)
        points.append(p)
    msg.points = points
    return msg


def msg_to_series(msg) -> bagio.Series:
    """An rclpy ``JointTrajectory`` as a :class:`bagio.Series`."""
    stamp = time_to_ns(msg.header.stamp)
    t_ns = np.array([stamp + time_to_ns(p.time_from_start) for p in msg.points], dtype=np.int64)
    m = len(msg.joint_names)
    fields = {}
    for f in FIELDS:
        rows = [np.asarray(getattr(p, f), dtype=np.float64) for p in msg.points]
        arr = np.array(rows).reshape(len(rows), -1) if rows else np.zeros((0, 0))
        fields[f] = arr if arr.shape[1:] == (m,) and m > 0 else None
    return bagio.Series(t=t_ns / NS_PER_S, names=tuple(msg.joint_names), **fields)


def block_energy_msg(blocks: Iterable[tuple[int, float, float]], *, stamp_ns: int,
                     program: str = '', frame_id: str = ''):
    """Per-block energy as a ``DiagnosticArray`` (the content of ``write_block_energy``;
    ``frame_id``: the job id)."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    msg = DiagnosticArray()
    msg.header.stamp = _time(stamp_ns)
    msg.header.frame_id = frame_id
    for line, energy, duration in blocks:
        msg.status.append(DiagnosticStatus(
            level=DiagnosticStatus.OK, name=f'{program}:{line}', message='block energy',
            hardware_id='', values=[KeyValue(key='line', value=str(line)),
                                    KeyValue(key='energy_j', value=repr(float(energy))),
                                    KeyValue(key='duration_s', value=repr(float(duration)))]))
    return msg


def block_energy_from_msg(msg) -> list[tuple[int, float, float]]:
    """Inverse of :func:`block_energy_msg`."""
    out = []
    for status in msg.status:
        vals = {kv.key: kv.value for kv in status.values}
        out.append((int(vals['line']), float(vals['energy_j']), float(vals['duration_s'])))
    return out


def program_end_msg(end: ProgramEnd, *, aborted: bool = False):
    """The end-of-program marker as a ``DiagnosticArray`` stamped with the last batch
    (``frame_id``: the job id; an aborted job's marker says so in its message)."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    msg = DiagnosticArray()
    msg.header.stamp = _time(max(end.last_ns, 0))
    msg.header.frame_id = end.job_id
    text = 'job aborted: streamed up to the abort' if aborted else 'program streamed completely'
    msg.status = [DiagnosticStatus(level=DiagnosticStatus.OK, name='program_end',
                                   message=text, hardware_id='',
                                   values=[KeyValue(key=k, value=v) for k, v in end.to_pairs()])]
    return msg


def program_end_from_msg(msg) -> ProgramEnd:
    """Inverse of :func:`program_end_msg` (``DataError`` if it is not a marker)."""
    for status in msg.status:
        if status.name == 'program_end':
            return ProgramEnd.from_pairs((kv.key, kv.value) for kv in status.values)
    msg_ = 'DiagnosticArray on program/end has no status named program_end'
    raise DataError(msg_, file='program/end')


def lines_to_cdr(starts_ns: np.ndarray, lines: np.ndarray, *, first_ns: int,
                 frame_id: str = '') -> bytes:
    """Run-length code of source lines as a JointTrajectory (joint ``line``, see docs;
    ``frame_id``: the job id)."""
    starts_ns = np.asarray(starts_ns, dtype=np.int64)
    pos = np.asarray(lines, dtype=np.float64).reshape(-1, 1)
    return encode_trajectory(int(first_ns), starts_ns - int(first_ns), ['line'],
                             {'positions': pos}, frame_id=frame_id)


def lines_from_cdr(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`lines_to_cdr`: ``(starts_ns, lines)``."""
    batch = decode_trajectory(data)
    if batch.names != ('line',) or batch.fields['positions'] is None:
        msg = f'program/lines must have the single joint "line", got {batch.names}'
        raise DataError(msg, file='program/lines')
    return batch.t_ns, np.rint(batch.fields['positions'][:, 0]).astype(np.int64)


def clock_msg(ns: int):
    """``rosgraph_msgs/Clock`` at ``ns``."""
    from rosgraph_msgs.msg import Clock
    return Clock(clock=_time(ns))


def stamp_msg(ns: int, frame_id: str = ''):
    """``std_msgs/Header`` carrying a stamp (flow-control acknowledgements)."""
    from std_msgs.msg import Header
    return Header(stamp=_time(ns), frame_id=frame_id)
