"""The summary of a simulation from the energy by phase: no samples (issue 23).

The same keys and meanings as the sampled summary (:func:`.stream.simulate_stream`,
:func:`.simulate.summarize`), integrated by quadrature on the planned phases
(:func:`.quadrature.iter_window_nodes`) instead of the trapezoid rule over 1 kHz samples:
energy per axis, by cause (net and gross), per source line, per operation, subroutine, tool
and axis, the energy returned by braking, the friction losses and the energy's uncertainty.
These are the truth the sampled sums converge to as the rate rises; they differ from them by
the samples' discretization error. Besides, ``method`` (``'phases'``) and
``quadrature_error_j`` (the estimated error of the quadrature per axis [J]).

``samples`` and ``rate_hz`` are those of the grid a recording of the run would have;
``peak_power_w`` is the largest drawn power at the pieces' ends and quadrature nodes (a
sampled peak is the largest at the samples: either can miss a maximum between its points).
``quadrature_error_j`` is the difference from a lower rule on the same rows
(:class:`.quadrature.WindowNodes` ``low_j``).

Memory: two planned windows, plus ``8 (k + 1)`` bytes per source line up to the largest line
number (``8 (2 k + c)`` with ``block_breakdown``).
"""
from __future__ import annotations

from collections.abc import Iterable
from typing import Any, cast

import numpy as np

from ..gcode import Move
from ..machine import Machine, PlannerOptions
from ..physics import (add_block_electrical, add_breakdown, add_uncertainty,
                       BreakdownAccumulator, ElectricalAccumulator, LineEnergy,
                       UncertaintyAccumulator)
from ..plan import grid_samples
from ..units import rate_from_interval
from .quadrature import iter_window_nodes, LineSums, PHASE_ORDER, weighted_sum, WindowNodes
from .summary import row_sum

__all__ = ['summarize_phases', 'PhaseSummary', 'FIGURES']

FIGURES = ('all', 'energy')
"""What a summary by phase holds: ``'all'`` (every key of the sampled summary), or
``'energy'`` (what a sweep compares: ``energy_j``, ``duration_s``, ``samples``,
``rate_hz``, ``quadrature_error_j``, the uncertainty, and ``figures`` itself; cut only
where the drawn power kinks, no per-line or per-cause sums)."""


class _Peaks:
    """The largest drawn power per axis and in total at the nodes and the pieces' ends."""

    def __init__(self, k: int) -> None:
        self.peak = np.full(k + 1, -np.inf)

    def add(self, drawn: np.ndarray) -> None:
        if drawn.shape[0]:
            # column by column: numpy reduces a few columns of many rows (axis 0) 20 times
            # slower than one column
            top = [drawn[:, j].max() for j in range(drawn.shape[1])]
            self.peak = np.maximum(self.peak, np.array(top + [row_sum(drawn).max()]))

    def result(self) -> np.ndarray:
        return np.where(np.isfinite(self.peak), self.peak, 0.0)


def summarize_phases(moves: Iterable[Move], machine: Machine, *, file: str = '',
                     load_kg: float = 0.0, options: PlannerOptions | None = None,
                     top_blocks: int = 5, block_breakdown: bool = False,
                     rollup: bool = False, context: Any = None,
                     order: int = PHASE_ORDER,
                     figures: str = 'all') -> tuple[dict[str, Any], LineEnergy]:
    """Summary and energy per block of ``moves`` on ``machine``, by phase.

    Parameters are those of :func:`.stream.simulate_stream` (without the sample
    consumers); ``order``: quadrature nodes per piece; ``figures``: :data:`FIGURES`.

    Returns
    -------
    (dict, LineEnergy)
        The summary (keys of :func:`.simulate.summarize`, plus ``method`` and
        ``quadrature_error_j``) and the energy per source line.

    Raises
    ------
    ConfigError
        A machine :func:`.quadrature.phase_covered` refuses.
    PlanningError
        As the planner.
    """
    if options is None:
        options = machine.planner.options()
    acc = PhaseSummary(machine, file=file, load_kg=load_kg, options=options,
                       top_blocks=top_blocks, block_breakdown=block_breakdown,
                       rollup=rollup, context=context, figures=figures)
    for w in iter_window_nodes(acc.wrap(moves), machine, load_kg=load_kg, options=options,
                               file=file, order=order, every_sign=acc.every_sign):
        acc.add(w)
    return acc.result()


