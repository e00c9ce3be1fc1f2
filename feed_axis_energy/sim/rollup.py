"""Energy and time per operation, subroutine, tool and axis, accumulated chunk by chunk.

The interpreter marks where the context of the moves changes
(:class:`.gcode.context.OperationContext`); the samples carry only their source line. The
two are joined in order: :meth:`RollupAccumulator.wrap` notes ``(line, context)`` of every
move as the planner takes it, and :meth:`RollupAccumulator.add` walks the runs of source
lines in the samples along those notes. While the notes ahead hold one context only (the
usual case: contexts change a few times per program) a whole chunk is summed at once; the
run-by-run walk is needed only in a chunk where the context changes. Each trapezoid
interval goes to the context of its end sample (as the energy per block).

Known limit: a move too short to get a sample of its own is skipped in the walk; if its
line is also the line of the next run, the context may change a run early.
"""
from __future__ import annotations

from bisect import bisect_right
from collections.abc import Iterable, Iterator, Sequence
from itertools import chain, islice
from operator import attrgetter
from typing import Any, cast

import numpy as np

from ..gcode import Move
from .summary import line_runs, row_sum

__all__ = ['RollupAccumulator', 'NO_TOOL']

NO_TOOL = 'no tool'
NOTE_BATCH = 4096
"""Moves noted at a time by :meth:`RollupAccumulator.wrap` from a plain iterable."""
_NO_MARKS = [(0, 0)]
_LINE = attrgetter('line')


def _lists(it: Iterator[Move], size: int) -> Iterator[list[Move]]:
    """The items of ``it`` in lists of ``size``."""
    while batch := list(islice(it, size)):
        yield batch


