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
``quadrature_error_j`` is the difference from the rule with two nodes fewer.

Memory: two planned windows, plus ``8 (k + 1)`` bytes per source line up to the largest line
number (``8 (2 k + c)`` with ``block_breakdown``).
"""
from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from ..gcode import Move
from ..machine import Machine, PlannerOptions
from ..physics import (add_breakdown, add_uncertainty, BreakdownAccumulator, LineEnergy,
                       UncertaintyAccumulator)
from ..plan import grid_samples
from ..units import rate_from_interval
from .quadrature import iter_window_nodes, LineSums, PHASE_ORDER, weighted_sum, WindowNodes
from .summary import row_sum

__all__ = ['summarize_phases']


class _Peaks:
    """The largest drawn power per axis and in total at the nodes and the pieces' ends."""

    def __init__(self, k: int) -> None:
        self.peak = np.full(k + 1, -np.inf)

    def add(self, drawn: np.ndarray) -> None:
        if drawn.shape[0]:
            self.peak = np.maximum(self.peak, np.append(drawn.max(axis=0),
                                                        row_sum(drawn).max()))

    def result(self) -> np.ndarray:
        return np.where(np.isfinite(self.peak), self.peak, 0.0)


def summarize_phases(moves: Iterable[Move], machine: Machine, *, file: str = '',
                     load_kg: float = 0.0, options: PlannerOptions | None = None,
                     top_blocks: int = 5, block_breakdown: bool = False,
                     rollup: bool = False, context: Any = None,
                     order: int = PHASE_ORDER) -> tuple[dict[str, Any], LineEnergy]:
    """Summary and energy per block of ``moves`` on ``machine``, by phase.

    Parameters are those of :func:`.stream.simulate_stream` (without the sample
    consumers); ``order``: quadrature nodes per piece.

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
    axes = tuple(machine.limits())
    k = len(axes)
    braking = machine.braking
    causes = BreakdownAccumulator(per_line=block_breakdown)
    spread = UncertaintyAccumulator.of(machine)
    lines = LineSums(k)
    peaks = _Peaks(k)
    rolls = None
    if rollup:
        from .rollup import RollupAccumulator
        rolls = RollupAccumulator(context)
        moves = rolls.wrap(moves)
    energy, low = np.zeros(k), np.zeros(k)
    loss = returned = 0.0
    t_end = 0.0
    for w in iter_window_nodes(moves, machine, load_kg=load_kg, options=options, file=file,
                               order=order, every_sign=True):
        weight, dyn, mech, drawn = w.weight_s, w.dyn, w.mechanical_w, w.drawn_w
        energy += weighted_sum(weight, drawn)
        low += w.low_j
        loss += float(np.einsum('n,n->', weight, row_sum(dyn.loss_power_w)))
        returned += float(np.einsum('n,n->', weight, row_sum(np.minimum(mech, 0.0))))
        lines.add(w.motion.line, weight, drawn)
        causes.add(dyn, mech, braking=braking, weights=weight)
        if spread is not None:
            spread.add(dyn, mech, braking=braking, weights=weight)
        peaks.add(drawn)                  # the nodes and the pieces' ends
        if rolls is not None:
            _roll(rolls, w, axes, drawn)
        t_end = w.at.win.t_end
    n = grid_samples(t_end, options.rate_hz)
    by_line = lines.result(axes)
    order_ = np.argsort(-np.abs(by_line.energy_j), kind='stable')[:max(0, int(top_blocks))]
    peak = peaks.result()
    error = np.abs(energy - low)
    energy_d = {a: float(energy[j]) for j, a in enumerate(axes)}
    energy_d['total'] = float(energy.sum())
    summary = add_breakdown({
        'program': file,
        'machine': machine.name,
        'load_kg': float(load_kg),
        'duration_s': float(t_end),
        'samples': n,
        'rate_hz': rate_from_interval(1.0 / options.rate_hz) if n >= 2 else 0.0,
        'braking': braking,
        'energy_j': energy_d,
        'peak_power_w': {**{a: float(peak[j]) for j, a in enumerate(axes)},
                         'total': float(peak[k])},
        'regenerated_energy_j': max(0.0, -returned),
        'loss_energy_j': loss,
        'top_blocks': [{'line': int(by_line.lines[i]), 'energy_j': float(by_line.energy_j[i]),
                        'duration_s': float(by_line.duration_s[i])} for i in order_],
    }, causes)
    summary['method'] = 'phases'
    summary['quadrature_error_j'] = {**{a: float(error[j]) for j, a in enumerate(axes)},
                                     'total': float(error.sum())}
    summary = add_uncertainty(summary, spread)
    if rolls is not None:
        summary['rollups'] = rolls.rollups(summary['energy_j'], None)
    table = causes.lines_table(by_line.lines)
    by_axis, by_cause = (by_line.by_axis_j, None) if table is None else table
    return summary, LineEnergy(by_line.lines, by_line.energy_j, by_line.duration_s, axes=axes,
                               causes=causes.causes, by_axis_j=by_axis, by_cause_j=by_cause)


def _roll(rolls: Any, w: WindowNodes, axes: tuple[str, ...], drawn: np.ndarray) -> None:
    """The window's pieces, in time order, to the roll-ups: each piece's line, energy,
    duration, and the time each axis moved (a piece where its speed is not zero at a row)."""
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
    rolls.add_pieces(axes, line[order], piece_e[order], h[order],
                     weighted_sum(h, moving.astype(float)))
