"""Live samples put together into rows: one stamp, every axis, in stamp order, counted.

A live drive stream sends one value per message (one axis, one quantity, one stamp). The
comparison needs rows: all the values of one stamp. :class:`RowAssembler` holds the rows
not yet complete in a bounded table keyed by the stamp (integer nanoseconds, so that equal
stamps are equal), and hands rows on strictly in stamp order:

* a row leaves when it is complete and no older row is pending; an incomplete row at the
  head leaves, dropped and counted as ``incomplete``, once a sample ``reorder_s`` newer has
  arrived (a sample that never came: the gap is counted when the next row leaves);
* a sample is ``duplicate`` when its slot already holds a value (the first one is kept) or
  its stamp equals the last row handed on; ``late`` when its stamp is older than the last
  row handed on (it cannot be used any more); ``out_of_order`` when its stamp is older than
  the newest seen for its slot but its row is still pending (it is used);
* a step between two rows handed on longer than :data:`GAP_FACTOR` times the median of the
  recent steps is a ``gap``; the samples it lacks are counted as ``missing``.

Nothing here raises on data; memory is bounded by ``max_pending`` rows.
"""
from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass, field
import math

import numpy as np

from ..run import GAP_FACTOR

__all__ = ['COUNTER_KEYS', 'Row', 'RowAssembler', 'StreamCounters']

_STEPS_KEPT = 31    # recent steps whose median is the stream's period

COUNTER_KEYS = ('accepted', 'rows', 'duplicate', 'late', 'out_of_order', 'incomplete',
                'gaps', 'missing', 'overflow')
"""The counters of :class:`StreamCounters`, the keys of ``counters`` in the comparison."""


@dataclass
class StreamCounters:
    """What happened to the samples of one stream (see the module docstring).

    Attributes
    ----------
    accepted
        Samples stored in a pending row.
    rows
        Complete rows handed on.
    duplicate, late, out_of_order
        Samples by what was odd about their stamp (``out_of_order`` ones are used).
    incomplete
        Rows dropped because a value of theirs never came.
    gaps, missing
        Steps between rows handed on longer than ``GAP_FACTOR`` periods; the samples they
        lack.
    overflow
        Pending rows dropped because more than ``max_pending`` were waiting.
    """

    accepted: int = 0
    rows: int = 0
    duplicate: int = 0
    late: int = 0
    out_of_order: int = 0
    incomplete: int = 0
    gaps: int = 0
    missing: int = 0
    overflow: int = 0

    def as_dict(self) -> dict[str, int]:
        """The counters under :data:`COUNTER_KEYS`."""
        return {k: int(getattr(self, k)) for k in COUNTER_KEYS}


@dataclass(frozen=True)
class Row:
    """One stamp's values, in the assembler's slot order.

    Attributes
    ----------
    stamp_ns
        The stamp [ns] (wall clock or any clock the stream uses).
    values
        One value per slot, shape ``(len(slots),)``.
    """

    stamp_ns: int
    values: np.ndarray


@dataclass
class _Pending:
    values: np.ndarray
    filled: np.ndarray
    count: int = 0


