"""The energy's uncertainty from the loss function's: the covariance propagated, chunk by chunk.

A machine config may give, per axis, the covariance ``C`` of the loss parameters
``theta`` (``loss_covariance``, :mod:`feed_axis_energy.machine.covariance`; ``fit-loss``
writes it). The energy ``E`` the axis draws over a program depends on ``theta`` through the
loss force; its standard uncertainty is ``u(E) = sqrt(g' C g)`` with the gradient
``g = dE/dtheta`` (the delta method). ``g`` is accumulated while the program is simulated,
from the samples of each chunk (``(p,)`` numbers per axis; no per-program array):

* the drawn power is ``M·omega`` (after the braking rule) and ``theta`` enters ``M`` only
  through the loss force, so ``dP/dtheta = w·dP_loss/dtheta`` with ``P_loss = F_loss·v``
  (:meth:`.losses.PowerRegressionLoss.power_gradient_w`) and the weight ``w`` of the screw
  torque (:mod:`.dynamics`): ``1/eta`` where the motor drives (``F·v >= 0``), ``eta`` where
  the load drives, and ``0`` at samples a ``'dissipated'`` braking rule sets to zero draw;
* ``g = integral dP/dtheta dt`` by the trapezoid rule on the simulation's samples, as the
  energy itself (:class:`.energy.EnergyIntegrator`).

Exact or first order: ``g`` is the exact derivative of the simulated energy wherever the
driving state and the braking rule do not switch at a sample. A parameter that enters the
loss power linearly (``a`` of ``power_regression``; ``coulomb_n``, ``viscous_n_s_m``, ``mu``
of ``coulomb_viscous``) gives an energy that is linear in it where ``w`` is fixed, i.e. on
axes with ``eta = 1`` and ``'regenerative'`` braking: ``E(theta + d) = E + g·d`` exactly, and
``u(E)`` is exact for the covariance given. Otherwise (``b``, the exponent; a screw efficiency
below 1 or ``'dissipated'`` braking, whose switching points move with ``theta``) ``u(E)`` is
first order. The covariance ``fit-loss`` writes is itself first order in ``a``
(:meth:`.identify.fit.lossfit.LossFit.covariance`).

Declared effects (:mod:`.effects`) are held fixed: one that depends on the torque (``copper``)
would also change with ``theta``; its share is not in ``g``.

The axes' loss functions are taken as independent (each is fitted on its own axis's power),
so ``u(E_total)² = sum_k u(E_k)²``. Axes without ``loss_covariance`` add nothing and are
named: the figure covers only the axes listed.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
import math
from typing import Any

import numpy as np

from .dynamics import AxisDynamics
from ..machine import LossCovariance
from ..units import GRAVITY_M_S2

__all__ = ['UncertaintyAccumulator', 'UNCERTAINTY_KEY', 'METHOD', 'add_uncertainty',
           'uncertainty_words', 'two_digits', 'relative_sd_pct']

UNCERTAINTY_KEY = 'energy_uncertainty'
"""Summary key (present only when some axis has a ``loss_covariance``)."""

METHOD = ('standard uncertainty from the covariance of the loss parameters (loss_covariance), '
          'propagated by the gradient of the energy (delta method): exact for parameters that '
          'enter the loss power linearly on axes with eta = 1 and regenerative braking, first '
          'order otherwise; the axes taken as independent')


class UncertaintyAccumulator:
    """Gradient of each axis's energy with respect to its loss parameters, chunk by chunk.

    Parameters
    ----------
    machine
        The machine (axes with ``loss_covariance``, inclinations for the normal force).

    Use :meth:`of`, which returns ``None`` when no axis has a covariance (nothing to show).
    """

    def __init__(self, machine: Any) -> None:
        self.machine = machine
        self.covariances: dict[str, LossCovariance] = {
            a.name: a.loss_covariance for a in machine.axes if a.loss_covariance is not None}
        self.gradient: dict[str, np.ndarray] = {
            name: np.zeros(len(cov.params)) for name, cov in self.covariances.items()}
        self._last: dict[str, np.ndarray] = {}
        self._t_last: float | None = None
        self._seen: list[str] = []

    @classmethod
    def of(cls, machine: Any) -> 'UncertaintyAccumulator | None':
        """An accumulator for ``machine``, or ``None`` when no axis has ``loss_covariance``."""
        if not any(a.loss_covariance is not None for a in machine.axes):
            return None
        return cls(machine)

    def _weight(self, dyn: AxisDynamics, mechanical_w: np.ndarray, j: int,
                braking: str) -> np.ndarray | float:
        eta = float(dyn.efficiency[j])
        w: np.ndarray | float = 1.0
        if eta != 1.0:
            drives = dyn.force_n[:, j] * dyn.velocity_m_s[:, j] >= 0.0
            w = np.where(drives, 1.0 / eta, eta)
        if braking == 'dissipated':
            w = np.where(np.asarray(mechanical_w)[:, j] < 0.0, 0.0, w)
        return w

    def add(self, dyn: AxisDynamics, mechanical_w: np.ndarray, *, braking: str,
            weights: np.ndarray | None = None) -> None:
        """Take one chunk (in time order; the interval from the previous chunk included).

        Parameters
        ----------
        dyn
            The chunk's dynamics.
        mechanical_w
            ``M·omega`` per axis before the braking rule [W], ``(n, k)``.
        braking
            ``'regenerative'`` or ``'dissipated'``.
        weights
            The rows are quadrature nodes: the integral of ``f`` is ``f @ weights`` [s]
            (instead of the trapezoid rule continued from the previous chunk).
        """
        t = np.asarray(dyn.t, dtype=float)
        if t.shape[0] == 0:
            return
        if weights is not None:
            self._add(dyn, mechanical_w, braking, np.asarray(weights, dtype=float), None)
            return
        # trapezoid weights of the samples: the integral of f is f @ c, plus the interval
        # from the previous chunk's last sample (its half is added with the carried value)
        c = np.zeros(t.shape[0])
        dt = np.diff(t)
        c[:-1] += 0.5 * dt
        c[1:] += 0.5 * dt
        d0 = None if self._t_last is None else float(t[0] - self._t_last)
        if d0 is not None:
            c[0] += 0.5 * d0
        self._add(dyn, mechanical_w, braking, c, d0)
        self._t_last = float(t[-1])

    def _add(self, dyn: AxisDynamics, mechanical_w: np.ndarray, braking: str, c: np.ndarray,
             d0: float | None) -> None:
        """Add ``gradient @ c`` per axis (``d0``: the interval from the previous chunk's
        last row, whose value is carried)."""
        t = dyn.t
        for j, name in enumerate(dyn.axes):
            cov = self.covariances.get(name)
            if cov is None:
                continue
            if name not in self._seen:
                self._seen.append(name)
            spec = self.machine.axis(name)
            normal = float(dyn.mass_kg[j]) * GRAVITY_M_S2 * abs(
                math.cos(math.radians(spec.inclination_deg)))
            grads = spec.loss.power_gradient_w(dyn.velocity_m_s[:, j], normal_force_n=normal)
            w = self._weight(dyn, mechanical_w, j, braking)
            cw = c * w if isinstance(w, np.ndarray) else c
            last = np.array([float(grads[p][-1]) for p in cov.params])
            if isinstance(w, np.ndarray):
                last *= w[-1]
            g = self.gradient[name]
            buf = np.empty(t.shape[0])
            for i, param in enumerate(cov.params):
                # multiply and sum, not np.dot: BLAS may start threads for a long vector
                g[i] += float(np.multiply(grads[param], cw, out=buf).sum())
            if d0 is not None:
                g += 0.5 * d0 * self._last[name]
            self._last[name] = last

    def standard_uncertainty_j(self) -> dict[str, float]:
        """``u(E)`` per simulated axis with a covariance and ``'total'`` [J]."""
        out = {}
        for name in self._seen:
            g = self.gradient[name]
            out[name] = math.sqrt(max(float(g @ self.covariances[name].array() @ g), 0.0))
        out['total'] = math.sqrt(math.fsum(v * v for v in out.values()))
        return out

    def summary(self, energy_j: Mapping[str, float]) -> dict[str, Any] | None:
        """The summary's :data:`UNCERTAINTY_KEY` value, or ``None`` when not finite.

        Parameters
        ----------
        energy_j
            The summary's energy per axis and ``'total'`` [J].

        Returns
        -------
        dict or None
            ``energy_sd_j`` ({axis: J, 'total': J}, standard uncertainty),
            ``relative_pct`` (``100·u(E_total)/E_total``, ``None`` unless ``E_total > 0``),
            ``axes`` (the axes covered), ``axes_without`` (axes of the program without a
            covariance), ``gradient`` ({axis: {param: dE/dparam}}, J per unit of the
            parameter), ``units`` ({axis: {param: unit}}), ``method``.
        """
        sd = self.standard_uncertainty_j()
        if not all(math.isfinite(v) for v in sd.values()):
            return None
        total = float(energy_j.get('total', 0.0))
        moved = [a for a in energy_j if a != 'total']
        return {
            'energy_sd_j': sd,
            'relative_pct': 100.0 * sd['total'] / total if total > 0.0 else None,
            'axes': list(self._seen),
            'axes_without': [a for a in moved if a not in self._seen],
            'gradient': {a: {p: float(g) for p, g in zip(self.covariances[a].params,
                                                         self.gradient[a])}
                         for a in self._seen},
            'units': {a: dict(zip(self.covariances[a].params, self.covariances[a].units))
                      for a in self._seen},
            'method': METHOD,
        }


def add_uncertainty(summary: dict[str, Any],
                    spread: UncertaintyAccumulator | None) -> dict[str, Any]:
    """Add :data:`UNCERTAINTY_KEY` to ``summary`` when ``spread`` has a finite figure.

    Parameters
    ----------
    summary
        A simulation summary (``energy_j`` read); changed in place.
    spread
        The accumulator fed with the simulation, or ``None`` (nothing known: nothing added).

    Returns
    -------
    dict
        ``summary``.
    """
    if spread is not None and summary.get('samples', 0):
        found = spread.summary(summary['energy_j'])
        if found is not None:
            summary[UNCERTAINTY_KEY] = found
    return summary


def two_digits(value: float) -> str:
    """``value`` rounded to two significant digits, without an exponent (``0.012``, ``4.1``,
    ``120``)."""
    if value == 0.0 or not math.isfinite(value):
        return '0' if value == 0.0 else '-'
    decimals = 1 - int(math.floor(math.log10(abs(value))))
    if abs(round(value, decimals)) >= 10.0 ** (2 - decimals):
        decimals -= 1           # 0.999 rounds up to 1.0: one digit fewer after the point
    return f'{round(value, decimals):.{max(decimals, 0)}f}'


def uncertainty_words(summary: Mapping[str, Any], *, per_axis: bool = True) -> str | None:
    """One phrase for people: ``±4.1 J (±0.82 % of the total) from the loss-function
    uncertainty``, with the axes it covers; ``None`` when the summary has none.

    Parameters
    ----------
    summary
        A simulation summary.
    per_axis
        Add each axis's figure and the axes not covered.
    """
    u = summary.get(UNCERTAINTY_KEY)
    if not isinstance(u, Mapping):
        return None
    sd = u['energy_sd_j']
    text = f'±{two_digits(sd["total"])} J'
    if u.get('relative_pct') is not None:
        text += f' (±{two_digits(u["relative_pct"])} % of the total)'
    text += ' from the loss-function uncertainty'
    if per_axis:
        parts = [f'{a} ±{two_digits(sd[a])} J' for a in u['axes']]
        text += f' ({", ".join(parts)}'
        if u.get('axes_without'):
            text += f'; not known for {", ".join(u["axes_without"])}'
        text += '; one standard uncertainty)'
    return text


def relative_sd_pct(result: Any, axes: Sequence[str]) -> float:
    """Standard uncertainty of a whole simulation's energy on ``axes``, as % of that energy.

    ``nan`` unless every axis of ``axes`` that the simulation moves has a ``loss_covariance``
    and the energy of ``axes`` is positive (``compare``: the simulated energy of the measured
    axes).

    Parameters
    ----------
    result
        A :class:`.simulate.SimulationResult` of the whole record.
    axes
        The axes summed.
    """
    spread = UncertaintyAccumulator.of(result.machine)
    power = result.power
    moved = [a for a in axes if a in power.axes]
    if spread is None or not moved or power.t.shape[0] < 2:
        return math.nan
    if any(a not in spread.covariances for a in moved):
        return math.nan
    spread.add(result.dynamics, power.mechanical_w, braking=power.braking)
    sd = spread.standard_uncertainty_j()
    energy = math.fsum(float(power.energy_j[-1, power.axes.index(a)]) for a in moved)
    value = math.sqrt(math.fsum(sd[a] ** 2 for a in moved))
    return 100.0 * value / energy if energy > 0.0 and math.isfinite(value) else math.nan
