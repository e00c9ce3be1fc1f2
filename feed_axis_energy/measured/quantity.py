"""What a measured trace is: power, current, torque or force, each with its unit and conversion.

A campaign's ``instrument.measures`` names the quantity every run's trace holds
(:data:`QUANTITIES`). The three power kinds are compared with the simulated power in W; the
others are compared in their own unit with a prediction from the motor torque ``M`` of the
dynamics (:mod:`feed_axis_energy.physics.dynamics`):

=========  ======  ======================  =============================================
measures   unit    manifest column         prediction per axis
=========  ======  ======================  =============================================
shaft      W       ``power``               ``M·omega`` after the braking rule
motor      W       ``power``               electrical power at the motor terminals
supply     W       ``power``               electrical power at the drive's supply side
current    A       ``current``             ``I = M / kt`` (signed, torque-producing)
torque     N·m     ``torque``              ``M`` (motor shaft)
force      N       ``force``               ``F = M·2·pi/lead`` (the actuator's force)
=========  ======  ======================  =============================================

Each non-power quantity ``q`` is the motor torque divided by a *gain* ``g`` [N·m per unit of
``q``] (:func:`torque_per_unit`): the torque constant ``kt`` [N·m/A] for current (declared per
axis in the machine file, ``axes.<A>.drive.kt_nm_a``, or in the manifest,
``instrument.kt_nm_a.<A>``), 1 for torque, ``lead/(2·pi)`` [m] for force. So ``q·g·omega`` is
a power [W] (for current ``I·kt·omega``), which ``compare`` reports as Table-1 metrics beside
the metrics in the measured unit.

Force on a linear test stand: with the rotary inertias 0 and the screw efficiency 1,
``M·2·pi/lead`` is the axis force ``m·a + m·g·sin(incl) + F_loss(v)`` of the dynamics,
whatever lead the machine file gives; a real screw adds the rotor's inertia as equivalent
mass, as a force computed from the motor's output does. A holding torque (a vertical axis at
rest) is part of ``M``: the prediction is not zero at standstill. Declared effects, which the
catalog gives as powers, enter the prediction as ``P_effect/omega`` while the axis moves; at
rest only the constant forces along the axis (:data:`HELD_EFFECTS`: ``offset_force``'s
``F0`` and ``gravity``'s ``m·g·sin(theta)``, which pull at rest as in motion, as ``analyze``
fits them on a drive trace), the others nothing. At rest the prediction adds the force the
drive keeps holding after a stop, in the last direction of motion
(``axes.<A>.standstill_hold_n``,
:mod:`feed_axis_energy.physics.standstill`), which ``fit-loss --method samples`` fits; on such
an axis the held force replaces the kinetic friction at rest (``|v| <= REST_SPEED_M_S``:
static friction holds it; ``F_c·sgn(v)`` of a measured velocity's noise would jump by
``2·F_c`` from sample to sample; on the KIT DMC 60H air cut it was most of the residual).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
import math
from typing import Any, TYPE_CHECKING

import numpy as np

from ..errors import ConfigError, DataError
from ..physics import AxisDynamics, holding_force, HoldState, REST_SPEED_M_S
from ..units import GRAVITY_M_S2
from .metrics import CHUNK

if TYPE_CHECKING:       # types only: the manifest reader imports this module, not the simulation
    from ..machine import Machine
    from ..sim import SimulationResult

__all__ = ['Quantity', 'QUANTITIES', 'MEASURES', 'POWER_MEASURES', 'SignalMetrics',
           'quantity_of', 'measured_signal', 'torque_per_unit', 'predicted_signal',
           'omega_columns', 'signal_metrics', 'pool_signal_metrics', 'sign_warnings',
           'ANTI_CORRELATION', 'HELD_EFFECTS']

_OMEGA_EPS = 1.0e-9     # rad/s: below this an axis is at rest (no power -> torque)
ANTI_CORRELATION = -0.3
"""A measured trace whose correlation with its prediction is below this has the wrong sign."""
HELD_EFFECTS = ('offset_force', 'gravity')
"""Declared effects that are a constant force along the axis, at rest as in motion."""


@dataclass(frozen=True)
class Quantity:
    """One measurable quantity of a feed axis.

    Attributes
    ----------
    name
        The value of ``instrument.measures``.
    column
        The manifest's per-axis column key the trace is read from.
    unit
        SI unit, as shown to users.
    key
        Unit suffix of JSON keys (``rmse_a``, ``bias_nm``).
    symbol
        Letter in formulas (``P``, ``I``, ``M``, ``F``).
    words
        What it is, in a few words.
    """

    name: str
    column: str
    unit: str
    key: str
    symbol: str
    words: str

    @property
    def is_power(self) -> bool:
        """The trace is a power (compared as such, no conversion)."""
        return self.column == 'power'

    @property
    def run_field(self) -> str:
        """Key of the trace in ``MeasuredRun.extra`` (non-power quantities)."""
        return f'{self.column}_{self.key}'


QUANTITIES: dict[str, Quantity] = {
    'shaft': Quantity('shaft', 'power', 'W', 'w', 'P', 'shaft power M·omega'),
    'motor': Quantity('motor', 'power', 'W', 'w', 'P', 'electrical power at the motor'),
    'supply': Quantity('supply', 'power', 'W', 'w', 'P', 'electrical power at the supply side'),
    'current': Quantity('current', 'current', 'A', 'a', 'I', 'torque-producing motor current'),
    'torque': Quantity('torque', 'torque', 'N·m', 'nm', 'M', 'motor shaft torque'),
    'force': Quantity('force', 'force', 'N', 'n', 'F', 'actuator force on the axis'),
}
MEASURES = tuple(QUANTITIES)
"""Values of ``instrument.measures``."""
POWER_MEASURES = tuple(k for k, q in QUANTITIES.items() if q.is_power)


def quantity_of(measures: str) -> Quantity:
    """The :class:`Quantity` of an ``instrument.measures`` value (``KeyError`` if unknown)."""
    return QUANTITIES[measures]


def measured_signal(run: Any, *, measures: str, axes: Sequence[str],
                    invert: Sequence[str] = ()) -> np.ndarray:
    """The measured trace of ``axes``, ``(n, len(axes))`` in SI, sign-corrected.

    Parameters
    ----------
    run
        A :class:`~.run.MeasuredRun`.
    measures
        What the trace is (:data:`MEASURES`).
    axes
        Axes with a column of that quantity.
    invert
        Axes whose trace counts the other way (``instrument.invert``): negated.

    Returns
    -------
    numpy.ndarray
        A new array; or, when the trace is the run's own power columns as they are, a
        read-only view of them (a long run is not copied).

    Raises
    ------
    DataError
        An axis without the trace.
    """
    q = quantity_of(measures)
    if q.is_power:
        cols = [run.power_w[:, run.power_axes.index(a)] if a in run.power_axes else None
                for a in axes]
    else:
        got = run.extra.get(q.run_field, {})
        cols = [got.get(a) for a in axes]
    missing = [a for a, c in zip(axes, cols) if c is None]
    if missing:
        msg = f'run {run.name!r} has no {q.column} column for axis {missing[0]}'
        raise DataError(msg, file=run.file)
    if (q.is_power and axes and not any(a in invert for a in axes)
            and isinstance(run.power_w, np.ndarray) and run.power_w.dtype == np.float64):
        index = [run.power_axes.index(a) for a in axes]
        if index == list(range(index[0], index[0] + len(index))):
            # the run's own columns: a read-only view, no copy of a long run
            view = run.power_w[:, index[0]:index[0] + len(index)]
            view.flags.writeable = False
            return view
    out = np.column_stack([np.asarray(c, dtype=float) for c in cols])
    for j, a in enumerate(axes):
        if a in invert:
            out[:, j] = -out[:, j]
    return out


def torque_per_unit(measures: str, machine: Machine, axes: Sequence[str], *,
                    declared_kt: Mapping[str, float] | None = None, manifest: str = '<manifest>',
                    key: str = '', required: bool = True) -> list[float | None]:
    """The gain ``g`` [N·m per unit] of every axis: measured ``q = M/g``.

    Parameters
    ----------
    measures
        A non-power quantity (:data:`MEASURES`).
    machine
        The machine (torque constants of its drives, screw leads).
    axes
        The measured axes.
    declared_kt
        ``instrument.kt_nm_a`` of the manifest (wins over the machine file).
    manifest, key
        Name the manifest and the run's key in errors.
    required
        A current trace without a torque constant is an error (else ``None``: to be fitted).

    Returns
    -------
    list of float or None
        Per axis.

    Raises
    ------
    ConfigError
        A current trace of an axis without a torque constant (naming both keys that declare
        it), or an axis the machine lacks.
    """
    q = quantity_of(measures)
    out: list[float | None] = []
    for a in axes:
        if a not in machine.axis_names:
            msg = f'measured axis {a!r} is not an axis of machine {machine.name!r} ' \
                  f'{machine.axis_names}'
            raise ConfigError(msg, file=manifest, key=f'{key}.axes.{a}' if key else 'axes')
        spec = machine.axis(a)
        if q.name == 'torque':
            out.append(1.0)
        elif q.name == 'force':
            out.append(spec.screw.lead_m / (2.0 * math.pi))
        elif q.name == 'current':
            kt = (declared_kt or {}).get(a)
            if kt is None and spec.drive is not None:
                kt = spec.drive.kt_nm_a
            if kt is None and required:
                where = f'{key}.instrument.kt_nm_a.{a}' if key else f'instrument.kt_nm_a.{a}'
                msg = (f'axis {a} is measured in current, but no torque constant is known: add '
                       f'axes.{a}.drive.kt_nm_a [N·m/A] to the machine config '
                       f'({machine.name!r}) or {where} to the manifest (or fit it: '
                       'fit-loss --method samples)')
                raise ConfigError(msg, file=manifest, key=where)
            out.append(None if kt is None else float(kt))
        else:
            msg = f'{q.name} is a power; it has no torque gain'
            raise ConfigError(msg, file=manifest, key=f'{key}.instrument.measures')
    return out


def omega_columns(sim: SimulationResult, axes: Sequence[str]) -> np.ndarray:
    """Simulated screw (motor) speed [rad/s] of ``axes``, ``(m, k)``; axes not moved are 0."""
    dyn = sim.dynamics
    m = dyn.t.shape[0]
    return np.column_stack([dyn.omega_rad_s[:, dyn.axes.index(a)] if a in dyn.axes
                            else np.zeros(m) for a in axes])


def _effects_torque(sim: SimulationResult, j: int) -> np.ndarray | None:
    """Declared effects of axis column ``j`` as torque ``P/omega`` while moving [N·m]."""
    parts = sim.power.effect_power_w
    if not parts:
        return None
    extra = np.zeros(sim.power.t.shape[0])
    for _label, part in parts:
        extra += part[:, j]
    omega = sim.dynamics.omega_rad_s[:, j]
    moving = np.abs(omega) > _OMEGA_EPS
    out = np.zeros_like(extra)
    np.divide(extra, omega, out=out, where=moving)
    return out


def _held_effect_force(machine: Machine, axis: str, mass_kg: float) -> float:
    """The constant force [N] of the declared :data:`HELD_EFFECTS` on ``axis`` (moved mass
    ``mass_kg``), which acts at rest too."""
    total = 0.0
    for e in machine.effects:
        if e.axis not in (None, axis) or e.id not in HELD_EFFECTS:
            continue
        values = e.values
        if e.id == 'offset_force':
            total += float(values.get('f0_n', 0.0))
        else:
            total += float(values.get('sin_theta', 0.0)) * mass_kg * GRAVITY_M_S2
    return total


def _loss_torque(dyn: AxisDynamics, j: int) -> np.ndarray:
    """The part of axis ``j``'s screw torque that overcomes its loss force [N·m], ``(n,)``.

    The screw efficiency as in the dynamics: ``F·r/eta`` where the motor drives the nut
    (``F·v >= 0`` for the total force), ``F·r·eta`` where it is driven back.
    """
    r = float(dyn.lead_m[j]) / (2.0 * math.pi)
    eta = float(dyn.efficiency[j])
    loss = dyn.loss_force_n[:, j]
    drives = dyn.force_n[:, j] * dyn.velocity_m_s[:, j] >= 0.0
    return np.where(drives, loss * r / eta, loss * r * eta)


def _power_columns(measures: str, sim: SimulationResult, machine: Machine,
                   axes: Sequence[str], *, manifest: str, key: str) -> np.ndarray:
    p = sim.power
    source = p.power_w
    if measures != 'shaft':
        if p.electrical is None:
            msg = (f'the meter measures {measures} power, but machine {machine.name!r} '
                   'declares no motors and drives (axes.<A>.drive, docs/electrical.md)')
            raise ConfigError(msg, file=manifest, key=f'{key}.instrument.measures')
        source = p.electrical.motor_w if measures == 'motor' else p.electrical.supply_w
    cols = []
    for axis in axes:
        if axis in p.axes:
            cols.append(source[:, p.axes.index(axis)])
        elif axis in machine.axis_names:
            # An axis that never moves has omega = 0, hence zero actual power (eq. 1).
            cols.append(np.zeros(p.t.shape[0]))
        else:
            msg = (f'measured axis {axis!r} is not an axis of machine {machine.name!r} '
                   f'{machine.axis_names}')
            raise ConfigError(msg, file=manifest, key=f'{key}.axes.{axis}')
    return np.column_stack(cols)


def predicted_signal(measures: str, sim: SimulationResult, machine: Machine,
                     axes: Sequence[str], *, gains: Sequence[float | None] | None = None,
                     manifest: str = '<manifest>', key: str = '',
                     start_direction: Mapping[str, float] | None = None) -> np.ndarray:
    """The simulated trace of ``axes`` in the quantity's SI unit, ``(m, k)`` on ``sim``'s times.

    Parameters
    ----------
    measures
        What the trace is (:data:`MEASURES`).
    sim
        The simulation of the run.
    machine
        The machine simulated.
    axes
        The measured axes.
    gains
        :func:`torque_per_unit` of the axes (non-power quantities; ``None`` entries are
        not allowed here).
    manifest, key
        Name the manifest and the run in errors.
    start_direction
        Axis -> the direction (-1, 0, +1) it last moved in before the first sample (a window
        of a longer record, ``extra['direction_before']`` of a measured run): what the drive
        holds at rest until the axis moves (:mod:`feed_axis_energy.physics.standstill`);
        default 0 (nothing held before the first move).

    Raises
    ------
    ConfigError
        Electrical power without declared drives, an axis the machine lacks, a gain missing.
    """
    if quantity_of(measures).is_power:
        return _power_columns(measures, sim, machine, axes, manifest=manifest, key=key)
    if gains is None or any(g is None for g in gains):
        msg = f'{measures}: every measured axis needs its torque gain'
        raise ConfigError(msg, file=manifest, key=f'{key}.instrument')
    dyn = sim.dynamics
    m = dyn.t.shape[0]
    cols = []
    for axis, g in zip(axes, gains):
        if axis not in dyn.axes:
            if axis not in machine.axis_names:
                msg = (f'measured axis {axis!r} is not an axis of machine {machine.name!r} '
                       f'{machine.axis_names}')
                raise ConfigError(msg, file=manifest, key=f'{key}.axes.{axis}')
            msg = (f'axis {axis} has a {measures} trace but is not in the simulated motion; '
                   'its torque (a holding torque too) cannot be predicted')
            raise ConfigError(msg, file=manifest, key=f'{key}.axes.{axis}')
        j = dyn.axes.index(axis)
        torque = dyn.torque_nm[:, j].copy()
        extra = _effects_torque(sim, j)
        if extra is not None:
            torque += extra
            held = _held_effect_force(machine, axis, float(dyn.mass_kg[j]))
            if held != 0.0:
                still = np.abs(dyn.omega_rad_s[:, j]) <= _OMEGA_EPS
                torque[still] += held * float(dyn.lead_m[j]) / (2.0 * math.pi)
        hold = machine.axis(axis).standstill_hold_n
        if hold > 0.0:
            # at rest friction is static: the drive holds the force it kept after the stop
            # (physics/standstill.py) instead of the kinetic F_c·sgn(v) of a velocity's noise
            rest = np.abs(dyn.velocity_m_s[:, j]) <= REST_SPEED_M_S
            torque[rest] -= _loss_torque(dyn, j)[rest]
            before = (start_direction or {}).get(axis, 0.0)
            state = HoldState(direction=np.array([before], dtype=float))
            torque += (holding_force(dyn.velocity_m_s[:, j], hold, state=state)[:, 0]
                       * float(dyn.lead_m[j]) / (2.0 * math.pi))
        cols.append(torque / float(g))       # type: ignore[arg-type]  # checked above
    return np.column_stack(cols) if cols else np.zeros((m, 0))


@dataclass(frozen=True)
class SignalMetrics:
    """Agreement of a predicted with a measured trace, in the trace's own unit.

    Attributes
    ----------
    unit, key
        The unit (``'A'``) and its JSON-key suffix (``'a'``).
    n_samples
        Samples compared.
    rmse, mae, max_abs_error
        RMS, mean and largest ``|q_meas - q_sim|``.
    bias
        Mean of ``q_sim - q_meas`` (positive: the model predicts too much).
    r2
        ``1 - SS_res/SS_tot`` of the measured trace about its mean (pooled: sums over runs,
        each about its own mean); NaN for a constant trace.
    correlation
        Pearson correlation of measured and predicted (NaN for a constant one; pooled: the
        sample-weighted mean).
    rms_meas
        RMS of the measured trace.
    ss_res, ss_tot
        Sums of squares behind ``r2`` (kept for pooling).
    """

    unit: str
    key: str
    n_samples: int
    rmse: float
    mae: float
    max_abs_error: float
    bias: float
    r2: float
    correlation: float
    rms_meas: float
    ss_res: float
    ss_tot: float

    def to_dict(self) -> dict[str, float | int | str]:
        """Plain dict; keys carry the unit suffix (``rmse_a``, ``bias_nm``)."""
        k = self.key
        return {'unit': self.unit, 'n_samples': self.n_samples, f'rmse_{k}': self.rmse,
                f'mae_{k}': self.mae, f'max_abs_error_{k}': self.max_abs_error,
                f'bias_{k}': self.bias, 'r2': self.r2, 'correlation': self.correlation,
                f'rms_meas_{k}': self.rms_meas}


def signal_metrics(meas: np.ndarray, sim: np.ndarray, *, quantity: Quantity) -> SignalMetrics:
    """Metrics of one aligned column pair ``(n,)`` (see :class:`SignalMetrics`).

    Raises
    ------
    DataError
        Shapes differ, fewer than 2 samples or a value that is not finite.
    """
    meas = np.asarray(meas, dtype=float)
    sim = np.asarray(sim, dtype=float)
    if meas.shape != sim.shape or meas.ndim != 1 or meas.size < 2:
        msg = f'expected two equal (n,) arrays, n >= 2; got {meas.shape} and {sim.shape}'
        raise DataError(msg, file='<metrics>')
    n = meas.size
    # two passes of bounded chunks (a long run's temporaries are a chunk, not the run): the
    # means, then the sums about them
    sum_m = sum_s = 0.0
    for a in range(0, n, CHUNK):
        m, s = meas[a:a + CHUNK], sim[a:a + CHUNK]
        if not (np.isfinite(m).all() and np.isfinite(s).all()):
            raise DataError('a value is not finite', file='<metrics>')
        sum_m += float(m.sum())
        sum_s += float(s.sum())
    mean_m, mean_s = sum_m / n, sum_s / n
    ss_res = bias = mae = max_abs = ss_tot = ss_sim = cross = ss_meas = 0.0
    for a in range(0, n, CHUNK):
        m, s = meas[a:a + CHUNK], sim[a:a + CHUNK]
        err = s - m
        ss_res += float(err @ err)
        bias += float(err.sum())
        np.abs(err, out=err)
        mae += float(err.sum())
        max_abs = max(max_abs, float(err.max()))
        ss_meas += float(m @ m)
        dm, ds = m - mean_m, s - mean_s
        ss_tot += float(dm @ dm)
        ss_sim += float(ds @ ds)
        cross += float(dm @ ds)
    den = math.sqrt(ss_tot * ss_sim)
    return SignalMetrics(
        unit=quantity.unit, key=quantity.key, n_samples=int(n),
        rmse=math.sqrt(ss_res / n), mae=mae / n, max_abs_error=max_abs, bias=bias / n,
        r2=1.0 - ss_res / ss_tot if ss_tot > 0.0 else math.nan,
        correlation=cross / den if den > 0.0 else math.nan,
        rms_meas=math.sqrt(ss_meas / n), ss_res=ss_res, ss_tot=ss_tot)


def pool_signal_metrics(items: Sequence[SignalMetrics]) -> SignalMetrics:
    """Pool runs as if their samples were concatenated (each ``r2`` term about its own mean).

    Raises
    ------
    DataError
        No runs.
    """
    if not items:
        raise DataError('no runs to pool', file='<metrics>')
    n = sum(m.n_samples for m in items)
    ss_res = sum(m.ss_res for m in items)
    ss_tot = sum(m.ss_tot for m in items)
    corr = [(m.n_samples, m.correlation) for m in items if math.isfinite(m.correlation)]
    return SignalMetrics(
        unit=items[0].unit, key=items[0].key, n_samples=n, rmse=math.sqrt(ss_res / n),
        mae=sum(m.n_samples * m.mae for m in items) / n,
        max_abs_error=max(m.max_abs_error for m in items),
        bias=sum(m.n_samples * m.bias for m in items) / n,
        r2=1.0 - ss_res / ss_tot if ss_tot > 0.0 else math.nan,
        correlation=(sum(w * c for w, c in corr) / sum(w for w, _ in corr) if corr
                     else math.nan),
        rms_meas=math.sqrt(sum(m.n_samples * m.rms_meas ** 2 for m in items) / n),
        ss_res=ss_res, ss_tot=ss_tot)


def sign_warnings(metrics: Mapping[str, SignalMetrics], *, quantity: Quantity,
                  invert: Sequence[str] = ()) -> list[str]:
    """One sentence per axis whose trace is anti-correlated with its prediction.

    A correlation below :data:`ANTI_CORRELATION` means the trace counts the other way than
    the model (``+`` driving the axis in its positive direction): the fix is
    ``instrument.invert`` in the manifest (or taking it out, when it is there).
    """
    out = []
    for axis, m in metrics.items():
        if math.isfinite(m.correlation) and m.correlation < ANTI_CORRELATION:
            fix = (f'remove {axis} from instrument.invert' if axis in invert
                   else f'declare instrument.invert: [{axis}] in the manifest')
            out.append(f'{axis}: the measured {quantity.name} is anti-correlated with the '
                       f'prediction (r = {m.correlation:+.2f}): its sign convention is the '
                       f'opposite of the model\'s; {fix}')
    return out
