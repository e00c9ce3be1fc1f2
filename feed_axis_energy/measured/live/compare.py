"""Running comparison of a live measured power stream with its prediction.

The rules are :mod:`feed_axis_energy.measured.compare`'s, applied as the data arrive:

* **Lag**: how much later the measured stream is than the prediction is found by
  :func:`~feed_axis_energy.measured.align.estimate_offset` on the summed power of the measured
  axes, within ``±max_lag_s``, with the instrument's window and stamp. It is re-estimated every
  ``realign_every_s`` of measured time on what the rings hold (the last ``ring_s``), from
  ``min_align_s`` on. A ``'weak'`` estimate is used as offset 0, as ``compare`` does. The lag
  is *frozen* (no more estimates) once ``freeze_count`` estimates in a row agree within
  ``freeze_tol_s``; ``freeze_count = 0`` never freezes. At :meth:`LiveComparison.finish`, a
  lag not yet frozen is estimated once more on the rings. Estimates run where the caller's
  ``lag_runner`` says (:mod:`.lagworker`): at once (the default), or on a worker thread so
  that delivering samples never waits for one (the ``measured_live`` node).
* **Aligned prediction**: the prediction averaged over each measured sample's window at the
  lag (:func:`~feed_axis_energy.measured.align.align_simulated`, the instrument model; window 0
  is linear interpolation), held at its first and last value outside its range (the machine
  rests before and after).
* **Energies to date**: trapezoids over the measured stamps of the measured and the aligned
  predicted power, per axis and total, as Table 1's ``energy_meas_j``/``energy_sim_j``. The
  rows of the last ``ring_s`` follow the current lag; older rows are *settled* with the lag
  in force when they left the ring and only their sums are kept. For a run shorter than
  ``ring_s`` the final figures therefore equal an offline comparison at the same lag.
  Measured rows the prediction does not reach yet (lag and stream delay) wait, counted as
  ``pending``; :meth:`LiveComparison.finish` evaluates them with the prediction held.
* **Alarm**: the residual (measured minus aligned predicted power, total of the measured
  axes), averaged over the last ``alarm_window_s`` of rows as they are evaluated, against a
  band ``band_floor_w + band_pct % of |mean predicted power|`` over the same window. The alarm
  switches on when the mean stays outside the band for ``alarm_hold_s`` and off when it stays
  inside ``release_fraction`` of the band for as long (hysteresis). ``band_source`` says where
  ``band_pct`` came from (the machine's calibration, or the configured default). The alarm is
  armed once the lag has a usable estimate (not before the first, nor while it is
  ``'weak'``): at an unknown lag a residual says nothing.

**Drive traces** (``measures`` current, torque or force, ``compare``'s quantities): the measured
rows hold the trace ``q`` in its unit and the prediction ``q`` and the screw speed ``omega``
[rad/s] per axis. As ``compare`` does, the lag is estimated on the magnitudes of the traces,
each scaled by its measured RMS (over the ring), and everything in watts (the powers at the
stamp, the energies, the alarm) is ``q·g·omega`` of both sides with the aligned predicted
``omega`` and the axis's gain ``g`` [N·m per unit] (``I·kt·omega`` for current); the trace
itself is reported in its unit beside (``signal``: values at the stamp, RMS of the residual
over the rows evaluated).

Memory is bounded: ``ring_s`` (and at most ``max_ring_samples``) of each stream, a window
of alarm rows, and sums. Nothing raises on data.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import math
from typing import Any

import numpy as np

from ...errors import DataError
from ..align import align_simulated, stamp_shift, STAMPS
from ..compare import DEFAULT_MAX_LAG_S
from ..quantity import MEASURES, quantity_of
from .lagworker import InlineLag, LagOutcome, LagRequest, LagRunner
from .ring import SampleRing

__all__ = ['BAND_SOURCES', 'LagState', 'LiveComparison', 'LiveSettings']

BAND_SOURCES = ('calibration', 'default')
"""Where an alarm band's percentage came from."""


