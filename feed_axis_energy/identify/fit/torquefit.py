"""Loss, inertia and torque constant fitted to every moving sample of a drive trace.

``fit-loss --method samples`` on a campaign whose instrument measures ``current``, ``torque``
or ``force`` (:mod:`feed_axis_energy.measured.quantity`): the trace ``q`` of an axis is its
motor torque divided by a gain ``g`` [N·m per unit of ``q``] (the torque constant ``kt`` for
current, 1 for torque, ``lead/(2·pi)`` for force), and the motor torque of the dynamics
(:mod:`feed_axis_energy.physics.dynamics`) at each sample, with the velocity ``v`` and
acceleration ``a`` of the run's columns, is

``M = J·alpha + k·r·(m·a + m·g0·sin(incl) + F_c·sgn(v) + c_v·v)``

with ``r = lead/(2·pi)``, ``alpha = a/r``, ``k = 1/eta`` when the motor drives the nut and
``eta`` when it is back-driven, ``J`` the motor plus the configured coupling and screw
inertias and ``m`` the configured moved mass. Fitted, bounded at zero:

* gain known (declared ``kt``; torque; force): ``q·g = M`` is linear in the motor inertia,
  ``F_c`` and ``c_v``, as :mod:`.samplefit` does it for power (the inertia only when at
  least ``min_accel_samples`` samples accelerate);
* current without a torque constant: ``q = M/kt`` is linear in ``1/kt``, ``F_c/kt`` and
  ``c_v/kt`` once the motor inertia is taken as configured (the scale of ``M`` then comes
  from the configured masses and inertias: ``kt`` and an unknown inertia cannot be told
  apart, so the inertia is not fitted). ``kt`` and the loss follow by division, their
  standard errors by the delta method.

The drive direction of every sample comes from the previous estimate (a few rounds; one
when ``eta = 1``). The braking rule does not enter: a current or torque is what it is
whether the drive returns the braking energy or burns it. Standstill samples (slower than
``min_speed_m_s``) are left out of that fit: static friction takes any value up to ``F_c``
there. From them (at least :data:`REST_GUARD_S` from any motion) the force the drive holds
after a stop is fitted: ``q·g = r·m·g0·sin(incl)/eta + h·r·d`` with ``d`` the direction of the
last move and ``h >= 0`` (:mod:`feed_axis_energy.physics.standstill`); ``fit-loss
--out-machine`` writes it as ``axes.<A>.standstill_hold_n``.

Before fitting, the trace is correlated with the configured model's torque: a trace that
runs against it (correlation below :data:`~feed_axis_energy.measured.quantity.ANTI_CORRELATION`)
has the opposite sign convention, and the axis gets the status ``'wrong_sign'`` with a message
that names ``instrument.invert`` instead of a fit that would hold every parameter at its bound.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
import math

import numpy as np

from ...errors import ConfigError, DataError
from ...machine import CalibratedRange, Machine, moved_mass_kg
from ...measured import MeasuredRun, measured_signal, quantity_of
from ...physics import last_direction
from ...units import GRAVITY_M_S2
from .samplefit import nonnegative_lsq, SampleFit, SampleFitOptions
from .steady import kinematics, VELOCITY_SOURCES

__all__ = ['fit_drive_samples', 'WRONG_SIGN']

WRONG_SIGN = -0.3
"""Correlation of trace and configured model below which the trace has the wrong sign."""
_MAX_ROUNDS = 20
REST_GUARD_S = 0.02
"""A resting sample for the standstill hold is this far from any moving sample [s]."""
_MM_PER_M = 1000.0


def _collect(runs: Sequence[MeasuredRun], axis: str, machine: Machine, measures: str,
             velocity: Sequence[str], invert: Sequence[Sequence[str]],
             options: SampleFitOptions) -> tuple[np.ndarray, ...] | None:
    column = quantity_of(measures).run_field
    vs, accs, qs, masses, loads = [], [], [], [], []
    dirs, q_rest, m_rest = [], [], []
    for run, source, inv in zip(runs, velocity, invert):
        if axis not in run.extra.get(column, {}) or axis not in run.axes:
            continue
        vel, acc, _ = kinematics(run, source)
        j = run.axes.index(axis)
        v, a = vel[:, j], acc[:, j]
        q = measured_signal(run, measures=measures, axes=[axis], invert=inv)[:, 0]
        keep = np.abs(v) >= options.min_speed_m_s
        mass = moved_mass_kg(machine, axis, run.load_kg)
        vs.append(v[keep])
        accs.append(a[keep])
        qs.append(q[keep])
        masses.append(np.full(int(keep.sum()), mass))
        loads.append(run.load_kg)
        # resting samples after a move, with the direction of that move (physics/standstill)
        d = last_direction(v, rest_speed=options.min_speed_m_s)[:, 0]
        # at rest for REST_GUARD_S on both sides: the last creep of a stop is still friction
        dt = float(np.median(np.diff(run.t))) if run.t.size > 1 else 1.0
        guard = max(1, int(round(REST_GUARD_S / dt)))
        near = np.convolve(keep.astype(float), np.ones(2 * guard + 1), mode='same') > 0.0
        rest = ~near & (d != 0.0) & (np.abs(a) <= options.accel_m_s2)
        dirs.append(d[rest])
        q_rest.append(q[rest])
        m_rest.append(np.full(int(rest.sum()), mass))
    if not loads:
        return None
    return (np.concatenate(vs), np.concatenate(accs), np.concatenate(qs),
            np.concatenate(masses), np.array(loads), np.concatenate(dirs),
            np.concatenate(q_rest), np.concatenate(m_rest))


def _se(cov: np.ndarray | None, i: int) -> float | None:
    return None if cov is None else math.sqrt(max(float(cov[i, i]), 0.0))


def _fit_axis(cols: tuple[np.ndarray, ...], *, axis: str, machine: Machine, measures: str,
              gain: float | None, options: SampleFitOptions) -> SampleFit:
    v, a, q, mass, loads, d_rest, q_rest, m_rest = cols
    qty = quantity_of(measures)
    spec = machine.axis(axis)
    n = v.size
    n_accel = int(np.count_nonzero(np.abs(a) > options.accel_m_s2))

    def failed(status: str, message: str) -> SampleFit:
        return SampleFit(axis=axis, status=status, message=message, n_samples=n,
                         n_accel=n_accel, measures=measures, unit=qty.unit, gain=gain,
                         gain_fitted=gain is None)

    if n < options.min_samples:
        return failed('insufficient', f'{n} moving sample(s) (speed >= '
                      f'{1e3 * options.min_speed_m_s:g} mm/s); need at least '
                      f'{options.min_samples}')
    eta = spec.screw.efficiency
    r = spec.screw.lead_m / (2.0 * math.pi)
    alpha = a / r
    rest = spec.inertias.coupling_kg_m2 + spec.screw_inertia_kg_m2
    motor = spec.inertias.motor_kg_m2
    sin_incl = math.sin(math.radians(spec.inclination_deg))
    # the weight the drive carries: fitted (a counterbalance against the configured mass's
    # weight) or as configured (its counterbalance included)
    fit_balance = options.fit_counterbalance and sin_incl != 0.0
    weight = mass * GRAVITY_M_S2 * sin_incl
    if not fit_balance and spec.counterbalance_n:
        weight = weight - math.copysign(spec.counterbalance_n, sin_incl)
    known = mass * a + weight
    sgn = np.sign(v)
    normal = mass * GRAVITY_M_S2 * abs(math.cos(math.radians(spec.inclination_deg)))
    # the configured model's torque: the sign check
    f_cfg = known - np.asarray(spec.loss.force_n(v, normal_force_n=normal), dtype=float)
    k_cfg = np.where(f_cfg * v >= 0.0, 1.0 / eta, eta)
    m_cfg = (motor + rest) * alpha + k_cfg * r * f_cfg
    if np.std(q) > 0.0 and np.std(m_cfg) > 0.0:
        corr = float(np.corrcoef(q, m_cfg)[0, 1])
        if corr < WRONG_SIGN:
            msg = (f'the measured {measures} of axis {axis} runs against the model torque '
                   f'(correlation {corr:+.2f} over {n} moving samples): the trace counts the '
                   f'other way; declare instrument.invert: [{axis}] in the manifest')
            return failed('wrong_sign', msg)
    fit_inertia = gain is not None and n_accel >= options.min_accel_samples
    coulomb = viscous = 0.0
    inertia = motor
    theta0 = 1.0 / gain if gain is not None else 1.0
    drive = None
    cov = None
    coef = np.zeros(3)
    balance = 0.0
    up = math.copysign(1.0, sin_incl)      # the counterbalance pushes against the weight
    for _ in range(_MAX_ROUNDS):
        force = known - up * balance + coulomb * sgn + viscous * v
        new_drive = force * v >= 0.0
        if drive is not None and np.array_equal(new_drive, drive):
            break
        drive = new_drive
        k = np.where(drive, 1.0 / eta, eta)
        if gain is not None:
            y = q * gain - rest * alpha - k * r * known
            basis = [k * r * sgn, k * r * v]
            if fit_inertia:
                basis.insert(0, alpha)
            else:
                y = y - motor * alpha
            if fit_balance:
                basis.append(-up * k * r)
            coef, cov = nonnegative_lsq(np.column_stack(basis), y)
            if fit_inertia:
                inertia, coulomb, viscous = (float(c) for c in coef[:3])
            else:
                coulomb, viscous = (float(c) for c in coef[:2])
            if fit_balance:
                balance = float(coef[-1])
        else:
            xcols = [(motor + rest) * alpha + k * r * known, k * r * sgn, k * r * v]
            if fit_balance:
                xcols.append(-up * k * r)
            coef, cov = nonnegative_lsq(np.column_stack(xcols), q)
            theta0 = float(coef[0])
            if fit_balance and theta0 > 0.0:
                balance = float(coef[3]) / theta0
            if theta0 <= 0.0:
                msg = (f'the torque constant of axis {axis} cannot be told from the data (the '
                       'configured masses and inertias explain none of the trace); declare '
                       f'it: axes.{axis}.drive.kt_nm_a or instrument.kt_nm_a.{axis}')
                return failed('insufficient', msg)
            coulomb, viscous = float(coef[1]) / theta0, float(coef[2]) / theta0
    known = known - up * balance
    k = np.where((known + coulomb * sgn + viscous * v) * v >= 0.0, 1.0 / eta, eta)
    torque = (inertia + rest) * alpha + k * r * (known + coulomb * sgn + viscous * v)
    fitted_gain = gain if gain is not None else 1.0 / theta0
    res = q - torque / fitted_gain
    ss_tot = float(np.sum((q - q.mean()) ** 2))
    r2 = 1.0 - float(res @ res) / ss_tot if ss_tot > 0.0 else 0.0
    rmse = math.sqrt(float(res @ res) / n)
    se: dict[str, float | None] = {'motor': None, 'coulomb': None, 'viscous': None,
                                   'gain': None, 'balance': None}
    cov_loss = None
    if cov is not None:
        if gain is not None:
            j = 1 if fit_inertia else 0
            if fit_inertia:
                se['motor'] = _se(cov, 0)
            se['coulomb'], se['viscous'] = _se(cov, j), _se(cov, j + 1)
            if fit_balance:
                se['balance'] = _se(cov, j + 2)
            block = cov[j:j + 2, j:j + 2]
        else:
            # (kt, Fc, cv) = (1, theta2, theta3) / theta0: the delta method
            t0, t2, t3 = (float(c) for c in coef[:3])
            jac = np.array([[-1.0 / t0 ** 2, 0.0, 0.0], [-t2 / t0 ** 2, 1.0 / t0, 0.0],
                            [-t3 / t0 ** 2, 0.0, 1.0 / t0]])
            if fit_balance:
                # (kt, Fc, cv, balance) = (1, theta2, theta3, theta4) / theta0
                jac = np.pad(jac, ((0, 1), (0, 1)))
                jac[3, 0], jac[3, 3] = -float(coef[3]) / t0 ** 2, 1.0 / t0
            full = jac @ cov @ jac.T
            se['gain'], se['coulomb'], se['viscous'] = (_se(full, i) for i in range(3))
            if fit_balance:
                se['balance'] = _se(full, 3)
            block = full[1:3, 1:3]
        block = 0.5 * (block + block.T)
        if np.all(np.isfinite(block)):
            cov_loss = ((float(block[0, 0]), float(block[0, 1])),
                        (float(block[1, 0]), float(block[1, 1])))
    speed = np.abs(v)
    steady = np.abs(a) <= options.accel_m_s2
    feeds = speed[steady] if steady.any() else speed
    calibrated = CalibratedRange(
        feed_mm_s=(float(feeds.min() * _MM_PER_M), float(feeds.max() * _MM_PER_M)),
        load_kg=(float(loads.min()), float(loads.max())))
    if gain is None:
        how = (f'torque constant fitted ({fitted_gain:.4g} N·m/A), inertia kept as configured '
               '(with kt unknown the two cannot be told apart)')
    elif fit_inertia:
        how = 'inertia fitted'
    else:
        how = (f'inertia kept as configured ({n_accel} samples accelerate by more than '
               f'{options.accel_m_s2:g} m/s^2, need {options.min_accel_samples})')
    msg = (f'{n} moving samples ({n_accel} accelerating), {how}; RMS residual '
           f'{rmse:.3g} {qty.unit}, R^2 = {r2:.4f}')
    if fit_balance:
        msg += (f'; counterbalance {balance:.4g} N against the weight of the configured mass '
                f'({float(np.mean(mass)) * GRAVITY_M_S2 * abs(sin_incl):.4g} N)')
    w_rest = m_rest * GRAVITY_M_S2 * sin_incl
    net_balance = balance if fit_balance else spec.counterbalance_n
    if sin_incl != 0.0:
        w_rest = w_rest - up * net_balance
    hold, rest_rmse = _standstill_hold(d_rest, q_rest, w_rest, spec=spec,
                                       gain=float(fitted_gain), options=options)
    if hold is not None:
        msg += (f'; after a stop the drive holds {hold:.3g} N in the last direction of motion '
                f'({d_rest.size} resting samples, RMS residual {rest_rmse:.3g} {qty.unit})')
    return SampleFit(
        axis=axis, status='ok', message=msg, coulomb_n=coulomb, viscous_n_s_m=viscous,
        motor_kg_m2=inertia, motor_se=se['motor'], coulomb_se=se['coulomb'],
        viscous_se=se['viscous'], inertia_fitted=fit_inertia,
        effective_mass_kg=float(np.mean(mass) + (inertia + rest) / r ** 2), rmse_w=None,
        r2=r2, n_samples=n, n_accel=n_accel, calibrated=calibrated, cov_loss=cov_loss,
        measures=measures, rmse=rmse, unit=qty.unit, gain=float(fitted_gain),
        gain_se=se['gain'], gain_fitted=gain is None, standstill_hold_n=hold,
        n_rest=int(d_rest.size) if hold is not None else 0, rest_rmse=rest_rmse,
        counterbalance_n=balance if fit_balance else None,
        counterbalance_se=se['balance'] if fit_balance else None)


def _correlation_time(res: np.ndarray, *, max_lag: int = 200) -> float:
    """Integrated autocorrelation time of a residual series [samples] (1 for white noise):
    ``1 + 2·sum rho_k`` over the lags until the autocorrelation first falls below 0.05."""
    y = res - float(np.mean(res))
    var = float(y @ y)
    if y.size < 3 or var <= 0.0:
        return 1.0
    tau = 1.0
    for k in range(1, min(max_lag, y.size - 1)):
        rho = float(y[:-k] @ y[k:]) / var
        if rho < 0.05:
            break
        tau += 2.0 * rho
    return tau


def _standstill_hold(d: np.ndarray, q: np.ndarray, weight: np.ndarray, *, spec, gain: float,
                     options: SampleFitOptions) -> tuple[float | None, float | None]:
    """The force held at rest after a move [N] (``>= 0``, in the last direction ``d``) and
    the resting samples' residual RMS, from ``q·g = M_weight + h·d·r`` at rest (``weight``:
    the weight the drive carries per sample [N]); ``(None, None)`` with fewer than
    ``min_samples`` such samples or no move in either direction; ``(None, RMS)`` when the
    hold is within 2 standard errors of 0: a declared hold, however small, replaces the
    kinetic friction at rest (:mod:`feed_axis_energy.physics.standstill`), so a hold the
    data do not show is none (on a stand whose drive holds nothing a fitted 1e-4 N turned
    the friction of the few samples slower than ``REST_SPEED_M_S`` into a 26 N residual)."""
    if d.size < options.min_samples:
        return None, None
    eta = spec.screw.efficiency
    r = spec.screw.lead_m / (2.0 * math.pi)
    # holding the weight: the motor drives the nut (as the dynamics take it at rest)
    y = q * gain - r * weight / eta
    x = (d * r)[:, None]
    coef, _ = nonnegative_lsq(x, y)
    hold = float(coef[0])
    res = q - (r * weight / eta + hold * d * r) / gain
    rms = math.sqrt(float(res @ res) / res.size)
    xx = float(x[:, 0] @ x[:, 0])
    dof = res.size - 1
    # standard error of h, the white-noise formula widened by the residual's correlation
    # time (a filtered controller output wanders over several samples)
    se = (math.sqrt(float((res * gain) @ (res * gain)) / dof / xx * _correlation_time(res))
          if xx > 0.0 and dof > 0 else math.inf)
    if not hold > 2.0 * se:
        return None, rms
    return hold, rms


def fit_drive_samples(runs: Sequence[MeasuredRun], *, machine: Machine, measures: str,
                      gains: Mapping[str, float | None], axes: Sequence[str] | None = None,
                      velocity: str | Sequence[str] = 'auto',
                      invert: Sequence[Sequence[str]] | None = None,
                      options: SampleFitOptions = SampleFitOptions()) -> dict[str, SampleFit]:
    """Fit loss, inertia and (current without ``kt``) the torque constant per axis.

    Parameters
    ----------
    runs
        Measured runs with the drive trace and velocity (or position) columns.
    machine
        Machine model: moved masses, screw, efficiency, inclination, inertias.
    measures
        ``'current'``, ``'torque'`` or ``'force'``.
    gains
        Axis -> torque per unit of the trace (:func:`~feed_axis_energy.measured.torque_per_unit`
        with ``required=False``); ``None`` for a current whose ``kt`` is to be fitted.
    axes
        Axes to fit; default every axis with the trace in any run and in the machine.
    velocity
        Kinematics of every run (``'auto'``, ``'actual'``, ``'commanded'``), one or per run.
    invert
        Per run, the axes whose trace is negated (``instrument.invert``).
    options
        Sample selection.

    Returns
    -------
    dict
        Axis name -> :class:`~.samplefit.SampleFit` (status ``'ok'``, ``'insufficient'`` or
        ``'wrong_sign'``).

    Raises
    ------
    ConfigError
        A power quantity, an unknown velocity source, counts that do not match the runs.
    DataError
        A run without velocity or position columns, an axis the machine lacks.
    """
    qty = quantity_of(measures)
    if qty.is_power:
        msg = f'{measures} power is fitted by fit_loss_samples, not as a drive trace'
        raise ConfigError(msg, file='fit options', key='measures')
    sources = [velocity] * len(runs) if isinstance(velocity, str) else list(velocity)
    if len(sources) != len(runs) or any(s not in VELOCITY_SOURCES for s in sources):
        msg = (f'expected one of {", ".join(VELOCITY_SOURCES)} for every run, got '
               f'{sources!r:.60}')
        raise ConfigError(msg, file='fit options', key='velocity')
    flips = [()] * len(runs) if invert is None else [tuple(i) for i in invert]
    if len(flips) != len(runs):
        raise ConfigError('expected one invert list per run', file='fit options', key='invert')
    if axes is None:
        names: list[str] = []
        for run in runs:
            names.extend(a for a in run.extra.get(qty.run_field, {}) if a not in names)
        names = [a for a in names if a in machine.axis_names]
    else:
        names = list(axes)
    out = {}
    for axis in names:
        if axis not in machine.axis_names:
            raise DataError(f'machine {machine.name!r} has no axis {axis!r}', file='fit-loss')
        cols = _collect(runs, axis, machine, measures, sources, flips, options)
        if cols is None:
            out[axis] = SampleFit(axis=axis, status='insufficient', measures=measures,
                                  unit=qty.unit, message=f'no run has a {qty.column} trace '
                                  f'of axis {axis}')
            continue
        out[axis] = _fit_axis(cols, axis=axis, machine=machine, measures=measures,
                              gain=gains.get(axis), options=options)
    return out
