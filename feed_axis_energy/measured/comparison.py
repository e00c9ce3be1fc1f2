"""Results of ``compare``: one run, a load group, a campaign (JSON-able, units in keys)."""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any

import numpy as np

from .align import OffsetResult
from .instrument import instrument_verdict, MeterFit
from .metrics import Metrics
from .quantity import quantity_of, SignalMetrics
from .spatial import WorkOffset
from .states import pool_states, StateResidual

__all__ = ['CampaignComparison', 'GroupComparison', 'RunComparison', 'TOTAL', 'json_clean',
           'offset_dict']

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
        'anchor': offset.anchor,
        'motion_s': offset.motion_s,
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
        Axes with a measured trace (:attr:`measures`), the columns of every array.
    window_s
        Measuring interval the simulated power was averaged over [s] (0: point samples).
    offset
        The offset estimate (status ``'ok'``, ``'weak'``, ``'edge'``, ``'ambiguous'`` or
        ``'fixed'`` when the caller gave the offset).
    offset_used_s
        The offset the comparison was made at [s].
    metrics
        Table-1 metrics of the summed power of ``axes`` (of a drive trace: its power
        equivalent ``q·g·omega``, :mod:`.quantity`).
    axis_metrics
        Table-1 metrics per axis of ``axes``.
    t
        Measured stamps [s], shape ``(n,)``, on the simulation's clock (``clock_ppm``).
    power_meas_w, power_sim_w
        Measured and aligned, interval-averaged simulated power [W], shape ``(n, len(axes))``;
        of a drive trace its power equivalent ``q·g·omega`` with the simulated ``omega``.
    sim_duration_s
        Length of the simulation [s].
    excluded_rows
        Data rows dropped by the manifest's row filter.
    stamp
        Where the instrument stamps its window: ``'end'``, ``'centre'`` or ``'start'``.
    instrument
        The meter in words (``'100 ms window stamped at its end (default)'``).
    meter_fits
        The declared meter and the alternatives, offsets refitted
        (:func:`.instrument.check_instrument`).
    states
        Residual of the total by motion state (:mod:`.states`).
    energy_sd_pct
        Standard uncertainty of the simulated energy of ``axes`` from the covariance of the
        loss parameters, % of that energy (:func:`..uncertainty.relative_sd_pct`; ``nan``
        when the machine config gives no ``loss_covariance`` for every axis).
    measures
        What the trace is (``instrument.measures``: a power kind, ``current``, ``torque``,
        ``force``; :mod:`.quantity`).
    signal_meas, signal_sim
        Measured and aligned simulated trace in its own SI unit, ``(n, len(axes))``.
    signal_metrics
        Per axis, the agreement in the trace's unit (:class:`.quantity.SignalMetrics`).
    torque_per_unit
        Per axis the gain ``g`` [N·m per unit] of a drive trace (``kt`` for current), else
        ``None``.
    sign_warnings
        Axes whose trace is anti-correlated with its prediction (the wrong sign).
    filter_s
        Time constant [s] of the meter's first-order smoothing the simulation was put
        through (:func:`.align.first_order_lag`; 0: none).
    work_offset
        A run simulated from its program whose data has positions: the translation from the
        simulated (program) to the measured (machine) positions at the time offset used
        (:mod:`.spatial`), else ``None``.
    clock_ppm
        The record's clock rate [ppm] the stamps ``t`` are corrected for
        (:func:`.align.clock_corrected`: timed by the measured motion, ``offset.drift_ppm``);
        0 when the stamps are the file's.
    step_error
        Per measured axis, the estimated RMS error that the simulation's sampling step puts
        into what the meter reads, in the trace's unit (:func:`.align.step_error_rms`; it
        shrinks with the square of the step, ``planner.rate_hz``).
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
    instrument: str = ''
    meter_fits: tuple[MeterFit, ...] = ()
    states: tuple[StateResidual, ...] = ()
    energy_sd_pct: float = math.nan
    measures: str = 'shaft'
    signal_meas: np.ndarray | None = field(default=None, repr=False)
    signal_sim: np.ndarray | None = field(default=None, repr=False)
    signal_metrics: dict[str, SignalMetrics] = field(default_factory=dict)
    torque_per_unit: dict[str, float] | None = None
    sign_warnings: tuple[str, ...] = ()
    work_offset: WorkOffset | None = None
    filter_s: float = 0.0
    clock_ppm: float = 0.0
    step_error: dict[str, float] = field(default_factory=dict)

    def quantity_dict(self) -> dict[str, Any]:
        """The ``quantity`` block of :meth:`to_dict` (docs/compare.md, "Measured quantity")."""
        qty = quantity_of(self.measures)
        out: dict[str, Any] = {
            'measures': qty.name, 'unit': qty.unit, 'column': qty.column,
            'metrics': {a: m.to_dict() for a, m in self.signal_metrics.items()},
            'sign_check': list(self.sign_warnings),
        }
        if self.torque_per_unit is not None:
            out['torque_per_unit'] = dict(self.torque_per_unit)
            out['power_equivalent'] = f'{qty.symbol}*g*omega'
            # energy-like figures of Table-1 style: the integral of |q·g·omega|
            meas = np.abs(self.power_meas_w)
            sim = np.abs(self.power_sim_w)
            out['abs_energy_j'] = {
                a: {'meas': float(np.trapezoid(meas[:, j], self.t)),
                    'sim': float(np.trapezoid(sim[:, j], self.t))}
                for j, a in enumerate(self.axes)}
        return out

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
        # the loss-function uncertainty only where it is known
        spread = ({'energy_sd_pct': self.energy_sd_pct} if math.isfinite(self.energy_sd_pct)
                  else {})
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
            'filter_s': self.filter_s,
            'clock_ppm': self.clock_ppm,
            'sim_step_error': dict(self.step_error),
            'instrument': self.instrument,
            'instrument_check': [f.to_dict() for f in self.meter_fits],
            'residual_by_state': [st.to_dict() for st in self.states],
            'offset': offset_dict(self.offset, used_s=self.offset_used_s),
            'work_offset': None if self.work_offset is None else self.work_offset.to_dict(),
            'metrics': metrics,
            'quantity': self.quantity_dict(),
        } | spread)


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
    signal_metrics
        Pooled metrics per axis in the trace's own unit (runs of one quantity only).
    """

    load_kg: float
    runs: tuple[str, ...]
    metrics: Metrics
    axis_metrics: dict[str, Metrics]
    signal_metrics: dict[str, SignalMetrics] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able summary; keys carry units, NaN becomes ``None``."""
        metrics = {TOTAL: self.metrics.to_dict()}
        metrics.update({a: m.to_dict() for a, m in self.axis_metrics.items()})
        return json_clean({'load_kg': self.load_kg, 'runs': list(self.runs),
                           'metrics': metrics,
                           'quantity_metrics': {a: m.to_dict()
                                                for a, m in self.signal_metrics.items()}})


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

    @property
    def instrument_warnings(self) -> list[str]:
        """One line per declared meter (runs grouped by it) that an alternative beats."""
        out = []
        by_meter: dict[str, list[RunComparison]] = {}
        for r in self.runs:
            if r.meter_fits:
                by_meter.setdefault(r.instrument, []).append(r)
        for meter, runs in by_meter.items():
            text = instrument_verdict([r.meter_fits for r in runs], describe=meter)
            if text is not None:
                out.append(f'{", ".join(r.name for r in runs)[:60]}: {text}')
        return out

    @property
    def residual_by_state(self) -> tuple[StateResidual, ...]:
        """Residual of the total by motion state, every run pooled."""
        return pool_states([r.states for r in self.runs])

    @property
    def sign_warnings(self) -> list[str]:
        """One line per run and axis whose drive trace has the wrong sign convention."""
        return [f'{r.name}: {w}' for r in self.runs for w in r.sign_warnings]

    @property
    def warnings(self) -> list[str]:
        """Offset, instrument and sign-convention warnings."""
        return self.offset_warnings + self.instrument_warnings + self.sign_warnings

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
            'residual_by_state': json_clean([st.to_dict() for st in self.residual_by_state]),
            'warnings': self.warnings,
        }