class RollupAccumulator:
    """Energy and time by context (and moving time per axis) from the simulation chunks.

    Parameters
    ----------
    context
        The run's :class:`.gcode.context.OperationContext` (its ``table`` and ``marks``),
        or ``None``: every move in one context (no operation, no tool).
    """

    def __init__(self, context: Any = None) -> None:
        self.context = context
        # the notes: the line of every move from ordinal ``_popped - _at`` on, and the
        # ordinals where the context changes (``_change_at``, ascending) with the new one
        self._lines: list[int] = []
        self._at = 0                # index in _lines of the first note not left behind
        self._noted = 0             # moves noted
        self._mark = 0              # marks of the context read so far
        self._noted_ctx = 0         # context of the last note
        self._change_at: list[int] = [0]
        self._change_ctx: list[int] = [0]
        self._popped = 0            # moves left behind
        self._last_change = -1      # ordinal of the last note whose context differs
        self._ctx = 0               # context of the samples now
        self.energy = np.zeros(4)
        self.duration = np.zeros(4)
        # with declared drives: energy at the motor terminals and at the supply side
        # (cabinet included) per context, columns 0 and 1; None without
        self.electrical: np.ndarray | None = None
        self.axes: tuple[str, ...] = ()
        self.axis_time: np.ndarray | None = None
        self._prev: tuple[float, float, np.ndarray] | None = None
        self._prev_elec: np.ndarray | None = None     # motor and supply power, last sample

    # -- the move side ----------------------------------------------------------------------
    def wrap(self, moves: Iterable[Move]) -> Iterator[Move]:
        """The moves unchanged, noting each one's line and context as it is taken.

        Taken a list at a time: from ``moves.batches()`` where it exists (a
        :class:`.gcode.MoveStream` or what wraps it; the context's marks are complete up to
        the end of each list), else in lists of :data:`NOTE_BATCH` moves; the moves are
        then chained in C, without a generator step or a tuple per move.
        """
        batches = getattr(moves, 'batches', None)
        lists = batches() if batches is not None else _lists(iter(moves), NOTE_BATCH)
        return chain.from_iterable(self._noted_lists(lists))

    def _noted_lists(self, lists: Iterable[list[Move]]) -> Iterator[list[Move]]:
        for moves in lists:
            self.note(moves)
            yield moves

    def note(self, moves: Sequence[Move]) -> None:
        """Note the next moves (in program order, once they all exist): their lines, and
        the context changes the marks give for their ordinals."""
        first = self._noted
        end = first + len(moves)
        ctx = self.context
        marks = ctx.marks if ctx is not None else _NO_MARKS
        j = self._mark
        current = self._noted_ctx
        while j < len(marks) and marks[j][0] < end:
            # every mark up to a move's ordinal applies from that move on; several at one
            # ordinal: the last one
            at = max(marks[j][0], first)
            current = marks[j][1]
            j += 1
            while j < len(marks) and max(marks[j][0], first) == at:
                current = marks[j][1]
                j += 1
            if current != self._noted_ctx:
                self._noted_ctx = current
                self._last_change = at
                self._change_at.append(at)
                self._change_ctx.append(current)
        self._mark = j
        self._lines.extend(map(_LINE, moves))
        self._noted = end

    def _ctx_at(self, ordinal: int) -> int:
        """The context of the note ``ordinal``."""
        return self._change_ctx[bisect_right(self._change_at, ordinal) - 1]

    # -- the sample side --------------------------------------------------------------------
    def _advance_to(self, line: int) -> None:
        """Make the first note with ``line`` the current one (none: stay)."""
        lines = self._lines
        try:
            i = lines.index(line, self._at)
        except ValueError:
            return
        self._popped += i - self._at
        self._at = i
        self._ctx = self._ctx_at(self._popped)
        if i > 4096 and 2 * i > len(lines):
            # forget the notes left behind (and the changes before the current one)
            del lines[:i]
            self._at = 0
            keep = bisect_right(self._change_at, self._popped) - 1
            if keep > 0:
                del self._change_at[:keep]
                del self._change_ctx[:keep]

    def _grow(self, size: int) -> None:
        if size > self.energy.shape[0]:
            n = max(size, 2 * self.energy.shape[0])
            extra = n - self.energy.shape[0]
            self.energy = np.concatenate((self.energy, np.zeros(extra)))
            self.duration = np.concatenate((self.duration, np.zeros(extra)))
            if self.electrical is not None:
                self.electrical = np.concatenate((self.electrical, np.zeros((extra, 2))))

    def _electrical_steps(self, chunk: Any, t: np.ndarray, t0: float,
                          first: bool) -> np.ndarray | None:
        """Motor-terminal and supply energy ``(m - first, 2)`` [J] of every interval (the
        one from the previous chunk's last sample first), or None without drives."""
        elec = chunk.power.electrical
        if elec is None:
            return None
        power = np.empty((t.shape[0], 2))
        power[:, 0] = row_sum(elec.motor_w)
        power[:, 1] = row_sum(elec.supply_w) + elec.cabinet_w
        if self.electrical is None:
            self.electrical = np.zeros((self.energy.shape[0], 2))
        steps = 0.5 * (power[1:] + power[:-1]) * np.diff(t)[:, None]
        if not first:
            prev = cast(np.ndarray, self._prev_elec)    # not the first chunk: its last row
            head = 0.5 * (power[:1] + prev) * (float(t[0]) - t0)
            steps = np.concatenate((head, steps))
        self._prev_elec = power[-1:].copy()
        return steps

    def add(self, chunk: Any) -> None:
        """Take one :class:`.simulate.SimulationResult` chunk (in time order)."""
        p = chunk.power
        t, line = p.t, p.line
        m = int(t.shape[0])
        if m == 0:
            return
        vel = chunk.dynamics.velocity_m_s
        first = self._prev is None
        if first:
            self.axes = tuple(p.axes)
            self.axis_time = np.zeros(len(self.axes))
            t0, e0, v0 = float(t[0]), float(p.total_energy_j[0]), vel[0]
        else:
            t0, e0, v0 = cast('tuple[float, float, np.ndarray]', self._prev)   # not first
        self._prev = (float(t[-1]), float(p.total_energy_j[-1]), vel[-1].copy())
        steps = self._electrical_steps(chunk, t, t0, first)
        if m == 1 and first:
            return
        self._axis_time(t, vel, t0, v0, first)
        ends = np.asarray(line[1:] if first else line, dtype=np.int64)
        starts = np.concatenate(([0], np.nonzero(ends[1:] != ends[:-1])[0] + 1))
        keys = ends[starts]
        if self._last_change <= self._popped:
            # every note ahead has the current context: the whole chunk is one context,
            # and its energy and time are the increments of the cumulative series
            if self._at < len(self._lines):
                self._ctx = self._ctx_at(self._popped)
            self._advance_to(int(keys[-1]))
            self._grow(self._ctx + 1)
            self.energy[self._ctx] += float(p.total_energy_j[-1]) - e0
            self.duration[self._ctx] += float(t[-1]) - t0
            if steps is not None:       # the cast: _electrical_steps set it
                cast(np.ndarray, self.electrical)[self._ctx] += steps.sum(axis=0)
            return
        total = p.total_w
        dt = np.diff(t) if first else np.diff(t, prepend=t0)
        if first:
            de = 0.5 * (total[1:] + total[:-1]) * dt
        else:
            de = np.empty(m)
            de[0] = float(p.total_energy_j[0]) - e0      # the interval between the chunks
            de[1:] = 0.5 * (total[1:] + total[:-1]) * dt[1:]
        ctxs = np.empty(keys.shape[0], dtype=np.int64)
        for i, key in enumerate(keys.tolist()):
            self._advance_to(key)
            ctxs[i] = self._ctx
        e = np.add.reduceat(de, starts)
        d = np.add.reduceat(dt, starts)
        self._grow(int(ctxs.max()) + 1)
        np.add.at(self.energy, ctxs, e)
        np.add.at(self.duration, ctxs, d)
        if steps is not None:           # the cast: _electrical_steps set it
            for c in range(2):
                np.add.at(cast(np.ndarray, self.electrical)[:, c], ctxs,
                          np.add.reduceat(steps[:, c], starts))

    def add_pieces(self, axes: tuple[str, ...], line: np.ndarray, energy_j: np.ndarray,
                   duration_s: np.ndarray, axis_moving_s: np.ndarray,
                   electrical_j: np.ndarray | None = None) -> None:
        """Take the pieces of the energy by phase (:mod:`.quadrature`), in time order: the
        source line, energy [J] and duration [s] of each (a piece lies in one block, so
        each goes wholly to its move's context), and the time ``(k,)`` [s] each axis
        moved in them; with drives ``electrical_j`` ``(p, 2)``: each piece's energy at the
        motor terminals and at the supply side (the cabinet's standby included) [J]."""
        if self.axis_time is None:
            self.axes = tuple(axes)
            self.axis_time = np.zeros(len(self.axes))
        self.axis_time += axis_moving_s
        line = np.asarray(line, dtype=np.int64)
        if line.size == 0:
            return
        keys, e, d = line_runs(line, energy_j, duration_s)
        elec = None
        if electrical_j is not None:
            _, motor, supply = line_runs(line, electrical_j[:, 0], electrical_j[:, 1])
            elec = np.stack((motor, supply), axis=1)
            if self.electrical is None:
                self.electrical = np.zeros((self.energy.shape[0], 2))
        if self._last_change <= self._popped:
            # every note ahead has the current context (see add)
            if self._at < len(self._lines):
                self._ctx = self._ctx_at(self._popped)
            self._advance_to(int(keys[-1]))
            self._grow(self._ctx + 1)
            self.energy[self._ctx] += float(e.sum())
            self.duration[self._ctx] += float(d.sum())
            if elec is not None:
                cast(np.ndarray, self.electrical)[self._ctx] += elec.sum(axis=0)
            return
        ctxs = np.empty(keys.shape[0], dtype=np.int64)
        for i, key in enumerate(keys.tolist()):
            self._advance_to(key)
            ctxs[i] = self._ctx
        self._grow(int(ctxs.max()) + 1)
        np.add.at(self.energy, ctxs, e)
        np.add.at(self.duration, ctxs, d)
        if elec is not None:
            for c in range(2):
                np.add.at(cast(np.ndarray, self.electrical)[:, c], ctxs, elec[:, c])

    def _axis_time(self, t: np.ndarray, vel: np.ndarray, t0: float, v0: np.ndarray,
                   first: bool) -> None:
        """Add the time each axis moves: the intervals with a non-zero speed at either end
        (the chunk's span minus its few standing intervals)."""
        span = float(t[-1]) - t0
        moving = vel != 0.0
        for j in range(len(self.axes)):
            mj = moving[:, j]
            stand = ~(mj[1:] | mj[:-1])
            idx = np.flatnonzero(stand)
            still = float(np.sum(t[idx + 1] - t[idx])) if idx.size else 0.0
            if not first and not (mj[0] or v0[j] != 0.0):
                still += float(t[0]) - t0
            cast(np.ndarray, self.axis_time)[j] += span - still     # set by the first chunk

    # -- results ----------------------------------------------------------------------------
    def rollups(self, energy_j: dict[str, float],
                electrical: dict[str, Any] | None = None) -> dict[str, list[dict[str, Any]]]:
        """``{'operation', 'subroutine', 'tool', 'axis': [{'name', 'energy_j',
        'duration_s'}]}``, each sorted by energy (largest first); ``energy_j`` is the
        summary's energy per axis. With declared drives every item also has
        ``motor_energy_j`` and ``supply_energy_j`` (the axes' from ``electrical``, the
        summary's electrical object; the supply side of operations, subroutines and tools
        includes the cabinet's standby for their time)."""
        table = self.context.table if self.context is not None else [('', '', 0)]
        elec = self.electrical
        groups: dict[str, dict[str, list[float]]] = {'operation': {}, 'subroutine': {},
                                                     'tool': {}}
        for index, (operation, subroutine, tool) in enumerate(table):
            if index >= self.energy.shape[0]:
                break
            e, d = float(self.energy[index]), float(self.duration[index])
            if e == 0.0 and d == 0.0:
                continue
            names = {'operation': operation or '(none)',
                     'subroutine': subroutine or '(main program)',
                     'tool': f'T{tool}' if tool else NO_TOOL}
            for group, name in names.items():
                item = groups[group].setdefault(name, [0.0, 0.0, 0.0, 0.0])
                item[0] += e
                item[1] += d
                if elec is not None:
                    item[2] += float(elec[index, 0])
                    item[3] += float(elec[index, 1])
        out: dict[str, list[dict[str, Any]]] = {}
        for group, items in groups.items():
            rows = []
            for n, v in items.items():
                row = {'name': n, 'energy_j': v[0], 'duration_s': v[1]}
                if elec is not None:
                    row['motor_energy_j'], row['supply_energy_j'] = v[2], v[3]
                rows.append(row)
            out[group] = sorted(rows, key=lambda r: -abs(r['energy_j']))
        axis_time = self.axis_time if self.axis_time is not None else np.zeros(0)
        axes = []
        for j, a in enumerate(self.axes):
            row = {'name': a, 'energy_j': float(energy_j.get(a, 0.0)),
                   'duration_s': float(axis_time[j])}
            if elec is not None and electrical:
                row['motor_energy_j'] = float(electrical['motor_energy_j'].get(a, 0.0))
                row['supply_energy_j'] = float(electrical['supply_energy_j'].get(a, 0.0))
            axes.append(row)
        out['axis'] = sorted(axes, key=lambda r: -abs(r['energy_j']))
        return out
