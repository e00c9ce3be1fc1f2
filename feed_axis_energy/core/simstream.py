"""Streaming simulation: motion chunks -> dynamics, power, energy and the summary, chunk by chunk.

Every stage of :func:`.simulate.simulate_program` is per sample except the energy integral,
which :class:`.energy.EnergyIntegrator` continues across chunks with the same bits; the
summary (:func:`.simulate.summarize`) is accumulated by :class:`SummaryAccumulator`. Memory is
one chunk of samples (:data:`.planstream.DEFAULT_CHUNK_SAMPLES`) plus one entry per source
line, whatever the program's length.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
import math
from typing import Any

import numpy as np

from .dynamics import compute_dynamics
from .energy import apply_braking, EnergyIntegrator, PowerResult
from .errors import ConfigError
from .machine import Machine
from .motion import Motion
from .planstream import DEFAULT_CHUNK_SAMPLES, iter_motion
from .program import Move
from .simulate import declared_effects_power_w, SimulationResult
from .trajectory import PlannerOptions

__all__ = ['streamable', 'iter_simulation', 'LineEnergy', 'SummaryAccumulator',
           'simulate_stream']


def _row_sum(a: np.ndarray) -> np.ndarray:
    """Sum over the (few) columns, added in column order as ``a.sum(axis=1)`` adds them."""
    out = a[:, 0].copy()
    for j in range(1, a.shape[1]):
        out += a[:, j]
    return out


def streamable(machine: Machine) -> bool:
    """True when every declared effect of ``machine`` is sample-local (can run per chunk)."""
    if not machine.effects:
        return True
    from .effects import get_effect
    return all(get_effect(e.id).sample_local for e in machine.effects)


def iter_simulation(motions: Iterable[Motion], machine: Machine, *, load_kg: float = 0.0,
                    program: str = '') -> Iterator[SimulationResult]:
    """Dynamics and power of each motion chunk; energies continue from chunk to chunk.

    Parameters
    ----------
    motions
        Consecutive motion chunks (:func:`.planstream.iter_motion`).
    machine
        The machine model (braking rule, declared sample-local effects).
    load_kg
        Workpiece mass [kg].
    program
        Program file, stored in every result.

    Yields
    ------
    SimulationResult
        One per chunk; ``power.energy_j`` and ``total_energy_j`` are cumulative from the
        program start, as in the whole-program result.

    Raises
    ------
    ConfigError
        A declared effect that needs the whole record (see :func:`streamable`).
    """
    if not streamable(machine):
        msg = 'a declared effect needs the whole record; it cannot be simulated chunk by chunk'
        raise ConfigError(msg, key='effects')
    integrator: EnergyIntegrator | None = None
    for motion in motions:
        dyn = compute_dynamics(motion, machine, load_kg=load_kg)
        mechanical = dyn.torque_nm * dyn.omega_rad_s
        drawn = apply_braking(mechanical, braking=machine.braking)
        k = drawn.shape[1]
        if integrator is None:
            integrator = EnergyIntegrator(k + 1)
        base = PowerResult(t=dyn.t, axes=dyn.axes, power_w=drawn, total_w=drawn[:, 0],
                           energy_j=drawn, total_energy_j=drawn[:, 0],
                           mechanical_w=mechanical, loss_power_w=dyn.loss_power_w,
                           line=dyn.line, braking=machine.braking)
        extra = declared_effects_power_w(dyn, base, machine)
        if extra is not None:
            drawn = drawn + extra
        total = _row_sum(drawn)
        energy = integrator.update(dyn.t, np.column_stack((drawn, total)))
        power = PowerResult(t=dyn.t, axes=dyn.axes, power_w=drawn, total_w=total,
                            energy_j=energy[:, :k], total_energy_j=energy[:, k],
                            mechanical_w=mechanical, loss_power_w=dyn.loss_power_w,
                            line=dyn.line, braking=machine.braking)
        yield SimulationResult(program=program or motion.source, machine=machine,
                               load_kg=float(load_kg), motion=motion, dynamics=dyn,
                               power=power)


class LineEnergy(Sequence):
    """Energy and time per source line as arrays, read as ``(line, energy_j, duration_s)``.

    A sequence of tuples like :func:`.energy.energy_by_line` returns, without a Python
    tuple per line (a 24-hour contour has millions of lines).
    """

    def __init__(self, lines: np.ndarray, energy_j: np.ndarray, duration_s: np.ndarray) -> None:
        self.lines = lines
        self.energy_j = energy_j
        self.duration_s = duration_s

    def __len__(self) -> int:
        return int(self.lines.shape[0])

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        return (int(self.lines[i]), float(self.energy_j[i]), float(self.duration_s[i]))

    def __iter__(self) -> Iterator[tuple[int, float, float]]:
        step = 65536
        for lo in range(0, len(self), step):
            yield from zip(self.lines[lo:lo + step].tolist(),
                           self.energy_j[lo:lo + step].tolist(),
                           self.duration_s[lo:lo + step].tolist())


class SummaryAccumulator:
    """The values of :func:`.simulate.summarize`, accumulated chunk by chunk.

    Sums are taken per chunk and added, so they agree with the whole-record sums to rounding
    (``1e-12`` relative); the median sample interval is exact (intervals are counted by value).
    """

    def __init__(self) -> None:
        self.n = 0
        self.t_first = 0.0
        self.t_last = 0.0
        self.total_last = 0.0
        self.loss_last: float = 0.0
        self.neg_last: np.ndarray | None = None
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

    def add(self, chunk: SimulationResult) -> None:
        """Take one chunk (in time order)."""
        p = chunk.power
        m = int(p.t.shape[0])
        if m == 0:
            return
        if self.first is None:
            self.first = chunk
            self.axes = tuple(p.axes)
            self.braking = p.braking
            self.t_first = float(p.t[0])
        # column by column: a reduction along axis 0 of a narrow array is slow in numpy
        peak = np.array([p.power_w[:, j].max() for j in range(p.power_w.shape[1])]
                        + [p.total_w.max()])
        self.peak = peak if self.peak is None else np.maximum(self.peak, peak)
        loss = _row_sum(p.loss_power_w)
        neg = np.minimum(p.mechanical_w, 0.0)
        t, total, lines = p.t, p.total_w, p.line[1:]
        dt = np.diff(t)
        if self.n:
            # the interval from the previous chunk's last sample to this chunk's first
            d0 = float(t[0] - self.t_last)
            self.loss_energy += 0.5 * (loss[0] + self.loss_last) * d0
            self.regenerated += float(np.sum(0.5 * (neg[0] + self.neg_last) * d0))
            self._count_dt(np.array([d0]))
            self._add_lines(np.array([p.line[0]]),
                            np.array([0.5 * (total[0] + self.total_last) * d0]),
                            np.array([d0]))
        if dt.size:
            self.loss_energy += float(np.sum(0.5 * (loss[1:] + loss[:-1]) * dt))
            self.regenerated += float(np.sum(0.5 * (neg[1:] + neg[:-1]) * dt[:, None]))
            self._count_dt(dt)
            self._add_lines(lines, 0.5 * (total[1:] + total[:-1]) * dt, dt)
        self.n += m
        self.t_last = float(p.t[-1])
        self.total_last = float(total[-1])
        self.loss_last = float(loss[-1])
        self.neg_last = neg[-1].copy()
        self.energy = np.append(p.energy_j[-1], p.total_energy_j[-1])

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
        starts = np.concatenate(([0], np.nonzero(lines[1:] != lines[:-1])[0] + 1))
        keys = lines[starts]
        e = np.add.reduceat(de, starts)
        d = np.add.reduceat(dt, starts)
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
        return LineEnergy(idx, self._line_e[idx], self._line_d[idx])

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
        rate = float(1.0 / self._median_dt()) if n >= 2 else 0.0
        axes = self.axes
        energy = {a: float(self.energy[j]) if n else 0.0 for j, a in enumerate(axes)}
        energy['total'] = float(self.energy[-1]) if n else 0.0
        peak = {a: float(self.peak[j]) if n else 0.0 for j, a in enumerate(axes)}
        peak['total'] = float(self.peak[-1]) if n else 0.0
        blocks = self.top_blocks(top_blocks)
        return {
            'program': program,
            'machine': machine.name,
            'load_kg': float(load_kg),
            'duration_s': float(self.t_last - self.t_first) if n else 0.0,
            'samples': n,
            'rate_hz': rate if math.isfinite(rate) else 0.0,
            'braking': self.braking,
            'energy_j': energy,
            'peak_power_w': peak,
            'regenerated_energy_j': max(0.0, -self.regenerated) if n >= 2 else 0.0,
            'loss_energy_j': self.loss_energy,
            'top_blocks': [{'line': ln, 'energy_j': e, 'duration_s': d} for ln, e, d in blocks],
        }


def simulate_stream(moves: Iterable[Move], machine: Machine, *, file: str = '',
                    load_kg: float = 0.0, options: PlannerOptions | None = None,
                    top_blocks: int = 5, chunk_samples: int = DEFAULT_CHUNK_SAMPLES,
                    total_moves: int | None = None, duration_s: float | None = None,
                    on_chunk: Callable[[SimulationResult], None] | None = None,
                    progress: Callable[[float], None] | None = None,
                    limits: Mapping | None = None) -> tuple[dict[str, Any], LineEnergy]:
    """Simulate a program chunk by chunk; return its summary and energy per block.

    Equal (``1e-12`` relative) to ``summarize(simulate_program(...))`` and
    ``energy_by_line(...)`` of the whole-program result, in memory bounded by
    ``chunk_samples``.

    Parameters
    ----------
    moves
        Canonical moves: ``Program.moves`` or a generator.
    machine
        The machine model (limits, planner settings, braking, declared effects).
    file
        Program file (messages, summary ``program``).
    load_kg
        Workpiece mass [kg].
    options
        Planner options; ``None`` uses ``machine.planner``.
    top_blocks
        How many source lines to list, by energy.
    chunk_samples
        Samples per chunk.
    total_moves
        Number of moves if known (progress).
    duration_s
        Program duration if known (progress by time, see :func:`.planstream.iter_motion`).
    on_chunk
        Called with every chunk's :class:`.simulate.SimulationResult` (e.g. a bag writer).
    progress
        Called with the fraction of moves planned.
    limits
        Axis limits; ``None`` uses ``machine.limits()``.

    Returns
    -------
    (dict, LineEnergy)
        The summary (keys of :func:`.simulate.summarize`) and ``(line, energy_j,
        duration_s)`` by line.
    """
    if options is None:
        options = machine.planner.options()
    motions = iter_motion(moves, machine.limits() if limits is None else limits,
                          options=options, file=file, chunk_samples=chunk_samples,
                          total_moves=total_moves, duration_s=duration_s,
                          progress=progress)
    acc = SummaryAccumulator()
    for chunk in iter_simulation(motions, machine, load_kg=load_kg, program=file):
        acc.add(chunk)
        if on_chunk is not None:
            on_chunk(chunk)
    summary = acc.summary(program=file, machine=machine, load_kg=load_kg,
                          top_blocks=top_blocks)
    return summary, acc.block_energy()
