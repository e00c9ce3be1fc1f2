"""Loss function and rotor inertia fitted to every moving sample (``fit-loss --method samples``).

The paper's fit (:mod:`.lossfit`) uses steady segments only: the mean power of stretches of
constant speed at least half a second long. A record sampled every 100 ms holds few such
stretches at high speed (a rapid cruises for one or two samples) and none of the starts and
stops, so the loss at rapid speeds is extrapolated and the inertia stays whatever the machine
config guessed. This fit uses every moving sample instead, each with the velocity ``v`` and
acceleration ``a`` the run's columns give at its stamp, and the model of
:mod:`..dynamics` and :mod:`..energy` at that instant (point samples):

``P = J·(2·pi/L)²·a·v + k·(m·a + m·g·sin(incl) + F_c·sgn(v) + c_v·v)·v``

with ``k = 1/eta`` when the motor drives the nut (``F·v >= 0``) and ``k = eta`` when it is
back-driven; ``J`` is the motor inertia plus the configured coupling and screw inertias, ``m``
the moved mass of the machine config and ``L`` the lead. Unknown and fitted, bounded at zero:
the Coulomb force ``F_c`` [N], the viscous coefficient ``c_v`` [N·s/m] (the loss model
:class:`..losses.CoulombViscousLoss`) and the motor inertia [kg·m²]. On a horizontal axis
with ``eta = 1`` the motor inertia also absorbs any error of the configured moved mass (both
multiply ``a·v``); the *effective mass* ``m + J·(2·pi/L)²`` is what the data determine.

The model is linear in the three unknowns once the drive direction of every sample is known:
that is taken from the previous estimate and the fit repeated until it no longer changes (a
few rounds; one when ``eta = 1``). With ``braking: dissipated`` a sample whose model power is
negative is left out (the meter reads zero whatever the force). The inertia is fitted only
when at least ``min_accel_samples`` samples accelerate by more than ``accel_m_s2``; otherwise
the configured one is kept and said so. Standard errors come from ``s²·(X'X)^-1`` of the last
linear fit (``s²``: residual variance over ``n - p`` degrees of freedom), ignoring the bounds.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
import math
from typing import Any, cast

import numpy as np
from scipy.optimize import lsq_linear

from ...machine import CalibratedRange, CoulombViscousLoss, LossCovariance, Machine, moved_mass_kg
from ...errors import ConfigError, DataError
from ...units import GRAVITY_M_S2
from ...measured import MeasuredRun
from .steady import kinematics, VELOCITY_SOURCES

__all__ = ['SampleFit', 'SampleFitOptions', 'fit_loss_samples', 'machine_with_sample_fits',
           'nonnegative_lsq']

_MAX_ROUNDS = 20
_MM_PER_M = 1000.0


@dataclass(frozen=True)
class SampleFitOptions:
    """Which samples enter the fit.

    Attributes
    ----------
    min_speed_m_s
        Samples slower than this [m/s] are standstill and left out.
    accel_m_s2
        Samples accelerating by more than this [m/s²] identify the inertia; slower ones make
        the calibrated feed range.
    min_samples
        Moving samples needed per axis.
    min_accel_samples
        Accelerating samples needed to fit the inertia (else the configured one is kept).
    fit_counterbalance
        A drive trace of an inclined axis: fit the weight the drive carries, as the
        counterbalance ``axes.<A>.counterbalance_n`` (a weight compensation, ``>= 0``) on top
        of the configured ``m·g·sin(incl)``, instead of taking the configured mass's weight
        as it is (:func:`.torquefit.fit_drive_samples`).
    """

    min_speed_m_s: float = 5.0e-4
    accel_m_s2: float = 0.05
    min_samples: int = 20
    min_accel_samples: int = 10
    fit_counterbalance: bool = False

    def __post_init__(self) -> None:
        for name in ('min_speed_m_s', 'accel_m_s2'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0.0):
                msg = f'expected a finite number >= 0, got {value!r}'
                raise ConfigError(msg, file='fit options', key=name)
        for name in ('min_samples', 'min_accel_samples'):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                msg = f'expected an integer >= 1, got {value!r}'
                raise ConfigError(msg, file='fit options', key=name)


@dataclass(frozen=True)
class SampleFit:
    """Loss function and motor inertia of one axis fitted to its samples.

    Attributes
    ----------
    axis, status, message
        ``status`` is ``'ok'`` or ``'insufficient'`` (too few moving samples).
    coulomb_n, viscous_n_s_m, motor_kg_m2
        Fitted Coulomb force [N], viscous coefficient [N·s/m] and motor inertia [kg·m²].
    coulomb_se, viscous_se, motor_se
        Their standard errors (``None`` where not fitted or no degree of freedom is left).
    inertia_fitted
        ``False`` when too few samples accelerate: ``motor_kg_m2`` is the configured one.
    effective_mass_kg
        ``m + J·(2·pi/L)²`` with the fitted inertia [kg] (what ``a·v`` is multiplied by).
    rmse_w, r2
        Residual RMS [W] and R² of the fitted samples' power.
    n_samples, n_accel
        Moving samples fitted, and those accelerating by more than ``accel_m_s2``.
    calibrated
        Speeds of the moving samples that do not accelerate, loads of the runs.
    cov_loss
        Covariance of ``(coulomb_n, viscous_n_s_m)`` [N², N²·s/m, N²·s²/m²] from the
        least-squares fit (``None`` where no degree of freedom is left).
    measures
        What the fitted trace is (``instrument.measures``); a drive trace (``current``,
        ``torque``, ``force``) is fitted by :func:`.torquefit.fit_drive_samples`.
    rmse, unit
        Residual RMS in the trace's unit, and the unit (``rmse_w`` holds it for power).
    gain, gain_se, gain_fitted
        A drive trace: torque per unit of the trace [N·m per unit] (``kt`` [N·m/A] for
        current), its standard error, and whether it was fitted (else declared).
    standstill_hold_n, n_rest, rest_rmse
        A drive trace: the force the drive holds after a stop, in the last direction of
        motion [N] (:mod:`feed_axis_energy.physics.standstill`; ``None`` when too few
        samples rest after a move), the resting samples it was fitted on, and their
        residual RMS in the trace's unit.
    counterbalance_n, counterbalance_se
        A drive trace of an inclined axis fitted with ``fit_counterbalance``: the weight
        compensation [N] (``axes.<A>.counterbalance_n``) and its standard error; else ``None``.
    """

    axis: str
    status: str
    message: str
    coulomb_n: float | None = None
    viscous_n_s_m: float | None = None
    motor_kg_m2: float | None = None
    coulomb_se: float | None = None
    viscous_se: float | None = None
    motor_se: float | None = None
    inertia_fitted: bool = False
    effective_mass_kg: float | None = None
    rmse_w: float | None = None
    r2: float | None = None
    n_samples: int = 0
    n_accel: int = 0
    calibrated: CalibratedRange | None = None
    cov_loss: tuple[tuple[float, float], tuple[float, float]] | None = None
    measures: str = 'shaft'
    rmse: float | None = None
    unit: str = 'W'
    gain: float | None = None
    gain_se: float | None = None
    gain_fitted: bool = False
    standstill_hold_n: float | None = None
    n_rest: int = 0
    rest_rmse: float | None = None
    counterbalance_n: float | None = None
    counterbalance_se: float | None = None

    @property
    def ok(self) -> bool:
        """``True`` when the fit can be used."""
        return self.status == 'ok'

    def covariance(self) -> LossCovariance | None:
        """Covariance of the loss parameters in the units of :meth:`loss` (``None`` if unknown).

        The block of ``(coulomb_n, viscous_n_s_m)`` in the least-squares covariance; the
        motor inertia's own uncertainty is not carried (it changes the inertia's energy, not
        the loss), and a coefficient held at its bound of 0 keeps the unbounded figure.
        """
        if not self.ok or self.cov_loss is None:
            return None
        units = self.loss().param_units()
        return LossCovariance.of(('coulomb_n', 'viscous_n_s_m'),
                                 (units['coulomb_n'], units['viscous_n_s_m']), self.cov_loss)

    def loss(self) -> CoulombViscousLoss:
        """The fitted loss model (``ValueError`` unless the status is ``'ok'``)."""
        if not self.ok:
            msg = f'axis {self.axis}: no usable fit ({self.status}: {self.message})'
            raise ValueError(msg)
        # the casts: an ok fit has both values
        return CoulombViscousLoss(coulomb_n=float(cast(float, self.coulomb_n)),
                                  viscous_n_s_m=float(cast(float, self.viscous_n_s_m)))

    def to_dict(self) -> dict[str, Any]:
        """Plain-type form (for JSON); keys carry units."""
        return {'axis': self.axis, 'status': self.status, 'message': self.message,
                'method': 'samples', 'model': CoulombViscousLoss.model,
                'coulomb_n': self.coulomb_n, 'coulomb_se': self.coulomb_se,
                'viscous_n_s_m': self.viscous_n_s_m, 'viscous_se': self.viscous_se,
                'motor_kg_m2': self.motor_kg_m2, 'motor_se': self.motor_se,
                'inertia_fitted': self.inertia_fitted,
                'effective_mass_kg': self.effective_mass_kg, 'rmse_w': self.rmse_w,
                'r2': self.r2, 'n_samples': self.n_samples, 'n_accel': self.n_accel,
                'calibrated': None if self.calibrated is None else self.calibrated.to_dict(),
                'cov_loss': None if self.cov_loss is None else [list(r) for r in self.cov_loss],
                'measures': self.measures, 'unit': self.unit, 'rmse': self.rmse,
                'torque_per_unit': self.gain, 'torque_per_unit_se': self.gain_se,
                'torque_per_unit_fitted': self.gain_fitted,
                'standstill_hold_n': self.standstill_hold_n, 'n_rest': self.n_rest,
                'rest_rmse': self.rest_rmse, 'counterbalance_n': self.counterbalance_n,
                'counterbalance_se': self.counterbalance_se}


@dataclass
class _Columns:
    """Every moving sample of one axis over the runs (1-D arrays of equal length)."""

    v: np.ndarray
    a: np.ndarray
    p: np.ndarray
    mass: np.ndarray
    loads: list[float]


def _collect(runs: Sequence[MeasuredRun], axis: str, machine: Machine,
             velocity: Sequence[str], options: SampleFitOptions) -> _Columns:
    vs, accs, ps, masses, loads = [], [], [], [], []
    for run, source in zip(runs, velocity):
        if axis not in run.power_axes or axis not in run.axes:
            continue
        vel, acc, _ = kinematics(run, source)
        j = run.axes.index(axis)
        v, a = vel[:, j], acc[:, j]
        p = run.power_w[:, run.power_axes.index(axis)]
        keep = np.abs(v) >= options.min_speed_m_s
        vs.append(v[keep])
        accs.append(a[keep])
        ps.append(p[keep])
        masses.append(np.full(int(keep.sum()), moved_mass_kg(machine, axis, run.load_kg)))
        loads.append(run.load_kg)
    cat = (lambda parts: np.concatenate(parts) if parts else np.zeros(0))
    return _Columns(cat(vs), cat(accs), cat(ps), cat(masses), loads)


def nonnegative_lsq(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Non-negative least squares and the (unbounded) covariance of the coefficients (the
    fits on every sample of power and of drive traces, :mod:`.torquefit`)."""
    sol = lsq_linear(x, y, bounds=(0.0, np.inf), method='bvls')
    coef = np.asarray(sol.x, dtype=float)
    n, k = x.shape
    cov = None
    if n > k:
        res = y - x @ coef
        xtx = x.T @ x
        if np.linalg.matrix_rank(xtx) == k:
            cov = float(res @ res) / (n - k) * np.linalg.inv(xtx)
    return coef, cov


