"""The summary of a streamed simulation (:func:`.simulate.summarize`'s values), chunk by chunk.

Split from :mod:`.stream`, which feeds it: energy per axis and source line, peaks, the
median sample interval, the breakdown by cause, the electrical side and the energy's
uncertainty, each accumulated per chunk so memory does not grow with the program.
"""
from __future__ import annotations

import math
from typing import Any, cast

import numpy as np

from ..physics import (add_block_electrical, add_breakdown, add_uncertainty, BreakdownAccumulator,
                       ElectricalAccumulator, LineEnergy, UncertaintyAccumulator)
from ..machine import Machine
from .simulate import SimulationResult
from ..plan import grid_interval_counts
from ..units import rate_from_interval

__all__ = ['SummaryAccumulator', 'row_sum', 'line_runs']


def row_sum(a: np.ndarray) -> np.ndarray:
    """Sum over the (few) columns, added in column order as ``a.sum(axis=1)`` adds them."""
    out = a[:, 0].copy()
    for j in range(1, a.shape[1]):
        out += a[:, j]
    return out


def line_runs(lines: np.ndarray, *values: np.ndarray) -> tuple[np.ndarray, ...]:
    """Sums of ``values`` over the runs of equal consecutive ``lines``: ``(the run's line,
    sum of each value...)``; rows come in runs of one line, so no sort is needed. ``lines``
    must not be empty."""
    starts = np.concatenate(([0], np.nonzero(lines[1:] != lines[:-1])[0] + 1))
    return (lines[starts],) + tuple(np.add.reduceat(v, starts) for v in values)


