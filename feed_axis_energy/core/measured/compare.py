"""Compare a campaign of measured runs with the simulation: alignment, Table-1 metrics, groups.

For every run: load the measured data (:func:`.csvload.load_run`); build the motion from the
run's NC program (planned with the machine's limits) or from the data's own commanded or
actual positions; simulate with the run's load; estimate how much later the measured record
is than the simulated one (:func:`.align.estimate_offset`, on the summed power of the
measured axes); average the simulated power over each measuring interval
(:func:`.align.align_simulated`, the instrument model, never point samples) and compute the
Table-1 metrics (:func:`.metrics.table1_metrics`) per measured axis and for their sum.
Runs are pooled by load (:func:`.metrics.group_metrics`), as the paper's Table 1 does.

Offset policy: the estimate is used unless its status is ``'weak'`` (peak correlation below
``min_correlation`` or a constant signal), in which case the run is compared at offset 0 and
the status and message are carried into the result. A poor match is a result, not an error.

"total" means the sum over the axes that have a measured power column; simulated axes
without a measured counterpart (e.g. a Z axis without a power column) are left out of it.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError, DataError
from ..gcode import load_gcode
from ..machine import load_machine, Machine
from ..motion import Motion
from ..simulate import simulate_motion, SimulationResult
from ..trajectory import motion_from_samples, plan
from .align import align_simulated, estimate_offset, OffsetResult
from .csvload import load_run, MeasuredRun
from .campaign import Campaign, RunSpec
from .metrics import group_metrics, Metrics, table1_metrics

__all__ = [
    'DEFAULT_MAX_LAG_S', 'CampaignComparison', 'GroupComparison', 'RunComparison',
    'compare_campaign', 'compare_run', 'json_clean',
]

DEFAULT_MAX_LAG_S = 5.0
"""Largest time offset searched by default, in either direction [s]."""

TOTAL = 'total'


def json_clean(value: Any) -> Any:
    """Return ``value`` with NaN/inf floats replaced by ``None`` (strict JSON has no NaN)."""
    if isinstance(value, dict):
        return {k: json_clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_clean(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def offset_dict(offset: OffsetResult, *, used_s: float) -> dict[str, Any]:
    """JSON-able offset estimate: found/used offset, scores, runner-up and drift."""
    runner = None
    if math.isfinite(offset.runner_up_s):
        runner = {'offset_s': offset.runner_up_s, 'correlation': offset.runner_up_correlation,
                  'rms_w': offset.runner_up_rms_w}
    return {
        'found_s': offset.offset_s,
        'used_s': used_s,
        'correlation': offset.peak_correlation,
        'rms_w': offset.rms_w,
        'status': offset.status,
        'message': offset.message,
        'runner_up': runner,
        'drift_ppm': offset.drift_ppm,
        'drift_message': offset.drift_message,
    }


def _cumulative_energy(t: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Trapezoidal cumulative energy [J] of ``p`` (n,) or (n, k) over ``t``, 0 at t[0]."""
    dt = np.diff(t) if p.ndim == 1 else np.diff(t)[:, None]
    steps = 0.5 * (p[1:] + p[:-1]) * dt
    return np.concatenate([np.zeros((1,) + p.shape[1:]), np.cumsum(steps, axis=0)])