@dataclass(frozen=True)
class LiveSettings:
    """Options of :class:`LiveComparison` (see the module docstring for their roles).

    Attributes
    ----------
    max_lag_s, window_s, stamp, min_correlation
        As ``compare``'s (largest lag searched [s], instrument window [s] and stamp, weak
        correlation threshold).
    ring_s
        Time span of measured rows kept for re-alignment [s]; the prediction is kept from
        ``max_lag_s + window_s + 1 s`` before the oldest of them (and at most
        ``max_ring_samples``: a prediction that runs further ahead loses its oldest
        samples).
    realign_every_s
        Measured time between lag estimates [s].
    min_align_s
        Measured time before the first estimate [s].
    freeze_count, freeze_tol_s
        Estimates in a row within ``freeze_tol_s`` [s] that freeze the lag (0: never).
    max_ring_samples
        Most samples either ring holds, whatever its time span.
    alarm_window_s, alarm_hold_s
        Averaging window of the alarm's residual [s]; how long it must stay outside (or
        back inside) the band [s].
    band_floor_w, band_pct, band_source
        The band: ``band_floor_w`` [W] plus ``band_pct`` [%] of the mean predicted power;
        ``band_source`` one of :data:`BAND_SOURCES`.
    release_fraction
        Fraction of the band the residual must fall within to release the alarm.
    alarm_every_s
        Measured time between evaluations of the newest rows for the alarm [s] (rows are
        evaluated in batches: a fast stream costs one alignment per batch, not per row).
    fixed_lag_s
        Compare at this lag [s] instead of estimating one (status ``'fixed'``, as
        ``compare``'s ``offset_s``).
    """

    max_lag_s: float = DEFAULT_MAX_LAG_S
    window_s: float = 0.0
    stamp: str = 'end'
    min_correlation: float = 0.5
    ring_s: float = 300.0
    realign_every_s: float = 5.0
    min_align_s: float = 10.0
    freeze_count: int = 0
    freeze_tol_s: float = 0.5e-3
    max_ring_samples: int = 2_000_000
    alarm_window_s: float = 2.0
    alarm_hold_s: float = 1.0
    band_floor_w: float = 5.0
    band_pct: float = 25.0
    band_source: str = 'default'
    release_fraction: float = 0.8
    fixed_lag_s: float | None = None
    alarm_every_s: float = 0.1

    def __post_init__(self) -> None:
        positive = ('ring_s', 'realign_every_s', 'alarm_window_s', 'freeze_tol_s',
                    'alarm_every_s')
        at_least_0 = ('max_lag_s', 'window_s', 'min_align_s', 'alarm_hold_s', 'band_floor_w',
                      'band_pct')
        for name in positive + at_least_0:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value) or value < 0 \
                    or (name in positive and value == 0):
                bound = '> 0' if name in positive else '>= 0'
                msg = f'{name} must be a finite number {bound}, got {value!r}'
                raise DataError(msg, file='<live settings>', column=name)
        if self.stamp not in STAMPS:
            msg = f'stamp must be one of {", ".join(STAMPS)}, got {self.stamp!r}'
            raise DataError(msg, file='<live settings>', column='stamp')
        if self.band_source not in BAND_SOURCES:
            msg = f'band_source must be one of {", ".join(BAND_SOURCES)}'
            raise DataError(msg, file='<live settings>', column='band_source')
        if not 0.0 < self.release_fraction <= 1.0:
            msg = f'release_fraction must lie in (0, 1], got {self.release_fraction!r}'
            raise DataError(msg, file='<live settings>', column='release_fraction')
        if self.fixed_lag_s is not None and not math.isfinite(self.fixed_lag_s):
            raise DataError('fixed_lag_s must be a finite number', file='<live settings>',
                            column='fixed_lag_s')
        if self.freeze_count < 0 or self.max_ring_samples < 16:
            msg = 'freeze_count must be >= 0 and max_ring_samples >= 16'
            raise DataError(msg, file='<live settings>', column='freeze_count')