class PhaseSummary:
    """The summary of one run by phase, window by window (:func:`summarize_phases`; the
    variants of a sweep feed one each from shared windows, :mod:`.bundle`).

    Parameters are those of :func:`summarize_phases`; ``lines=False`` keeps no per-line
    sums (``top_blocks`` must then be 0 and the energy per line is empty): a run whose
    blocks nobody reads needs no memory per source line.

    The windows given to :meth:`add` come from :func:`.quadrature.iter_window_nodes` (or a
    :class:`.quadrature.WindowEvaluator` of this machine and load) with ``every_sign`` as
    :attr:`every_sign` says (``True`` for all figures: the returned power and the inertia's
    share have their own sign changes).
    """

    def __init__(self, machine: Machine, *, file: str = '', load_kg: float = 0.0,
                 options: PlannerOptions, top_blocks: int = 5, block_breakdown: bool = False,
                 rollup: bool = False, context: Any = None, lines: bool = True,
                 figures: str = 'all') -> None:
        if figures not in FIGURES:
            raise ValueError(f'figures must be one of {", ".join(FIGURES)}, got {figures!r}')
        self.figures = figures
        self.every_sign = figures == 'all'
        if figures == 'energy':
            top_blocks, block_breakdown, rollup, lines = 0, False, False, False
        if not lines and (top_blocks or block_breakdown):
            raise ValueError('top_blocks and block_breakdown need the per-line sums')
        self.machine = machine
        self.file = file
        self.load_kg = load_kg
        self.options = options
        self.top_blocks = top_blocks
        self.axes = axes = tuple(machine.limits())
        self.k = k = len(axes)
        self.causes = BreakdownAccumulator(per_line=block_breakdown)
        self.elec = (ElectricalAccumulator(per_line=block_breakdown) if machine.electrical
                     else None)
        self.spread = UncertaintyAccumulator.of(machine)
        self.lines = LineSums(k) if lines else None
        self.peaks = _Peaks(k)
        self.rolls = None
        if rollup:
            from .rollup import RollupAccumulator
            self.rolls = RollupAccumulator(context)
        self.energy, self.low = np.zeros(k), np.zeros(k)
        self.loss = self.returned = 0.0
        self.t_end = 0.0

    def wrap(self, moves: Iterable[Move]) -> Iterable[Move]:
        """The moves as the planner should take them (noted for the roll-ups)."""
        return moves if self.rolls is None else self.rolls.wrap(moves)

    def add(self, w: WindowNodes) -> None:
        """Take the next window."""
        weight, dyn, mech, drawn = w.weight_s, w.dyn, w.mechanical_w, w.drawn_w
        braking = self.machine.braking
        self.energy += weighted_sum(weight, drawn)
        self.low += w.low_j
        if self.elec is not None and w.elec is not None:
            self.elec.add(dyn, mech, w.elec, braking=braking, weights=weight,
                          span_s=(w.at.win.t_begin, w.at.win.t_end))
        self.t_end = w.at.win.t_end
        if self.figures == 'energy':
            if self.spread is not None:
                self.spread.add(dyn, mech, braking=braking, weights=weight)
            return
        self.loss += float(np.einsum('n,n->', weight, row_sum(dyn.loss_power_w)))
        self.returned += float(np.einsum('n,n->', weight, row_sum(np.minimum(mech, 0.0))))
        if self.lines is not None:
            self.lines.add(w.motion.line, weight, drawn)
        self.causes.add(dyn, mech, braking=braking, weights=weight)
        if self.spread is not None:
            self.spread.add(dyn, mech, braking=braking, weights=weight)
        self.peaks.add(drawn)                  # the nodes and the pieces' ends
        if self.rolls is not None:
            _roll(self.rolls, w, self.axes, drawn)

    def result(self) -> tuple[dict[str, Any], LineEnergy]:
        """The summary and the energy per source line (empty without ``lines``)."""
        axes, k, energy, t_end = self.axes, self.k, self.energy, self.t_end
        options = self.options
        n = grid_samples(t_end, options.rate_hz)
        if self.lines is not None:
            by_line = self.lines.result(axes)
        else:
            by_line = LineEnergy(np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0),
                                 axes=axes, by_axis_j=np.zeros((0, k)))
        order_ = np.argsort(-np.abs(by_line.energy_j),
                            kind='stable')[:max(0, int(self.top_blocks))]
        peak = self.peaks.result()
        error = np.abs(energy - self.low)
        energy_d = {a: float(energy[j]) for j, a in enumerate(axes)}
        energy_d['total'] = float(energy.sum())
        errors = {**{a: float(error[j]) for j, a in enumerate(axes)}, 'total': float(error.sum())}
        summary: dict[str, Any] = {
            'program': self.file,
            'machine': self.machine.name,
            'load_kg': float(self.load_kg),
            'duration_s': float(t_end),
            'samples': n,
            'rate_hz': rate_from_interval(1.0 / options.rate_hz) if n >= 2 else 0.0,
            'braking': self.machine.braking,
            'energy_j': energy_d,
        }
        electrical = self.elec.summary() if self.elec is not None else {}
        if self.figures == 'energy':
            summary.update(method='phases', figures='energy', quadrature_error_j=errors)
            summary = add_uncertainty(summary, self.spread)
            if electrical:
                summary['electrical'] = electrical
            return summary, by_line
        summary.update({
            'peak_power_w': {**{a: float(peak[j]) for j, a in enumerate(axes)},
                             'total': float(peak[k])},
            'regenerated_energy_j': max(0.0, -self.returned),
            'loss_energy_j': self.loss,
            'top_blocks': [{'line': int(by_line.lines[i]),
                            'energy_j': float(by_line.energy_j[i]),
                            'duration_s': float(by_line.duration_s[i])} for i in order_],
        })
        summary = add_breakdown(summary, self.causes)
        summary['method'] = 'phases'
        summary['quadrature_error_j'] = errors
        summary = add_uncertainty(summary, self.spread)
        if electrical:
            summary['electrical'] = electrical
            add_block_electrical(summary['top_blocks'], cast(ElectricalAccumulator, self.elec))
        if self.rolls is not None:
            summary['rollups'] = self.rolls.rollups(summary['energy_j'], electrical or None)
        table = self.causes.lines_table(by_line.lines)
        by_axis, by_cause = (by_line.by_axis_j, None) if table is None else table
        lines_elec = (self.elec.lines_energy(by_line.lines, by_line.duration_s)
                      if self.elec is not None else None)
        motor, supply = (None, None) if lines_elec is None else lines_elec
        return summary, LineEnergy(by_line.lines, by_line.energy_j, by_line.duration_s,
                                   axes=axes, causes=self.causes.causes, by_axis_j=by_axis,
                                   by_cause_j=by_cause, motor_j=motor, supply_j=supply)