@dataclass(frozen=True)
class RunComparison:
    """One measured run against its simulation, on the measured stamps.

    Attributes
    ----------
    name, role, load_kg
        From the manifest.
    data_file
        The measured data file.
    motion_source
        The NC program file, or ``'data:commanded'`` / ``'data:actual'``.
    axes
        Axes with measured power, the columns of the power arrays.
    window_s
        Measuring interval the simulated power was averaged over [s] (0: point samples).
    offset
        The offset estimate (status ``'ok'``, ``'weak'``, ``'edge'``, ``'ambiguous'`` or
        ``'fixed'`` when the caller gave the offset).
    offset_used_s
        The offset the comparison was made at [s].
    metrics
        Table-1 metrics of the summed power of ``axes``.
    axis_metrics
        Table-1 metrics per axis of ``axes``.
    t
        Measured stamps [s], shape ``(n,)``.
    power_meas_w, power_sim_w
        Measured and aligned, interval-averaged simulated power [W], shape ``(n, len(axes))``.
    sim_duration_s
        Length of the simulation [s].
    excluded_rows
        Data rows dropped by the manifest's row filter.
    stamp
        Where the instrument stamps its window: ``'end'``, ``'centre'`` or ``'start'``.
    """

    name: str
    role: str | None
    load_kg: float
    data_file: str
    motion_source: str
    axes: tuple[str, ...]
    window_s: float
    offset: OffsetResult
    offset_used_s: float
    metrics: Metrics
    axis_metrics: dict[str, Metrics]
    t: np.ndarray = field(repr=False)
    power_meas_w: np.ndarray = field(repr=False)
    power_sim_w: np.ndarray = field(repr=False)
    sim_duration_s: float = 0.0
    excluded_rows: int = 0
    stamp: str = 'end'

    @property
    def total_meas_w(self) -> np.ndarray:
        """Measured power summed over ``axes`` [W], ``(n,)``."""
        return self.power_meas_w.sum(axis=1)

    @property
    def total_sim_w(self) -> np.ndarray:
        """Aligned simulated power summed over ``axes`` [W], ``(n,)``."""
        return self.power_sim_w.sum(axis=1)

    def energy_meas_j(self) -> np.ndarray:
        """Cumulative measured energy of the total [J], ``(n,)``, 0 at the first stamp."""
        return _cumulative_energy(self.t, self.total_meas_w)

    def energy_sim_j(self) -> np.ndarray:
        """Cumulative simulated energy of the total on the measured stamps [J], ``(n,)``."""
        return _cumulative_energy(self.t, self.total_sim_w)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able summary (no time series); keys carry units, NaN becomes ``None``."""
        metrics = {TOTAL: self.metrics.to_dict()}
        metrics.update({a: m.to_dict() for a, m in self.axis_metrics.items()})
        return json_clean({
            'name': self.name,
            'role': self.role,
            'load_kg': self.load_kg,
            'data_file': self.data_file,
            'motion_source': self.motion_source,
            'axes': list(self.axes),
            'window_s': self.window_s,
            'duration_meas_s': float(self.t[-1] - self.t[0]),
            'duration_sim_s': self.sim_duration_s,
            'excluded_rows': self.excluded_rows,
            'stamp': self.stamp,
            'offset': offset_dict(self.offset, used_s=self.offset_used_s),
            'metrics': metrics,
        })


@dataclass(frozen=True)
class GroupComparison:
    """Runs at one load pooled (the columns of the paper's Table 1).

    Attributes
    ----------
    load_kg
        The load shared by the runs [kg].
    runs
        Names of the pooled runs.
    metrics
        Pooled metrics of the total.
    axis_metrics
        Pooled metrics per axis (axes measured in every run of the group).
    """

    load_kg: float
    runs: tuple[str, ...]
    metrics: Metrics
    axis_metrics: dict[str, Metrics]

    def to_dict(self) -> dict[str, Any]:
        """JSON-able summary; keys carry units, NaN becomes ``None``."""
        metrics = {TOTAL: self.metrics.to_dict()}
        metrics.update({a: m.to_dict() for a, m in self.axis_metrics.items()})
        return json_clean({'load_kg': self.load_kg, 'runs': list(self.runs),
                           'metrics': metrics})


@dataclass(frozen=True)
class CampaignComparison:
    """Every compared run of a campaign and the per-load groups.

    Attributes
    ----------
    campaign
        Campaign name.
    manifest
        The manifest file.
    machine
        Machine name.
    machine_file
        The machine config used (``''`` when the caller passed a machine object).
    max_lag_s
        Offset search range [s].
    runs
        Per-run results, in manifest order.
    groups
        Per-load groups, by increasing load.
    """

    campaign: str
    manifest: str
    machine: str
    machine_file: str
    max_lag_s: float
    runs: tuple[RunComparison, ...]
    groups: tuple[GroupComparison, ...]

    @property
    def offset_warnings(self) -> list[str]:
        """One line per run whose offset estimate is not ``'ok'`` (or given)."""
        return [f'{r.name}: offset {r.offset.status}: {r.offset.message}'
                for r in self.runs if r.offset.status not in ('ok', 'fixed')]

    def to_dict(self) -> dict[str, Any]:
        """JSON-able summary (see docs/compare.md); keys carry units, NaN becomes ``None``."""
        return {
            'campaign': self.campaign,
            'manifest': self.manifest,
            'machine': self.machine,
            'machine_file': self.machine_file,
            'max_lag_s': self.max_lag_s,
            'runs': [r.to_dict() for r in self.runs],
            'groups': [g.to_dict() for g in self.groups],
            'warnings': self.offset_warnings,
        }


class _MotionCache:
    """Plans each NC program once; runs that share a program differ only in load."""

    def __init__(self, machine: Machine):
        self.machine = machine
        self._plans: dict[Path, Motion] = {}

    def program_motion(self, path: Path) -> Motion:
        if path not in self._plans:
            program = load_gcode(path, **self.machine.gcode_keywords())
            self._plans[path] = plan(program, self.machine.limits(),
                                     options=self.machine.planner.options())
        return self._plans[path]


def _simulate(spec: RunSpec, run: MeasuredRun, machine: Machine,
              cache: _MotionCache) -> tuple[SimulationResult, str]:
    if spec.motion_program is not None:
        motion = cache.program_motion(spec.motion_program)
        source = str(spec.motion_program)
    else:
        kind = spec.motion_from_data or 'commanded'
        # Measured velocity/acceleration columns, where mapped, beat differentiated positions.
        vel, acc = run.derivatives(kind)
        motion = motion_from_samples(run.t, run.positions(kind), axes=run.axes,
                                     source=f'{run.file} ({kind} positions)', vel=vel, acc=acc)
        source = f'data:{kind}'
    return simulate_motion(motion, machine, load_kg=spec.load_kg), source


def _sim_columns(spec: RunSpec, sim: SimulationResult, machine: Machine) -> np.ndarray:
    """Simulated power of the run's measured axes, ``(m, k)``; axes the motion lacks are 0."""
    p = sim.power
    cols = []
    for axis in spec.power_axes:
        if axis in p.axes:
            cols.append(p.power_w[:, p.axes.index(axis)])
        elif axis in machine.axis_names:
            # An axis that never moves has omega = 0, hence zero actual power (eq. 1).
            cols.append(np.zeros(p.t.shape[0]))
        else:
            msg = (f'measured axis {axis!r} is not an axis of machine {machine.name!r} '
                   f'{machine.axis_names}')
            raise ConfigError(msg, file=spec.manifest, key=f'{spec.key}.axes.{axis}')
    return np.column_stack(cols)


def compare_run(spec: RunSpec, machine: Machine, *, max_lag_s: float = DEFAULT_MAX_LAG_S,
                window_s: float | None = None, offset_s: float | None = None,
                min_correlation: float = 0.5, floor_fraction: float = 0.05) -> RunComparison:
    """Compare one measured run with its simulation.

    Parameters
    ----------
    spec
        The run (from a campaign manifest).
    machine
        The machine model.
    max_lag_s
        Largest offset searched, in either direction [s].
    window_s
        Measuring interval [s]; default: the median period of the measured stamps.
    offset_s
        Compare at this offset instead of estimating one (status ``'fixed'``).
    min_correlation
        Below this peak correlation the estimate is ``'weak'`` and offset 0 is used.
    floor_fraction
        Floor of the percentual error, as a fraction of the run's peak measured power.

    Returns
    -------
    RunComparison
        Offset, metrics and the aligned series.

    Raises
    ------
    DataError, ConfigError, GcodeError, PlanningError
        Unreadable data, program or a run that does not fit the machine (never for a poor
        match).
    """
    return _compare(spec, machine, _MotionCache(machine), max_lag_s=max_lag_s,
                    window_s=window_s, offset_s=offset_s, min_correlation=min_correlation,
                    floor_fraction=floor_fraction)


def _compare(spec: RunSpec, machine: Machine, cache: _MotionCache, *, max_lag_s: float,
             window_s: float | None, offset_s: float | None, min_correlation: float,
             floor_fraction: float) -> RunComparison:
    run = load_run(spec)
    sim, source = _simulate(spec, run, machine, cache)
    sim_w = _sim_columns(spec, sim, machine)
    window = float(np.median(np.diff(run.t))) if window_s is None else float(window_s)
    if not np.isfinite(sim_w).all():
        sample = int(np.flatnonzero(~np.isfinite(sim_w).all(axis=1))[0]) + 1
        msg = (f'the simulation of this run overflowed (simulated power sample {sample} is '
               'not finite); check the run\'s kinematics and the machine config')
        raise DataError(msg, file=run.file)
    if offset_s is None:
        try:
            found = estimate_offset(run.t, run.total_power_w, sim.power.t, sim_w.sum(axis=1),
                                    max_lag_s=max_lag_s, window_s=window,
                                    min_correlation=min_correlation)
        except DataError as err:
            msg = f'the time offset cannot be estimated: {err.reason}'
            raise DataError(msg, file=run.file, column=err.column) from err
        used = 0.0 if found.status == 'weak' else found.offset_s
        if found.status == 'weak':
            found = replace(found, message=f'{found.message}; compared at offset 0')
    else:
        used = float(offset_s)
        found = OffsetResult(used, math.nan, 'fixed', f'offset {used:+.4f} s given by the caller')
    try:
        aligned = align_simulated(sim.power.t, sim_w, run.t, offset_s=used, window_s=window)
    except DataError as err:
        # align names its arrays only; the run's file is the place the user can act on
        msg = f'simulated power cannot be aligned: {err.reason}'
        raise DataError(msg, file=run.file, column=err.column) from err
    meas = run.power_w
    where = {'file': run.file, 'rows': run.extra.get('rows'), 'floor_fraction': floor_fraction}
    total = table1_metrics(run.t, meas.sum(axis=1), aligned.sum(axis=1),
                           columns=('time', 'measured total power', 'simulated total power'),
                           **where)
    per_axis = {a: table1_metrics(run.t, meas[:, j], aligned[:, j],
                                  columns=('time', f'measured {a} power',
                                           f'simulated {a} power'), **where)
                for j, a in enumerate(spec.power_axes)}
    return RunComparison(
        name=spec.name, role=spec.role, load_kg=spec.load_kg, data_file=run.file,
        motion_source=source, axes=spec.power_axes, window_s=window, offset=found,
        offset_used_s=used, metrics=total, axis_metrics=per_axis, t=run.t,
        power_meas_w=meas, power_sim_w=aligned,
        sim_duration_s=float(sim.power.t[-1] - sim.power.t[0]),
        excluded_rows=int(run.extra.get('excluded_rows', 0)),
    )


def _groups(runs: Sequence[RunComparison]) -> tuple[GroupComparison, ...]:
    by_load: dict[float, list[RunComparison]] = {}
    for r in runs:
        by_load.setdefault(r.load_kg, []).append(r)
    out = []
    for load in sorted(by_load):
        members = by_load[load]
        shared = [a for a in members[0].axes if all(a in m.axes for m in members)]
        out.append(GroupComparison(
            load_kg=load, runs=tuple(m.name for m in members),
            metrics=group_metrics([m.metrics for m in members]),
            axis_metrics={a: group_metrics([m.axis_metrics[a] for m in members])
                          for a in shared}))
    return tuple(out)


def compare_campaign(campaign: Campaign, *, machine: Machine | None = None,
                     runs: Sequence[str] | None = None, max_lag_s: float = DEFAULT_MAX_LAG_S,
                     window_s: float | None = None, min_correlation: float = 0.5,
                     floor_fraction: float = 0.05,
                     progress: Callable[[float], None] | None = None) -> CampaignComparison:
    """Compare every (or the named) run of a campaign with the simulation.

    Parameters
    ----------
    campaign
        From :func:`.manifest.load_campaign`.
    machine
        The machine model; default: the manifest's machine config.
    runs
        Names of the runs to compare, in this order; default: all, in manifest order.
    max_lag_s
        Largest time offset searched, in either direction [s].
    window_s
        Measuring interval [s]; default: each run's median sampling period.
    min_correlation
        Peak correlation below which an offset estimate is ``'weak'`` (then offset 0).
    floor_fraction
        Floor of the percentual error, as a fraction of each run's peak measured power.
    progress
        Called with the finished fraction (0..1) after every run.

    Returns
    -------
    CampaignComparison
        Per-run results and per-load groups.

    Raises
    ------
    ConfigError
        Unknown run names (naming the known ones), a bad machine config or a run whose
        axes the machine lacks.
    DataError, GcodeError, PlanningError
        Unusable data or programs.
    """
    if not (math.isfinite(max_lag_s) and max_lag_s >= 0.0):
        msg = f'max_lag_s must be a finite number >= 0, got {max_lag_s!r}'
        raise ConfigError(msg, file=str(campaign.file), key='max_lag_s')
    if runs is None:
        specs = list(campaign.runs)
    else:
        known = [r.name for r in campaign.runs]
        missing = [n for n in runs if n not in known]
        if missing:
            msg = f'no run named {missing[0]!r}; runs are {", ".join(known)}'
            raise ConfigError(msg, file=str(campaign.file), key='runs')
        specs = [campaign.run(n) for n in runs]
        if not specs:
            raise ConfigError('no runs selected', file=str(campaign.file), key='runs')
    machine_file = ''
    if machine is None:
        machine = load_machine(campaign.machine)
        machine_file = str(campaign.machine)
    cache = _MotionCache(machine)
    results = []
    for i, spec in enumerate(specs):
        results.append(_compare(spec, machine, cache, max_lag_s=max_lag_s, window_s=window_s,
                                offset_s=None, min_correlation=min_correlation,
                                floor_fraction=floor_fraction))
        if progress is not None:
            progress((i + 1) / len(specs))
    return CampaignComparison(
        campaign=campaign.name, manifest=str(campaign.file), machine=machine.name,
        machine_file=machine_file, max_lag_s=float(max_lag_s), runs=tuple(results),
        groups=_groups(results))
