"""Prediction from the live motion: measured kinematics in, predicted power out, chunk by chunk.

For runs without an NC program (the UMich mill: motion from data), the prediction is what
``compare`` computes offline from the run's own kinematics: the motion rebuilt at the
machine's simulation rate between the coarse stamps
(:func:`~feed_axis_energy.measured.motiondata.reconstruct_motion`, the ``pulses`` model,
from positions, velocities and, where the stream sends them, accelerations; 0 otherwise), then
:func:`~feed_axis_energy.sim.simulate_motion` and the measured quantity's predicted trace
(:func:`~feed_axis_energy.measured.quantity.predicted_signal`).

The reconstruction of an interval depends only on the samples at its two ends, and the
power of a machine whose declared effects are all sample-local depends only on its sample, so
rebuilding ``chunk_rows`` intervals at a time (each chunk starting at the last row of the
previous one, whose sample is not repeated) gives the whole-record prediction, chunk by
chunk, with the data's one-chunk delay. Rows with a gap between them are bridged the same
way (the offline comparison refuses gaps unless a run allows them).
"""
from __future__ import annotations

import math

import numpy as np

from ...errors import ConfigError, DataError
from ...machine import Machine
from ...physics import REST_SPEED_M_S, UncertaintyAccumulator
from ...sim import simulate_motion, streamable
from ..motiondata import reconstruct_motion
from ..quantity import MEASURES, omega_columns, predicted_signal, quantity_of, torque_per_unit

__all__ = ['KINEMATICS', 'LiveMotionPredictor']

KINEMATICS = ('position_m', 'velocity_m_s', 'acceleration_m_s2')
"""Live quantities a kinematics row may hold, in this order (position and velocity needed)."""