def _roll(rolls: Any, w: WindowNodes, axes: tuple[str, ...], drawn: np.ndarray) -> None:
    """The window's pieces, in time order, to the roll-ups: each piece's line, energy,
    duration, and the time each axis moved (a piece where its speed is not zero at a row);
    with drives also its energy at the motor terminals and at the supply side (the
    cabinet's standby for its duration included)."""
    a, b = w.piece_a, w.piece_b
    p = a.size
    if p == 0:
        return
    npt = w.points
    piece_e = (w.weight_s * row_sum(drawn)).reshape(p, npt).sum(axis=1)
    line = w.motion.line.reshape(p, npt)[:, 1]
    moving = np.any(w.motion.vel.reshape(p, npt, len(axes)) != 0.0, axis=1)
    order = np.argsort(a, kind='stable')
    h = b - a
    elec = None
    if w.elec is not None:
        elec = np.empty((p, 2))
        elec[:, 0] = (w.weight_s * row_sum(w.elec.motor_w)).reshape(p, npt).sum(axis=1)
        elec[:, 1] = ((w.weight_s * row_sum(w.elec.supply_w)).reshape(p, npt).sum(axis=1)
                      + w.elec.cabinet_w * h)
        elec = elec[order]
    rolls.add_pieces(axes, line[order], piece_e[order], h[order],
                     weighted_sum(h, moving.astype(float)), electrical_j=elec)
