"""A simulation's time series reduced chunk by chunk to a fixed number of time columns.

A report plots a program of any length on a page about a thousand pixels wide, so it keeps per
column only what a plot of that column shows: the smallest and largest power of every axis and
of the total (peaks survive decimation), the cumulative energy at the column's last sample, the
axis positions and source line at the column's peak total power, the time span of its samples.
Memory is ``columns`` rows plus one float per source line (the time a line first runs), whatever
the program's length.

Columns have a fixed width in time. When the duration is not known beforehand the width starts
small and doubles (neighbouring columns merged) whenever a sample falls beyond the last column,
so the trace always spans the program with between ``columns / 2`` and ``columns`` columns.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

__all__ = ['PowerTrace', 'Trace']


@dataclass(frozen=True)
class Trace:
    """The decimated series (occupied columns only, in time order).

    Attributes
    ----------
    axes
        Axis names; power and energy columns are the axes then the total.
    t_lo, t_hi
        Time of the first and last sample in each column [s], shape ``(m,)``.
    count
        Samples per column (standstill samples left out of a chunk are not counted).
    p_min, p_max
        Smallest and largest drawn power [W], shape ``(m, k + 1)``.
    e_end
        Cumulative energy at the column's last sample [J], shape ``(m, k + 1)``.
    pos_at_peak
        Axis positions [m] at the column's largest total power, shape ``(m, k)``.
    line_at_peak
        Source line at the column's largest total power (0: none), shape ``(m,)``.
    pos_min, pos_max
        The bounding box of every sample's position [m], shape ``(k,)``.
    width_s
        Column width [s].
    """

    axes: tuple[str, ...]
    t_lo: np.ndarray
    t_hi: np.ndarray
    count: np.ndarray
    p_min: np.ndarray
    p_max: np.ndarray
    e_end: np.ndarray
    pos_at_peak: np.ndarray
    line_at_peak: np.ndarray
    pos_min: np.ndarray
    pos_max: np.ndarray
    width_s: float


def _groups(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start index and length of every run of equal values of the sorted ``keys``."""
    starts = np.concatenate(([0], np.flatnonzero(keys[1:] != keys[:-1]) + 1))
    lengths = np.diff(np.append(starts, keys.shape[0]))
    return starts, lengths