@dataclass
class RowAssembler:
    """Bounded reorder table: samples in, complete rows out in stamp order.

    Parameters
    ----------
    slots
        ``(axis, quantity)`` pairs that make up a row, in the order of :attr:`Row.values`.
    reorder_s
        How long a row may wait for its missing values once newer samples arrive [s].
    max_pending
        Most rows waiting at once; beyond, the oldest leaves (complete) or is dropped.
    """

    slots: tuple[tuple[str, str], ...]
    reorder_s: float = 0.5
    max_pending: int = 4096
    counters: StreamCounters = field(default_factory=StreamCounters)

    def __post_init__(self) -> None:
        if not self.slots:
            raise ValueError('a row needs at least one (axis, quantity) slot')
        if not (math.isfinite(self.reorder_s) and self.reorder_s >= 0.0):
            raise ValueError(f'reorder_s must be a finite number >= 0, got {self.reorder_s!r}')
        self._index = {s: i for i, s in enumerate(self.slots)}
        self._pending: dict[int, _Pending] = {}
        self._order: list[int] = []          # pending stamps, sorted
        self._newest: dict[tuple[str, str], int] = {}
        self._newest_any: int | None = None
        self._last_out: int | None = None
        self._steps: deque[int] = deque(maxlen=_STEPS_KEPT)

    def wants(self, axis: str, quantity: str) -> bool:
        """Whether ``(axis, quantity)`` is one of the row's slots."""
        return (axis, quantity) in self._index

    @property
    def pending(self) -> int:
        """Rows waiting now."""
        return len(self._pending)

    @property
    def period_ns(self) -> int | None:
        """Median of the recent steps between rows handed on [ns] (None before two rows)."""
        return int(np.median(np.fromiter(self._steps, dtype=np.int64))) if self._steps else None

    def add(self, axis: str, quantity: str, stamp_ns: int, value: float) -> list[Row]:
        """Take one sample (of a slot: see :meth:`wants`); return the rows it completes.

        Parameters
        ----------
        axis, quantity
            The sample's slot.
        stamp_ns
            Its stamp [ns].
        value
            Its value (finite; the caller checked it).

        Returns
        -------
        list of Row
            Rows now complete and next in stamp order (often none or one).
        """
        slot = (axis, quantity)
        j = self._index[slot]
        c = self.counters
        if self._last_out is not None and stamp_ns <= self._last_out:
            if stamp_ns == self._last_out:
                c.duplicate += 1
            else:
                c.late += 1
            return []
        row = self._pending.get(stamp_ns)
        if row is not None and row.filled[j]:
            c.duplicate += 1
            return []
        newest = self._newest.get(slot)
        if newest is not None and stamp_ns < newest:
            c.out_of_order += 1
        else:
            self._newest[slot] = stamp_ns
        if row is None:
            row = _Pending(np.zeros(len(self.slots)), np.zeros(len(self.slots), dtype=bool))
            self._pending[stamp_ns] = row
            self._insert(stamp_ns)
        row.values[j] = value
        row.filled[j] = True
        row.count += 1
        c.accepted += 1
        if self._newest_any is None or stamp_ns > self._newest_any:
            self._newest_any = stamp_ns
        return self._release(force=False)

    def flush(self) -> list[Row]:
        """Hand on every complete pending row, drop the others (the stream has ended)."""
        return self._release(force=True)

    def _insert(self, stamp_ns: int) -> None:
        order = self._order
        if not order or stamp_ns > order[-1]:
            order.append(stamp_ns)
        else:
            bisect.insort(order, stamp_ns)
        if len(order) > self.max_pending:
            self.counters.overflow += 1
            self._leave(order[0], keep=self._pending[order[0]].count == len(self.slots))

    def _release(self, *, force: bool) -> list[Row]:
        out: list[Row] = []
        wait_ns = int(round(self.reorder_s * 1e9))
        while self._order:
            head = self._order[0]
            row = self._pending[head]
            complete = row.count == len(self.slots)
            expired = (force or (self._newest_any is not None
                                 and self._newest_any - head > wait_ns))
            if not (complete or expired):
                break
            done = self._leave(head, keep=complete)
            if done is not None:
                out.append(done)
        return out

    def _leave(self, stamp_ns: int, *, keep: bool) -> Row | None:
        if self._order[0] == stamp_ns:
            self._order.pop(0)
        else:
            self._order.remove(stamp_ns)
        row = self._pending.pop(stamp_ns)
        if not keep:
            self.counters.incomplete += 1
            return None
        self._note_step(stamp_ns)
        self.counters.rows += 1
        return Row(stamp_ns, row.values)

    def _note_step(self, stamp_ns: int) -> None:
        if self._last_out is not None:
            step = stamp_ns - self._last_out
            period = self.period_ns
            if period is not None and period > 0 and step > GAP_FACTOR * period:
                self.counters.gaps += 1
                self.counters.missing += max(int(round(step / period)) - 1, 0)
            self._steps.append(step)
        self._last_out = stamp_ns
