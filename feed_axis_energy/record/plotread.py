"""Read the plot topics (:mod:`.plottopics`) of a bag back as arrays, every message checked.

Reads as a viewer does: one sample per message, its time the header stamp (which must equal
the log time), one value per name and field.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .bagcheck import check_joint_state
from .bagio import decode_message, iter_messages, open_reader, topic_connections
from ..errors import DataError
from .plottopics import JOINT_STATE

__all__ = ['PlotSeries', 'read_plot_topic']

_NS = 1_000_000_000


@dataclass(frozen=True)
class PlotSeries:
    """The messages of one JointState topic as columns.

    Attributes
    ----------
    t_ns
        Header stamp (= log time) of every message [ns], ``(m,)``.
    names
        The names of the first message (every message must have the same).
    position, velocity, effort
        ``(m, len(names))`` arrays, or ``None`` where the messages leave the field empty.
    """

    t_ns: np.ndarray
    names: tuple[str, ...]
    position: np.ndarray | None
    velocity: np.ndarray | None
    effort: np.ndarray | None


def read_plot_topic(path: str | Path, topic: str) -> PlotSeries:
    """Read every ``sensor_msgs/JointState`` message of ``topic`` in log-time order.

    Raises
    ------
    DataError
        Not a bag, the topic missing or of another type, a message that cannot be decoded,
        fails :func:`.bagcheck.check_joint_state`, has other names or fields than message 0,
        or a log time other than its header stamp; naming topic and message index.
    """
    path = Path(path)
    rows: list[tuple[int, object]] = []
    with open_reader(path) as reader:
        conns = topic_connections(reader, path, topic, msgtype=JOINT_STATE)
        first = None
        for _, index, log_ns, raw in iter_messages(reader, path, conns):
            message = decode_message(path, topic, index, raw, JOINT_STATE)
            check_joint_state(message, file=str(path), topic=topic, index=index)
            stamp = message.header.stamp.sec * _NS + message.header.stamp.nanosec
            if stamp != log_ns:
                msg = f'header stamp {stamp} ns differs from the log time {log_ns} ns'
                raise DataError(msg, file=str(path), topic=topic, index=index)
            shape = (tuple(message.name),) + tuple(
                len(getattr(message, f)) > 0 for f in ('position', 'velocity', 'effort'))
            if first is None:
                first = shape
            elif shape != first:
                msg = ('names or filled fields differ from those of message 0; expected the '
                       'same columns in every message of a topic')
                raise DataError(msg, file=str(path), topic=topic, index=index)
            rows.append((stamp, message))
    rows.sort(key=lambda r: r[0])
    names = first[0] if first else ()
    fields = []
    for i, field in enumerate(('position', 'velocity', 'effort')):
        if first is None or not first[1 + i]:
            fields.append(None)
        else:
            fields.append(np.array([getattr(m, field) for _, m in rows], np.float64))
    return PlotSeries(np.array([s for s, _ in rows], np.int64), names, *fields)