def _fit_axis(cols: _Columns, *, axis: str, machine: Machine,
              options: SampleFitOptions) -> SampleFit:
    spec = machine.axis(axis)
    n = cols.v.size
    n_accel = int(np.count_nonzero(np.abs(cols.a) > options.accel_m_s2))
    if n < options.min_samples:
        msg = (f'{n} moving sample(s) (speed >= {1e3 * options.min_speed_m_s:g} mm/s); '
               f'need at least {options.min_samples}')
        return SampleFit(axis=axis, status='insufficient', message=msg, n_samples=n,
                         n_accel=n_accel)
    eta = spec.screw.efficiency
    to_rot = (2.0 * math.pi / spec.screw.lead_m) ** 2
    rest = spec.inertias.coupling_kg_m2 + spec.screw_inertia_kg_m2
    incl = math.sin(math.radians(spec.inclination_deg))
    v, a, p = cols.v, cols.a, cols.p
    rot = to_rot * a * v                                 # rotor power per kg·m² [W/(kg·m²)]
    known = (cols.mass * a + cols.mass * GRAVITY_M_S2 * incl) * v   # force power, no loss
    speed = np.abs(v)
    fit_inertia = n_accel >= options.min_accel_samples
    motor = spec.inertias.motor_kg_m2
    params = np.array([motor, 0.0, 0.0])
    use = np.ones(n, dtype=bool)
    cov = None
    drive = None
    for _ in range(_MAX_ROUNDS):
        force_power = known + params[1] * speed + params[2] * v * v
        new_drive = force_power >= 0.0
        k = np.where(new_drive, 1.0 / eta, eta)
        mech = (params[0] + rest) * rot + k * force_power
        new_use = mech >= 0.0 if machine.braking == 'dissipated' else use
        if drive is not None and np.array_equal(new_drive, drive) and np.array_equal(new_use,
                                                                                     use):
            break
        drive, use = new_drive, new_use
        y = p - rest * rot - k * known
        basis = [k * speed, k * v * v]
        if fit_inertia:
            basis.insert(0, rot)
        else:
            y = y - motor * rot
        x = np.column_stack(basis)[use]
        if x.shape[0] < options.min_samples:
            msg = (f'{x.shape[0]} moving sample(s) with positive model power (braking: '
                   f'dissipated reads 0 otherwise); need at least {options.min_samples}')
            return SampleFit(axis=axis, status='insufficient', message=msg, n_samples=n,
                             n_accel=n_accel)
        coef, cov = nonnegative_lsq(x, y[use])
        params = coef.copy() if fit_inertia else np.array([motor, *coef])
    force_power = known + params[1] * speed + params[2] * v * v
    k = np.where(force_power >= 0.0, 1.0 / eta, eta)
    model = (params[0] + rest) * rot + k * force_power
    if machine.braking == 'dissipated':
        model = np.maximum(model, 0.0)
    res = p - model
    ss_tot = float(np.sum((p - p.mean()) ** 2))
    r2 = 1.0 - float(res @ res) / ss_tot if ss_tot > 0.0 else 0.0
    se: list[float | None] = [None, None, None]
    cov_loss = None
    if cov is not None:
        diag: list[float | None] = [math.sqrt(max(float(c), 0.0)) for c in np.diag(cov)]
        se = diag if fit_inertia else [None, *diag]
        j = 1 if fit_inertia else 0
        block = np.asarray(cov, dtype=float)[j:j + 2, j:j + 2]
        block = 0.5 * (block + block.T)
        if np.all(np.isfinite(block)):
            cov_loss = ((float(block[0, 0]), float(block[0, 1])),
                        (float(block[1, 0]), float(block[1, 1])))
    steady = np.abs(a) <= options.accel_m_s2
    feeds = speed[steady] if steady.any() else speed
    calibrated = CalibratedRange(
        feed_mm_s=(float(feeds.min() * _MM_PER_M), float(feeds.max() * _MM_PER_M)),
        load_kg=(float(min(cols.loads)), float(max(cols.loads))) if cols.loads else None)
    mass = float(np.mean(cols.mass) + (params[0] + rest) * to_rot)
    how = ('inertia fitted' if fit_inertia else
           f'inertia kept as configured ({n_accel} samples accelerate by more than '
           f'{options.accel_m_s2:g} m/s^2, need {options.min_accel_samples})')
    msg = (f'{n} moving samples ({n_accel} accelerating), {how}; RMS residual '
           f'{math.sqrt(float(res @ res) / n):.3g} W, R^2 = {r2:.4f}')
    return SampleFit(axis=axis, status='ok', message=msg, coulomb_n=float(params[1]),
                     viscous_n_s_m=float(params[2]), motor_kg_m2=float(params[0]),
                     motor_se=se[0], coulomb_se=se[1], viscous_se=se[2],
                     inertia_fitted=fit_inertia, effective_mass_kg=mass,
                     rmse_w=math.sqrt(float(res @ res) / n), r2=r2, n_samples=n,
                     rmse=math.sqrt(float(res @ res) / n),
                     n_accel=n_accel, calibrated=calibrated, cov_loss=cov_loss)


