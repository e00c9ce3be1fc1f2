"""rosbag2 (MCAP storage) read through ``rosbags``: no rclpy needed; the series form of a topic.

Time series are stored batched as ``trajectory_msgs/msg/JointTrajectory``: one message holds
up to ``batch`` samples; ``header.stamp`` is the time of the batch's first sample and every
point's ``time_from_start`` is relative to it. The bag's log time of a message equals its
header stamp, so recordings compare by simulation time, never by wall-clock receive time.
Bags are written by :class:`.bagwrite.StreamBagWriter` (the node graph's by
:class:`.crashsafe.ChunkedBagWriter`). Topic names, field meanings and units are listed in
``docs/ARCHITECTURE.md`` and README.
"""
from __future__ import annotations

import contextlib
from contextlib import contextmanager
from dataclasses import dataclass
import json
import math
from pathlib import Path
from typing import Iterable, Iterator, Sequence

import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.typesys import get_typestore, Stores

from feed_axis_energy.record.bagcheck import check_trajectory, field_layout, guard
from feed_axis_energy.errors import DataError, describe, shorten
from feed_axis_energy.record.mcapcheck import check_mcap
from feed_axis_energy.safeyaml import load_yaml_file
from feed_axis_energy.units import MAX_ABS_SI

__all__ = ['TOPIC_SETPOINTS', 'TOPIC_AXIS_STATE', 'TOPIC_POWER', 'TOPIC_BLOCK_ENERGY',
           'TOPIC_MEASURED_POWER', 'TOPIC_MEASURED_KINEMATICS', 'JOINT_TRAJECTORY',
           'DIAGNOSTIC_ARRAY', 'Series', 'read_series', 'read_block_energy',
           'read_custom_data', 'bag_topics', 'typestore', 'series_to_messages',
           'messages_to_series', 'read_metadata', 'read_raw_messages']

TOPIC_SETPOINTS = '/setpoints'
TOPIC_AXIS_STATE = '/axis_state'
TOPIC_POWER = '/power'
TOPIC_BLOCK_ENERGY = '/block_energy'
TOPIC_MEASURED_POWER = '/measured/power'
TOPIC_MEASURED_KINEMATICS = '/measured/kinematics'

JOINT_TRAJECTORY = 'trajectory_msgs/msg/JointTrajectory'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'

_NS = 1_000_000_000
_TYPESTORE = None


def typestore():
    """Return the (cached) ROS 2 Kilted typestore used for every bag we read or write."""
    global _TYPESTORE
    if _TYPESTORE is None:
        _TYPESTORE = get_typestore(Stores.ROS2_KILTED)
    return _TYPESTORE


@dataclass(frozen=True)
class Series:
    """A batched time series on one topic.

    Attributes
    ----------
    t
        Sample times [s] since ``t0_ns``, shape ``(n,)``.
    names
        Joint names (columns), e.g. ``('X', 'X_screw')`` or ``('X', 'total')``.
    positions, velocities, accelerations, effort
        Arrays of shape ``(n, len(names))`` or ``None`` when the field is absent.
    t0_ns
        The time ``t`` counts from [ns since the epoch of the stamps]: 0 for simulation time.
        :func:`read_series` sets it to the first sample's stamp, so that ``t`` keeps every
        nanosecond of a recording stamped in wall-clock time (``--start-time``; float64
        seconds since 1970 hold only about 0.2 us there).
    """

    t: np.ndarray
    names: tuple[str, ...]
    positions: np.ndarray | None = None
    velocities: np.ndarray | None = None
    accelerations: np.ndarray | None = None
    effort: np.ndarray | None = None
    t0_ns: int = 0

    def __post_init__(self) -> None:
        if isinstance(self.t0_ns, bool) or not isinstance(self.t0_ns, (int, np.integer)):
            msg = f'Series.t0_ns must be an integer [ns], got {type(self.t0_ns).__name__}'
            raise ValueError(msg)
        n, m = self.t.shape[0], len(self.names)
        for field in ('positions', 'velocities', 'accelerations', 'effort'):
            arr = getattr(self, field)
            if arr is not None and arr.shape != (n, m):
                msg = f'Series.{field} has shape {arr.shape}, expected ({n}, {m})'
                raise ValueError(msg)

    def stamps_ns(self) -> np.ndarray:
        """The sample times as integer stamps [ns]: ``t0_ns + round(t * 1e9)``, int64."""
        return np.rint(self.t * _NS).astype(np.int64) + np.int64(self.t0_ns)


