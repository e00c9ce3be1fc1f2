"""The end-of-program marker of the node graph (topic ``program/end``, docs/nodes.md).

:class:`ProgramEnd` is what the marker says (batches per stream, first and last stamp),
:class:`EndTracker` knows when a consumer has seen every stream up to it, and
:func:`restamp_end_marker` moves a serialized marker to wall-clock time with the recording
(``start_time``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable

from ..errors import DataError

__all__ = ['ProgramEnd', 'EndTracker', 'restamp_end_marker']

_NS = 1_000_000_000


@dataclass(frozen=True)
class ProgramEnd:
    """The end-of-program marker (see docs/nodes.md, topic ``program/end``).

    Attributes
    ----------
    program
        Program file.
    samples, batches
        Number of samples and of messages per stream.
    first_ns, last_ns
        Stamp of the first sample and of the last batch's header.
    topic_last_ns
        Producers whose streams end at different stamps (``measured_replay``): last header
        stamp per topic (``{'measured/power': ns}``, no leading slash). When given, a topic
        that is not listed has no message to wait for. Empty: every stream ends at ``last_ns``.
    job_id
        The job the marker ends (key ``job_id``; '' and absent for a graph started on one
        program). An aborted job's marker counts what was sent before the abort.
    """

    program: str
    samples: int
    batches: int
    first_ns: int
    last_ns: int
    topic_last_ns: dict[str, int] = field(default_factory=dict)
    job_id: str = ''

    def last_ns_of(self, topic: str) -> int:
        """Last stamp stream ``topic`` must reach (-1: nothing to wait for)."""
        if not self.topic_last_ns:
            return self.last_ns
        return self.topic_last_ns.get(topic.lstrip('/'), -1)

    def to_pairs(self) -> list[tuple[str, str]]:
        """Key/value strings (for a ``diagnostic_msgs/KeyValue`` list)."""
        return [('program', self.program), ('samples', str(self.samples)),
                ('batches', str(self.batches)), ('first_stamp_ns', str(self.first_ns)),
                ('last_stamp_ns', str(self.last_ns))] + [
                    (f'{_TOPIC_LAST}{t}', str(ns)) for t, ns in sorted(self.topic_last_ns.items())
                ] + ([('job_id', self.job_id)] if self.job_id else [])

    @classmethod
    def from_pairs(cls, pairs: Iterable[tuple[str, str]]) -> 'ProgramEnd':
        """Inverse of :meth:`to_pairs` (``DataError`` on a missing or bad value)."""
        d = dict(pairs)
        try:
            per_topic = {k[len(_TOPIC_LAST):].lstrip('/'): int(v) for k, v in d.items()
                         if k.startswith(_TOPIC_LAST)}
            return cls(program=d['program'], samples=int(d['samples']),
                       batches=int(d['batches']), first_ns=int(d['first_stamp_ns']),
                       last_ns=int(d['last_stamp_ns']), topic_last_ns=per_topic,
                       job_id=str(d.get('job_id', '')))
        except (KeyError, ValueError) as err:
            msg = f'bad end-of-program marker {d!r}: {err}'
            raise DataError(msg, file='program/end') from err


_TOPIC_LAST = 'last_stamp_ns:'


def restamp_end_marker(cdr: bytes, start_ns: int) -> bytes:
    """A serialized ``program/end`` marker moved ``start_ns`` later: its header stamp and the
    stamps it carries as values (``first_stamp_ns``, ``last_stamp_ns``, per topic), so that
    a recording in wall-clock time (``start_time``) holds a marker in the same time.

    Raises
    ------
    DataError
        Not a ``DiagnosticArray`` with a ``program_end`` status and whole-number stamps, or a
        stamp outside the ROS 2 time range (naming ``program/end``).
    """
    from ..record import DIAGNOSTIC_ARRAY, MAX_STAMP_NS, typestore
    ts = typestore()
    try:
        msg = ts.deserialize_cdr(bytes(cdr), DIAGNOSTIC_ARRAY)
    except Exception as err:    # rosbags raises assorted errors on damaged CDR
        msg_ = f'cannot decode the end-of-program marker ({type(err).__name__})'
        raise DataError(msg_, file='program/end') from None
    found = False
    for status in msg.status:
        if status.name != 'program_end':
            continue
        found = True
        ProgramEnd.from_pairs((kv.key, kv.value) for kv in status.values)    # checks values
        for kv in status.values:
            if kv.key in ('first_stamp_ns', 'last_stamp_ns') or kv.key.startswith(_TOPIC_LAST):
                kv.value = str(_moved(int(kv.value), start_ns, MAX_STAMP_NS))
    if not found:
        msg_ = 'DiagnosticArray on program/end has no status named program_end'
        raise DataError(msg_, file='program/end')
    stamp = _moved(msg.header.stamp.sec * _NS + msg.header.stamp.nanosec, start_ns,
                   MAX_STAMP_NS)
    msg.header.stamp = ts.types['builtin_interfaces/msg/Time'](sec=stamp // _NS,
                                                               nanosec=stamp % _NS)
    return bytes(ts.serialize_cdr(msg, DIAGNOSTIC_ARRAY))


def _moved(stamp_ns: int, start_ns: int, limit_ns: int) -> int:
    out = stamp_ns + start_ns
    if not 0 <= out <= limit_ns:
        msg = f'stamp {stamp_ns} ns + start {start_ns} ns is outside the ROS 2 time range'
        raise DataError(msg, file='program/end')
    return out


class EndTracker:
    """Knows when every stream has delivered its last batch of the program.

    Parameters
    ----------
    streams
        Topics that must each reach the end marker's last stamp.
    extra
        Topics of which at least one message must have arrived (e.g. ``block_energy``).
    """

    def __init__(self, streams: Iterable[str], extra: Iterable[str] = ()) -> None:
        self._last = {s: -1 for s in streams}
        self._extra = {e: False for e in extra}
        self.end: ProgramEnd | None = None

    @property
    def streams(self) -> tuple[str, ...]:
        """The topics that must reach the end marker's last stamp."""
        return tuple(self._last)

    def seen(self, topic: str, stamp_ns: int) -> None:
        """Record a message of ``topic`` with header stamp ``stamp_ns``."""
        if topic in self._last:
            self._last[topic] = max(self._last[topic], stamp_ns)
        if topic in self._extra:
            self._extra[topic] = True

    def min_stamp_ns(self) -> int:
        """Newest stamp that every stream has reached (-1 before)."""
        return min(self._last.values()) if self._last else -1

    @property
    def done(self) -> bool:
        """True once the marker arrived and every stream and extra topic caught up.

        A stream has caught up when it reached the marker's last stamp for it
        (:meth:`ProgramEnd.last_ns_of`).
        """
        end = self.end
        return (end is not None and all(last >= end.last_ns_of(topic)
                                        for topic, last in self._last.items())
                and all(self._extra.values()))
