"""Actual power (paper eq. 1), energy (eq. 2) and per-block attribution.

* Actual power of axis ``k``: ``P_k = M_k·omega_k`` (eq. 1); total = sum over axes.
* Braking: ``'regenerative'`` keeps negative axis power (energy returned to the DC link
  counts negative); ``'dissipated'`` counts negative axis power as zero draw (burned in a brake
  resistor). The rule is applied per axis, so a shared DC link that passes braking energy of
  one axis to another is not modelled in ``'dissipated'`` mode.
* Energy ``E = integral P dt`` (eq. 2) by the trapezoid rule, cumulative, starting at 0.
  Accumulation is strictly sequential (``numpy.add.accumulate``) so that
  :class:`EnergyIntegrator` fed chunk by chunk gives the same bits as the offline result.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dynamics import AxisDynamics
from ..errors import ConfigError, DataError
from ..machine import BRAKING_MODES

__all__ = ['ElectricalPower', 'PowerResult', 'EnergyIntegrator', 'compute_power', 'energy_by_line',
           'power_with_total',
           'apply_braking']


@dataclass(frozen=True)
class ElectricalPower:
    """Electrical power of one chunk, per axis ``(n, k)`` [W].

    Attributes
    ----------
    motor_w
        At the motor terminals, declared effects included.
    supply_w
        At the supply side of each axis's drive, declared effects included (without the
        cabinet).
    parts
        ``(cause, power)`` of :data:`ELECTRICAL_CAUSES`.
    burned_w
        Braking power burned in the brake chopper (beyond the regeneration limit).
    cabinet_w
        The cabinet's standby [W] (once for the machine).
    measured_at
        ``'motor'`` or ``'supply'``: the meter's point (``supply.measured_at``).
    """

    motor_w: np.ndarray
    supply_w: np.ndarray
    parts: tuple[tuple[str, np.ndarray], ...]
    burned_w: np.ndarray
    cabinet_w: float = 0.0
    measured_at: str = 'motor'

    def append(self, other: 'ElectricalPower') -> 'ElectricalPower':
        """The rows of this one followed by those of ``other`` (same axes and causes)."""
        return ElectricalPower(
            motor_w=np.concatenate((self.motor_w, other.motor_w)),
            supply_w=np.concatenate((self.supply_w, other.supply_w)),
            parts=tuple((n, np.concatenate((p, q)))
                        for (n, p), (_, q) in zip(self.parts, other.parts)),
            burned_w=np.concatenate((self.burned_w, other.burned_w)),
            cabinet_w=self.cabinet_w, measured_at=self.measured_at)

    def take(self, rows: np.ndarray) -> 'ElectricalPower':
        """The samples ``rows`` (e.g. a chunk expanded to the full rate)."""
        return ElectricalPower(motor_w=self.motor_w[rows], supply_w=self.supply_w[rows],
                               parts=tuple((n, p[rows]) for n, p in self.parts),
                               burned_w=self.burned_w[rows], cabinet_w=self.cabinet_w,
                               measured_at=self.measured_at)

    @property
    def measured_w(self) -> np.ndarray:
        """Per axis at the meter's point [W] (the cabinet is not in the axes' columns)."""
        return self.motor_w if self.measured_at == 'motor' else self.supply_w


@dataclass(frozen=True)
class PowerResult:
    """Power and energy time series.

    Attributes
    ----------
    t
        Sample times [s], ``(n,)``.
    axes
        Axis names (column order).
    power_w
        Actual power per axis after the braking rule [W], ``(n, k)``.
    total_w
        Sum of ``power_w`` over the axes [W], ``(n,)``.
    energy_j
        Cumulative energy per axis [J], ``(n, k)``, 0 at the first sample.
    total_energy_j
        Cumulative energy of ``total_w`` [J], ``(n,)``.
    mechanical_w
        ``M·omega`` per axis before the braking rule [W], ``(n, k)``.
    loss_power_w
        Power spent on passive resistances ``F_loss·v`` [W], ``(n, k)``.
    line
        Source line of every sample, ``(n,)``.
    braking
        The braking rule applied.
    effect_power_w
        ``(label, power (n, k))`` of every declared effect (included in ``power_w``), in
        declaration order; labels as :func:`.simulate.declared_effects_parts`.
    electrical
        Electrical power at the motor terminals and the supply side
        (:class:`ElectricalPower`) when the machine declares drives, else
        ``None``.
    """

    t: np.ndarray
    axes: tuple[str, ...]
    power_w: np.ndarray
    total_w: np.ndarray
    energy_j: np.ndarray
    total_energy_j: np.ndarray
    mechanical_w: np.ndarray
    loss_power_w: np.ndarray
    line: np.ndarray
    braking: str = 'regenerative'
    effect_power_w: tuple[tuple[str, np.ndarray], ...] = ()
    electrical: ElectricalPower | None = None

    @property
    def regenerated_energy_j(self) -> float:
        """Energy the axes return while braking, ``-integral min(M·omega, 0) dt`` [J], >= 0.

        Fed back to the DC link with ``'regenerative'`` braking, burned with ``'dissipated'``.
        """
        negative = np.minimum(self.mechanical_w, 0.0)
        if self.t.shape[0] < 2:
            return 0.0
        dt = np.diff(self.t)[:, None]
        # max() also turns the -0.0 of a motion that never brakes into 0.0
        return max(0.0, float(-np.sum(0.5 * (negative[1:] + negative[:-1]) * dt)))


def apply_braking(mechanical_w: np.ndarray, *, braking: str) -> np.ndarray:
    """Apply the braking rule to per-axis mechanical power.

    Parameters
    ----------
    mechanical_w
        ``M·omega`` per axis [W].
    braking
        ``'regenerative'`` (unchanged) or ``'dissipated'`` (negative values become 0).

    Returns
    -------
    numpy.ndarray
        Power drawn per axis [W].
    """
    if braking not in BRAKING_MODES:
        msg = f'braking must be one of {", ".join(BRAKING_MODES)}, got {braking!r}'
        raise ConfigError(msg, key='braking')
    mechanical_w = np.asarray(mechanical_w, dtype=float)
    if braking == 'dissipated':
        return np.maximum(mechanical_w, 0.0)
    return mechanical_w.copy(order='K')


class EnergyIntegrator:
    """Streaming trapezoid integration of power, one chunk at a time.

    The last sample of each chunk is kept, so that the interval between chunks is
    integrated too; the numbers are bit-identical to integrating everything at once.

    Parameters
    ----------
    n_channels
        Number of power columns (e.g. axes, or axes + total).
    """

    def __init__(self, n_channels: int) -> None:
        self.n_channels = int(n_channels)
        self.reset()

    def reset(self) -> None:
        """Forget all samples: the next sample starts at energy 0."""
        self._t: float | None = None
        self._p = np.zeros(self.n_channels)
        self._e = np.zeros(self.n_channels)

    @property
    def energy_j(self) -> np.ndarray:
        """Energy accumulated so far per channel [J] (a copy)."""
        return self._e.copy()

    @property
    def last_time_s(self) -> float | None:
        """Time of the last sample seen, or ``None``."""
        return self._t

    def update(self, t: np.ndarray, power_w: np.ndarray) -> np.ndarray:
        """Integrate one chunk and return the cumulative energy at its samples.

        Parameters
        ----------
        t
            Sample times [s], ``(m,)``, strictly increasing and after the previous chunk.
        power_w
            Power [W], ``(m, n_channels)`` (or ``(m,)`` when ``n_channels == 1``).

        Returns
        -------
        numpy.ndarray
            Cumulative energy [J] at every sample of the chunk, same shape as ``power_w``.

        Raises
        ------
        DataError
            Shapes that do not match or time that does not increase.
        """
        t = np.asarray(t, dtype=float)
        p = np.asarray(power_w, dtype=float)
        flat = p.ndim == 1
        p2 = p.reshape(-1, 1) if flat else p
        if t.ndim != 1 or p2.shape != (t.shape[0], self.n_channels):
            msg = (f'EnergyIntegrator.update: power shape {p.shape} does not match '
                   f'{t.shape[0]} samples x {self.n_channels} channels')
            raise DataError(msg, file='<power>')
        if t.shape[0] == 0:
            return p.copy()
        first = self._t is None
        if first:
            dt = np.diff(t)
        else:
            dt = np.empty(t.shape[0])
            dt[0] = t[0] - self._t
            np.subtract(t[1:], t[:-1], out=dt[1:])
        if np.any(dt <= 0.0):
            bad = int(np.argmax(dt <= 0.0))
            at = t[bad + 1] if first else t[bad]
            msg = f'EnergyIntegrator.update: time does not increase at t = {at!r} s'
            raise DataError(msg, file='<power>', row=bad + 1)
        # channel-major: the running sum is one contiguous accumulate per channel (a sum
        # along the rows of a narrow row-major array is slow); same additions, same bits
        pt = p2.T
        acc = np.empty((self.n_channels, dt.shape[0] + 1))
        acc[:, 0] = self._e
        inc = acc[:, 1:]
        if first:
            np.add(pt[:, 1:], pt[:, :-1], out=inc)
        else:
            np.add(pt[:, :1], self._p[:, None], out=inc[:, :1])
            np.add(pt[:, 1:], pt[:, :-1], out=inc[:, 1:])
        inc *= 0.5
        inc *= dt
        np.add.accumulate(acc, axis=1, out=acc)
        out = (acc if first else acc[:, 1:]).T
        self._t = float(t[-1])
        self._p = p2[-1].copy()
        self._e = acc[:, -1].copy()
        return out[:, 0] if flat else out


def power_with_total(power_w: np.ndarray, total_w: np.ndarray) -> np.ndarray:
    """``(n, k + 1)`` columns: axes then total, column-major (see ``EnergyIntegrator``)."""
    k = power_w.shape[1]
    out = np.empty((power_w.shape[0], k + 1), order='F')
    out[:, :k] = power_w
    out[:, k] = total_w
    return out


def compute_power(dyn: AxisDynamics, *, braking: str) -> PowerResult:
    """Actual power ``M·omega`` per axis (eq. 1) and cumulative energy (eq. 2).

    Parameters
    ----------
    dyn
        Torques and screw speeds from :func:`.dynamics.compute_dynamics`.
    braking
        ``'regenerative'`` or ``'dissipated'`` (see the module docstring).

    Returns
    -------
    PowerResult
        Power, energy and loss power per axis and in total.
    """
    mechanical = dyn.torque_nm * dyn.omega_rad_s
    power = apply_braking(mechanical, braking=braking)
    total = power.sum(axis=1)
    k = power.shape[1]
    integrator = EnergyIntegrator(k + 1)
    energy = integrator.update(dyn.t, power_with_total(power, total))
    return PowerResult(t=dyn.t, axes=dyn.axes, power_w=power, total_w=total,
                       energy_j=energy[:, :k], total_energy_j=energy[:, k],
                       mechanical_w=mechanical, loss_power_w=dyn.loss_power_w, line=dyn.line,
                       braking=braking)


def energy_by_line(result: PowerResult) -> list[tuple[int, float, float]]:
    """Energy and time spent per source line.

    Each trapezoid interval ``[t[i-1], t[i]]`` is attributed to the line of its *end* sample
    ``line[i]`` (the sample the planner produced while executing that block). The first
    sample has no interval. The per-line energies therefore sum to ``total_energy_j[-1]``
    and the durations to ``t[-1] - t[0]``.

    Parameters
    ----------
    result
        A power result.

    Returns
    -------
    list of (int, float, float)
        ``(line, energy [J], duration [s])`` sorted by line number; line 0 collects samples
        without a source line.
    """
    if result.t.shape[0] < 2:
        return []
    dt = np.diff(result.t)
    de = 0.5 * (result.total_w[1:] + result.total_w[:-1]) * dt
    lines = np.asarray(result.line[1:], dtype=np.int64)
    keys, inverse = np.unique(lines, return_inverse=True)
    energy = np.bincount(inverse, weights=de, minlength=keys.shape[0])
    duration = np.bincount(inverse, weights=dt, minlength=keys.shape[0])
    return [(int(k), float(e), float(d)) for k, e, d in zip(keys, energy, duration)]
