"""One live comparison: samples of any kind in, the comparison's JSON-ready dict out.

:class:`LiveMonitor` routes each live sample (axis, quantity, stamp, value): the measured
trace of the measured axes (``power_w``; with a predictor for a drive trace, ``current_a``,
``torque_nm`` or ``force_n``: ``compare``'s ``instrument.measures``) to a
:class:`~.rows.RowAssembler` whose rows feed the :class:`~.compare.LiveComparison`; in
``live_motion`` mode, the kinematics of the motion axes to a second assembler whose rows feed
the :class:`~.motion.LiveMotionPredictor`, whose output is the prediction. In ``job_live``
mode the prediction comes from outside (:meth:`LiveMonitor.add_prediction`: the running job's
``job/live`` power). Samples of other axes or quantities are counted, never raised on.

Stamps are integer nanoseconds (wall clock); the monitor counts time from the first stamp it
sees (:attr:`LiveMonitor.origin_ns`), so the float seconds of the core keep sub-microsecond
resolution.
"""
from __future__ import annotations

from collections.abc import Mapping
import math
from typing import Any

import numpy as np

from ...errors import DataError
from .compare import LiveComparison, LiveSettings
from .lagworker import LagRunner
from .motion import LiveMotionPredictor
from .rows import Row, RowAssembler

__all__ = ['LIVE_QUANTITIES', 'LiveMonitor', 'SOURCES']

SOURCES = ('job_live', 'live_motion')
"""Where the prediction comes from: the running job's ``job/live``, or the stream's motion."""

LIVE_QUANTITIES = ('power_w', 'current_a', 'torque_nm', 'force_n', 'velocity_m_s',
                   'speed_rad_s', 'position_m', 'acceleration_m_s2', 'energy_j')
"""Quantity names a live sample may carry (as the MQTT bridge's ``QUANTITIES``)."""