def series_to_messages(series: Series, *, batch: int = 100, frame_id: str = '') -> list:
    """Cut a series into JointTrajectory messages of at most ``batch`` points.

    Returns a list of ``(stamp_ns, message)`` pairs (rosbags message objects).
    """
    ts = typestore()
    jt_cls = ts.types[JOINT_TRAJECTORY]
    pt_cls = ts.types['trajectory_msgs/msg/JointTrajectoryPoint']
    header_cls = ts.types['std_msgs/msg/Header']
    time_cls = ts.types['builtin_interfaces/msg/Time']
    dur_cls = ts.types['builtin_interfaces/msg/Duration']
    empty = np.zeros(0, dtype=np.float64)
    fields = [getattr(series, f) for f in ('positions', 'velocities', 'accelerations', 'effort')]
    t_ns = series.stamps_ns()
    if np.any(t_ns < 0):
        msg = 'bag time series must not have negative times'
        raise ValueError(msg)
    out = []
    names = list(series.names)
    for i0 in range(0, t_ns.shape[0], batch):
        i1 = min(i0 + batch, t_ns.shape[0])
        stamp = int(t_ns[i0])
        rel = t_ns[i0:i1] - stamp
        points = []
        for j in range(i0, i1):
            vals = [empty if f is None else np.ascontiguousarray(f[j]) for f in fields]
            r = int(rel[j - i0])
            points.append(pt_cls(positions=vals[0], velocities=vals[1], accelerations=vals[2],
                                 effort=vals[3],
                                 time_from_start=dur_cls(sec=r // _NS, nanosec=r % _NS)))
        header = header_cls(stamp=time_cls(sec=stamp // _NS, nanosec=stamp % _NS),
                            frame_id=frame_id)
        out.append((stamp, jt_cls(header=header, joint_names=names, points=points)))
    return out


def messages_to_series(messages: Iterable) -> Series:
    """Join JointTrajectory messages (in stamp order) back into one :class:`Series`.

    Times are summed in integer nanoseconds; ``t0_ns`` is the first sample's stamp and ``t``
    counts from it, exactly to the nanosecond for any stamp (wall-clock ones included).
    """
    t_parts: list[np.ndarray] = []
    cols: dict[str, list[np.ndarray]] = {f: [] for f in
                                         ('positions', 'velocities', 'accelerations', 'effort')}
    names: tuple[str, ...] | None = None
    for msg in messages:
        if names is None:
            names = tuple(msg.joint_names)
        stamp = msg.header.stamp.sec * _NS + msg.header.stamp.nanosec
        rel = np.array([p.time_from_start.sec * _NS + p.time_from_start.nanosec
                        for p in msg.points], dtype=np.int64)
        t_parts.append(stamp + rel)
        for field, parts in cols.items():
            rows = [getattr(p, field) for p in msg.points]
            parts.append(np.array(rows, dtype=np.float64).reshape(len(rows), -1))
    if names is None:
        return Series(t=np.zeros(0), names=())
    m = len(names)
    arrays = {}
    for field, parts in cols.items():
        arr = np.concatenate(parts, axis=0) if parts else np.zeros((0, 0))
        arrays[field] = arr if arr.shape[1] == m and m > 0 else None
    t_ns = np.concatenate(t_parts)
    t0_ns = int(t_ns[0]) if t_ns.shape[0] else 0
    return Series(t=(t_ns - t0_ns) / _NS, names=names, t0_ns=t0_ns, **arrays)


# ----------------------------------------------------------------------------- reading
#
# Everything read from a bag passes through here: the metadata is parsed by the bounded
# YAML loader first, every rosbags call that touches file content is guarded, and every
# decoded message is checked (type, array lengths, finite values) before it is used, so a
# damaged bag ends in one DataError naming the bag, the topic and the message index.

def read_metadata(path: str | Path) -> dict:
    """Return the parsed ``metadata.yaml`` of a bag directory (the bounded YAML loader).

    Parameters
    ----------
    path
        The bag directory.

    Returns
    -------
    dict
        The ``rosbag2_bagfile_information`` mapping.

    Raises
    ------
    DataError
        Not a directory, no or unreadable ``metadata.yaml``, not valid YAML, or not the
        rosbag2 layout.
    """
    path = Path(path)
    meta_file = path / 'metadata.yaml'
    try:
        is_bag = path.is_dir() and meta_file.is_file()
    except OSError:  # a name too long, a loop in the path
        is_bag = False
    if not is_bag:
        msg = 'not a rosbag2 directory (no metadata.yaml)'
        raise DataError(msg, file=str(path))
    meta = load_yaml_file(meta_file, error=DataError, what='bag metadata')
    info = meta.get('rosbag2_bagfile_information') if isinstance(meta, dict) else None
    if not isinstance(info, dict):
        msg = (f'expected a mapping with the key rosbag2_bagfile_information, got '
               f'{describe(meta)}')
        raise DataError(msg, file=str(meta_file))
    return info


@contextmanager
def open_reader(path: str | Path) -> Iterator[Reader]:
    path = Path(path)
    info = read_metadata(path)  # bounded parse and layout check before rosbags parses it
    files = info.get('relative_file_paths')
    for name in files if isinstance(files, list) else []:
        storage = path / Path(str(name)).name
        if str(name).endswith('.mcap') and storage.is_file():
            check_mcap(storage, bag=path)
    with guard(path, doing='open the bag'):
        reader = Reader(path)
        reader.open()
    try:
        yield reader
    finally:
        with contextlib.suppress(Exception):
            reader.close()


def bag_topics(path: str | Path) -> dict[str, tuple[str, int]]:
    """Return ``{topic: (msgtype, message count)}`` of a bag.

    Raises
    ------
    DataError
        Not a bag, or a bag whose metadata or storage cannot be read.
    """
    with open_reader(path) as reader:
        # the counts come from metadata.yaml as written: a damaged one may hold any text
        with guard(Path(path), doing='read the message counts of metadata.yaml'):
            return {c.topic: (c.msgtype, max(int(c.msgcount), 0))
                    for c in reader.connections}


def _connections(reader: Reader, path: Path, topics: Sequence[str], *,
                 msgtype: str | None) -> list:
    conns = [c for c in reader.connections if c.topic in topics]
    for c in conns:
        if msgtype is not None and c.msgtype != msgtype:
            msg = f'has type {shorten(c.msgtype)}, expected {msgtype}'
            raise DataError(msg, file=str(path), topic=c.topic)
    return conns


def topic_connections(reader: Reader, path: Path, topic: str, *, msgtype: str) -> list:
    """The connections of ``topic``, all of type ``msgtype``; a missing topic is an error
    naming the topics the bag has."""
    conns = _connections(reader, path, [topic], msgtype=msgtype)
    if not conns:
        have = shorten(', '.join(sorted(c.topic for c in reader.connections)),
                       limit=200) or 'none'
        msg = f'topic {topic!r} not in bag (topics: {have})'
        raise DataError(msg, file=str(path))
    return conns


def iter_messages(reader: Reader, path: Path,
                  conns: list) -> Iterator[tuple[str, int, int, bytes]]:
    """``(topic, index within the topic, log time [ns], raw CDR)`` with guarded reading."""
    counts: dict[str, int] = {}
    it = reader.messages(connections=conns)
    while True:
        with guard(path, doing='read the messages'):
            item = next(it, None)
        if item is None:
            return
        conn, log_ns, raw = item
        index = counts.get(conn.topic, 0)
        counts[conn.topic] = index + 1
        yield conn.topic, index, int(log_ns), raw


def decode_message(path: Path, topic: str, index: int, raw: bytes, msgtype: str):
    with guard(path, topic=topic, index=index, doing='decode the message'):
        return typestore().deserialize_cdr(raw, msgtype)


def read_series(path: str | Path, topic: str) -> Series:
    """Read all JointTrajectory messages of ``topic`` into one :class:`Series`.

    ``t0_ns`` is the stamp of the topic's first sample and ``t`` [s] counts from it (exact to
    the nanosecond); a recording stamped in simulation time from 0 reads ``t0_ns = 0``.

    Raises
    ------
    DataError
        Not a bag, the topic is missing or of another type, a message cannot be decoded,
        or the decoded messages do not fit together (:func:`check_trajectory`, the same
        joint names and fields in every message); naming the topic and message index.
    """
    path = Path(path)
    msgs = []
    with open_reader(path) as reader:
        conns = topic_connections(reader, path, topic, msgtype=JOINT_TRAJECTORY)
        first = None
        for _, index, _, raw in iter_messages(reader, path, conns):
            message = decode_message(path, topic, index, raw, JOINT_TRAJECTORY)
            check_trajectory(message, file=str(path), topic=topic, index=index)
            shape = (tuple(message.joint_names), field_layout(message))
            if first is None:
                first = shape
            elif shape != first and message.points:
                msg = ('joint names or filled fields differ from those of message 0; '
                       'expected the same columns in every message of a topic')
                raise DataError(msg, file=str(path), topic=topic, index=index)
            msgs.append(message)
    msgs.sort(key=lambda m: (m.header.stamp.sec, m.header.stamp.nanosec))
    return messages_to_series(msgs)


def read_raw_messages(path: str | Path, topics: Sequence[str], *,
                      max_abs: float = MAX_ABS_SI) -> list[tuple[str, int, bytes]]:
    """Serialized JointTrajectory messages of ``topics``, by log time: ``[(topic, ns, cdr)]``.

    Each message is decoded once and checked (:func:`check_trajectory`, values at most
    ``max_abs``: by default the bound of measured SI values, as when a run is loaded) so
    that corrupt CDR is refused here rather than published. Topics missing from the bag are
    skipped.

    Raises
    ------
    DataError
        Not a bag; none of ``topics`` in it; a topic of another type; a present topic
        without messages; a message that cannot be decoded or fails the checks.
    """
    path = Path(path)
    out = []
    with open_reader(path) as reader:
        conns = _connections(reader, path, topics, msgtype=None)
        if not conns:
            have = shorten(', '.join(sorted(c.topic for c in reader.connections)),
                           limit=200) or 'none'
            msg = f'none of the topics {list(topics)} is in the bag (topics: {have})'
            raise DataError(msg, file=str(path))
        _connections(reader, path, topics, msgtype=JOINT_TRAJECTORY)
        for topic, index, log_ns, raw in iter_messages(reader, path, conns):
            message = decode_message(path, topic, index, raw, JOINT_TRAJECTORY)
            check_trajectory(message, file=str(path), topic=topic, index=index,
                             max_abs=max_abs)
            out.append((topic, log_ns, bytes(raw)))
    for topic in sorted({c.topic for c in conns} - {m[0] for m in out}):
        msg = 'the topic has no messages; expected a recorded run'
        raise DataError(msg, file=str(path), topic=topic)
    out.sort(key=lambda m: m[1])
    return out


def read_block_energy(path: str | Path) -> list[tuple[int, float, float]]:
    """Read the per-block energy summary: ``[(line, energy_j, duration_s), ...]``.

    Raises
    ------
    DataError
        Not a bag, a message that cannot be decoded, or a status without a whole-number
        ``line`` and finite ``energy_j`` and ``duration_s``.
    """
    path = Path(path)
    out = []
    with open_reader(path) as reader:
        conns = _connections(reader, path, [TOPIC_BLOCK_ENERGY], msgtype=DIAGNOSTIC_ARRAY)
        for topic, index, _, raw in iter_messages(reader, path, conns):
            msg = decode_message(path, topic, index, raw, DIAGNOSTIC_ARRAY)
            for status in msg.status:
                vals = {kv.key: kv.value for kv in status.values}
                try:
                    row = (int(vals['line']), float(vals['energy_j']),
                           float(vals['duration_s']))
                except (KeyError, ValueError) as err:
                    text = f'status {shorten(status.name)!r}: expected line, energy_j and ' \
                           f'duration_s numbers ({shorten(str(err))})'
                    raise DataError(text, file=str(path), topic=topic, index=index) from None
                if not (math.isfinite(row[1]) and math.isfinite(row[2])):
                    text = f'status {shorten(status.name)!r}: energy or duration not finite'
                    raise DataError(text, file=str(path), topic=topic, index=index)
                out.append(row)
    return out


def read_custom_data(path: str | Path, key: str) -> object:
    """Read a JSON value stored with :meth:`.bagwrite.StreamBagWriter.set_custom_data`
    (``None`` if absent).

    Raises
    ------
    DataError
        Not a bag, metadata that cannot be read, or a value that is not valid JSON,
        naming the bag and the key.
    """
    info = read_metadata(path)
    custom = info.get('custom_data') or {}
    where = str(Path(path) / 'metadata.yaml')
    if not isinstance(custom, dict):
        msg = f'custom_data: expected a mapping, got {describe(custom)}'
        raise DataError(msg, file=where)
    if key not in custom:
        return None
    text = custom[key]
    if not isinstance(text, str):
        msg = f'custom_data.{key}: expected JSON text, got {describe(text)}'
        raise DataError(msg, file=where)
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as err:
        reason = 'nested too deeply' if isinstance(err, RecursionError) else shorten(str(err))
        msg = f'custom_data.{key}: not valid JSON ({reason})'
        raise DataError(msg, file=where) from None
