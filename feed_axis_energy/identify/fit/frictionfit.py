"""Richer friction from a drive trace: asymmetric Coulomb and viscous, Stribeck, offset force.

``fit-loss --method samples --friction extended`` on a campaign that measures ``torque`` or
``force`` (or ``current`` with a known torque constant): the motor torque of every moving
sample is (``r = lead/(2·pi)``, ``alpha = a/r``, ``k = 1/eta`` driving, ``eta`` back-driven)

``q·g = (J + J_rest)·alpha + k·r·(m·a + m·g0·sin(incl) + F(v))``

``F(v) = Fc·sgn(v) + c·v + Fm + d·|v| + Fs·exp(-(|v|/vs)^delta)·sgn(v)``

with the symmetric Coulomb force ``Fc >= 0``, viscous ``c >= 0``, a constant ``Fm`` (either
sign), the viscous asymmetry ``d`` (``c± = c ± d``), and the Stribeck excess ``Fs >= 0``
whose speed ``vs`` and exponent ``delta`` (1 or 2) are searched on a grid. ``J`` (motor
inertia) is fitted, giving the equivalent mass ``m + (J + J_rest)/r²``.

While moving, a constant force ``F0`` and the asymmetry of Coulomb friction ``Fa`` (``F± =
Fc ± Fa``) are one column: ``Fm = F0 + Fa`` (the exact alias of
:func:`feed_axis_energy.effects.split_coulomb`). They separate at rest: friction holds no
force there, a constant force does. From resting samples (at least :data:`REST_GUARD_S` from
any motion) ``q·g - r·m·g0·sin(incl)/eta = r·(F0 + h·d)`` gives ``F0`` and the holding force
``h >= 0`` in the last direction of motion ``d``; then ``Fa = Fm - F0``. Without resting
samples in both directions ``F0`` cannot be told from ``Fa``: the whole ``Fm`` is reported as
the offset force and the status message says so.

:func:`machine_with_friction_fits` writes the result as a machine file: the loss function
``coulomb_viscous`` (``Fc``, ``c``), the motor inertia, and the catalog effects
``offset_force`` (``F0``), ``coulomb`` (``F+ = Fa``, ``F- = -Fa``), ``viscous_asymmetry``
(``d``) and ``stribeck`` (``Fs``, ``vs``, ``delta``) on that axis.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
import math
from typing import Any

import numpy as np
from scipy.optimize import lsq_linear

from ...errors import ConfigError, DataError
from ...machine import (CoulombViscousLoss, DeclaredEffect, Machine, moved_mass_kg)
from ...measured import MeasuredRun, measured_signal, quantity_of
from ...physics import last_direction
from ...units import GRAVITY_M_S2
from .samplefit import SampleFitOptions
from .steady import kinematics, VELOCITY_SOURCES

__all__ = ['FrictionFit', 'fit_drive_friction', 'machine_with_friction_fits',
           'STRIBECK_SPEEDS_M_S', 'STRIBECK_EXPONENTS', 'REST_GUARD_S']

STRIBECK_SPEEDS_M_S = tuple(float(v) for v in np.geomspace(5e-4, 0.05, 21))
"""Grid of Stribeck speeds searched [m/s]."""
STRIBECK_EXPONENTS = (1.0, 2.0)
"""Shape exponents searched (exponential, Gaussian)."""
REST_GUARD_S = 0.05
"""A resting sample is this far from any moving sample [s] (the controller has settled)."""
_ROUNDS = 10


@dataclass(frozen=True)
class FrictionFit:
    """Extended friction of one axis from its drive trace (SI units; ``None``: not fitted).

    Attributes
    ----------
    axis, status, message
        ``status``: ``'ok'`` or ``'insufficient'``.
    effective_mass_kg, motor_kg_m2
        ``m + J_total/r²`` with the fitted motor inertia [kg], and that inertia [kg·m²].
    coulomb_n, viscous_n_s_m
        Symmetric Coulomb force [N] and viscous coefficient [N·s/m].
    offset_n
        Constant force ``F0`` [N] (positive: moving in + costs more), from the resting
        samples; without them the moving constant ``Fm``.
    coulomb_asymmetry_n
        ``Fa = Fm - F0`` [N] (``F+ = Fc + Fa``, ``F- = Fc - Fa``); ``None`` without resting
        samples.
    moving_offset_n
        ``Fm = F0 + Fa`` [N]: what the moving samples see.
    viscous_asymmetry_n_s_m
        ``d`` [N·s/m]: ``c+ = c + d``, ``c- = c - d``.
    stribeck_n, stribeck_v_m_s, stribeck_delta
        Stribeck excess [N], speed [m/s] and exponent.
    hold_n
        Force held after a stop in the last direction of motion [N] (``None``: no resting
        samples).
    rmse, unit, r2, n_samples, n_rest
        Residual RMS of the moving samples in the trace's unit, R², moving and resting samples.
    """

    axis: str
    status: str
    message: str
    effective_mass_kg: float | None = None
    motor_kg_m2: float | None = None
    coulomb_n: float | None = None
    viscous_n_s_m: float | None = None
    offset_n: float | None = None
    coulomb_asymmetry_n: float | None = None
    moving_offset_n: float | None = None
    viscous_asymmetry_n_s_m: float | None = None
    stribeck_n: float | None = None
    stribeck_v_m_s: float | None = None
    stribeck_delta: float | None = None
    hold_n: float | None = None
    rmse: float | None = None
    unit: str = 'N'
    r2: float | None = None
    n_samples: int = 0
    n_rest: int = 0

    @property
    def ok(self) -> bool:
        """``True`` when the fit can be used."""
        return self.status == 'ok'

    def to_dict(self) -> dict[str, Any]:
        """Plain-type form (JSON keys carry units; docs/test-stand.md)."""
        return {'axis': self.axis, 'status': self.status, 'message': self.message,
                'method': 'samples', 'friction': 'extended',
                'effective_mass_kg': self.effective_mass_kg, 'motor_kg_m2': self.motor_kg_m2,
                'coulomb_n': self.coulomb_n, 'viscous_n_s_m': self.viscous_n_s_m,
                'offset_n': self.offset_n, 'coulomb_asymmetry_n': self.coulomb_asymmetry_n,
                'moving_offset_n': self.moving_offset_n,
                'viscous_asymmetry_n_s_m': self.viscous_asymmetry_n_s_m,
                'stribeck_n': self.stribeck_n, 'stribeck_v_m_s': self.stribeck_v_m_s,
                'stribeck_delta': self.stribeck_delta, 'hold_n': self.hold_n,
                'rmse': self.rmse, 'unit': self.unit, 'r2': self.r2,
                'n_samples': self.n_samples, 'n_rest': self.n_rest}


@dataclass
class _Samples:
    v: np.ndarray
    a: np.ndarray
    y: np.ndarray           # q·g [N·m]
    mass: np.ndarray
    rest_y: np.ndarray
    rest_d: np.ndarray
    rest_mass: np.ndarray


def _collect(runs: Sequence[MeasuredRun], axis: str, machine: Machine, measures: str,
             gain: float, sources: Sequence[str], flips: Sequence[Sequence[str]],
             options: SampleFitOptions) -> _Samples | None:
    column = quantity_of(measures).run_field
    parts: dict[str, list[np.ndarray]] = {k: [] for k in _Samples.__dataclass_fields__}
    for run, source, inv in zip(runs, sources, flips):
        if axis not in run.extra.get(column, {}) or axis not in run.axes:
            continue
        vel, acc, _ = kinematics(run, source)
        j = run.axes.index(axis)
        v, a = vel[:, j], acc[:, j]
        q = measured_signal(run, measures=measures, axes=[axis], invert=inv)[:, 0] * gain
        mass = moved_mass_kg(machine, axis, run.load_kg)
        moving = np.abs(v) >= options.min_speed_m_s
        d = last_direction(v, rest_speed=options.min_speed_m_s)[:, 0]
        dt = float(np.median(np.diff(run.t))) if run.t.size > 1 else 1.0
        guard = max(1, int(round(REST_GUARD_S / dt)))
        near = np.convolve(moving.astype(float), np.ones(2 * guard + 1), mode='same') > 0.0
        rest = ~near & (d != 0.0) & (np.abs(a) <= options.accel_m_s2)
        for key, value in (('v', v[moving]), ('a', a[moving]), ('y', q[moving]),
                           ('mass', np.full(int(moving.sum()), mass)), ('rest_y', q[rest]),
                           ('rest_d', d[rest]), ('rest_mass', np.full(int(rest.sum()), mass))):
            parts[key].append(value)
    if not parts['v']:
        return None
    return _Samples(**{k: np.concatenate(v) for k, v in parts.items()})


def _bounded_lsq(x: np.ndarray, y: np.ndarray, lower: np.ndarray) -> tuple[np.ndarray, float]:
    """Least squares with lower bounds (``-inf``: free), on unit-norm columns: ``(coef, SSE)``."""
    scale = np.linalg.norm(x, axis=0)
    scale[scale == 0.0] = 1.0
    sol = lsq_linear(x / scale, y, bounds=(lower * scale, np.full(lower.shape, np.inf)),
                     method='bvls')
    coef = np.asarray(sol.x, dtype=float) / scale
    res = y - x @ coef
    return coef, float(res @ res)


def _fit_axis(s: _Samples, *, axis: str, machine: Machine, unit: str, gain: float,
              options: SampleFitOptions) -> FrictionFit:
    n = s.v.size
    if n < options.min_samples:
        return FrictionFit(axis=axis, status='insufficient', unit=unit, n_samples=n,
                           message=f'{n} moving sample(s); need at least {options.min_samples}')
    spec = machine.axis(axis)
    eta = spec.screw.efficiency
    r = spec.screw.lead_m / (2.0 * math.pi)
    alpha = s.a / r
    j_rest = spec.inertias.coupling_kg_m2 + spec.screw_inertia_kg_m2
    sin_i = math.sin(math.radians(spec.inclination_deg))
    known = s.mass * s.a + s.mass * GRAVITY_M_S2 * sin_i
    sgn = np.sign(s.v)
    speed = np.abs(s.v)
    # inertia, Fc, c, Fm, d, Fs
    lower = np.array([0.0, 0.0, 0.0, -np.inf, -np.inf, 0.0])
    best: tuple[float, np.ndarray, float, float] | None = None
    for delta in STRIBECK_EXPONENTS:
        for vs in STRIBECK_SPEEDS_M_S:
            strib = np.exp(-(speed / vs) ** delta) * sgn
            coef = np.zeros(6)
            drive = None
            sse = math.inf
            for _ in range(_ROUNDS if eta < 1.0 else 1):
                force = known + coef[1] * sgn + coef[2] * s.v + coef[3] + coef[4] * speed \
                    + coef[5] * strib
                new_drive = force * s.v >= 0.0
                if drive is not None and np.array_equal(new_drive, drive):
                    break
                drive = new_drive
                k = np.where(drive, 1.0 / eta, eta)
                x = np.column_stack([alpha, k * r * sgn, k * r * s.v, k * r, k * r * speed,
                                     k * r * strib])
                coef, sse = _bounded_lsq(x, s.y - j_rest * alpha - k * r * known, lower)
            if best is None or sse < best[0]:
                best = (sse, coef, vs, delta)
    assert best is not None
    sse, coef, vs, delta = best
    inertia, fc, cv, fm, dv, fs = (float(c) for c in coef)
    ss_tot = float(np.sum((s.y - s.y.mean()) ** 2))
    r2 = 1.0 - sse / ss_tot if ss_tot > 0.0 else 0.0
    rmse = math.sqrt(sse / n) / gain
    offset, asym, hold = fm, None, None
    n_rest = int(s.rest_y.size)
    both = n_rest >= options.min_samples and np.any(s.rest_d > 0) and np.any(s.rest_d < 0)
    if both:
        y_rest = s.rest_y - r * s.rest_mass * GRAVITY_M_S2 * sin_i / eta
        x_rest = np.column_stack([np.full(n_rest, r), r * s.rest_d])
        c_rest, _ = _bounded_lsq(x_rest, y_rest, np.array([-np.inf, 0.0]))
        offset, hold = float(c_rest[0]), float(c_rest[1])
        asym = fm - offset
        split = (f'offset force {offset:.4g} N from {n_rest} resting samples, Coulomb '
                 f'asymmetry {asym:+.4g} N (F+ {fc + asym:.4g} N, F- {fc - asym:.4g} N)')
    else:
        split = (f'no resting samples after moves in both directions: the constant '
                 f'{fm:.4g} N of the moving samples is reported as the offset force (an '
                 'asymmetric Coulomb friction would look the same)')
    m_eq = float(np.mean(s.mass)) + (inertia + j_rest) / r ** 2
    msg = (f'{n} moving samples: equivalent mass {m_eq:.4g} kg, Coulomb {fc:.4g} N, viscous '
           f'{cv:.4g} N s/m (asymmetry {dv:+.4g}), Stribeck {fs:.4g} N at {1e3 * vs:.3g} mm/s '
           f'(delta {delta:g}); {split}; RMS residual {rmse:.3g} {unit}, R^2 = {r2:.5f}')
    return FrictionFit(
        axis=axis, status='ok', message=msg, effective_mass_kg=m_eq, motor_kg_m2=inertia,
        coulomb_n=fc, viscous_n_s_m=cv, offset_n=offset, coulomb_asymmetry_n=asym,
        moving_offset_n=fm, viscous_asymmetry_n_s_m=dv, stribeck_n=fs, stribeck_v_m_s=vs,
        stribeck_delta=delta, hold_n=hold, rmse=rmse, unit=unit, r2=r2, n_samples=n,
        n_rest=n_rest if both else 0)


def fit_drive_friction(runs: Sequence[MeasuredRun], *, machine: Machine, measures: str,
                       gains: Mapping[str, float | None], axes: Sequence[str] | None = None,
                       velocity: str | Sequence[str] = 'auto',
                       invert: Sequence[Sequence[str]] | None = None,
                       options: SampleFitOptions = SampleFitOptions()) -> dict[str, FrictionFit]:
    """Fit the extended friction model (module docstring) per axis of a drive trace.

    Parameters
    ----------
    runs, machine, measures, axes, velocity, invert, options
        As :func:`~feed_axis_energy.identify.fit_drive_samples`.
    gains
        Axis -> torque per unit of the trace; every fitted axis needs a known gain.

    Raises
    ------
    ConfigError
        A power quantity, a current without a torque constant, an unknown velocity source.
    DataError
        An axis the machine lacks.
    """
    qty = quantity_of(measures)
    if qty.is_power:
        msg = ('the extended friction model needs a drive trace (current, torque or force): '
               'power does not show a constant force at rest')
        raise ConfigError(msg, file='fit options', key='measures')
    sources = [velocity] * len(runs) if isinstance(velocity, str) else list(velocity)
    if len(sources) != len(runs) or any(s not in VELOCITY_SOURCES for s in sources):
        msg = f'expected one of {", ".join(VELOCITY_SOURCES)} for every run'
        raise ConfigError(msg, file='fit options', key='velocity')
    flips = [()] * len(runs) if invert is None else [tuple(i) for i in invert]
    names = list(axes) if axes is not None else [
        a for a in machine.axis_names
        if any(a in run.extra.get(qty.run_field, {}) for run in runs)]
    out = {}
    for axis in names:
        if axis not in machine.axis_names:
            raise DataError(f'machine {machine.name!r} has no axis {axis!r}', file='fit-loss')
        gain = gains.get(axis)
        if gain is None:
            msg = (f'axis {axis}: the extended friction fit needs the torque constant; declare '
                   f'axes.{axis}.drive.kt_nm_a or instrument.kt_nm_a.{axis}')
            raise ConfigError(msg, file='fit options', key='instrument.kt_nm_a')
        samples = _collect(runs, axis, machine, measures, gain, sources, flips, options)
        if samples is None:
            out[axis] = FrictionFit(axis=axis, status='insufficient', unit=qty.unit,
                                    message=f'no run has a {qty.column} trace of axis {axis}')
            continue
        out[axis] = _fit_axis(samples, axis=axis, machine=machine, unit=qty.unit, gain=gain,
                              options=options)
    return out


def machine_with_friction_fits(machine: Machine, fits: Mapping[str, FrictionFit]) -> Machine:
    """``machine`` with every ``'ok'`` axis's loss, inertia and friction effects replaced.

    The loss becomes ``coulomb_viscous`` (``Fc``, ``c``); ``offset_force``, ``coulomb`` (the
    asymmetry), ``viscous_asymmetry`` and ``stribeck`` on that axis replace declared ones of
    the same id; a holding force is written as ``standstill_hold_n``.
    """
    axes = []
    effects = list(machine.effects)
    for a in machine.axes:
        f = fits.get(a.name)
        if f is None or not f.ok:
            axes.append(a)
            continue
        a = replace(a, loss=CoulombViscousLoss(coulomb_n=float(f.coulomb_n or 0.0),
                                               viscous_n_s_m=float(f.viscous_n_s_m or 0.0)),
                    loss_calibrated=None, loss_covariance=None)
        if not a.direct:
            a = replace(a, inertias=replace(a.inertias, motor_kg_m2=float(f.motor_kg_m2 or 0.0)))
        if f.hold_n is not None:
            a = replace(a, standstill_hold_n=float(f.hold_n))
        axes.append(a)
        new = [('offset_force', {'f0_n': f.offset_n or 0.0}),
               ('coulomb', {'f_pos_n': f.coulomb_asymmetry_n or 0.0,
                            'f_neg_n': -(f.coulomb_asymmetry_n or 0.0)}),
               ('viscous_asymmetry', {'d_n_s_m': f.viscous_asymmetry_n_s_m or 0.0}),
               ('stribeck', {'f_s_n': f.stribeck_n or 0.0,
                             'v_s_m_s': f.stribeck_v_m_s or 0.01,
                             'delta': f.stribeck_delta or 2.0})]
        ids = {i for i, _ in new}
        effects = [e for e in effects if not (e.axis == a.name and e.id in ids)]
        effects += [DeclaredEffect(id=i, axis=a.name,
                                   params=tuple((k, float(v)) for k, v in p.items()))
                    for i, p in new if any(float(v) != 0.0 for k, v in p.items()
                                           if k in ('f0_n', 'f_pos_n', 'd_n_s_m', 'f_s_n'))]
    return replace(machine, axes=tuple(axes), effects=tuple(effects))
