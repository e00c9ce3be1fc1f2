"""Electrical power of the feed axes from the declared motor and drive (``docs/electrical.md``).

Per axis and sample, from the shaft power ``M·omega`` of :mod:`.dynamics` and the data-sheet
values of :mod:`feed_axis_energy.machine.drives`:

* motor terminals (between converter and motor, where the paper measured):
  ``P_motor = M·omega + P_cu + P_fe`` with copper ``P_cu = k_cu·M²`` (``k_cu = factor·R/kt²``)
  and iron ``P_fe = k_h·|omega| + k_e·omega²``; negative while the axis brakes;
* the drive's converter: ``P_conv = P_motor/eta_c`` while motoring, ``P_motor·eta_c`` while
  braking (it returns less), so its loss ``P_conv - P_motor`` is never negative;
* the braking rule: ``regenerative`` returns at most ``regeneration_limit_w`` (no limit when
  it is not given), ``dissipated`` returns nothing; the rest is burned in the brake chopper:
  ``burned = max(-P_conv - limit, 0)``;
* supply side (the grid side of the drive): ``P_supply = P_conv + burned + standby``, and the
  cabinet's standby (``supply.standby_w``) once for the machine.

Declared catalog effects add their power at both points, as they do to the mechanical power.
The causes (:mod:`.breakdown`: the mechanical ones with regenerative braking, the effects,
``copper``, ``iron``, ``converter``, ``standby``, ``braking_burned``) add up to ``P_supply``
of every axis at every sample; the mechanical ones, the effects, ``copper`` and ``iron`` add
up to ``P_motor``. Everything is per sample, so it runs chunk by chunk
(:class:`ElectricalAccumulator`) like the mechanical power.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any, cast

import numpy as np

from .breakdown import BreakdownAccumulator
from .dynamics import AxisDynamics
from .energy import ElectricalPower, PowerResult
from ..errors import ConfigError
from ..machine import Machine

__all__ = ['ELECTRICAL_CAUSES', 'POINTS', 'electrical_power',
           'with_electrical', 'ElectricalAccumulator', 'add_block_electrical']

ELECTRICAL_CAUSES = ('copper', 'iron', 'converter', 'standby')
POINTS = {'motor': 'motor terminals (between converter and motor)',
          'supply': 'supply side of the drives (grid side: converter losses, standby, '
                    'braking rule)'}


def electrical_power(dyn: AxisDynamics, mechanical_w: np.ndarray, machine: Machine, *,
                     effects_w: np.ndarray | None = None) -> ElectricalPower | None:
    """Electrical power of the axes of ``dyn`` (``None`` when the machine declares no drive).

    Parameters
    ----------
    dyn
        Dynamics of one chunk (screw torque and speed).
    mechanical_w
        ``M·omega`` per axis before the braking rule [W], ``(n, k)``.
    machine
        The machine: its axes' ``drive``, ``supply`` and ``braking``.
    effects_w
        Summed power of the declared effects ``(n, k)`` [W] or ``None``.

    Returns
    -------
    ElectricalPower or None
    """
    if not machine.electrical:
        return None
    n, k = dyn.torque_nm.shape
    # column-major like the planner's arrays: every step below works on one axis's column
    parts = {c: np.empty((n, k), order='F') for c in ELECTRICAL_CAUSES}
    motor = np.empty((n, k), order='F')
    supply = np.empty((n, k), order='F')
    burned = np.empty((n, k), order='F')
    for j, name in enumerate(dyn.axes):
        drive = machine.axis(name).drive
        if drive is None:
            # machine_from_dict refuses this; a machine built in code may still hold it
            msg = 'the electrical model needs a drive on every axis'
            raise ConfigError(msg, key=f'axes.{name}.drive')
        torque = dyn.torque_nm[:, j]
        omega = dyn.omega_rad_s[:, j]
        copper = np.multiply(torque, torque, out=parts['copper'][:, j])
        copper *= drive.copper_k_w_nm2
        iron = parts['iron'][:, j]
        np.multiply(np.abs(omega), drive.iron.k_h_w_s_rad, out=iron)
        iron += drive.iron.k_e_w_s2_rad2 * (omega * omega)
        p_motor = np.add(mechanical_w[:, j], copper, out=motor[:, j])
        p_motor += iron
        eta = drive.converter_efficiency
        # >= 0 both ways: motoring it takes P/eta, braking it returns P·eta
        conv = np.maximum(p_motor, 0.0, out=parts['converter'][:, j])
        conv *= 1.0 / eta - 1.0
        if eta != 1.0:
            conv -= (1.0 - eta) * np.minimum(p_motor, 0.0)
        if machine.braking == 'dissipated':
            limit = 0.0
        elif drive.regeneration_limit_w is None:
            limit = np.inf
        else:
            limit = drive.regeneration_limit_w
        p_supply = np.add(p_motor, conv, out=supply[:, j])      # the converter's input
        b = np.negative(p_supply, out=burned[:, j])
        b -= limit
        np.maximum(b, 0.0, out=b)
        parts['standby'][:, j] = drive.standby_w
        p_supply += b
        p_supply += drive.standby_w
    if effects_w is not None:
        motor += effects_w
        supply += effects_w
    cabinet = machine.supply.standby_w if machine.supply is not None else 0.0
    point = machine.supply.measured_at if machine.supply is not None else 'motor'
    return ElectricalPower(motor_w=motor, supply_w=supply,
                           parts=tuple((c, parts[c]) for c in ELECTRICAL_CAUSES),
                           burned_w=burned, cabinet_w=float(cabinet), measured_at=point)


def with_electrical(dyn: AxisDynamics, power: PowerResult, machine: Machine) -> PowerResult:
    """``power`` (declared effects included) with its ``electrical`` part when the machine
    declares drives; ``power`` itself otherwise."""
    if not machine.electrical:
        return power
    extra = None
    for _label, part in power.effect_power_w:
        extra = part.copy() if extra is None else extra + part
    return replace(power, electrical=electrical_power(dyn, power.mechanical_w, machine,
                                                      effects_w=extra))


class _Trapezoid:
    """Trapezoid integral and largest value of per-axis power and of its total (plus a
    constant ``offset``), continued across chunks."""

    def __init__(self) -> None:
        self.energy: np.ndarray | None = None     # (k,) per axis
        self.peak: np.ndarray | None = None       # (k + 1,): per axis, then the total
        self._last: np.ndarray | None = None
        self._t_last: float | None = None

    def add(self, t: np.ndarray, power: np.ndarray, offset: float = 0.0) -> None:
        self._start(power.shape[1])
        # one weighted sum over the samples (w_i = (dt_{i-1} + dt_i) / 2): no temporaries
        dt = np.diff(t)
        w = np.zeros(t.shape[0])
        w[:-1] += 0.5 * dt
        w[1:] += 0.5 * dt
        if self._last is not None:
            d0 = float(t[0]) - cast(float, self._t_last)     # set with self._last
            w[0] += 0.5 * d0
            cast(np.ndarray, self.energy)[:] += 0.5 * d0 * self._last
        self._columns(w, power, offset)
        self._last = power[-1].copy()
        self._t_last = float(t[-1])

    def add_weighted(self, w: np.ndarray, power: np.ndarray, offset: float = 0.0) -> None:
        """Quadrature nodes with weights ``w`` [s] (:mod:`feed_axis_energy.plan.nodes`): the
        integral is the weighted sum, no interval to the previous rows."""
        self._start(power.shape[1])
        if power.shape[0]:
            self._columns(w, power, offset)

    def _start(self, k: int) -> None:
        if self.energy is None:
            self.energy = np.zeros(k)
            self.peak = np.full(k + 1, -np.inf)

    def _columns(self, w: np.ndarray, power: np.ndarray, offset: float) -> None:
        """``w @ power`` into the energy, the largest values into the peaks: column by
        column (reductions across a narrow array are slow in numpy)."""
        energy, peak = cast(np.ndarray, self.energy), cast(np.ndarray, self.peak)
        k = power.shape[1]
        total = power[:, 0].copy()
        for j in range(k):
            column = power[:, j]
            energy[j] += np.einsum('i,i', w, column)
            peak[j] = max(peak[j], float(column.max()))
            if j:
                total += column
        peak[k] = max(peak[k], float(total.max()) + offset)


class ElectricalAccumulator:
    """Electrical energy, peaks and breakdown by cause, chunk by chunk (bounded memory).

    Memory: a few numbers per axis and cause; nothing per sample. With ``per_line``, also
    the energy of every source line per axis and cause (:class:`.breakdown.BreakdownAccumulator`),
    from which :meth:`lines_energy` gives each line's energy at the motor terminals and at the
    supply side.
    """

    def __init__(self, *, per_line: bool = False) -> None:
        self.axes: tuple[str, ...] = ()
        self.measured_at = 'motor'
        self.cabinet_w = 0.0
        self.causes = BreakdownAccumulator(per_line=per_line)
        self._motor = _Trapezoid()
        self._supply = _Trapezoid()
        self._returned = _Trapezoid()
        self._t_first: float | None = None
        self._t_last: float | None = None

    def add(self, dyn: AxisDynamics, mechanical_w: np.ndarray, elec: ElectricalPower, *,
            braking: str, effects: Sequence[tuple[str, np.ndarray]] = (),
            weights: np.ndarray | None = None, span_s: tuple[float, float] | None = None
            ) -> None:
        """Take one chunk (in time order): its dynamics, ``M·omega``, electrical power and
        the declared effects' parts (:func:`.simulate.declared_effects_parts`).

        ``weights`` and ``span_s``: the rows are quadrature nodes with these weights [s]
        covering the time ``(begin, end)`` [s] (the energy by phase,
        :mod:`feed_axis_energy.sim.quadrature`) instead of samples in time order."""
        t = dyn.t
        if weights is not None and span_s is None:
            raise ValueError('quadrature weights need the span_s they cover')
        if t.shape[0] == 0 and weights is None:
            return
        if self._t_first is None:
            self.axes = tuple(dyn.axes)
            self.measured_at = elec.measured_at
            self.cabinet_w = elec.cabinet_w
            self._t_first = float(t[0]) if span_s is None else float(span_s[0])
        # the mechanical causes with regenerative braking: the rule acts in the drive here
        self.causes.add(dyn, mechanical_w, braking=braking, effects=effects,
                        extra=elec.parts, burned=elec.burned_w, weights=weights)
        standby = elec.parts[ELECTRICAL_CAUSES.index('standby')][1]
        # what the drives return to the supply: the negative part without their standby
        returned = np.maximum(standby - elec.supply_w, 0.0)
        if weights is None:
            self._motor.add(t, elec.motor_w)
            self._supply.add(t, elec.supply_w, elec.cabinet_w)
            self._returned.add(t, returned)
            self._t_last = float(t[-1])
            return
        self._motor.add_weighted(weights, elec.motor_w)
        self._supply.add_weighted(weights, elec.supply_w, elec.cabinet_w)
        self._returned.add_weighted(weights, returned)
        self._t_last = float(cast(tuple, span_s)[1])

    def lines_energy(self, lines: np.ndarray,
                     duration_s: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Energy [J] of the given source lines at the motor terminals and at the supply side
        (the cabinet's standby for each line's ``duration_s`` included); ``None`` without
        ``per_line`` or before any chunk.

        Per line the causes add up to the supply side of every axis; the motor terminals are
        all causes but ``converter``, ``standby`` and ``braking_burned`` (module docstring).
        """
        table = self.causes.lines_table(lines)
        if table is None:
            return None
        _, by_cause = table
        causes = self.causes.causes
        supply = by_cause.sum(axis=1)
        drive = sum(by_cause[:, causes.index(c)] for c in ('converter', 'standby',
                                                           'braking_burned'))
        return supply - drive, supply + self.cabinet_w * np.asarray(duration_s, float)

    @property
    def duration_s(self) -> float:
        """Time from the first to the last sample [s]."""
        if self._t_first is None:
            return 0.0
        return cast(float, self._t_last) - self._t_first     # set with self._t_first

    def summary(self) -> dict[str, Any]:
        """The summary's ``electrical`` object (``docs/electrical.md``); ``{}`` before any
        chunk."""
        if self._motor.energy is None:
            return {}
        axes = self.axes
        cabinet_j = self.cabinet_w * self.duration_s

        def per_axis(values: np.ndarray, extra: float | None = None) -> dict[str, float]:
            out = {a: float(values[j]) for j, a in enumerate(axes)}
            if extra is not None:
                out['cabinet'] = float(extra)
            out['total'] = float(values.sum() + (extra or 0.0))
            return out

        # the casts: the supply and returned sums take every chunk the motor sums take
        supply_peak = cast(np.ndarray, self._supply.peak)
        returned = cast(np.ndarray, self._returned.energy)
        motor = per_axis(self._motor.energy)
        supply = per_axis(cast(np.ndarray, self._supply.energy), cabinet_j)
        by_cause = self.causes.by_cause()
        for cause, row in by_cause.items():
            total = row.pop('total')
            row['cabinet'] = cabinet_j if cause == 'standby' else 0.0
            row['total'] = total + row['cabinet']
        return {
            'measured_at': self.measured_at,
            'point': POINTS[self.measured_at],
            'energy_j': motor if self.measured_at == 'motor' else supply,
            'motor_energy_j': motor,
            'supply_energy_j': supply,
            'motor_peak_power_w': _peaks(cast(np.ndarray, self._motor.peak), axes),
            'supply_peak_power_w': _peaks(supply_peak, axes),
            'cabinet_standby_w': self.cabinet_w,
            'returned_j': float(returned.sum()),
            'causes': list(self.causes.causes),
            'energy_by_cause_j': by_cause,
        }


def _peaks(peak: np.ndarray, axes: tuple[str, ...]) -> dict[str, float]:
    out = {a: float(peak[j]) for j, a in enumerate(axes)}
    out['total'] = float(peak[-1])
    return out


def add_block_electrical(blocks: list[dict[str, Any]], acc: ElectricalAccumulator) -> None:
    """Give every block dict (``line``, ``duration_s``: a summary's ``top_blocks``) its
    ``motor_energy_j`` and ``supply_energy_j`` [J]; nothing without a per-line accumulator."""
    if not blocks:
        return
    energy = acc.lines_energy(np.array([b['line'] for b in blocks], dtype=np.int64),
                              np.array([b['duration_s'] for b in blocks]))
    if energy is None:
        return
    for block, motor, supply in zip(blocks, energy[0].tolist(), energy[1].tolist()):
        block['motor_energy_j'] = motor
        block['supply_energy_j'] = supply
