"""Which samples a recording keeps during a standstill: the first, one per second, the last.

A *standstill run* is a stretch of consecutive samples whose recorded values all equal the
previous sample's except time and cumulative energy (positions, speeds, accelerations,
forces, torques and power: a dwell, or the machine at rest between moves). Of a run the
recording keeps

* its first sample (the one that first has the run's values),
* the first sample in every further period of :data:`STANDSTILL_PERIOD_S` (1 s) counted from
  the first sample,
* its last sample;

every other sample is left out. Nothing is approximated: the values are constant and the
energy grows linearly (constant power), so linear interpolation between the kept samples
gives every left-out sample to rounding. Motion is recorded at the full rate. The rule is
idempotent (thinning a thinned run keeps it) and does not depend on how the samples are
chunked.

Samples that the simulation itself left out of a chunk (``Motion.gaps``, branch simspeed's
compact dwells: ``(row, first_index, count)``, ``count`` grid samples ``i / rate_hz`` between
row ``row - 1`` and row ``row``, equal to row ``row`` but for time and energy) are part of
the run; the ones the rule keeps are put back with their exact time and energy.
"""
from __future__ import annotations

from dataclasses import dataclass
import numpy as np

__all__ = ['STANDSTILL_PERIOD_S', 'Selection', 'StandstillThinner']

STANDSTILL_PERIOD_S = 1.0
_EPS = 1e-9                     # relative slack of a period boundary (grid times are rounded)


@dataclass(frozen=True)
class Selection:
    """The rows a chunk contributes to the recording.

    Attributes
    ----------
    src
        Row of the chunk each recorded sample takes its values from; ``-1``: the row held
        back from the previous chunk.
    t
        Time of each recorded sample [s].
    filled
        True where the sample was left out of the chunk (a gap): its values are those of row
        ``src``, its energy ``E_src - P_src (t_src - t)``.
    hold_last
        The chunk's last row is held back: whether it is recorded is known with the next
        chunk (it is when its run ends there).
    """

    src: np.ndarray
    t: np.ndarray
    filled: np.ndarray
    hold_last: bool


class StandstillThinner:
    """Apply the rule of the module docstring chunk by chunk.

    Parameters
    ----------
    period_s
        Spacing of the samples kept inside a run [s].
    rate_hz
        Sample rate of the grid (needed only for chunks with gaps).
    """

    def __init__(self, *, period_s: float = STANDSTILL_PERIOD_S,
                 rate_hz: float | None = None) -> None:
        self.period_s = float(period_s)
        self.rate_hz = rate_hz
        self._anchor = 0.0        # time of the current run's first sample
        self._t_prev = 0.0        # time of the previous sample (kept or not)
        self.held = False         # the previous chunk's last row waits: recorded if its run ends
        self.held_t = 0.0

    def _period(self, t, anchor):
        return np.floor((t - anchor) / self.period_s + _EPS)

    def select(self, t: np.ndarray, still: np.ndarray,
               gaps: tuple[tuple[int, int, int], ...] = ()) -> Selection | None:
        """The recorded samples of a chunk, or ``None`` when they are exactly its rows.

        Parameters
        ----------
        t
            Row times [s], ``(n,)``.
        still
            Per row: equal to the previous row but for time and energy (row 0: to the
            previous chunk's last row; ``False`` for the program's first sample).
        gaps
            ``Motion.gaps`` of the chunk.
        """
        n = int(t.shape[0])
        if n == 0:
            return None
        if not gaps and not self.held and not still.any():
            self._anchor = self._t_prev = float(t[-1])
            return None
        # the run's first sample for every row: the last row that is not still, or the anchor
        last_moving = np.maximum.accumulate(np.where(still, -1, np.arange(n)))
        gaps = sorted((int(r), int(f), int(c)) for r, f, c in gaps)
        for row, first, count in gaps:
            if not still[row]:
                msg = f'gap before row {row}, but row {row} differs from the row before'
                raise ValueError(msg)
            if self.rate_hz is None:
                msg = 'a chunk with gaps needs the grid rate (rate_hz)'
                raise ValueError(msg)
        ends_run = np.zeros(n, bool)
        ends_run[:-1] = still[:-1] & ~still[1:]
        keep = ~still | ends_run
        # the period test only where it can matter: the still rows (the others are kept)
        rows = np.flatnonzero(still)
        if rows.shape[0]:
            lm = last_moving[rows]
            anchor_s = np.where(lm >= 0, t[np.maximum(lm, 0)], self._anchor)
            prev_s = np.where(rows > 0, t[rows - 1], self._t_prev)
            for row, first, count in gaps:
                prev_s[np.searchsorted(rows, row)] = (first + count - 1) / self.rate_hz
            keep[rows] |= self._period(t[rows], anchor_s) > self._period(prev_s, anchor_s)
        last_anchor = (float(t[last_moving[-1]]) if last_moving[-1] >= 0 else self._anchor)
        src = [np.flatnonzero(keep)]
        times = [t[src[0]]]
        filled = [np.zeros(src[0].shape[0], bool)]
        for row, first, count in gaps:
            before = float(t[row - 1]) if row > 0 else self._t_prev
            lm = int(last_moving[row])
            idx = self._gap_keep(first, count, float(t[lm]) if lm >= 0 else self._anchor,
                                 before)
            src.append(np.full(idx.shape[0], row))
            times.append(idx / self.rate_hz)
            filled.append(np.ones(idx.shape[0], bool))
        if self.held and not still[0]:
            src.append(np.array([-1]))
            times.append(np.array([self.held_t]))
            filled.append(np.zeros(1, bool))
        hold_last = bool(still[-1] and not keep[-1])
        self.held, self.held_t = hold_last, float(t[-1])
        self._anchor, self._t_prev = last_anchor, float(t[-1])
        src_a = np.concatenate(src) if len(src) > 1 else src[0]
        t_a = np.concatenate(times) if len(times) > 1 else times[0]
        f_a = np.concatenate(filled) if len(filled) > 1 else filled[0]
        if hold_last:
            mask = ~((src_a == n - 1) & ~f_a)
            src_a, t_a, f_a = src_a[mask], t_a[mask], f_a[mask]
        if len(src) == 1:                        # the chunk's own rows: in time order already
            return Selection(src=src_a, t=t_a, filled=f_a, hold_last=hold_last)
        order = np.argsort(t_a, kind='stable')   # the gaps' samples lie between rows
        return Selection(src=src_a[order], t=t_a[order], filled=f_a[order],
                         hold_last=hold_last)

    def _gap_keep(self, first: int, count: int, anchor: float, before: float) -> np.ndarray:
        """Grid indices of the left-out samples ``first..first+count-1`` that start a period.

        ``before`` is the time of the sample before the gap.
        """
        rate = self.rate_hz
        p0 = int(self._period(before, anchor))
        p1 = int(self._period((first + count - 1) / rate, anchor))
        if p1 <= p0:
            return np.zeros(0, np.int64)
        bounds = anchor + np.arange(p0 + 1, p1 + 1) * self.period_s
        idx = np.ceil(bounds * rate - _EPS * np.maximum(1.0, bounds * rate)).astype(np.int64)
        # the first grid sample in each new period (rounding of i / rate checked directly)
        idx = np.where(self._period(idx / rate, anchor) < np.arange(p0 + 1, p1 + 1), idx + 1,
                       idx)
        return np.unique(np.clip(idx, first, first + count - 1))
