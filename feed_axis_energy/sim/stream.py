"""Streaming simulation: motion chunks -> dynamics, power, energy and the summary, chunk by chunk.

Every stage of :func:`.simulate.simulate_program` is per sample except the energy integral,
which :class:`.energy.EnergyIntegrator` continues across chunks with the same bits; the
summary (:func:`.simulate.summarize`) is accumulated by :class:`SummaryAccumulator`. Memory is
one chunk of samples (:data:`feed_axis_energy.plan.stream.DEFAULT_CHUNK_SAMPLES`) plus one
entry per source line, whatever the program's length. The interior of a dwell is not computed
sample by sample (:mod:`.standstill`, ``Motion.gaps``): every stage integrates across the gap by
the trapezoid rule with the same power at both ends, which is the sum over its samples.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from ..physics import (apply_braking, compute_dynamics, electrical_power, EnergyIntegrator,
                       LineEnergy, power_with_total, PowerResult)
from ..errors import ConfigError
from ..machine import Machine, PlannerOptions
from ..plan import DEFAULT_CHUNK_SAMPLES, iter_motion, Motion
from ..gcode import Move
from .summary import row_sum, SummaryAccumulator
from .simulate import declared_effects_parts, SimulationResult, sum_effect_parts

__all__ = ['streamable', 'compactable', 'iter_simulation', 'expand_gaps', 'sample_chunks',
           'simulate_stream', 'COMPACT_MIN_SAMPLES']

COMPACT_MIN_SAMPLES = 64    # standstill phases with more samples are left out of the rows


def streamable(machine: Machine) -> bool:
    """True when every declared effect of ``machine`` is sample-local (can run per chunk)."""
    if not machine.effects:
        return True
    from ..effects import get_effect
    return all(get_effect(e.id).sample_local for e in machine.effects)


def compactable(machine: Machine) -> bool:
    """True when standstill samples may be left out: every declared effect is sample-local
    and constant at rest (``Effect.constant_at_rest``), so the power is the same at every
    sample of a dwell."""
    if not machine.effects:
        return True
    if not streamable(machine):
        return False
    from ..effects import get_effect
    return all(get_effect(e.id).constant_at_rest for e in machine.effects)


def iter_simulation(motions: Iterable[Motion], machine: Machine, *, load_kg: float = 0.0,
                    program: str = '') -> Iterator[SimulationResult]:
    """Dynamics and power of each motion chunk; energies continue from chunk to chunk.

    Parameters
    ----------
    motions
        Consecutive motion chunks (:func:`feed_axis_energy.plan.stream.iter_motion`).
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
        loss_power = dyn.loss_power_w          # a property: computed on every access
        if integrator is None:
            integrator = EnergyIntegrator(k + 1)
        base = PowerResult(t=dyn.t, axes=dyn.axes, power_w=drawn, total_w=drawn[:, 0],
                           energy_j=drawn, total_energy_j=drawn[:, 0],
                           mechanical_w=mechanical, loss_power_w=loss_power,
                           line=dyn.line, braking=machine.braking)
        parts = declared_effects_parts(dyn, base, machine)
        extra = sum_effect_parts(parts)
        if extra is not None:
            drawn = drawn + extra
        total = row_sum(drawn)
        elec = electrical_power(dyn, mechanical, machine, effects_w=extra)
        energy = integrator.update(dyn.t, power_with_total(drawn, total))
        power = PowerResult(t=dyn.t, axes=dyn.axes, power_w=drawn, total_w=total,
                            energy_j=energy[:, :k], total_energy_j=energy[:, k],
                            mechanical_w=mechanical, loss_power_w=loss_power,
                            line=dyn.line, braking=machine.braking,
                            effect_power_w=tuple(parts), electrical=elec)
        yield SimulationResult(program=program or motion.source, machine=machine,
                               load_kg=float(load_kg), motion=motion, dynamics=dyn,
                               power=power)


_MOTION_ROWS = ('t', 'pos', 'vel', 'acc', 'line')
_DYNAMICS_ROWS = ('t', 'position_m', 'velocity_m_s', 'acceleration_m_s2', 'angle_rad',
                  'omega_rad_s', 'alpha_rad_s2', 'force_n', 'loss_force_n', 'gravity_force_n',
                  'torque_nm', 'line')