class LiveMotionPredictor:
    """Kinematics rows in, predicted power samples out (see the module docstring).

    Parameters
    ----------
    machine
        The machine model (its simulation rate, braking rule and losses).
    axes
        The motion axes the stream sends, in row order.
    measured_axes
        Axes whose predicted power is returned, in this order.
    quantities
        The kinematic quantities of a row (:data:`KINEMATICS`; position and velocity
        required), per axis in this order.
    load_kg
        Workpiece mass [kg].
    measures
        What the measured trace is (``compare``'s ``instrument.measures``: ``shaft``,
        ``motor``, ``supply``, ``current``, ``torque``, ``force``).
    kt_nm_a
        Torque constants [N·m/A] per axis for ``current`` (win over the machine's drives).
    chunk_rows
        Intervals rebuilt at once.

    Raises
    ------
    ConfigError
        An axis the machine lacks, a machine with effects that are not sample-local, bad
        quantities or options.
    """

    def __init__(self, machine: Machine, *, axes: tuple[str, ...],
                 measured_axes: tuple[str, ...], quantities: tuple[str, ...] = KINEMATICS,
                 load_kg: float = 0.0, measures: str = 'shaft', chunk_rows: int = 10,
                 kt_nm_a: dict[str, float] | None = None):
        where = '<measured_live>'
        known = machine.axis_names
        missing = [a for a in tuple(axes) + tuple(measured_axes) if a not in known]
        if missing:
            msg = f'axis {missing[0]!r} is not an axis of the machine ({", ".join(known)})'
            raise ConfigError(msg, file=where, key='axes')
        if not set(measured_axes) <= set(axes):
            raise ConfigError('the measured axes must be among the motion axes', file=where,
                              key='axes')
        if quantities[:2] != KINEMATICS[:2] or not set(quantities) <= set(KINEMATICS):
            msg = f'quantities must start with position_m, velocity_m_s; got {quantities}'
            raise ConfigError(msg, file=where, key='quantities')
        if not streamable(machine):
            msg = 'the machine declares effects that are not sample-local: no live prediction'
            raise ConfigError(msg, file=where, key='effects')
        if measures not in MEASURES:
            msg = f'measures must be one of {", ".join(MEASURES)}, got {measures!r}'
            raise ConfigError(msg, file=where, key='measures')
        self.quantity = quantity_of(measures)
        if not (math.isfinite(load_kg) and load_kg >= 0.0) or chunk_rows < 1:
            raise ConfigError('load_kg must be >= 0 and chunk_rows >= 1', file=where,
                              key='load_kg')
        self.machine = machine
        self.axes = tuple(axes)
        self.measured_axes = tuple(measured_axes)
        self.quantities = tuple(quantities)
        self.load_kg = float(load_kg)
        self.measures = measures
        self.gains: tuple[float, ...] | None = None
        """``torque_per_unit`` of the measured axes for a drive trace (None: a power)."""
        if not self.quantity.is_power:
            gains = torque_per_unit(measures, machine, self.measured_axes,
                                    declared_kt=kt_nm_a, manifest=where)
            self.gains = tuple(float(g) for g in gains)     # type: ignore[arg-type]
        self._direction = {a: 0.0 for a in self.measured_axes}
        self.chunk_rows = int(chunk_rows)
        self.failures = 0
        """Chunks that could not be simulated (a message says why: :attr:`last_error`)."""
        self.last_error = ''
        self._t: list[float] = []
        self._rows: list[np.ndarray] = []
        self._started = False
        # the energy's uncertainty from the loss parameters' covariance (a calibrated
        # machine, fit-loss): the alarm's band (monitor)
        self._uncertainty = UncertaintyAccumulator.of(machine)
        self._energy_j = np.zeros(len(self.measured_axes))

    def relative_sd_pct(self) -> float:
        """Standard uncertainty of the predicted energy of the measured axes so far, in % of
        it, from the machine's ``loss_covariance`` (NaN without one on every measured axis)."""
        if self._uncertainty is None:
            return math.nan
        sd = self._uncertainty.standard_uncertainty_j()
        if any(a not in sd for a in self.measured_axes):
            return math.nan
        energy = abs(float(self._energy_j.sum()))
        value = math.sqrt(math.fsum(sd[a] ** 2 for a in self.measured_axes))
        return 100.0 * value / energy if energy > 0.0 else math.nan

    @property
    def slots(self) -> tuple[tuple[str, str], ...]:
        """``(axis, quantity)`` of a row's values, axis by axis."""
        return tuple((a, q) for a in self.axes for q in self.quantities)

    def add(self, t: float, values: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Take one kinematics row (time [s], values in :attr:`slots` order).

        Returns
        -------
        tuple or None
            ``(t, values)`` of new predicted samples ([s]; ``(n, k)`` power [W], or for a
            drive trace ``(n, 2k)``: the trace in its unit, then ``omega`` [rad/s], per
            measured axis) once a chunk is complete, else ``None``.
        """
        self._t.append(float(t))
        self._rows.append(np.asarray(values, dtype=float))
        if len(self._t) - 1 < self.chunk_rows:
            return None
        return self._run()

    def flush(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Predict what is left (the stream has ended)."""
        return self._run() if len(self._t) >= 2 else None

    def _run(self) -> tuple[np.ndarray, np.ndarray] | None:
        t = np.array(self._t)
        rows = np.vstack(self._rows).reshape(t.size, len(self.axes), len(self.quantities))
        # the last row starts the next chunk
        self._t, self._rows = self._t[-1:], self._rows[-1:]
        acc = rows[:, :, 2] if len(self.quantities) > 2 else None
        try:
            motion = reconstruct_motion(t, rows[:, :, 0], axes=self.axes,
                                        rate_hz=self.machine.planner.rate_hz,
                                        vel=rows[:, :, 1], acc=acc, source='measured/live')
            sim = simulate_motion(motion, self.machine, load_kg=self.load_kg)
            if self.gains is None:
                power = values = predicted_signal(self.measures, sim, self.machine,
                                                  self.measured_axes)
            else:
                signal = predicted_signal(self.measures, sim, self.machine,
                                          self.measured_axes, gains=self.gains,
                                          start_direction=self._direction)
                omega = omega_columns(sim, self.measured_axes)
                power = signal * np.array(self.gains) * omega
                values = np.hstack([signal, omega])
                self._track_direction(sim)
        except (DataError, ConfigError, ValueError) as err:
            self.failures += 1
            self.last_error = str(err)
            return None
        times = sim.power.t
        if self._uncertainty is not None:
            self._uncertainty.add(sim.dynamics, sim.power.mechanical_w,
                                  braking=self.machine.braking)
        self._energy_j += np.trapezoid(power, times, axis=0)
        if self._started:
            times, values = times[1:], values[1:]
        self._started = True
        return times, values

    def _track_direction(self, sim) -> None:
        """The direction each measured axis last moved in (the next chunk's start)."""
        dyn = sim.dynamics
        for a in self.measured_axes:
            if a not in dyn.axes:
                continue
            v = dyn.velocity_m_s[:, dyn.axes.index(a)]
            moving = np.flatnonzero(np.abs(v) > REST_SPEED_M_S)
            if moving.size:
                self._direction[a] = float(np.sign(v[moving[-1]]))