@dataclass
class LagState:
    """The lag in use and how it was found.

    Attributes
    ----------
    lag_s
        Offset used: how much later the measured stream is than the prediction [s].
    found_s
        The last estimate (NaN before one), used unless its status is ``'weak'``.
    status
        ``'none'`` before the first estimate, else the estimate's status
        (``estimate_offset``: ok, weak, edge, ambiguous), or ``'fixed'`` (given).
    frozen
        Whether the lag is fixed for the rest of the stream.
    estimates
        Estimates made so far.
    correlation, drift_ppm
        Peak correlation and clock-rate difference of the last estimate (NaN if none).
    message
        The last estimate's sentence, or why there is none.
    """

    lag_s: float = 0.0
    found_s: float = math.nan
    status: str = 'none'
    frozen: bool = False
    estimates: int = 0
    correlation: float = math.nan
    drift_ppm: float = math.nan
    message: str = 'not estimated yet'
    agreeing: int = 0

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (NaN stays NaN: the payload maps it to null)."""
        return {'lag_s': self.lag_s, 'found_s': self.found_s, 'status': self.status,
                'frozen': self.frozen, 'estimates': self.estimates,
                'correlation': self.correlation, 'drift_ppm': self.drift_ppm,
                'message': self.message}


class _Alarm:
    """Windowed mean residual against a band, with hysteresis in time."""

    def __init__(self, s: LiveSettings):
        self.s = s
        self.rows: deque[tuple[float, float, float]] = deque()
        self.sum_r = 0.0
        self.sum_p = 0.0
        self.active = False
        self.count = 0
        self.since: float | None = None     # start of the current excursion (or return)
        self.mean_r = math.nan
        self.band = math.nan
        self.armed = False
        self.pct = s.band_pct
        self.source = s.band_source

    def feed(self, t: float, residual: float, predicted: float) -> None:
        s = self.s
        self.armed = True
        self.rows.append((t, residual, predicted))
        self.sum_r += residual
        self.sum_p += predicted
        while self.rows and self.rows[0][0] <= t - s.alarm_window_s:
            _, r, p = self.rows.popleft()
            self.sum_r -= r
            self.sum_p -= p
        n = len(self.rows)
        self.mean_r = self.sum_r / n
        self.band = s.band_floor_w + 0.01 * self.pct * abs(self.sum_p / n)
        switching = (abs(self.mean_r) > self.band if not self.active
                     else abs(self.mean_r) < s.release_fraction * self.band)
        if not switching:
            self.since = None
            return
        if self.since is None:
            self.since = t
        if t - self.since >= s.alarm_hold_s:
            self.active = not self.active
            self.count += int(self.active)
            self.since = None

    def as_dict(self) -> dict[str, Any]:
        s = self.s
        return {'armed': self.armed, 'active': self.active, 'count': self.count,
                'residual_w': self.mean_r, 'band_w': self.band, 'band_floor_w': s.band_floor_w,
                'band_pct': self.pct, 'band_source': self.source, 'window_s': s.alarm_window_s,
                'hold_s': s.alarm_hold_s}


class LiveComparison:
    """Measured rows and predicted samples in, running comparison out (module docstring).

    Parameters
    ----------
    axes
        The measured axes, in the order of the values given to :meth:`add_measured` and
        :meth:`add_prediction`.
    settings
        Options (:class:`LiveSettings`).
    lag_runner
        Where the lag estimates run (:mod:`.lagworker`): :class:`~.lagworker.InlineLag` (the
        default: at once, in the caller's thread) or :class:`~.lagworker.ThreadedLag` (on a
        worker thread, so that :meth:`add_measured` never waits for one; an estimate is then
        used from the first row after it finished, and rows that leave the ring before are
        settled at the lag in force, so only runs longer than ``ring_s`` can end otherwise).
        :meth:`finish` closes it.
    measures, gains
        What the measured rows hold (``compare``'s ``instrument.measures``; a power by
        default) and, for a drive trace, the gain ``g`` [N·m per unit] of each axis
        (:func:`~feed_axis_energy.measured.quantity.torque_per_unit`); the prediction then
        holds the trace and ``omega`` [rad/s] per axis (module docstring).

    Times are float seconds on one clock shared by both streams (the caller subtracts one
    origin from wall-clock stamps, so that float seconds keep microseconds).
    """

    def __init__(self, axes: tuple[str, ...], settings: LiveSettings | None = None, *,
                 lag_runner: LagRunner | None = None, measures: str = 'shaft',
                 gains: tuple[float, ...] | None = None):
        if not axes:
            raise DataError('no measured axes to compare', file='<live>', column='axes')
        self.axes = tuple(axes)
        self.s = settings or LiveSettings()
        k = len(self.axes)
        s = self.s
        if measures not in MEASURES:
            msg = f'measures must be one of {", ".join(MEASURES)}, got {measures!r}'
            raise DataError(msg, file='<live>', column='measures')
        self.quantity = quantity_of(measures)
        self._gains: np.ndarray | None = None
        if not self.quantity.is_power:
            g = np.asarray(gains if gains is not None else (), dtype=float).reshape(-1)
            if g.size != k or not (np.isfinite(g).all() and (g != 0.0).all()):
                msg = f'a {measures} trace needs a finite, non-zero gain per measured axis'
                raise DataError(msg, file='<live>', column='gains')
            self._gains = g
        self._pred_cols = k if self._gains is None else 2 * k
        self.meas = SampleRing(k, span_s=s.ring_s, max_samples=s.max_ring_samples)
        # the prediction is kept as far back as the oldest measured row may look
        self.pred = SampleRing(self._pred_cols, span_s=math.inf,
                               max_samples=s.max_ring_samples)
        self._reach_s = s.max_lag_s + s.window_s + 1.0
        self.lag = LagState()
        if s.fixed_lag_s is not None:
            self.lag = LagState(lag_s=float(s.fixed_lag_s), status='fixed', frozen=True,
                                message=f'lag {s.fixed_lag_s:+.4f} s given by the caller')
        self._shift = stamp_shift(s.window_s, s.stamp)
        self._next_align = math.nan
        self._first_t = math.nan
        # settled sums: trapezoid sums of rows that left the ring, and the last such row
        self._e_meas = np.zeros(k)
        self._e_pred = np.zeros(k)
        self._settled_last: tuple[float, np.ndarray, np.ndarray] | None = None
        # drive traces: the residual in the trace's unit, squared and summed, over settled rows
        self._sq_settled = np.zeros(k)
        self._latest_q: tuple[np.ndarray, np.ndarray] | None = None
        self._alarm = _Alarm(s)
        self._alarm_t = -math.inf     # newest row fed to the alarm
        self.prediction_late = 0
        self.settled_rows = 0
        self._latest: tuple[float, np.ndarray, np.ndarray] | None = None
        self._finished = False
        self.lag_runner: LagRunner = lag_runner if lag_runner is not None else InlineLag()
        self._lag_seq = 0

    def set_band(self, band_pct: float, source: str) -> None:
        """The alarm band's share of the predicted power [%] from now on, and its source."""
        if source not in BAND_SOURCES or not (math.isfinite(band_pct) and band_pct >= 0.0):
            return
        self._alarm.pct = float(band_pct)
        self._alarm.source = source

    # -- input -------------------------------------------------------------------------
    def add_prediction(self, t: np.ndarray, power_w: np.ndarray) -> None:
        """Append predicted samples, times ``(n,)`` [s] and power ``(n, k)`` [W] (a drive
        trace: ``(n, 2k)``, the trace in its unit, then ``omega`` [rad/s]).

        Samples not later than the newest held, or not finite, are dropped and counted as
        ``prediction_late``.
        """
        t = np.asarray(t, dtype=float).reshape(-1)
        y = np.asarray(power_w, dtype=float).reshape(t.size, self._pred_cols)
        keep = np.isfinite(t) & np.isfinite(y).all(axis=1)
        last = self.pred.last_t
        if last is not None:
            keep &= t > last
        keep[1:] &= np.diff(t) > 0.0
        self.prediction_late += int(t.size - np.count_nonzero(keep))
        if keep.any():
            self.pred.extend(t[keep], y[keep])

    def add_measured(self, t: float, power_w: np.ndarray) -> None:
        """Append one measured row (time [s] after the last, power per axis [W])."""
        values = np.asarray(power_w, dtype=float).reshape(len(self.axes))
        last = self.meas.last_t
        if last is not None and t <= last:
            return      # the assembler hands rows on in order; a caller's slip is ignored
        self._take_lag()
        if math.isnan(self._first_t):
            self._first_t = t
            self._next_align = t + max(self.s.min_align_s, self.s.realign_every_s)
        settled = self.meas.extend(np.array([t]), values[None, :])
        if settled is not None:
            self._settle(*settled)
            oldest = self.meas.arrays()[0][0]
            self.pred.drop_before(float(oldest) - abs(self.lag.lag_s) - self._reach_s)
        if not self.lag.frozen and t >= self._next_align:
            self._request_lag()
            self._take_lag()        # an inline runner's outcome: used at once, as always
            self._next_align = t + self.s.realign_every_s
        if t >= self._alarm_t + self.s.alarm_every_s:
            self._feed_alarm()

    # -- lag ---------------------------------------------------------------------------
    def _lag_request(self) -> LagRequest | None:
        tm, ym = self.meas.arrays()
        tp, yp = self.pred.arrays()
        if tm.size < 2 or tp.size < 2:
            self.lag.message = 'too few samples to estimate the lag yet'
            return None
        self._lag_seq += 1
        s = self.s
        if self._gains is None:
            y_meas, y_pred = ym.sum(axis=1), yp.sum(axis=1)
        else:
            # compare's rule: magnitudes, each axis scaled by its measured RMS
            rms = np.sqrt(np.mean(ym * ym, axis=0))
            scale = np.where(rms > 0.0, rms, 1.0)
            k = len(self.axes)
            y_meas = (np.abs(ym) / scale).sum(axis=1)
            y_pred = (np.abs(yp[:, :k]) / scale).sum(axis=1)
        return LagRequest(self._lag_seq, tm.copy(), y_meas, tp.copy(), y_pred,
                          max_lag_s=s.max_lag_s, window_s=s.window_s, stamp=s.stamp,
                          min_correlation=s.min_correlation)

    def _request_lag(self) -> None:
        request = self._lag_request()
        if request is not None:
            self.lag_runner.submit(request)

    def _take_lag(self) -> None:
        out = self.lag_runner.take()
        if out is not None and not self.lag.frozen:
            self._use_lag(out)

    def _use_lag(self, out: LagOutcome) -> None:
        lag = self.lag
        found = out.found
        if found is None:
            lag.message = f'lag not estimated: {out.reason}'
            return
        lag.estimates += 1
        previous = lag.found_s
        lag.found_s = found.offset_s
        lag.status = found.status
        lag.correlation = found.peak_correlation
        lag.drift_ppm = found.drift_ppm
        lag.message = found.message
        lag.lag_s = 0.0 if found.status == 'weak' else found.offset_s
        if found.status == 'weak':
            lag.message += '; compared at offset 0'
        if (found.status != 'weak' and math.isfinite(previous)
                and abs(found.offset_s - previous) <= self.s.freeze_tol_s):
            lag.agreeing += 1
        else:
            lag.agreeing = 0
        if self.s.freeze_count and lag.agreeing + 1 >= self.s.freeze_count \
                and found.status != 'weak':
            lag.frozen = True

    # -- evaluation --------------------------------------------------------------------
    def _watts(self, t: np.ndarray,
               y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Measured and aligned predicted power [W] of rows ``y``, and the aligned
        prediction in the rows' unit (a power: the same array)."""
        aligned = self._aligned(t)
        if self._gains is None:
            return y, aligned, aligned
        k = len(self.axes)
        q, omega = aligned[:, :k], aligned[:, k:]
        return y * self._gains * omega, q * self._gains * omega, q

    def _aligned(self, t: np.ndarray) -> np.ndarray:
        if t.size == 0:
            return np.zeros((0, self._pred_cols))
        # only the stretch of prediction these rows look at (plus a sample either side)
        start = float(t[0]) - self.lag.lag_s + self._shift - self.s.window_s
        tp, yp = self.pred.window(start, float(t[-1]) - self.lag.lag_s + self._shift)
        if tp.size == 0:
            return np.full((t.size, self._pred_cols), math.nan)
        if tp.size == 1:
            return np.repeat(yp, t.size, axis=0)
        if self.s.window_s == 0.0:
            # point samples: align_simulated's linear interpolation, without its set-up
            tau = t - self.lag.lag_s
            return np.column_stack([np.interp(tau, tp, yp[:, j]) for j in range(yp.shape[1])])
        return align_simulated(tp, yp, t, offset_s=self.lag.lag_s, window_s=self.s.window_s,
                               stamp=self.s.stamp)

    def _covered(self, t: np.ndarray) -> np.ndarray:
        """Rows whose aligned prediction the predicted stream reaches already."""
        last = self.pred.last_t
        if last is None:
            return np.zeros(t.size, dtype=bool)
        return t - self.lag.lag_s + self._shift <= last

    def _settle(self, t: np.ndarray, y: np.ndarray) -> None:
        """Fold rows leaving the measured ring into the sums, at the lag in force."""
        q = y
        y, pred, pred_q = self._watts(t, y)
        if self._gains is not None:
            self._sq_settled += np.sum((q - pred_q) ** 2, axis=0)
        self.settled_rows += t.size
        if self._settled_last is not None:
            t0, m0, p0 = self._settled_last
            t, y, pred = np.r_[t0, t], np.vstack([m0, y]), np.vstack([p0, pred])
        if t.size >= 2:
            self._e_meas += np.trapezoid(y, t, axis=0)
            self._e_pred += np.trapezoid(pred, t, axis=0)
        self._settled_last = (float(t[-1]), y[-1].copy(), pred[-1].copy())

    def _feed_alarm(self) -> None:
        tm, ym = self.meas.arrays(since=self._alarm_t)
        if tm.size == 0:
            return
        ok = self._covered(tm)
        if not ok.any():
            return
        n = int(np.argmin(ok)) if not ok.all() else ok.size    # a covered prefix
        tm, q = tm[:n], ym[:n]
        ym, pred, pred_q = self._watts(tm, q)
        self._latest = (float(tm[-1]), ym[-1].copy(), pred[-1].copy())
        self._latest_q = (q[-1].copy(), pred_q[-1].copy())
        self._alarm_t = float(tm[-1])
        if self.lag.status in ('none', 'weak'):
            return      # not armed: at an unknown lag, a residual says nothing
        for i in range(tm.size):
            self._alarm.feed(float(tm[i]), float(ym[i].sum() - pred[i].sum()),
                             float(pred[i].sum()))

    def finish(self) -> dict[str, Any]:
        """The stream has ended: a last lag estimate (unless frozen), every row evaluated."""
        if not self._finished:
            self._finished = True
            self._take_lag()
            self.lag_runner.close()     # an estimate still running is of older data
            if not self.lag.frozen and self.meas.size >= 2:
                request = self._lag_request()
                if request is not None:
                    self._use_lag(self.lag_runner.run_now(request))
        return self.snapshot()

    def close(self) -> None:
        """Let go of the lag runner (its thread, if any) without finishing."""
        self.lag_runner.close()

    def snapshot(self) -> dict[str, Any]:
        """The comparison so far: keys documented in docs/nodes.md ("measured_live").

        Values are floats (NaN where not known yet: the JSON payload maps it to null).
        """
        tm, ym = self.meas.arrays()
        pending = 0
        if tm.size and not self._finished:
            ok = self._covered(tm)
            pending = int(tm.size - np.count_nonzero(ok))
            tm, ym = tm[ok], ym[ok]     # covered rows are a prefix: times increase
        e_meas = self._e_meas.copy()
        e_pred = self._e_pred.copy()
        sq = self._sq_settled.copy()
        n_rows = self.settled_rows + tm.size
        if tm.size:
            q = ym
            ym, pred, pred_q = self._watts(tm, q)
            if self._gains is not None:
                sq += np.sum((q - pred_q) ** 2, axis=0)
            if self._finished:
                self._latest_q = (q[-1].copy(), pred_q[-1].copy())
            if self._settled_last is not None:
                t0, m0, p0 = self._settled_last
                tm, ym, pred = np.r_[t0, tm], np.vstack([m0, ym]), np.vstack([p0, pred])
            if tm.size >= 2:
                e_meas += np.trapezoid(ym, tm, axis=0)
                e_pred += np.trapezoid(pred, tm, axis=0)
            if self._finished:
                self._latest = (float(tm[-1]), ym[-1].copy(), pred[-1].copy())
        names = self.axes + ('total',)

        def named(values: np.ndarray) -> dict[str, float]:
            return {a: float(v) for a, v in zip(names, np.append(values, values.sum()))}

        meas_j, pred_j = named(e_meas), named(e_pred)
        error_j = {a: pred_j[a] - meas_j[a] for a in names}
        error_pct = {a: (100.0 * error_j[a] / abs(meas_j[a]) if meas_j[a] != 0.0 else math.nan)
                     for a in names}
        nan_row = named(np.full(len(self.axes), math.nan))
        if self._latest is not None:
            t_last, m_last, p_last = self._latest
            meas_w, pred_w = named(m_last), named(p_last)
            res_w = {a: meas_w[a] - pred_w[a] for a in names}
        else:
            t_last, meas_w, pred_w, res_w = math.nan, nan_row, nan_row, nan_row
        return {
            'time_s': t_last,
            'elapsed_s': (t_last - self._first_t) if self._latest is not None else 0.0,
            'measured_power_w': meas_w,
            'predicted_power_w': pred_w,
            'residual_power_w': res_w,
            'measured_energy_j': meas_j,
            'predicted_energy_j': pred_j,
            'energy_error_j': error_j,
            'energy_error_pct': error_pct,
            'lag': self.lag.as_dict(),
            'alarm': self._alarm.as_dict(),
            'rows': {'evaluated': int(self.settled_rows + (tm.size if self._settled_last is None
                                                           else tm.size - 1)),
                     'pending': pending, 'ring': self.meas.size,
                     'prediction_ring': self.pred.size},
            'prediction_late': self.prediction_late,
            'final': self._finished,
            'measures': self.quantity.name,
            'signal': self._signal(sq, n_rows),
        }

    def _signal(self, sq: np.ndarray, n_rows: int) -> dict[str, Any] | None:
        """A drive trace in its unit: values at the stamp, residual RMS (None: a power)."""
        if self._gains is None:
            return None
        qty = self.quantity
        k = len(self.axes)

        def per_axis(values: np.ndarray | None) -> dict[str, float]:
            return {a: (float(values[j]) if values is not None else math.nan)
                    for j, a in enumerate(self.axes)}

        meas, pred = self._latest_q if self._latest_q is not None else (None, None)
        res = meas - pred if meas is not None and pred is not None else None
        rms = np.sqrt(sq / n_rows) if n_rows else np.full(k, math.nan)
        return {'quantity': qty.name, 'unit': qty.unit, 'key': qty.key,
                'measured': per_axis(meas), 'predicted': per_axis(pred),
                'residual': per_axis(res), 'residual_rms': per_axis(rms),
                'gain': per_axis(self._gains)}