_POWER_ROWS = ('t', 'power_w', 'total_w', 'energy_j', 'total_energy_j', 'mechanical_w',
               'loss_power_w', 'line')


def _gap_pieces(chunk: SimulationResult, size: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """``(source rows, grid index or -1)`` of every full-rate sample, ``size`` at a time."""
    m = chunk.power.t.shape[0]
    parts: list[tuple[int, int, int]] = []        # (row, grid first, count); grid -1: a row
    row = 0
    for gap_row, first, count in chunk.motion.gaps:
        if gap_row > row:
            parts.append((row, -1, gap_row - row))
        parts.append((gap_row, first, count))
        row = gap_row
    if m > row:
        parts.append((row, -1, m - row))
    src: list[np.ndarray] = []
    grid: list[np.ndarray] = []
    held = 0
    for row, first, count in parts:
        done = 0
        while done < count:
            take = min(count - done, size - held)
            if first < 0:
                src.append(np.arange(row + done, row + done + take))
                grid.append(np.full(take, -1, np.int64))
            else:
                src.append(np.full(take, row, np.int64))
                grid.append(np.arange(first + done, first + done + take, dtype=np.int64))
            done += take
            held += take
            if held == size:
                yield np.concatenate(src), np.concatenate(grid)
                src, grid, held = [], [], 0
    if held:
        yield np.concatenate(src), np.concatenate(grid)


def expand_gaps(chunk: SimulationResult, *, rate_hz: float,
                chunk_samples: int = DEFAULT_CHUNK_SAMPLES) -> Iterator[SimulationResult]:
    """The chunk at the full rate: standstill samples left out (``Motion.gaps``) put back.

    A left-out sample equals the row after its gap except its time (``i / rate_hz``) and its
    cumulative energy, ``E = E_row - P (t_row - t)`` (constant power across the gap).

    Parameters
    ----------
    chunk
        A chunk of :func:`iter_simulation`.
    rate_hz
        Sample rate of the grid [Hz].
    chunk_samples
        Largest result yielded [samples].

    Yields
    ------
    SimulationResult
        Consecutive pieces without gaps; the chunk itself when it has none.
    """
    if not chunk.motion.gaps:
        yield chunk
        return
    mo, dyn, pw = chunk.motion, chunk.dynamics, chunk.power
    for src, grid in _gap_pieces(chunk, max(int(chunk_samples), 1)):
        fill = np.nonzero(grid >= 0)[0]
        t = mo.t[src]
        t[fill] = grid[fill].astype(float) / rate_hz
        back = (pw.t[src[fill]] - t[fill])
        energy = pw.energy_j[src]
        energy[fill] -= pw.power_w[src[fill]] * back[:, None]
        total_energy = pw.total_energy_j[src]
        total_energy[fill] -= pw.total_w[src[fill]] * back
        motion = replace(mo, **{f: (t if f == 't' else getattr(mo, f)[src])
                                for f in _MOTION_ROWS}, gaps=())
        dynamics = replace(dyn, **{f: (t if f == 't' else getattr(dyn, f)[src])
                                   for f in _DYNAMICS_ROWS})
        rows = {f: getattr(pw, f)[src] for f in _POWER_ROWS[1:]}
        rows.update(t=t, energy_j=energy, total_energy_j=total_energy,
                    effect_power_w=tuple((label, a[src]) for label, a in pw.effect_power_w),
                    electrical=None if pw.electrical is None else pw.electrical.take(src))
        yield replace(chunk, motion=motion, dynamics=dynamics, power=replace(pw, **rows))


def sample_chunks(moves: Iterable[Move], machine: Machine, *, file: str = '',
                  load_kg: float = 0.0, options: PlannerOptions | None = None,
                  chunk_samples: int = DEFAULT_CHUNK_SAMPLES, total_moves: int | None = None,
                  duration_s: float | None = None,
                  progress: Callable[[float], None] | None = None,
                  limits: Mapping | None = None,
                  compact: bool = True) -> Iterator[SimulationResult]:
    """The sampled simulation's chunks as computed (standstill interiors left out where
    :func:`compactable` allows and ``compact``; ``Motion.gaps``), without a summary: for a
    recording or an export beside the summary by phase. Parameters as
    :func:`simulate_stream`."""
    if options is None:
        options = machine.planner.options()
    compact_min = COMPACT_MIN_SAMPLES if compact and compactable(machine) else 0
    motions = iter_motion(moves, machine.limits() if limits is None else limits,
                          options=options, file=file, chunk_samples=chunk_samples,
                          total_moves=total_moves, duration_s=duration_s,
                          progress=progress, compact_min_samples=compact_min)
    return iter_simulation(motions, machine, load_kg=load_kg, program=file)


def simulate_stream(moves: Iterable[Move], machine: Machine, *, file: str = '',
                    load_kg: float = 0.0, options: PlannerOptions | None = None,
                    top_blocks: int = 5, chunk_samples: int = DEFAULT_CHUNK_SAMPLES,
                    total_moves: int | None = None, duration_s: float | None = None,
                    on_chunk: Callable[[SimulationResult], None] | None = None,
                    progress: Callable[[float], None] | None = None,
                    limits: Mapping | None = None, compact: bool = True,
                    chunk_gaps: bool = False, block_breakdown: bool = False,
                    rollup: bool = False,
                    context: Any = None) -> tuple[dict[str, Any], LineEnergy]:
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
        Program duration if known (progress by time, see
        :func:`feed_axis_energy.plan.stream.iter_motion`).
    on_chunk
        Called with every chunk's :class:`.simulate.SimulationResult` (e.g. a bag writer), at
        the full rate (:func:`expand_gaps`) unless ``chunk_gaps``.
    progress
        Called with the fraction of moves planned.
    limits
        Axis limits; ``None`` uses ``machine.limits()``.
    compact
        Leave the interior of standstill phases (dwells) of more than
        :data:`COMPACT_MIN_SAMPLES` samples out of the rows (:mod:`.standstill`; results
        equal to rounding) where :func:`compactable` allows it. ``False``: every sample.
    chunk_gaps
        ``on_chunk`` receives the chunks as computed, with ``Motion.gaps``, instead of
        expanded to the full rate.
    block_breakdown
        Keep the energy of every source line per axis and per cause (``LineEnergy.by_axis_j``,
        ``by_cause_j``, and in the summary's ``top_blocks``): ``8 (k + c)`` bytes per line
        of the program. The totals by cause (``energy_by_cause_j``) are always there.
    rollup
        Add the summary's ``rollups`` (energy and time per operation, subroutine, tool and
        axis; :mod:`.rollup`).
    context
        The operation context of ``moves`` (``MoveStream.context`` of
        :func:`.gcode.iter_moves`); ``None``: no operations or tools.

    Returns
    -------
    (dict, LineEnergy)
        The summary (keys of :func:`.simulate.summarize`) and ``(line, energy_j,
        duration_s)`` by line.
    """
    if options is None:
        options = machine.planner.options()
    rate = options.rate_hz
    acc = SummaryAccumulator(rate_hz=rate, block_breakdown=block_breakdown)
    rolls = None
    if rollup:
        from .rollup import RollupAccumulator
        rolls = RollupAccumulator(context)
        moves = rolls.wrap(moves)
    for chunk in sample_chunks(moves, machine, file=file, load_kg=load_kg, options=options,
                               chunk_samples=chunk_samples, total_moves=total_moves,
                               duration_s=duration_s, progress=progress, limits=limits,
                               compact=compact):
        acc.add(chunk)
        if rolls is not None:
            rolls.add(chunk)
        if on_chunk is None:
            continue
        if chunk_gaps:
            on_chunk(chunk)
        else:
            for piece in expand_gaps(chunk, rate_hz=rate, chunk_samples=chunk_samples):
                on_chunk(piece)
    summary = acc.summary(program=file, machine=machine, load_kg=load_kg,
                          top_blocks=top_blocks)
    if rolls is not None:
        summary['rollups'] = rolls.rollups(summary['energy_j'], summary.get('electrical'))
    return summary, acc.block_energy()