def fit_loss_samples(runs: Sequence[MeasuredRun], *, machine: Machine,
                     axes: Sequence[str] | None = None,
                     velocity: str | Sequence[str] = 'auto',
                     options: SampleFitOptions = SampleFitOptions()) -> dict[str, SampleFit]:
    """Fit Coulomb + viscous loss and motor inertia per axis (see the module docstring).

    Parameters
    ----------
    runs
        Measured runs with power and velocity (or position) columns.
    machine
        Machine model: moved masses, screw, efficiency, inclination, braking rule.
    axes
        Axes to fit; default every axis with power in any run and in the machine.
    velocity
        Kinematics of every run (``'auto'``: commanded, else actual; ``'actual'``;
        ``'commanded'``), one for all runs or one per run.
    options
        Sample selection.

    Returns
    -------
    dict
        Axis name -> :class:`SampleFit`, in the order the axes first appear.

    Raises
    ------
    DataError
        A run without velocity or position columns for the chosen source.
    ConfigError
        An unknown velocity source or a count of sources that does not match the runs.
    """
    sources = [velocity] * len(runs) if isinstance(velocity, str) else list(velocity)
    if len(sources) != len(runs) or any(s not in VELOCITY_SOURCES for s in sources):
        msg = (f'expected one of {", ".join(VELOCITY_SOURCES)} for every run, got '
               f'{sources!r:.60}')
        raise ConfigError(msg, file='fit options', key='velocity')
    if axes is None:
        names: list[str] = []
        for run in runs:
            names.extend(a for a in run.power_axes if a not in names)
        names = [a for a in names if a in machine.axis_names]
    else:
        names = list(axes)
    out = {}
    for axis in names:
        if axis not in machine.axis_names:
            raise DataError(f'machine {machine.name!r} has no axis {axis!r}', file='fit-loss')
        cols = _collect(runs, axis, machine, sources, options)
        out[axis] = _fit_axis(cols, axis=axis, machine=machine, options=options)
    return out


def machine_with_sample_fits(machine: Machine, fits: dict[str, SampleFit]) -> Machine:
    """Return ``machine`` with every ``'ok'`` axis's loss, calibrated range and inertia replaced.

    Parameters
    ----------
    machine
        The machine.
    fits
        Axis name -> fit; other statuses leave the axis unchanged.

    Returns
    -------
    Machine
        A new machine.
    """
    axes = []
    for a in machine.axes:
        f = fits.get(a.name)
        if f is not None and f.ok:
            a = replace(a, loss=f.loss(), loss_calibrated=f.calibrated,
                        loss_covariance=f.covariance(),
                        inertias=replace(a.inertias,
                                         motor_kg_m2=float(cast(float, f.motor_kg_m2))))
            if f.standstill_hold_n is not None:
                a = replace(a, standstill_hold_n=float(f.standstill_hold_n))
            if f.counterbalance_n is not None:
                a = replace(a, counterbalance_n=float(f.counterbalance_n))
            if f.gain_fitted and f.measures == 'current' and a.drive is not None:
                # a fitted torque constant replaces the data sheet's
                a = replace(a, drive=replace(a.drive, kt_nm_a=float(cast(float, f.gain))))
        axes.append(a)
    return replace(machine, axes=tuple(axes))
