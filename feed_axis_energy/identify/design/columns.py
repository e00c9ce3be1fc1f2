"""Each run's residual and every candidate's columns on the analysis grid.

:func:`prepare_runs` simulates each run's declared model (its state kept in a
:class:`.statestore.StateStore`, within the memory budget) and puts the run's residual and
its motion states on the analysis grid (:mod:`.grid`): a :class:`RunData`. From it,
:func:`candidate_block` builds one candidate's columns, per run, aligned through the run's
meter model (the same offset, window and smoothing as the comparison), with the physical
bounds of its linear parameters; :func:`shape_grid` lists the variants of an effect's
shape parameter and :func:`refine_shape` refines a selected block's shape by a bounded 1-D
search. ``analyze`` (:mod:`feed_axis_energy.identify.analyze`) puts these blocks into the
selection's :class:`~feed_axis_energy.identify.selection.Design`.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
import math
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from ...effects import EffectState, get_effect
from ...measured import (align_simulated, Campaign, load_run, MeasuredRun, MotionCache,
                         quantity_of, RunComparison, simulate_declared_chunks, stamp_shift)
from ...machine import Machine
from ...physics import state_from_simulation
from ..driveforms import current_basis
from ..selection import Block, Design, solve_normal
from .grid import bin_windows, Bins, bins_for
from .statestore import StateStore

__all__ = ['ALIGN_CHUNK_BYTES', 'BASIS_CHUNK_SAMPLES', 'POSITION_DIVISIONS', 'RunData',
           'StatesOf', 'axis_basis', 'axis_index', 'candidate_block', 'effect_columns',
           'prepare_runs', 'refine_shape', 'shape_grid']

POSITION_DIVISIONS = (15, 10, 6, 3)
"""Candidate resolutions of ``position_friction``: bump spacing = travelled span / n."""

ALIGN_CHUNK_BYTES = 16 * 2 ** 20
"""Size [bytes] of the simulated columns aligned at once: a wide candidate's columns (the
bumps of ``position_friction``) go through the meter model a few at a time, so its filter
and running integral hold a few columns of the run's samples, not all of them (the columns
are independent: the same values)."""
BASIS_CHUNK_SAMPLES = 2 ** 16
"""Simulated samples a sample-local candidate's basis is computed on at a time."""