def _first_peak(peak: np.ndarray, starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Index of the first largest ``peak`` of every group."""
    gmax = np.maximum.reduceat(peak, starts)
    hit = np.flatnonzero(peak == np.repeat(gmax, lengths))
    # hits are in order and groups contiguous: the first hit of each group starts a new group
    group = np.searchsorted(starts, hit, side='right') - 1
    first = hit[np.concatenate(([True], group[1:] != group[:-1]))] if hit.size else hit
    if first.shape[0] != starts.shape[0]:       # a group of NaN only: take its first row
        return starts.copy()
    return first


class PowerTrace:
    """Min/max per time column of a simulation's power, fed chunk by chunk.

    Parameters
    ----------
    columns
        Number of time columns (about the pixel width of a plot).
    duration_s
        Expected duration [s] if known (then the width is fixed from the start).
    start_width_s
        First column width [s] when the duration is not known.
    """

    def __init__(self, *, columns: int = 1200, duration_s: float | None = None,
                 start_width_s: float = 1e-3) -> None:
        if columns < 2:
            msg = f'PowerTrace needs at least 2 columns, got {columns}'
            raise ValueError(msg)
        self.columns = int(columns)
        if duration_s is not None and math.isfinite(duration_s) and duration_s > 0:
            self.width = duration_s / (self.columns - 1)
        else:
            self.width = float(start_width_s)
        self.axes: tuple[str, ...] = ()
        self.t0: float | None = None
        self._k = 0
        self._line_t = np.full(0, np.nan)

    def _allocate(self, k: int) -> None:
        n = self.columns
        self._k = k
        self.count = np.zeros(n, np.int64)
        self.t_lo = np.full(n, np.inf)
        self.t_hi = np.full(n, -np.inf)
        self.p_min = np.full((n, k + 1), np.inf)
        self.p_max = np.full((n, k + 1), -np.inf)
        self.e_end = np.zeros((n, k + 1))
        self.pos = np.zeros((n, k))
        self.line = np.zeros(n, np.int64)
        self.pos_min = np.full(k, np.inf)
        self.pos_max = np.full(k, -np.inf)

    def add(self, chunk) -> None:
        """Take one chunk of :func:`feed_axis_energy.sim.stream.iter_simulation` (or a
        whole :class:`~feed_axis_energy.sim.simulate.SimulationResult`), in time order."""
        p = chunk.power
        t = np.asarray(p.t, dtype=float)
        if t.shape[0] == 0:
            return
        k = len(p.axes)
        if self.t0 is None:
            self.t0 = float(t[0])
            self.axes = tuple(p.axes)
            self._allocate(k)
        # column by column: the chunks' arrays are column-major, a stacked copy costs more
        # than the reductions
        columns = [p.power_w[:, j] for j in range(k)] + [p.total_w]
        pos = chunk.motion.pos
        self.pos_min = np.minimum(self.pos_min, [pos[:, j].min() for j in range(k)])
        self.pos_max = np.maximum(self.pos_max, [pos[:, j].max() for j in range(k)])
        line = np.asarray(p.line)
        self._first_times(t, line)
        keys = np.floor((t - self.t0) / self.width).astype(np.int64)
        np.maximum(keys, 0, out=keys)
        top = int(keys[-1])
        if top >= self.columns:
            factor = 1
            while top // factor >= self.columns:
                factor *= 2
            self._coarsen(factor)
            keys //= factor
        starts, lengths = _groups(keys)
        peak = _first_peak(p.total_w, starts, lengths)
        ends = starts + lengths - 1
        e_end = np.empty((starts.shape[0], k + 1))
        e_end[:, :k] = p.energy_j[ends]
        e_end[:, k] = p.total_energy_j[ends]
        self._combine(keys[starts], lengths, t[starts], t[ends],
                      np.column_stack([np.minimum.reduceat(c, starts) for c in columns]),
                      np.column_stack([np.maximum.reduceat(c, starts) for c in columns]),
                      e_end, pos[peak], line[peak].astype(np.int64))

    def _combine(self, keys, count, t_lo, t_hi, p_min, p_max, e_end, pos, line) -> None:
        """Add per-column records (unique sorted ``keys``, later in time than or in the same
        column as what is held) into the columns."""
        k = self._k
        old_peak = self.p_max[keys, k]
        better = p_max[:, k] > old_peak
        self.count[keys] += count
        self.t_lo[keys] = np.minimum(self.t_lo[keys], t_lo)
        self.t_hi[keys] = np.maximum(self.t_hi[keys], t_hi)
        self.p_min[keys] = np.minimum(self.p_min[keys], p_min)
        self.p_max[keys] = np.maximum(self.p_max[keys], p_max)
        self.e_end[keys] = e_end
        self.pos[keys[better]] = pos[better]
        self.line[keys[better]] = line[better]

    def _coarsen(self, factor: int) -> None:
        """Merge every ``factor`` neighbouring columns into one (width times ``factor``)."""
        held = np.flatnonzero(self.count)
        rec = (self.count[held], self.t_lo[held], self.t_hi[held], self.p_min[held],
               self.p_max[held], self.e_end[held], self.pos[held], self.line[held])
        self._allocate_keep_box()
        self.width *= factor
        if held.shape[0] == 0:
            return
        keys = held // factor
        starts, lengths = _groups(keys)
        ends = starts + lengths - 1
        count, t_lo, t_hi, p_min, p_max, e_end, pos, line = rec
        peak = _first_peak(p_max[:, self._k], starts, lengths)
        self._combine(keys[starts], np.add.reduceat(count, starts), t_lo[starts], t_hi[ends],
                      np.minimum.reduceat(p_min, starts, axis=0),
                      np.maximum.reduceat(p_max, starts, axis=0), e_end[ends], pos[peak],
                      line[peak])

    def _allocate_keep_box(self) -> None:
        lo, hi = self.pos_min, self.pos_max
        self._allocate(self._k)
        self.pos_min, self.pos_max = lo, hi

    def _first_times(self, t: np.ndarray, lines: np.ndarray) -> None:
        """Remember the time each source line first runs."""
        starts, _ = _groups(lines)
        keys = lines[starts]
        top = int(keys.max())
        if top >= self._line_t.shape[0]:
            grown = np.full(max(top + 1, 2 * self._line_t.shape[0], 1024), np.nan)
            grown[:self._line_t.shape[0]] = self._line_t
            self._line_t = grown
        keys, first = np.unique(keys, return_index=True)    # a line may run several times
        fresh = np.isnan(self._line_t[keys])
        self._line_t[keys[fresh]] = t[starts][first][fresh]

    def first_time(self, line: int) -> float:
        """Time [s] at which source line ``line`` first runs (NaN if it never does)."""
        if 0 <= line < self._line_t.shape[0]:
            return float(self._line_t[line])
        return math.nan

    def trace(self) -> Trace:
        """The occupied columns in time order."""
        if self.t0 is None:
            k = 0
            empty = np.zeros(0)
            return Trace((), empty, empty, np.zeros(0, np.int64), np.zeros((0, 1)),
                         np.zeros((0, 1)), np.zeros((0, 1)), np.zeros((0, 0)),
                         np.zeros(0, np.int64), np.zeros(k), np.zeros(k), self.width)
        held = np.flatnonzero(self.count)
        return Trace(self.axes, self.t_lo[held], self.t_hi[held], self.count[held],
                     self.p_min[held], self.p_max[held], self.e_end[held], self.pos[held],
                     self.line[held], self.pos_min.copy(), self.pos_max.copy(), self.width)