class LiveMonitor:
    """Samples and predictions in, the running comparison out (module docstring).

    Parameters
    ----------
    measured_axes
        Axes with a measured power.
    source
        One of :data:`SOURCES`.
    settings
        Comparison options.
    predictor
        The live-motion predictor (``source='live_motion'`` only).
    reorder_s
        How long a row waits for its missing values [s] (:class:`~.rows.RowAssembler`).
    job_id
        The job compared ('' when none).
    band_sigmas
        With a predictor whose machine carries the loss parameters' covariance (a calibrated
        machine): the alarm band's share of the predicted power is this many standard
        uncertainties of the predicted energy so far (``band_source`` ``'calibration'``);
        0, or no covariance: the settings' ``band_pct`` (``'default'``).
    lag_runner
        Where the lag estimates run (:class:`~.compare.LiveComparison`; default: at once).
    """

    def __init__(self, measured_axes: tuple[str, ...], *, source: str,
                 settings: LiveSettings | None = None,
                 predictor: LiveMotionPredictor | None = None, reorder_s: float = 0.5,
                 job_id: str = '', band_sigmas: float = 2.0,
                 lag_runner: LagRunner | None = None):
        if source not in SOURCES:
            msg = f'source must be one of {", ".join(SOURCES)}, got {source!r}'
            raise DataError(msg, file='<measured_live>', column='source')
        if (source == 'live_motion') != (predictor is not None):
            raise DataError('a live_motion comparison needs a predictor, job_live none',
                            file='<measured_live>', column='source')
        self.axes = tuple(measured_axes)
        self.source = source
        self.job_id = job_id
        measures = predictor.measures if predictor is not None else 'shaft'
        if predictor is not None and tuple(predictor.measured_axes) != self.axes:
            raise DataError('the predictor predicts other axes than the measured ones',
                            file='<measured_live>', column='measured_axes')
        self.core = LiveComparison(self.axes, settings, lag_runner=lag_runner,
                                   measures=measures,
                                   gains=predictor.gains if predictor is not None else None)
        self.quantity_name = self.core.quantity.run_field
        """The live quantity of the measured trace (``power_w``, ``current_a``, ...)."""
        self.measured = RowAssembler(tuple((a, self.quantity_name) for a in self.axes),
                                     reorder_s=reorder_s)
        self.predictor = predictor
        self.kinematics = (RowAssembler(predictor.slots, reorder_s=reorder_s)
                           if predictor is not None else None)
        known = set(self.axes) | (set(predictor.axes) if predictor is not None else set())
        self._known_axes = frozenset(known)
        self.origin_ns: int | None = None
        self.unknown_axis = 0
        self.unknown_quantity = 0
        self.unused_quantity = 0
        self.prediction_axes_missing = 0
        self.samples = 0
        self.band_sigmas = float(band_sigmas)

    def _seconds(self, stamp_ns: int) -> float:
        if self.origin_ns is None:
            self.origin_ns = int(stamp_ns)
        return (int(stamp_ns) - self.origin_ns) * 1e-9

    def add_sample(self, axis: str, quantity: str, stamp_ns: int, value: float) -> None:
        """Take one live sample (finite value; stamp [ns]); never raises on its content."""
        self.samples += 1
        if axis not in self._known_axes:
            self.unknown_axis += 1
            return
        if quantity not in LIVE_QUANTITIES:
            self.unknown_quantity += 1
            return
        if not (isinstance(value, float) and math.isfinite(value)):
            self.unknown_quantity += 1
            return
        if self.measured.wants(axis, quantity):
            self._seconds(stamp_ns)
            for row in self.measured.add(axis, quantity, stamp_ns, value):
                self._measured_row(row)
        elif self.kinematics is not None and self.kinematics.wants(axis, quantity):
            self._seconds(stamp_ns)
            for row in self.kinematics.add(axis, quantity, stamp_ns, value):
                self._kinematics_row(row)
        else:
            self.unused_quantity += 1

    def add_prediction(self, stamp_ns: int, power_w: Mapping[str, Any]) -> bool:
        """Take one predicted sample (``job/live``: power per axis [W]); False if unusable."""
        try:
            values = [float(power_w[a]) for a in self.axes]
        except (KeyError, TypeError, ValueError):
            self.prediction_axes_missing += 1
            return False
        t = self._seconds(stamp_ns)
        self.core.add_prediction(np.array([t]), np.array([values]))
        return True

    def _measured_row(self, row: Row) -> None:
        self.core.add_measured(self._seconds(row.stamp_ns), row.values)

    def _kinematics_row(self, row: Row) -> None:
        assert self.predictor is not None
        out = self.predictor.add(self._seconds(row.stamp_ns), row.values)
        if out is not None:
            self.core.add_prediction(*out)
            self._calibrated_band()

    def _calibrated_band(self) -> None:
        if self.predictor is None or not self.band_sigmas > 0.0:
            return
        rel = self.predictor.relative_sd_pct()
        if math.isfinite(rel):
            self.core.set_band(self.band_sigmas * rel, 'calibration')

    def finish(self) -> dict[str, Any]:
        """The stream has ended: flush the assemblers and the predictor; the final figures."""
        if self.kinematics is not None and self.predictor is not None:
            for row in self.kinematics.flush():
                self._kinematics_row(row)
            out = self.predictor.flush()
            if out is not None:
                self.core.add_prediction(*out)
                self._calibrated_band()
        for row in self.measured.flush():
            self._measured_row(row)
        return self._dress(self.core.finish())

    def close(self) -> None:
        """Let go of the comparison's lag runner (its thread) without finishing."""
        self.core.close()

    def snapshot(self) -> dict[str, Any]:
        """The comparison so far (keys: docs/nodes.md, "measured_live")."""
        return self._dress(self.core.snapshot())

    def _dress(self, core: dict[str, Any]) -> dict[str, Any]:
        t = core.pop('time_s')
        stamp = (self.origin_ns * 1e-9 + t
                 if self.origin_ns is not None and math.isfinite(t) else math.nan)
        counters: dict[str, Any] = {
            'samples': self.samples,
            'measured': self.measured.counters.as_dict(),
            'kinematics': (self.kinematics.counters.as_dict()
                           if self.kinematics is not None else None),
            'unknown_axis': self.unknown_axis,
            'unknown_quantity': self.unknown_quantity,
            'unused_quantity': self.unused_quantity,
            'prediction_late': core.pop('prediction_late'),
            'prediction_unusable': self.prediction_axes_missing + (
                self.predictor.failures if self.predictor is not None else 0),
        }
        return {'job_id': self.job_id, 'source': self.source, 'stamp': stamp,
                'axes': list(self.axes), **core, 'counters': counters}