class SummaryAccumulator:
    """The values of :func:`.simulate.summarize`, accumulated chunk by chunk.

    Sums are taken per chunk and added, so they agree with the whole-record sums to rounding
    (``1e-12`` relative); the median sample interval is exact (intervals are counted by value).
    Standstill samples left out of a chunk (``Motion.gaps``) count as samples; the trapezoid
    across a gap is the sum over its intervals (same power at both ends), and its intervals
    are counted on the grid of ``rate_hz``.

    Parameters
    ----------
    rate_hz
        Sample rate of the grid [Hz]; needed only for chunks with ``gaps``.
    block_breakdown
        Also keep the energy of every source line per axis and per cause
        (:class:`.breakdown.BreakdownAccumulator`; ``k + c`` numbers per line).
    """

    def __init__(self, *, rate_hz: float | None = None, block_breakdown: bool = False) -> None:
        self.rate_hz = rate_hz
        self.causes = BreakdownAccumulator(per_line=block_breakdown)
        self.electrical = ElectricalAccumulator(per_line=block_breakdown)
        self.n = 0
        self.t_first = 0.0
        self.t_last = 0.0
        self.total_last = 0.0
        self.loss_last: float = 0.0
        self.neg_last = 0.0
        self.line_last = 0
        self.axes: tuple[str, ...] = ()
        self.peak: np.ndarray | None = None
        self.loss_energy = 0.0
        self.regenerated = 0.0
        self.energy: np.ndarray | None = None
        self.braking = 'regenerative'
        self.dt_counts: dict[float, int] = {}
        self._recent: list[float] = []
        # energy, time and presence per source line, indexed by line number
        self._line_e = np.zeros(1024)
        self._line_d = np.zeros(1024)
        self._line_seen = np.zeros(1024, dtype=bool)
        self.first: SimulationResult | None = None
        self.spread: UncertaintyAccumulator | None = None

    def add(self, chunk: SimulationResult) -> None:
        """Take one chunk (in time order)."""
        p = chunk.power
        m = int(p.t.shape[0])
        if m == 0:
            return
        self.causes.add(chunk.dynamics, p.mechanical_w, braking=p.braking,
                        effects=p.effect_power_w)
        if p.electrical is not None:
            self.electrical.add(chunk.dynamics, p.mechanical_w, p.electrical,
                                braking=p.braking, effects=p.effect_power_w)
        if self.first is None:
            self.first = chunk
            self.spread = UncertaintyAccumulator.of(chunk.machine)
            self.axes = tuple(p.axes)
            self.braking = p.braking
            self.t_first = float(p.t[0])
        # column by column: a reduction along axis 0 of a narrow array is slow in numpy
        if self.spread is not None:
            self.spread.add(chunk.dynamics, p.mechanical_w, braking=p.braking)
        peak = np.array([p.power_w[:, j].max() for j in range(p.power_w.shape[1])]
                        + [p.total_w.max()])
        self.peak = peak if self.peak is None else np.maximum(self.peak, peak)
        loss = row_sum(p.loss_power_w)
        # braking power summed over the axes first: one trapezoid instead of one per axis
        neg = row_sum(np.minimum(p.mechanical_w, 0.0))
        t, total, lines = p.t, p.total_w, p.line[1:]
        dt = np.diff(t)
        gaps = chunk.motion.gaps
        if self.n:
            # the interval from the previous chunk's last sample to this chunk's first
            d0 = float(t[0] - self.t_last)
            self.loss_energy += 0.5 * (loss[0] + self.loss_last) * d0
            self.regenerated += 0.5 * (float(neg[0]) + self.neg_last) * d0
            if not (gaps and gaps[0][0] == 0):
                self._count_dt(np.array([d0]))
            self._add_lines(np.array([p.line[0]]),
                            np.array([0.5 * (total[0] + self.total_last) * d0]),
                            np.array([d0]))
        if dt.size:
            self.loss_energy += float(np.sum(0.5 * (loss[1:] + loss[:-1]) * dt))
            self.regenerated += float(np.sum(0.5 * (neg[1:] + neg[:-1]) * dt))
            inner = [row - 1 for row, _, _ in gaps if row > 0]
            self._count_dt(np.delete(dt, inner) if inner else dt)
            self._add_lines(lines, 0.5 * (total[1:] + total[:-1]) * dt, dt)
        if gaps:
            self._count_gaps(gaps)
        self.n += m + chunk.motion.omitted_samples
        self.t_last = float(p.t[-1])
        self.total_last = float(total[-1])
        self.loss_last = float(loss[-1])
        self.neg_last = float(neg[-1])
        self.energy = np.append(p.energy_j[-1], p.total_energy_j[-1])

    def _count_gaps(self, gaps) -> None:
        """Count the grid intervals spanned by every gap (from the row before to the row after)."""
        if self.rate_hz is None:
            msg = 'SummaryAccumulator needs rate_hz for chunks with standstill gaps'
            raise ValueError(msg)
        for _row, first, count in gaps:
            for value, c in grid_interval_counts(first - 1, first + count, self.rate_hz).items():
                self.dt_counts[value] = self.dt_counts.get(value, 0) + c

    def _count_dt(self, dt: np.ndarray) -> None:
        """Count the sample intervals by value (few distinct values on a uniform grid)."""
        rest = dt
        # values seen in the previous chunk first: a comparison is far cheaper than a sort
        for value in self._recent:
            hit = rest == value
            c = int(np.count_nonzero(hit))
            if c:
                self.dt_counts[value] += c
                rest = rest[~hit] if c < rest.size else rest[:0]
            if rest.size == 0:
                return
        values, counts = np.unique(rest, return_counts=True)
        for v, c in zip(values.tolist(), counts.tolist()):
            self.dt_counts[v] = self.dt_counts.get(v, 0) + c
        self._recent = values.tolist()

    def _add_lines(self, lines: np.ndarray, de: np.ndarray, dt: np.ndarray) -> None:
        """Add energy and time per source line (interval -> line of its end sample)."""
        lines = np.asarray(lines, dtype=np.int64)
        if lines.size == 0:
            return
        # samples come in runs of one line: sum per run (no sort), then add per line
        keys, e, d = line_runs(lines, de, dt)
        top = int(keys.max())
        if top >= self._line_e.shape[0]:
            size = max(2 * self._line_e.shape[0], top + 1)
            for name in ('_line_e', '_line_d', '_line_seen'):
                old = getattr(self, name)
                new = np.zeros(size, dtype=old.dtype)
                new[:old.shape[0]] = old
                setattr(self, name, new)
        if keys.shape[0] == 1:
            self._line_e[keys[0]] += e[0]
            self._line_d[keys[0]] += d[0]
        else:
            np.add.at(self._line_e, keys, e)      # a line may have several runs
            np.add.at(self._line_d, keys, d)
        self._line_seen[keys] = True

    def block_energy(self) -> 'LineEnergy':
        """``(line, energy [J], duration [s])`` by line, as :func:`.energy.energy_by_line`."""
        idx = np.nonzero(self._line_seen)[0]
        table = self.causes.lines_table(idx)
        by_axis, by_cause = (None, None) if table is None else table
        electrical = self.electrical.lines_energy(idx, self._line_d[idx])
        motor, supply = (None, None) if electrical is None else electrical
        return LineEnergy(idx, self._line_e[idx], self._line_d[idx], axes=self.causes.axes,
                          causes=self.causes.causes, by_axis_j=by_axis, by_cause_j=by_cause,
                          motor_j=motor, supply_j=supply)

    def top_blocks(self, count: int) -> list[tuple[int, float, float]]:
        """The ``count`` lines with the largest ``|energy|`` (ties: lower line first)."""
        idx = np.nonzero(self._line_seen)[0]
        order = np.argsort(-np.abs(self._line_e[idx]), kind='stable')[:max(0, int(count))]
        pick = idx[order]
        return list(zip(pick.tolist(), self._line_e[pick].tolist(), self._line_d[pick].tolist()))

    def _median_dt(self) -> float:
        total = sum(self.dt_counts.values())
        if total == 0:
            return math.nan
        wanted = sorted({(total - 1) // 2, total // 2})
        found: list[float] = []
        seen = 0
        for value in sorted(self.dt_counts):
            seen += self.dt_counts[value]
            while wanted and wanted[0] < seen:
                found.append(value)
                wanted.pop(0)
        if len(found) == 1:
            return found[0]
        return float(np.mean(found))

    def summary(self, *, program: str, machine: Machine, load_kg: float,
                top_blocks: int = 5) -> dict[str, Any]:
        """The summary dict of :func:`.simulate.summarize` (same keys and meanings)."""
        n = self.n
        rate = rate_from_interval(self._median_dt()) if n >= 2 else 0.0
        axes = self.axes
        # the casts: both are set once a sample is taken (n > 0)
        energy_a, peak_a = cast(np.ndarray, self.energy), cast(np.ndarray, self.peak)
        energy = {a: float(energy_a[j]) if n else 0.0 for j, a in enumerate(axes)}
        energy['total'] = float(energy_a[-1]) if n else 0.0
        peak = {a: float(peak_a[j]) if n else 0.0 for j, a in enumerate(axes)}
        peak['total'] = float(peak_a[-1]) if n else 0.0
        blocks = self.top_blocks(top_blocks)
        summary = add_breakdown({
            'program': program,
            'machine': machine.name,
            'load_kg': float(load_kg),
            'duration_s': float(self.t_last - self.t_first) if n else 0.0,
            'samples': n,
            'rate_hz': rate,
            'braking': self.braking,
            'energy_j': energy,
            'peak_power_w': peak,
            'regenerated_energy_j': max(0.0, -self.regenerated) if n >= 2 else 0.0,
            'loss_energy_j': self.loss_energy,
            'top_blocks': [{'line': ln, 'energy_j': e, 'duration_s': d} for ln, e, d in blocks],
        }, self.causes)
        electrical = self.electrical.summary()
        if electrical:
            summary['electrical'] = electrical
            add_block_electrical(summary['top_blocks'], self.electrical)
        return add_uncertainty(summary, self.spread)
