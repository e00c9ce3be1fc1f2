"""Sample chunks of the streaming planner: rows written in place, window by window.

:func:`.stream.iter_motion` evaluates the grid samples of each committed window
(:class:`WindowSampler`) straight into the rows of a preallocated chunk (:class:`Chunk`,
column-major per-axis arrays, no concatenation), in the order a :class:`GridCursor` walks
them; the cursor skips the interior of standstill phases, which become ``Motion.gaps``
(:mod:`.standstill`).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .motion import Motion
from .phases import BlockLocator, give_steps, PlannedWindow, sample_phases

__all__ = ['Chunk', 'GridCursor', 'PendingSteps', 'WindowSampler']


class PendingSteps(NamedTuple):
    """Corner velocity steps not yet (wholly) put into rows: the grid indices ``lo..hi`` of
    the samples that carry each (:func:`.phases.step_rows`), its junction time ``tc`` [s],
    per-axis step ``dv`` [m/s] and the first grid index ``next`` not yet given its share."""

    lo: np.ndarray
    hi: np.ndarray
    tc: np.ndarray
    dv: np.ndarray
    next: np.ndarray

    @classmethod
    def none(cls, k: int) -> 'PendingSteps':
        e = np.zeros(0, np.int64)
        return cls(e, e, np.zeros(0), np.zeros((0, k)), e)

    def join(self, lo: np.ndarray, hi: np.ndarray, tc: np.ndarray,
             dv: np.ndarray) -> 'PendingSteps':
        """These steps and new ones."""
        return PendingSteps(np.concatenate((self.lo, lo)), np.concatenate((self.hi, hi)),
                            np.concatenate((self.tc, tc)), np.concatenate((self.dv, dv)),
                            np.concatenate((self.next, lo)))

    def clip(self, top: int) -> 'PendingSteps':
        """Steps that reach beyond grid index ``top`` (the program's last sample) end
        there."""
        return PendingSteps(np.minimum(self.lo, top), np.minimum(self.hi, top), self.tc,
                            self.dv, np.minimum(self.next, top))

    def touch(self, a: int, b: int) -> bool:
        """True when a step still has a sample to give its share to in ``[a, b]``."""
        return bool(np.any((self.next <= b) & (self.hi >= a)))

    def select(self, keep: np.ndarray) -> 'PendingSteps':
        return PendingSteps(*(x[keep] for x in self))


class Chunk:
    """Rows being filled: ``t, pos, vel, acc, line`` and the grid index of each row.

    Rows are written in place by the sampler (no concatenation); ``gaps`` records the
    standstill samples left out between rows (``Motion.gaps``).
    """

    def __init__(self, k: int, capacity: int) -> None:
        self.k = k
        self.capacity = capacity
        self.fill = 0
        self.t = np.empty(capacity)
        # column-major: each axis is contiguous, so per-axis work runs along the rows
        self.pos = np.empty((capacity, k), order='F')
        self.vel = np.empty((capacity, k), order='F')
        self.acc = np.empty((capacity, k), order='F')
        self.line = np.empty(capacity, np.int32)
        self.gaps: list[tuple[int, int, int]] = []
        self.index = np.empty(capacity, np.int64)    # grid index of every row

    @property
    def space(self) -> int:
        return self.capacity - self.fill

    def rows_at(self, index: np.ndarray,
                gaps: list[tuple[int, int, int]]) -> tuple[slice, np.ndarray]:
        """Reserve rows for grid samples ``index``; ``gaps`` (offsets into ``index``) lists
        the samples left out before them."""
        r0 = self.fill
        r1 = r0 + index.size
        self.index[r0:r1] = index
        self.gaps += [(r0 + offset, first, count) for offset, first, count in gaps]
        self.fill = r1
        return slice(r0, r1), self.t[r0:r1]

    def apply(self, steps: PendingSteps, sample_s: float) -> PendingSteps:
        """Give the velocity steps their share in the rows held here; return what is left
        (the shares of samples not yet held)."""
        if steps.lo.size == 0 or self.fill == 0:
            return steps
        held = self.index[:self.fill]
        last = held[-1]
        ready = steps.next <= last
        if not np.any(ready):
            return steps
        sel = np.nonzero(ready)[0]
        upto = np.minimum(steps.hi[sel], last)
        fill = self.fill
        give_steps(self.t[:fill], held, steps.lo[sel], steps.hi[sel], steps.tc[sel],
                   steps.dv[sel], sample_s, vel=self.vel[:fill], acc=self.acc[:fill],
                   first=steps.next[sel], last=upto)
        moved = steps.next.copy()
        moved[sel] = upto + 1
        left = PendingSteps(steps.lo, steps.hi, steps.tc, steps.dv, moved)
        return left.select(moved <= steps.hi)

    def take(self, count: int, axes: tuple[str, ...], file: str) -> Motion:
        """The first ``count`` rows as a Motion; the rows after them start a new chunk."""
        n = self.fill
        gaps_here = tuple(g for g in self.gaps if g[0] < count)
        if count == n:
            arrays = (self.t[:n], self.pos[:n], self.vel[:n], self.acc[:n], self.line[:n])
            rest = None
        else:
            arrays = (self.t[:count], self.pos[:count], self.vel[:count], self.acc[:count],
                      self.line[:count])
            rest = (self.t[count:n].copy(), self.pos[count:n].copy(),
                    self.vel[count:n].copy(), self.acc[count:n].copy(),
                    self.line[count:n].copy(), self.index[count:n].copy())
        later = [(row - count, first, c) for row, first, c in self.gaps if row >= count]
        Chunk.__init__(self, self.k, self.capacity)
        if rest is not None and rest[0].size:
            m = rest[0].size
            self.t[:m], self.pos[:m], self.vel[:m], self.acc[:m], self.line[:m] = rest[:5]
            self.index[:m] = rest[5]
            self.fill = m
        self.gaps = later
        t, pos, vel, acc, line = arrays
        return Motion(t=t, axes=axes, pos=pos, vel=vel, acc=acc, line=line, source=file,
                      gaps=gaps_here)


class GridCursor:
    """Walks the grid samples ``[lo[i], hi[i])`` of a window in order (the rest are gaps)."""

    def __init__(self, lo: list[int], hi: list[int]) -> None:
        self.lo, self.hi = lo, hi
        self.i = 0
        self.at = lo[0] if lo else 0
        self.gap: tuple[int, int] | None = None       # left out before the next sample

    @property
    def done(self) -> bool:
        return self.i >= len(self.lo)

    def _advance(self) -> None:
        """Step past exhausted ranges; the samples between ranges become the next gap."""
        while self.i < len(self.lo) and self.at >= self.hi[self.i]:
            end = self.hi[self.i]
            self.i += 1
            if self.i < len(self.lo):
                if self.lo[self.i] > end:
                    self.gap = (end, self.lo[self.i] - end)
                self.at = self.lo[self.i]

    def take(self, count: int) -> tuple[np.ndarray, list[tuple[int, int, int]]]:
        """Up to ``count`` next grid indices and the gaps before them (offset, first, n)."""
        parts: list[np.ndarray] = []
        gaps: list[tuple[int, int, int]] = []
        got = 0
        self._advance()
        while got < count and self.i < len(self.lo):
            n = min(self.hi[self.i] - self.at, count - got)
            if self.gap is not None:
                gaps.append((got, self.gap[0], self.gap[1]))
                self.gap = None
            parts.append(np.arange(self.at, self.at + n, dtype=np.int64))
            got += n
            self.at += n
            self._advance()
        if not parts:
            return np.zeros(0, np.int64), gaps
        return (parts[0] if len(parts) == 1 else np.concatenate(parts)), gaps


class WindowSampler:
    """Evaluates grid samples of one planned window into a chunk's rows."""

    def __init__(self, win: PlannedWindow, cols: list[int]) -> None:
        seg, geo = win.seg, win.geo
        self.win = win
        self.cols = cols
        self.lines = np.array([x.line for x in seg.move], dtype=np.int32)
        self.locate = BlockLocator(win.groups, geo.length, path_start_m=win.path_start_m)
        self.p0c, self.uc = seg.p0[:, cols], geo.u[:, cols]
        self.t0 = win.phases[0]

    def fill(self, chunk: Chunk, index: np.ndarray, gaps: list[tuple[int, int, int]],
             rate: float, t_last: float | None) -> None:
        """Grid samples ``index`` into ``chunk``; ``t_last`` replaces the last one's time."""
        rows, t = chunk.rows_at(index, gaps)
        np.divide(index, rate, out=t)
        if t_last is not None:
            t[-1] = t_last
        n = t.size
        t0 = self.t0
        # each phase owns the samples from the first one at or after its start
        p_lo = max(int(np.searchsorted(t0, t[0], side='right')) - 1, 0)
        p_hi = max(int(np.searchsorted(t0, t[-1], side='right')), p_lo + 1)
        first = np.searchsorted(t, t0[p_lo:p_hi], side='left')
        owner = np.repeat(np.arange(p_lo, p_hi), np.diff(np.append(first, n)))
        win = self.win
        mi = sample_phases(t, owner, win.phases, self.locate, win.seg, win.geo, self.cols,
                           self.p0c,
                           self.uc, out=(chunk.pos[rows], chunk.vel[rows], chunk.acc[rows]))
        chunk.line[rows] = self.lines[mi]
