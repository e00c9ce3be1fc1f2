"""Offline simulation: program -> motion -> dynamics -> power and energy, plus a summary.

Effects the machine declares (``Machine.effects``, e.g. written by ``analyze
--out-machine``) add their extra power to the named axis after the braking rule; energies
are integrated from the sum (:func:`apply_declared_effects`).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from ..physics import (add_block_electrical, AxisDynamics, compute_dynamics, compute_power,
                       ElectricalAccumulator, ElectricalPower, energy_by_line, EnergyIntegrator,
                       LineEnergy, PowerResult, with_electrical)
from ..machine import Machine, PlannerOptions
from ..plan import Motion, plan
from ..gcode import Program
from ..units import rate_from_interval

__all__ = ['SimulationResult', 'apply_declared_effects', 'declared_effects_power_w',
           'declared_effects_parts', 'sum_effect_parts', 'line_table',
           'simulate_program', 'simulate_motion', 'summarize']


@dataclass(frozen=True)
class SimulationResult:
    """Everything one simulation produced.

    Attributes
    ----------
    program
        Program file (or motion source) the result comes from.
    machine
        The machine model used.
    load_kg
        Workpiece mass [kg].
    motion, dynamics, power
        The three stages of the pipeline.
    """

    program: str
    machine: Machine
    load_kg: float
    motion: Motion
    dynamics: AxisDynamics
    power: PowerResult


def declared_effects_parts(dyn: AxisDynamics, power: PowerResult,
                           machine: Machine) -> list[tuple[str, np.ndarray]]:
    """Extra power [W] per axis, ``(n, k)``, of each declared effect acting on the axes.

    Parameters
    ----------
    dyn, power
        Dynamics and power of the model without the effects (``power`` after braking).
    machine
        The machine; its ``effects`` act on their axis (every axis when ``axis`` is None).

    Returns
    -------
    list of (str, numpy.ndarray)
        ``('effect:<id>', power)`` or ``('effect:<id>:<axis>', power)`` (zero on the other
        axes) in declaration order; a repeated label gets ``#2``, ``#3``...; empty when no
        declared effect acts on the axes of ``power``.
    """
    active = [e for e in machine.effects if e.axis is None or e.axis in power.axes]
    if not active:
        return []
    # imported here: the effect catalog imports the machine module, not the other way round
    from ..physics import effect_state
    from ..effects import get_effect
    state = effect_state(dyn, power, machine=machine)
    parts: list[tuple[str, np.ndarray]] = []
    seen: dict[str, int] = {}
    for decl in active:
        contribution = get_effect(decl.id).power_w(state, decl.values)
        label = f'effect:{decl.id}' if decl.axis is None else f'effect:{decl.id}:{decl.axis}'
        seen[label] = seen.get(label, 0) + 1
        if seen[label] > 1:
            label = f'{label}#{seen[label]}'
        part = np.zeros(state.shape)
        if decl.axis is None:
            part += contribution
        else:
            j = power.axes.index(decl.axis)
            part[:, j] += contribution[:, j]
        parts.append((label, part))
    return parts


def sum_effect_parts(parts: list[tuple[str, np.ndarray]]) -> np.ndarray | None:
    """The sum of :func:`declared_effects_parts` (``None`` for none), in declaration order."""
    if not parts:
        return None
    extra = np.zeros(parts[0][1].shape)
    for _label, part in parts:
        extra += part
    return extra


def declared_effects_power_w(dyn: AxisDynamics, power: PowerResult,
                             machine: Machine) -> np.ndarray | None:
    """Extra power [W] per axis, ``(n, k)``, of the machine's declared effects.

    Parameters
    ----------
    dyn, power
        Dynamics and power of the model without the effects (``power`` after braking).
    machine
        The machine; its ``effects`` act on their axis (every axis when ``axis`` is None).

    Returns
    -------
    numpy.ndarray or None
        ``None`` when no declared effect acts on the axes of ``power``.
    """
    return sum_effect_parts(declared_effects_parts(dyn, power, machine))


def apply_declared_effects(dyn: AxisDynamics, power: PowerResult,
                           machine: Machine) -> PowerResult:
    """Add the extra power of the machine's declared effects to ``power``.

    Parameters
    ----------
    dyn, power
        Dynamics and power of the model without the effects.
    machine
        The machine; its ``effects`` act on their axis (every axis when ``axis`` is None).

    Returns
    -------
    PowerResult
        ``power`` itself when no declared effect acts on its axes; otherwise power, total
        and energies include the effects (``mechanical_w`` and ``loss_power_w`` do not).
    """
    parts = declared_effects_parts(dyn, power, machine)
    extra = sum_effect_parts(parts)
    if extra is None:
        return power
    drawn = power.power_w + extra
    total = drawn.sum(axis=1)
    k = drawn.shape[1]
    energy = EnergyIntegrator(k + 1).update(power.t, np.column_stack((drawn, total)))
    return PowerResult(t=power.t, axes=power.axes, power_w=drawn, total_w=total,
                       energy_j=energy[:, :k], total_energy_j=energy[:, k],
                       mechanical_w=power.mechanical_w, loss_power_w=power.loss_power_w,
                       line=power.line, braking=power.braking, effect_power_w=tuple(parts))


def simulate_motion(motion: Motion, machine: Machine, *, load_kg: float = 0.0) -> SimulationResult:
    """Dynamics and power of a given motion (planned or measured).

    Parameters
    ----------
    motion
        Sampled motion; its axes must exist in ``machine``.
    machine
        The machine model (its ``braking`` rule is applied, then its declared effects).
    load_kg
        Workpiece mass on the ``load_axis`` table [kg].

    Returns
    -------
    SimulationResult
        Motion, dynamics and power.
    """
    dyn = compute_dynamics(motion, machine, load_kg=load_kg)
    power = apply_declared_effects(dyn, compute_power(dyn, braking=machine.braking), machine)
    power = with_electrical(dyn, power, machine)
    return SimulationResult(program=motion.source, machine=machine, load_kg=float(load_kg),
                            motion=motion, dynamics=dyn, power=power)


def simulate_program(program: Program, machine: Machine, *, load_kg: float = 0.0,
                     options: PlannerOptions | None = None,
                     progress: Callable[[float], None] | None = None) -> SimulationResult:
    """Plan ``program`` with the machine's limits, then compute dynamics and power.

    Parameters
    ----------
    program
        Parsed NC program (:func:`.gcode.parse_gcode`).
    machine
        The machine model: its limits feed the planner, its ``planner`` settings are the
        default ``options``.
    load_kg
        Workpiece mass on the ``load_axis`` table [kg].
    options
        :class:`.trajectory.PlannerOptions`; ``None`` uses ``machine.planner``.
    progress
        Passed on to :func:`.trajectory.plan`.

    Returns
    -------
    SimulationResult
        Motion, dynamics and power; ``program`` is ``program.file``.
    """
    if options is None:
        options = machine.planner.options()
    motion = plan(program, machine.limits(), options=options, progress=progress)
    result = simulate_motion(motion, machine, load_kg=load_kg)
    return SimulationResult(program=program.file, machine=machine, load_kg=result.load_kg,
                            motion=motion, dynamics=result.dynamics, power=result.power)


def summarize(result: SimulationResult, *, top_blocks: int = 5) -> dict[str, Any]:
    """Summarise a simulation as plain, JSON-able values.

    Parameters
    ----------
    result
        A simulation result.
    top_blocks
        How many source lines to list, by energy (largest first).

    Returns
    -------
    dict
        ``program`` (str), ``machine`` (name), ``load_kg``, ``duration_s`` (last minus first
        sample time), ``samples`` (count), ``rate_hz`` (1 / median sample interval, 0 for
        fewer than 2 samples), ``braking``, ``energy_j`` ({axis: J, ..., 'total': J} at the
        end), ``peak_power_w`` ({axis: W, ..., 'total': W}, the maximum drawn power),
        ``regenerated_energy_j`` (J returned by braking axes, see
        :attr:`.energy.PowerResult.regenerated_energy_j`), ``loss_energy_j`` (J spent on passive
        resistances), ``top_blocks`` (list of ``{'line', 'energy_j', 'duration_s'}``), and
        the breakdown by cause (:func:`.breakdown.add_breakdown`: ``causes``,
        ``energy_by_cause_j``, ``braking_returned_j``; per top block ``energy_by_axis_j``,
        ``energy_by_cause_j``); with declared drives ``electrical``
        (:meth:`.electrical.ElectricalAccumulator.summary`, ``docs/electrical.md``; per top
        block ``motor_energy_j`` and ``supply_energy_j``), and
        ``energy_uncertainty`` where an axis has a ``loss_covariance`` (:mod:`.uncertainty`).
    """
    from ..physics import (add_breakdown, add_uncertainty, BreakdownAccumulator,
                           UncertaintyAccumulator)
    p = result.power
    n = int(p.t.shape[0])
    dt = np.diff(p.t)
    rate = rate_from_interval(float(np.median(dt))) if n >= 2 else 0.0
    energy = {a: float(p.energy_j[-1, j]) if n else 0.0 for j, a in enumerate(p.axes)}
    energy['total'] = float(p.total_energy_j[-1]) if n else 0.0
    peak = {a: float(np.max(p.power_w[:, j])) if n else 0.0 for j, a in enumerate(p.axes)}
    peak['total'] = float(np.max(p.total_w)) if n else 0.0
    loss_total = p.loss_power_w.sum(axis=1)
    loss_energy = float(np.sum(0.5 * (loss_total[1:] + loss_total[:-1]) * dt)) if n else 0.0
    blocks = sorted(energy_by_line(p), key=lambda b: -abs(b[1]))[:max(0, int(top_blocks))]
    duration = float(p.t[-1] - p.t[0]) if n else 0.0
    # per line only for the blocks listed: without them nothing per line is reported
    causes = BreakdownAccumulator(per_line=bool(blocks))
    causes.add(result.dynamics, p.mechanical_w, braking=p.braking, effects=p.effect_power_w)
    spread = UncertaintyAccumulator.of(result.machine)
    if spread is not None:
        spread.add(result.dynamics, p.mechanical_w, braking=p.braking)
    summary = add_breakdown({
        'program': result.program,
        'machine': result.machine.name,
        'load_kg': float(result.load_kg),
        'duration_s': duration,
        'samples': n,
        'rate_hz': rate,
        'braking': p.braking,
        'energy_j': energy,
        'peak_power_w': peak,
        'regenerated_energy_j': p.regenerated_energy_j,
        'loss_energy_j': loss_energy,
        'top_blocks': [{'line': ln, 'energy_j': e, 'duration_s': d} for ln, e, d in blocks],
    }, causes)
    if p.electrical is not None:
        electrical = _electrical_lines(result, per_line=bool(blocks))
        summary['electrical'] = electrical.summary()
        add_block_electrical(summary['top_blocks'], electrical)
    return add_uncertainty(summary, spread)


def _electrical_lines(result: SimulationResult, *, per_line: bool = True) -> ElectricalAccumulator:
    """The electrical side of a whole result (with the energy of every source line)."""
    p = result.power
    electrical = ElectricalAccumulator(per_line=per_line)
    # the cast: called only for a result with an electrical side
    electrical.add(result.dynamics, p.mechanical_w, cast(ElectricalPower, p.electrical),
                   braking=p.braking,
                   effects=p.effect_power_w)
    return electrical


def line_table(result: SimulationResult) -> LineEnergy:
    """Energy and time per source line of a whole result, with the per-block breakdown.

    Parameters
    ----------
    result
        A simulation result.

    Returns
    -------
    LineEnergy
        As :meth:`.stream.SummaryAccumulator.block_energy` with ``block_breakdown``.
    """
    from ..physics import BreakdownAccumulator
    p = result.power
    causes = BreakdownAccumulator(per_line=True)
    causes.add(result.dynamics, p.mechanical_w, braking=p.braking, effects=p.effect_power_w)
    rows = energy_by_line(p)
    lines = np.array([r[0] for r in rows], dtype=np.int64)
    table = causes.lines_table(lines)
    by_axis, by_cause = (None, None) if table is None else table
    duration = np.array([r[2] for r in rows])
    motor = supply = None
    if p.electrical is not None:
        # per_line and one chunk taken: not None
        motor, supply = cast('tuple[np.ndarray, np.ndarray]',
                             _electrical_lines(result).lines_energy(lines, duration))
    return LineEnergy(lines, np.array([r[1] for r in rows]), duration,
                      axes=tuple(p.axes), causes=causes.causes, by_axis_j=by_axis,
                      by_cause_j=by_cause, motor_j=motor, supply_j=supply)