@dataclass
class RunData:
    """One run as the analysis sees it: its baseline comparison, its simulation of the
    declared model (in ``store`` under ``key``), and on the analysis grid its residual per
    measured axis and its motion states (``velocity``, ``position``, ``acceleration``,
    ``kinetic_power``, ``time``)."""

    cmp: RunComparison
    store: StateStore               # the 1 kHz simulation of the declared model: .state
    key: int
    sim_index: list[int | None]     # measured axis j -> column of the simulation or None
    residual: np.ndarray            # (m, k_meas) on the analysis grid (bins)
    states: dict[str, np.ndarray]   # name -> (m, k_meas) on the analysis grid
    bins: Bins                      # measured samples -> analysis grid (.grid)
    t: np.ndarray                   # (m,) bin stamps: the mean of the samples' stamps [s]
    kt: list[float] | None = None   # a drive trace: torque per unit per axis (.driveforms)
    wide: tuple[np.ndarray, float] | None = None    # abutting windows: one per bin (.grid)

    @property
    def state(self) -> EffectState:
        """The run's simulation of the declared model (held or memory-mapped: .statestore)."""
        return self.store.get(self.key)

    def aligned(self, cols: np.ndarray, *, filtered: bool = True) -> np.ndarray:
        """Align 1 kHz columns ``(n, c)`` onto the analysis grid: ``(m, c)`` (each bin the
        mean of the columns averaged onto its measured stamps, the instrument model; a
        meter's first-order smoothing too unless ``filtered`` is false: the motion), at most
        :data:`ALIGN_CHUNK_BYTES` of columns at a time."""
        width = max(1, ALIGN_CHUNK_BYTES // max(8 * int(cols.shape[0]), 1))
        if cols.ndim == 2 and cols.shape[1] > width:
            return np.concatenate([self.aligned(cols[:, a:a + width], filtered=filtered)
                                   for a in range(0, cols.shape[1], width)], axis=1)
        filter_s = self.cmp.filter_s if filtered else 0.0
        if self.wide is not None:
            ends, span = self.wide
            return align_simulated(self.state.t, cols, ends, offset_s=self.cmp.offset_used_s,
                                   window_s=span, filter_s=filter_s)
        return self.bins.mean(align_simulated(
            self.state.t, cols, self.cmp.t, offset_s=self.cmp.offset_used_s,
            window_s=self.cmp.window_s, stamp=self.cmp.stamp, filter_s=filter_s))


class StatesOf:
    """``(state, sim_index, aligned)`` of each run, each state fetched when iterated to (one
    run's simulation in memory at a time, not every run's: .statestore)."""

    def __init__(self, runs: Sequence[RunData]) -> None:
        self._runs = runs

    def __iter__(self) -> Iterator[tuple[EffectState, list[int | None], Callable]]:
        for r in self._runs:
            yield r.state, r.sim_index, r.aligned


def prepare_runs(campaign: Campaign, cmp_runs: Sequence[RunComparison], machine: Machine, *,
                 loaded: Mapping[str, MeasuredRun], period_s: float,
                 store: StateStore) -> list[RunData]:
    """Each run's :class:`RunData`: its declared model simulated in chunks into ``store``,
    its residual (measured minus simulated, in the trace's unit) and motion states on the
    analysis grid of ``period_s``."""
    cache = MotionCache(machine)
    out = []
    for r in cmp_runs:
        spec = campaign.run(r.name)
        measured = loaded[r.name] if r.name in loaded else load_run(spec)
        # the simulation comes in chunks (a long run's is never whole in memory), each
        # kept as a piece of the run's state within the store's budget
        writer = store.writer()
        simulate_declared_chunks(spec, measured, machine, cache,
                                 lambda sim: writer.add(state_from_simulation(sim)))
        key = writer.finish()
        state = store.get(key)
        idx = [state.axes.index(a) if a in state.axes else None for a in r.axes]
        n = state.t.shape[0]
        cols = []
        for j in idx:
            for arr in (state.velocity_m_s, state.position_m, state.acceleration_m_s2):
                cols.append(arr[:, j] if j is not None else np.zeros(n))
        kt = None
        if (not quantity_of(r.measures).is_power and r.torque_per_unit is not None
                and r.signal_meas is not None and r.signal_sim is not None):
            # a drive trace (current, torque, force): the residual in the trace's unit, the
            # candidates in their force form (.driveforms)
            kt = [float(r.torque_per_unit[a]) for a in r.axes]
            residual = r.signal_meas - r.signal_sim
        else:
            residual = r.power_meas_w - r.power_sim_w
        bins = bins_for(r.t, period_s)
        run = RunData(cmp=r, store=store, key=key, sim_index=idx,
                      residual=bins.mean(residual), states={}, bins=bins, t=bins.mean(r.t),
                      kt=kt, wide=bin_windows(r.t, bins, window_s=r.window_s,
                                              shift_s=stamp_shift(r.window_s, r.stamp)))
        on = run.aligned(np.column_stack(cols), filtered=False)
        k = len(idx)
        # simulated time at the centre of each sample's window
        mid = bins.mean(r.t - r.offset_used_s + stamp_shift(r.window_s, r.stamp)
                        - 0.5 * r.window_s)
        run.states = {'velocity': on[:, 0::3], 'position': on[:, 1::3],
                      'acceleration': on[:, 2::3],
                      'kinetic_power': on[:, 0::3] * on[:, 2::3],
                      'time': np.repeat(mid[:, None], k, axis=1)}
        out.append(run)
    return out


def effect_columns(run: RunData, effect_id: str, axis_j: int,
                   shape: Mapping[str, float]) -> np.ndarray:
    """Aligned basis of one effect on measured axis ``axis_j``, flattened: ``(m*k, p)``."""
    effect = get_effect(effect_id)
    p = len(effect.linear_params())
    m, k = run.residual.shape
    out = np.zeros((m, k, p))
    j = run.sim_index[axis_j]
    if j is not None:
        kt = None if run.kt is None else run.kt[axis_j]
        out[:, axis_j, :] = run.aligned(axis_basis(effect_id, run.state, j, shape, kt))
    return out.reshape(m * k, p)


def axis_basis(effect_id: str, state: EffectState, j: int, shape: Mapping[str, float],
               kt: float | None) -> np.ndarray:
    """The basis of one effect on simulated axis ``j`` at the simulation's samples,
    ``(n, p)``, in a drive trace's unit when ``kt`` is given (.driveforms). A sample-local
    effect's is computed :data:`BASIS_CHUNK_SAMPLES` rows at a time into one array (the
    whole state's basis of every axis and its columns' list are never held at once: the
    same values, each row depends on its own sample only)."""
    effect = get_effect(effect_id)

    def on(part: EffectState) -> np.ndarray:
        basis = effect.basis(part, dict(shape))[:, j, :]
        return basis if kt is None else current_basis(effect_id, basis, part, j, kt)

    n = state.t.shape[0]
    if not effect.sample_local or n <= BASIS_CHUNK_SAMPLES:
        return on(state)
    out = np.empty((n, len(effect.linear_params())))
    for a in range(0, n, BASIS_CHUNK_SAMPLES):
        b = min(a + BASIS_CHUNK_SAMPLES, n)
        out[a:b] = on(state.rows(a, b))
    return out


def shape_grid(effect_id: str, runs: Sequence[RunData], axis_j: int,
               points: int) -> list[dict[str, float]]:
    """The variants of an effect's shape parameters a candidate is tried with (``[{}]`` for
    an effect without any): ``points`` values of the first one, geometrically spaced over
    its range; ``position_friction``'s bump spacings (:data:`POSITION_DIVISIONS`)."""
    effect = get_effect(effect_id)
    shapes = [p for p in effect.params if not p.linear]
    if not shapes:
        return [{}]
    if effect_id == 'position_friction':
        # bumps from the lowest travelled position; the spacing (the resolution) is one of
        # a few candidates, chosen by the held-out error like any other variant
        pos = [r.states['position'][:, axis_j] for r in runs]
        lo = min(float(np.min(x)) for x in pos if x.size) if any(x.size for x in pos) else 0.0
        hi = max(float(np.max(x)) for x in pos if x.size) if any(x.size for x in pos) else 0.0
        span = hi - lo if hi > lo else 0.4
        return [{'x0_m': lo, 'spacing_m': span / n} for n in POSITION_DIVISIONS]
    # the first shape parameter is searched, further ones (stribeck's delta) stay at default
    # here (the selected variant tries their other forms: refine_shape)
    par = shapes[0]
    rest = {p.name: p.default for p in shapes[1:]}
    grid = list(np.geomspace(max(par.low, 1e-12), par.high, points))
    if par.default > par.high:
        grid.append(par.default)    # thermal_drift: the linear limit (tau = 1e9 s)
    return [{par.name: float(v)} | rest for v in np.unique(grid)]


def candidate_block(runs: Sequence[RunData], effect_id: str, axis_j: int,
                    shape: Mapping[str, float]):
    """Names, per-run columns and physical bounds of one candidate.

    Columns that are zero, or whose largest value is below 1 % of the strongest column of
    the block *in the same unit* (the far tail of a position bump), are left out: they
    carry no information, and a fit on them would give huge, meaningless coefficients.
    Columns in different units are not compared: ``iron``'s ``|omega|`` column is about
    ``1/omega`` of its ``omega²`` column and carries half of the effect.
    """
    effect = get_effect(effect_id)
    cols = [effect_columns(r, effect_id, axis_j, shape) for r in runs]
    p = len(effect.linear_params())
    peak = np.array([max((float(np.max(np.abs(c[:, i]))) if c.shape[0] else 0.0)
                         for c in cols) for i in range(p)]) if cols else np.zeros(p)
    units = [next(q.unit for q in effect.params if q.name == n)
             for n in effect.linear_params()]
    top = {u: max(float(peak[i]) for i in range(p) if units[i] == u) for u in set(units)}
    used = [i for i in range(p) if peak[i] > 0.0 and peak[i] >= 0.01 * top[units[i]]]
    lo, hi = effect.linear_bounds()
    names = tuple(effect.linear_params()[i] for i in used)
    return names, [c[:, used] for c in cols], (lo[used], hi[used])


def _sse_with(design: Design, cols: list[int], extra: Sequence[np.ndarray],
              bounds: tuple[np.ndarray, np.ndarray]) -> float:
    """In-sample SSE of ``cols`` plus extra per-run columns (bounded), pooled over runs."""
    g_parts, b_parts = [], []
    for r, c in enumerate(extra):
        x = np.hstack([design.columns(r, cols), c])
        g_parts.append(x.T @ x)
        b_parts.append(x.T @ design.y[r])
    g, b = sum(g_parts), sum(b_parts)
    theta = solve_normal(g, b, np.concatenate([design.lower[cols], bounds[0]]),
                         np.concatenate([design.upper[cols], bounds[1]]))
    return float(design.yy.sum() - 2.0 * theta @ b + theta @ g @ theta)


def _other_forms(shapes: Sequence[Any], shape: Mapping[str, float]) -> list[dict[str, float]]:
    """The further shape parameters as selected, then each in its other form: the geometric
    middle of its range (stribeck's delta: 2 is the Gaussian decay, 1 the exponential)."""
    fixed = {p.name: float(shape[p.name]) for p in shapes[1:] if p.name in shape}
    forms = [fixed]
    for q in shapes[1:]:
        if q.name in fixed and q.low > 0.0 and q.high > q.low:
            middle = float(math.sqrt(q.low * q.high))
            if abs(middle - fixed[q.name]) > 1e-9 * max(abs(middle), 1.0):
                forms.append(fixed | {q.name: middle})
    return forms


def refine_shape(design: Design, runs: Sequence[RunData], block: Block,
                 others: list[int]) -> Block:
    """1-D bounded search of a selected block's first shape parameter around its grid value,
    for the further shape parameters as selected and in their other forms
    (:func:`_other_forms`): the best fit wins. Only a selected effect gets the other forms,
    so that they do not widen what the candidates can take on."""
    effect = get_effect(block.key[0])
    shapes = [p for p in effect.params if not p.linear]
    if not shapes or effect.id == 'position_friction':
        return block
    par = shapes[0]
    axis_j = axis_index(runs, block.key[1])
    grid = sorted(float(b.shape[par.name]) for b in design.blocks if b.key == block.key)
    value = float(block.shape[par.name])
    i = grid.index(value)
    lo = grid[i - 1] if i > 0 else max(par.low, value / 2.0)
    hi = grid[i + 1] if i + 1 < len(grid) else min(par.high, value * 2.0)
    if not hi > lo:
        return block

    used = [effect.linear_params().index(n) for n in block.names]
    bounds = (design.lower[list(block.cols)], design.upper[list(block.cols)])

    def columns(value: float, fixed: dict[str, float]) -> list[np.ndarray]:
        return [effect_columns(r, block.key[0], axis_j, {par.name: value} | fixed)[:, used]
                for r in runs]

    best_sse = _sse_with(design, others, [design.columns(r, block.cols)
                                          for r in range(design.runs)], bounds)
    best: tuple[float, dict[str, float]] | None = None
    for k, fixed in enumerate(_other_forms(shapes, block.shape)):
        # another form of the decay moves the best first parameter: a wider bracket
        a, b = ((lo, hi) if k == 0 else
                (max(par.low, value / 4.0), min(par.high, value * 4.0)))
        if not b > a:
            continue

        def cost(log_v: float, fixed: dict[str, float] = fixed) -> float:
            return _sse_with(design, others, columns(math.exp(log_v), fixed), bounds)

        res = minimize_scalar(cost, bounds=(math.log(a), math.log(b)), method='bounded',
                              options={'xatol': 1e-3, 'maxiter': 30})
        if float(res.fun) < best_sse:
            best_sse, best = float(res.fun), (math.exp(float(res.x)), fixed)
    if best is None:
        return block
    v, fixed = best
    return design.add_block(block.key, {par.name: v} | fixed, block.names, columns(v, fixed),
                            bounds=bounds)


def axis_index(runs: Sequence[RunData], axis: str) -> int:
    return list(runs[0].cmp.axes).index(axis)
