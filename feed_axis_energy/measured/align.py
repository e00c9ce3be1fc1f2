"""Time alignment of simulated and measured power.

Instrument model: a measured sample stamped ``t`` is the mean of the true signal over a
window of ``window_s`` (a power analyser that averages over its sampling period), stamped
at the window's end (``stamp='end'``: ``[t - window_s, t]``, the default), centre
(``[t - window_s/2, t + window_s/2]``) or start (``[t, t + window_s]``); ``window_s = 0`` is a
point sample at ``t``. The simulated signal is treated as piecewise linear between its
samples and held at its first and last value outside its time range (the machine is at rest
before and after a program). A meter may also smooth the signal before it averages
(``filter_s``: a first-order lag, a PT1 filter with that time constant, as drive traces and
filtered power meters do; :func:`first_order_lag`).

Sign convention: ``offset_s`` is how much *later* the measured record is than the simulated
one, i.e. ``y_meas(t) ~= mean of y_sim over [t - offset_s - window_s, t - offset_s]`` (stamp at
the end). An event at simulated time 2.0 s that the instrument stamps 2.5 s gives
``offset_s = +0.5``.

The offset search (:func:`estimate_offset`) is described in docs/compare.md, "Alignment".
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np
from numpy.typing import ArrayLike
from scipy.fft import irfft, next_fast_len, rfft
from scipy.optimize import minimize_scalar
from scipy.signal import lfilter

from ..errors import DataError

__all__ = ['DRIFT_MIN_DURATION_S', 'MAX_FILTER_S', 'STAMPS', 'OffsetResult', 'ShiftedAverage',
           'align_simulated', 'clock_corrected', 'estimate_offset', 'first_order_lag',
           'interval_average', 'stamp_shift', 'step_error_rms']

_MAX_LAG_STEPS = 100_000
_CHUNK_ELEMENTS = 2_000_000
_EVAL_CHUNK = 1 << 17   # times evaluated at once: bounds the temporaries of an average
_DIRECT_SHIFTS = 64     # sliding dot products of this few shifts are computed directly
_FFT_BLOCK = 1 << 16    # measured samples per FFT block of a long sliding dot product
_DIRECT_PRODUCTS_MAX = 400_000_000   # sample-lag products of a lag grid on irregular stamps
STAMPS = ('end', 'centre', 'start')
"""Where in its averaging window the instrument stamps a sample."""
DRIFT_MIN_DURATION_S = 60.0
"""Shortest record [s] on which a clock-rate difference is estimated (see ``_drift``)."""
MAX_FILTER_S = 10.0
"""Largest first-order time constant [s] of a meter's own smoothing accepted."""
_MAX_DRIFT = 2e-3   # largest clock-rate difference searched (2000 ppm: a poor quartz is 100)


@dataclass(frozen=True)
class OffsetResult:
    """Outcome of :func:`estimate_offset`; a poor alignment is a result, not an exception.

    Attributes
    ----------
    offset_s
        How much later the measured record is than the simulated one [s].
    peak_correlation
        Pearson correlation of measured and shifted, interval-averaged simulated power at
        ``offset_s`` (NaN when a signal is constant).
    status
        ``'ok'``; ``'weak'`` (correlation below ``min_correlation`` or a constant signal);
        ``'edge'`` (chosen lag at the end of the searched range: the true offset may lie
        outside); ``'ambiguous'`` (a distant lag, ``runner_up_s``, fits almost as well, as
        with repeated identical movements).
    message
        A sentence saying why.
    lags_s, correlation
        The searched lag grid [s] and the correlation at each lag (for plots).
    rms_w
        RMS of the measured minus the aligned simulated signal, its mean removed, at
        ``offset_s`` [W] (the score candidates are ranked by; NaN if not computed).
    runner_up_s, runner_up_correlation, runner_up_rms_w
        The best candidate lag farther than one feature width from ``offset_s``, its
        correlation and residual RMS [W]; NaN when there is none.
    drift_ppm
        Clock-rate difference: the measured clock runs this many parts per million faster
        than the simulation's (NaN when not estimable).
    drift_message
        How the drift was estimated, or why it was not.
    anchor
        What pinned the offset: ``'power'`` (this search on the power or drive trace) or
        ``'motion'`` (the record's measured motion, the power only refining it:
        :func:`.spatial.motion_anchor`); ``'given'`` for an offset the caller fixed.
    motion_s
        The offset the measured motion gave [s] (NaN when the record has none).
    """

    offset_s: float
    peak_correlation: float
    status: str
    message: str
    lags_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    correlation: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rms_w: float = math.nan
    runner_up_s: float = math.nan
    runner_up_correlation: float = math.nan
    runner_up_rms_w: float = math.nan
    drift_ppm: float = math.nan
    drift_message: str = 'not estimated'
    anchor: str = 'power'
    motion_s: float = math.nan


def _series(t: ArrayLike, y: ArrayLike, name: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if t.ndim != 1 or t.size < 2:
        msg = f'expected at least 2 times in a 1-D array, got shape {t.shape}'
        raise DataError(msg, file='<arrays>', column=f't_{name}')
    if y.shape[:1] != t.shape:
        msg = f'has {y.shape[:1]} samples, the time array has {t.size}'
        raise DataError(msg, file='<arrays>', column=f'y_{name}')
    if not (np.isfinite(t).all() and np.isfinite(y).all()):
        raise DataError('contains NaN or infinite values', file='<arrays>', column=name)
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        msg = 'time must increase strictly'
        raise DataError(msg, file='<arrays>', column=f't_{name}', row=int(bad[0]) + 2)
    return t, y


class _Prefix:
    """A piecewise-linear signal and its running integral, built once and then evaluated.

    The running integral at the samples is one cumulative sum; an integral up to any time
    is then that sum plus the part of one segment, so averaging over many windows (every
    lag of an offset search) costs O(1) per window instead of a pass over the signal. The
    segment of a time is found by arithmetic within runs of equal time steps (a simulation
    at its rate is a few such runs: the planner's phase ends break them), else by numpy's
    interpolation of the sample index. Construction and evaluations run in chunks of
    :data:`_EVAL_CHUNK` samples, so their temporaries stay bounded however long the record.
    """

    def __init__(self, t: np.ndarray, y: np.ndarray):
        self.t = t
        self.y = y
        m = t.size
        self.big_f = np.empty((m,) + y.shape[1:])
        self.big_f[0] = 0.0
        breaks: list[np.ndarray] = [np.zeros(1, dtype=np.intp)]
        last_dt = None
        for a in range(0, m - 1, _EVAL_CHUNK):
            b = min(a + _EVAL_CHUNK, m - 1)
            dt = t[a + 1:b + 1] - t[a:b]
            seg = 0.5 * (y[a + 1:b + 1] + y[a:b]) * (dt if y.ndim == 1 else dt[:, None])
            seg[0] += self.big_f[a]         # carried: the same sums as one cumulative sum
            np.cumsum(seg, axis=0, out=self.big_f[a + 1:b + 1])
            prev = np.concatenate([[dt[0] if last_dt is None else last_dt], dt[:-1]])
            # 1e-6: beyond the rounding of differences of times thousands of seconds long
            breaks.append(a + np.flatnonzero(np.abs(dt - prev) > 1e-6 * prev))
            last_dt = dt[-1]
        starts = np.unique(np.concatenate(breaks)).astype(np.intp)
        self.index: np.ndarray | None = None
        self.run_start: np.ndarray = np.zeros(0, dtype=np.intp)
        self.run_last: np.ndarray = self.run_start
        self.run_t: np.ndarray = np.zeros(0)
        self.run_step: np.ndarray = self.run_t
        if starts.size <= max(1, m // 16):
            ends = np.append(starts[1:], m - 1)        # one past each run's last segment
            self.run_start = starts
            self.run_t = t[starts]
            self.run_step = (t[ends] - t[starts]) / (ends - starts)
            self.run_last = ends - 1
        else:
            self.index = np.arange(m, dtype=np.float64)

    def _segment(self, tau: np.ndarray) -> np.ndarray:
        """Index ``i`` of the segment ``[t[i], t[i+1])`` holding each finite ``tau``, clipped.

        Rounding may give the neighbouring segment for a ``tau`` within a rounding error of
        a sample time; the running integral is continuously differentiable there, so the
        result is the same to rounding (:meth:`_integral` checks the rest).
        """
        last = self.t.size - 2
        if self.index is not None:
            x = np.interp(tau, self.t, self.index)
            np.floor(x, out=x)
            return np.clip(x, 0, last).astype(np.intp)
        r = np.clip(np.searchsorted(self.run_t, tau, side='right') - 1, 0, None)
        x = (tau - self.run_t[r]) / self.run_step[r]
        np.floor(x, out=x)
        np.clip(x, 0, self.run_last[r] - self.run_start[r], out=x)
        return np.clip(self.run_start[r] + x.astype(np.intp), 0, last)

    def _integral(self, tau: np.ndarray) -> np.ndarray:
        """Exact integral from ``t[0]`` to each ``tau`` (held values outside ``t``)."""
        t, y = self.t, self.y
        finite = bool(np.isfinite(tau).all())
        i = (self._segment(tau) if finite
             else np.clip(np.searchsorted(t, tau, side='right') - 1, 0, t.size - 2))
        h = np.clip(tau, t[0], t[-1]) - t[i]
        dt = t[i + 1] - t[i]
        if finite and not ((h >= -1e-6 * dt) & (h <= dt * (1.0 + 1e-6))).all():
            # a time base the arithmetic does not fit: a binary search instead
            i = np.clip(np.searchsorted(t, tau, side='right') - 1, 0, t.size - 2)
            h = np.clip(tau, t[0], t[-1]) - t[i]
            dt = t[i + 1] - t[i]
        before = np.minimum(tau - t[0], 0.0)
        after = np.maximum(tau - t[-1], 0.0)
        if y.ndim > 1:
            h, dt = h[:, None], dt[:, None]
            before, after = before[:, None], after[:, None]
        slope = (y[i + 1] - y[i]) / dt
        out = self.big_f[i] + y[i] * h + 0.5 * slope * h * h
        return out + y[0] * before + y[-1] * after

    def average(self, tau: np.ndarray, window_s: float,
                moved: tuple[float, float] | None = None) -> np.ndarray:
        """Mean over ``[tau - window_s, tau]`` of each ``tau`` (1-D); 0: the value at ``tau``.

        ``moved = (offset, shift)`` averages at ``tau - offset + shift`` instead, formed a
        chunk at a time (no shifted copy of a long record).
        """
        out = np.empty(tau.shape + self.y.shape[1:])
        for a in range(0, tau.size, _EVAL_CHUNK):
            part = tau[a:a + _EVAL_CHUNK]
            if moved is not None:
                part = part - moved[0] + moved[1]
            if window_s == 0.0:
                if self.y.ndim == 1:
                    out[a:a + _EVAL_CHUNK] = np.interp(part, self.t, self.y)
                else:
                    for j in range(self.y.shape[1]):
                        out[a:a + _EVAL_CHUNK, j] = np.interp(part, self.t, self.y[:, j])
            else:
                out[a:a + _EVAL_CHUNK] = (self._integral(part)
                                          - self._integral(part - window_s)) / window_s
        return out


def interval_average(t_sim: ArrayLike, y_sim: ArrayLike, t_meas: ArrayLike, *,
                     window_s: float) -> np.ndarray:
    """Simulated signal averaged over the measuring window ending at each measured stamp.

    Parameters
    ----------
    t_sim
        Simulation times [s], strictly increasing, shape ``(m,)``.
    y_sim
        Simulated signal, shape ``(m,)`` or ``(m, c)``; linear between samples, held
        constant outside ``t_sim``.
    t_meas
        Measured stamps [s], any shape ``s``.
    window_s
        Averaging window [s] (``0`` gives linear interpolation at the stamps).

    Returns
    -------
    numpy.ndarray
        Shape ``s`` (or ``s + (c,)``): mean of ``y_sim`` over ``[t - window_s, t]``.

    Raises
    ------
    DataError
        On malformed arrays or a negative window.
    """
    t_sim, y_sim = _series(t_sim, y_sim, 'sim')
    tau = np.asarray(t_meas, dtype=np.float64)
    if not (math.isfinite(window_s) and window_s >= 0.0):
        msg = f'window_s must be a finite number >= 0, got {window_s!r}'
        raise DataError(msg, file='<arrays>', column='window_s')
    out = _Prefix(t_sim, y_sim).average(tau.ravel(), float(window_s))
    return out.reshape(tau.shape + y_sim.shape[1:])


def step_error_rms(t_half: ArrayLike, y_half: ArrayLike, t_meas: ArrayLike,
                   aligned: ArrayLike, *, offset_s: float, window_s: float,
                   stamp: str = 'end', filter_s: float = 0.0) -> np.ndarray:
    """How much the simulation's sampling changes what the meter reads, RMS per column.

    A simulated signal is read as linear between its samples; its error in a window average
    (and through a first-order filter) shrinks with the square of the sampling step ``h``
    (the local mean of the error of the linear interpolant is ``-h²/12`` times the
    signal's curvature; at a kink the error is of the same order). So the same simulation at
    twice the step (``t_half, y_half``: every second sample) reads ``4·e`` where the full one
    reads ``e``, and ``e ≈ (aligned_half - aligned) / 3``.

    Parameters
    ----------
    t_half, y_half
        Every second simulated sample, unfiltered (as for :func:`align_simulated`).
    t_meas
        Measured stamps [s].
    aligned
        The full simulation as the meter reads it (:func:`align_simulated` with the same
        arguments), ``(n,)`` or ``(n, c)``.
    offset_s, window_s, stamp, filter_s
        As for :func:`align_simulated`.

    Returns
    -------
    numpy.ndarray
        ``(c,)`` (a scalar array for 1-D ``aligned``): the estimated RMS error over the
        stamps, in the signal's unit; zeros when the half simulation has fewer than two
        samples or the record none.
    """
    full = np.asarray(aligned, dtype=np.float64)
    t_h = np.asarray(t_half, dtype=np.float64)
    if t_h.size < 2 or full.shape[0] == 0:
        return np.zeros(full.shape[1:])
    half = align_simulated(t_h, y_half, t_meas, offset_s=offset_s, window_s=window_s,
                           stamp=stamp, filter_s=filter_s)
    return np.sqrt(np.mean(((half - full) / 3.0) ** 2, axis=0))


def clock_corrected(t: np.ndarray, drift_ppm: float) -> np.ndarray:
    """Measured stamps [s] put on the simulation's clock: a record whose offset grows by
    ``drift_ppm`` parts per million of its time (a meter clock that runs fast by that much,
    :func:`estimate_offset`'s ``drift_ppm``) has the stamps
    ``t - 1e-6·drift_ppm·(t - t_mid)``, equal at the middle ``t_mid`` of the record, so that
    one offset, the one at the middle, then holds for the whole record."""
    t = np.asarray(t, dtype=np.float64)
    if not drift_ppm or t.size == 0:
        return t
    mid = 0.5 * (float(t[0]) + float(t[-1]))
    return t - 1e-6 * float(drift_ppm) * (t - mid)


def stamp_shift(window_s: float, stamp: str) -> float:
    """How far after its stamp a sample's window ends [s] (0 for ``'end'``).

    Raises
    ------
    DataError
        If ``stamp`` is not one of :data:`STAMPS`.
    """
    if stamp not in STAMPS:
        msg = f'stamp must be one of {", ".join(STAMPS)}, got {str(stamp)[:60]!r}'
        raise DataError(msg, file='<arrays>', column='stamp')
    return {'end': 0.0, 'centre': 0.5, 'start': 1.0}[stamp] * window_s


def first_order_lag(t: ArrayLike, y: ArrayLike, tau_s: float) -> np.ndarray:
    """``y`` through a first-order lag (``tau·dz/dt = y - z``), started at rest on ``y[0]``.

    Exact for a signal linear between its samples (the instrument model's reading of the
    simulation): per step ``h``, with ``a = exp(-h/tau)`` and ``c = tau/h``,
    ``z1 = a·z0 + (1 - c + a·c)·y1 + (c - a - a·c)·y0``. A uniform time base is filtered in
    one pass (:func:`scipy.signal.lfilter`); an irregular one step by step in blocks of equal
    steps. ``tau_s = 0`` returns ``y`` itself.

    Parameters
    ----------
    t
        Times [s], strictly increasing, ``(n,)``.
    y
        Signal ``(n,)`` or ``(n, c)`` (filtered along axis 0).
    tau_s
        Time constant [s], ``0 <= tau_s <=`` :data:`MAX_FILTER_S`.

    Raises
    ------
    DataError
        On malformed arrays or a time constant out of range.
    """
    t_a, y_a = _series(t, y, 'sim')
    tau = float(tau_s)
    if not (math.isfinite(tau) and 0.0 <= tau <= MAX_FILTER_S):
        msg = f'filter_s must be a number in [0, {MAX_FILTER_S:g}] s, got {tau_s!r}'
        raise DataError(msg, file='<arrays>', column='filter_s')
    if tau == 0.0 or t_a.size < 2:
        return y_a
    h = np.diff(t_a)
    # runs of equal steps (a simulation's time base has one, a measured one a few)
    cut = np.flatnonzero(np.abs(np.diff(h)) > 1e-9 * np.maximum(h[1:], h[:-1])) + 1
    out = np.empty_like(y_a, dtype=np.float64)
    out[0] = y_a[0]
    for a, b in zip(np.r_[0, cut], np.r_[cut, h.size]):
        step = float(h[a])
        k = math.exp(-step / tau)
        c = tau / step
        seg = y_a[a:b + 1]
        # lfilter's state before the run of steps (transposed direct form):
        # z1 = b0·y1 + zi with zi = k·z0 + b1·y0
        b0, b1 = 1.0 - c + k * c, c - k - k * c
        zi = np.asarray(k * out[a] + b1 * seg[0], dtype=np.float64)[None]
        z, _ = lfilter([b0, b1], [1.0, -k], seg[1:], axis=0, zi=zi)
        out[a + 1:b + 1] = z
    return out


def align_simulated(t_sim: ArrayLike, y_sim: ArrayLike, t_meas: ArrayLike, *,
                    offset_s: float, window_s: float, stamp: str = 'end',
                    filter_s: float = 0.0) -> np.ndarray:
    """Simulated signal as the instrument would have recorded it, on the measured stamps.

    Parameters
    ----------
    t_sim, y_sim
        Simulated series, as for :func:`interval_average`.
    t_meas
        Measured stamps [s].
    offset_s
        How much later the measured record is than the simulated one [s].
    window_s
        Instrument averaging window [s] (0: point samples).
    stamp
        Where the instrument stamps its window: ``'end'``, ``'centre'`` or ``'start'``.
    filter_s
        Time constant [s] of the meter's own first-order smoothing before its window
        (:func:`first_order_lag`; 0: none).

    Returns
    -------
    numpy.ndarray
        ``interval_average(t_sim, first_order_lag(t_sim, y_sim, filter_s), t_meas - offset_s
        + shift, window_s=window_s)`` with ``shift`` from :func:`stamp_shift`.
    """
    if filter_s:
        y_sim = first_order_lag(t_sim, y_sim, filter_s)
    tau = np.asarray(t_meas, dtype=np.float64)
    series = ShiftedAverage(t_sim, y_sim, window_s=window_s, stamp=stamp)
    return series.at(tau.ravel(), offset_s).reshape(tau.shape + np.shape(y_sim)[1:])


class ShiftedAverage:
    """A simulated series read by the instrument at any offset, its running integral built
    once: :func:`align_simulated` for many offsets of the same series at O(stamps) each.

    Parameters
    ----------
    t_sim, y_sim
        Simulated series, as for :func:`interval_average` (``y_sim`` ``(m,)`` or ``(m, c)``;
        put it through :func:`first_order_lag` first for a meter that smooths).
    window_s
        Instrument averaging window [s] (0: point samples).
    stamp
        Where the instrument stamps its window (:data:`STAMPS`).

    Raises
    ------
    DataError
        On malformed arrays, a negative window or an unknown stamp.
    """

    def __init__(self, t_sim: ArrayLike, y_sim: ArrayLike, *, window_s: float,
                 stamp: str = 'end'):
        t, y = _series(t_sim, y_sim, 'sim')
        if not (math.isfinite(window_s) and window_s >= 0.0):
            msg = f'window_s must be a finite number >= 0, got {window_s!r}'
            raise DataError(msg, file='<arrays>', column='window_s')
        self._shift = stamp_shift(window_s, stamp)
        self._window = float(window_s)
        self._prefix = _Prefix(t, y)

    def at(self, t_meas: np.ndarray, offset_s: float) -> np.ndarray:
        """The series on the stamps ``t_meas`` (1-D) at ``offset_s`` [s]: ``(n,)`` or
        ``(n, c)``, equal to :func:`align_simulated` with the same instrument."""
        return self._prefix.average(np.asarray(t_meas, dtype=np.float64), self._window,
                                    moved=(float(offset_s), self._shift))


def _correlation(y: np.ndarray, model: np.ndarray) -> np.ndarray:
    """Pearson correlation of ``y`` (n,) with every row of ``model`` (l, n); 0 if flat."""
    yc = y - y.mean()
    mc = model - model.mean(axis=-1, keepdims=True)
    den = np.sqrt((yc @ yc) * np.einsum('...i,...i->...', mc, mc))
    num = mc @ yc
    with np.errstate(invalid='ignore', divide='ignore'):
        return np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), 0.0)


def _sliding_dot(a: np.ndarray, b: np.ndarray, count: int) -> np.ndarray:
    """``out[d] = sum_j a[d + j] b[j]`` for ``d < count`` (``a`` has ``b.size + count - 1``).

    Few shifts: one product each. Many: FFTs over blocks of ``b`` (overlap-add of the
    partial sums), O(len(b) log(count)) and memory bounded by the block, not the record.
    """
    n = b.size
    if count <= _DIRECT_SHIFTS:
        # einsum, not a BLAS dot: a threaded BLAS on a busy machine spends more time
        # handing small products between its threads than computing them
        return np.array([np.einsum('i,i->', a[d:d + n], b) for d in range(count)])
    block = max(_FFT_BLOCK, 2 * count)
    size = next_fast_len(block + count - 1, real=True)
    out = np.zeros(count)
    for j0 in range(0, n, block):
        part = b[j0:j0 + block]
        fa = rfft(a[j0:j0 + part.size + count - 1], size)
        fa *= np.conj(rfft(part, size))
        out += irfft(fa, size)[:count]
    return out


def _uniform_period(t: np.ndarray) -> float | None:
    """The sampling period of stamps uniform to within 1e-6 of it, else ``None``."""
    if t.size < 3:
        return None
    period = float(t[-1] - t[0]) / (t.size - 1)
    for a in range(0, t.size - 1, _EVAL_CHUNK):
        d = np.diff(t[a:a + _EVAL_CHUNK + 1])
        if float(np.max(np.abs(d - period))) > 1e-6 * period:
            return None
    return period


def _whole_fraction(period: float | None, step: float) -> int:
    """``q`` if ``step`` is ``period / q`` with ``q`` whole (the uniform fast path), else 0."""
    if period is None:
        return 0
    q = int(round(period / step))
    return q if q >= 1 and abs(q * step - period) <= 1e-9 * period else 0


@dataclass(frozen=True)
class _Signals:
    """The two series and the instrument, for scoring lags.

    The simulated signal's running integral (:class:`_Prefix`) is built once and shared by
    every lag the search, the refinement, the residual and the drift estimate evaluate.
    """

    t_meas: np.ndarray
    y_meas: np.ndarray
    t_sim: np.ndarray
    y_sim: np.ndarray
    window_s: float
    shift_s: float
    prefix: _Prefix = field(init=False, repr=False, compare=False)
    level: float = field(init=False, repr=False, compare=False)
    means: dict[tuple[int, int, int], tuple[float, float]] = field(
        init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, 'prefix', _Prefix(self.t_sim, self.y_sim))
        # the model is summed about this level: less cancellation in its variance
        span = float(self.t_sim[-1] - self.t_sim[0])
        level = float(self.prefix.big_f[-1]) / span if span > 0.0 else float(self.y_sim[0])
        object.__setattr__(self, 'level', level)
        object.__setattr__(self, 'means', {})

    def _mean(self, sel: slice) -> tuple[float, float]:
        """Mean of the measured signal on ``sel`` and its sum of squares about it."""
        key = sel.indices(self.t_meas.size)
        if key not in self.means:
            y = self.y_meas[sel]
            mean = float(y.mean())
            syy = math.fsum(float(np.sum((y[a:a + _EVAL_CHUNK] - mean) ** 2))
                            for a in range(0, y.size, _EVAL_CHUNK))
            self.means[key] = (mean, syy)
        return self.means[key]

    def score(self, lag: float, sel: slice = slice(None)) -> tuple[float, float]:
        """Correlation and residual RMS (mean removed) [W] at one lag, in bounded chunks."""
        t = self.t_meas[sel]
        y = self.y_meas[sel]
        n = t.size
        mean, syy = self._mean(sel)
        sm = smm = smy = sr = srr = 0.0
        for a in range(0, n, _EVAL_CHUNK):
            m = self.prefix.average(t[a:a + _EVAL_CHUNK] - lag + self.shift_s, self.window_s)
            m -= self.level
            yc = y[a:a + _EVAL_CHUNK] - mean
            # einsum: see _sliding_dot
            sm += float(m.sum())
            smm += float(np.einsum('i,i->', m, m))
            smy += float(np.einsum('i,i->', m, yc))
            yc -= m                     # residual, both about their levels
            sr += float(yc.sum())
            srr += float(np.einsum('i,i->', yc, yc))
        var_m = max(smm - sm * sm / n, 0.0)
        den = math.sqrt(syy * var_m)
        corr = smy / den if den > 0.0 else 0.0
        return corr, math.sqrt(max(srr / n - (sr / n) ** 2, 0.0))

    def correlation(self, lags: np.ndarray, sel: slice = slice(None)) -> np.ndarray:
        """Correlation at every lag, computed in chunks of bounded size."""
        t = self.t_meas[sel]
        y = self.y_meas[sel]
        out = np.empty(lags.size)
        per_chunk = _CHUNK_ELEMENTS // max(t.size, 1)
        if per_chunk < 2:
            # a long record: one lag at a time, itself in chunks
            for k, lag in enumerate(lags):
                out[k] = self.score(float(lag), sel)[0]
            return out
        for start in range(0, lags.size, per_chunk):
            part = lags[start:start + per_chunk]
            tau = t[None, :] - part[:, None] + self.shift_s
            model = self.prefix.average(tau.ravel(), self.window_s).reshape(tau.shape)
            out[start:start + per_chunk] = _correlation(y, model)
        return out

    def uniform_correlation(self, step: float, steps: int, sel: slice = slice(None),
                            centre: float = 0.0) -> np.ndarray | None:
        """Correlation at the lags ``centre + k * step``, ``|k| <= steps``, for uniform stamps.

        When the stamps are uniform (period ``P``, within 1e-6 of it) and ``step = P / q``
        with ``q`` whole, every lag's model samples the same instrument-averaged signal on
        the grid ``t_0 - centre + (j - steps) step``: it is computed one residue ``j mod q``
        and one block of stamps at a time, and the sums of the correlation become sliding
        sums and sliding dot products (:func:`_sliding_dot`). Returns ``None`` when not
        applicable.
        """
        t = self.t_meas[sel]
        q = _whole_fraction(_uniform_period(t), step)
        if not q:
            return None
        n = t.size
        y = self.y_meas[sel]
        mean, syy = self._mean(sel)
        width = 2 * steps + 1
        s1 = np.zeros(width)
        s2 = np.zeros(width)
        sy = np.zeros(width)
        for r in range(min(q, width)):
            # offsets c = r + q * dd of the model's first sample on the fine grid
            cnt = (width - 1 - r) // q + 1
            c = r + q * np.arange(cnt)
            block = max(_FFT_BLOCK, 2 * cnt)
            for j0 in range(0, n, block):
                nb = min(block, n - j0)
                k = np.arange(r - steps + q * j0, r - steps + q * (j0 + nb + cnt - 1), q)
                u = k * step
                u += t[0]
                if centre != 0.0:
                    u -= centre
                u += self.shift_s
                sub = self.prefix.average(u, self.window_s)
                sub -= self.level
                cs = np.concatenate([[0.0], np.cumsum(sub)])
                s1[c] += cs[nb:nb + cnt] - cs[:cnt]
                cs = np.concatenate([[0.0], np.cumsum(sub * sub)])
                s2[c] += cs[nb:nb + cnt] - cs[:cnt]
                sy[c] += _sliding_dot(sub, y[j0:j0 + nb] - mean, cnt)
        var_m = np.maximum(s2 - s1 * s1 / n, 0.0)
        den = np.sqrt(syy * var_m)
        with np.errstate(invalid='ignore', divide='ignore'):
            corr = np.where(den > 1e-300, sy / np.where(den > 1e-300, den, 1.0), 0.0)
        # offset c belongs to lag index k = 2 steps - c, i.e. lag centre + (steps - c) * step
        return corr[::-1]

    def grid_correlation(self, lags: np.ndarray, step: float, steps: int,
                         sel: slice = slice(None), centre: float = 0.0) -> np.ndarray:
        """Correlation on the grid ``lags`` (``centre + k * step``, clipped at its ends)."""
        corr = self.uniform_correlation(step, steps, sel, centre)
        if corr is None:
            return self.correlation(lags, sel)
        ends = [0, -1]
        if not np.allclose(lags[ends], centre + np.array([-steps, steps]) * step,
                           rtol=0.0, atol=1e-12 * max(1.0, abs(centre))):
            # clipped end lags are not on the uniform grid
            corr[ends] = self.correlation(lags[ends], sel)
        return corr

    def rms(self, lag: float) -> float:
        """RMS of measured minus model at ``lag``, its mean removed [W]."""
        return self.score(lag)[1]

    def refine(self, lag: float, lo: float, hi: float, *, tol: float,
               sel: slice = slice(None)) -> tuple[float, float]:
        """Lag of largest correlation in ``[lo, hi]`` near ``lag``: ``(lag, correlation)``."""
        best = self.score(lag, sel)[0]
        if not hi > lo:
            return lag, best

        def negative(x: float) -> float:
            return -self.score(x, sel)[0]

        res = minimize_scalar(negative, bounds=(lo, hi), method='bounded',
                              options={'xatol': tol})
        if -float(res.fun) > best:
            return float(res.x), -float(res.fun)
        return lag, best


def _grid_step(n: int, step: float, span_s: float, uniform: bool) -> float:
    """``step``, or a coarser one when scoring every lag directly would cost too much.

    Uniform stamps score any number of lags in O(n log) (:meth:`_Signals.uniform_correlation`);
    other stamps cost ``n`` per lag, so their grid is coarsened to at most
    :data:`_DIRECT_PRODUCTS_MAX` sample-lag products in all (the candidates are then
    refined within one such step).
    """
    if uniform or n * (span_s / step + 1.0) <= _DIRECT_PRODUCTS_MAX:
        return step
    return span_s / max(_DIRECT_PRODUCTS_MAX / n - 1.0, 8.0)


def _local_maxima(corr: np.ndarray) -> np.ndarray:
    """Indices of the local maxima of ``corr`` (ends included), best first."""
    if corr.size < 3:
        return np.argsort(-corr)
    left = np.concatenate([[True], corr[1:] >= corr[:-1]])
    right = np.concatenate([corr[:-1] >= corr[1:], [True]])
    idx = np.flatnonzero(left & right)
    return idx[np.argsort(-corr[idx], kind='stable')]


def estimate_offset(t_meas: ArrayLike, y_meas: ArrayLike, t_sim: ArrayLike, y_sim: ArrayLike,
                    *, max_lag_s: float, window_s: float, stamp: str = 'end',
                    min_correlation: float = 0.5, ambiguity_margin: float = 0.1,
                    grid_step_s: float | None = None, candidates: int = 8,
                    drift_min_duration_s: float = DRIFT_MIN_DURATION_S,
                    feature_s: float | None = None,
                    period_s: float | None = None) -> OffsetResult:
    """Find the time offset of the measured record: global search, candidates, residual.

    1. *Grid*: the measured signal is correlated with the instrument-averaged simulation
       (at its full rate) at every lag on a grid of ``grid_step_s`` within ``±max_lag_s``;
       the default step is a quarter of the shorter of the measured period and the window,
       finer than the narrowest feature the instrument can record (coarsened only if that
       needs more than 100 000 lags per side). On uniform stamps every lag is scored at
       once in O(n log) (:meth:`_Signals.uniform_correlation`); on irregular stamps each lag
       costs a pass, and a grid above :data:`_DIRECT_PRODUCTS_MAX` sample-lag products is
       coarsened to that budget (the candidates are then refined within the coarse step).
    2. *Candidates*: the ``candidates`` best local maxima of that correlation are each
       refined by a bounded scalar search within one grid step (to ~1e-4 of a period).
    3. *Choice*: the candidate with the smallest residual after the instrument model (RMS
       of measured minus aligned simulated power, its mean removed so that a constant
       standby power the model lacks favours no lag) wins among those correlating at least
       ``min_correlation`` (all, if none does). Correlation alone is blind to amplitude:
       a lag half a stroke cycle away can correlate well while its residual is large.
    4. *Runner-up*: the best other candidate farther than one feature width (the window or
       period, at least two grid steps) away; the result is ``'ambiguous'`` when its
       correlation is within ``ambiguity_margin`` of the winner's or its mean squared
       residual within that fraction of the winner's.
    5. *Drift*: on records of at least ``drift_min_duration_s``, the offset is re-estimated
       on each half of the record near the global one (the same grid, centred on it);
       their difference over the time between the halves' centres is the clock-rate
       difference (``drift_ppm``). Shorter records, or a half without structure, report it
       as not estimable.

    Parameters
    ----------
    t_meas, y_meas
        Measured stamps [s] and power [W], shape ``(n,)``.
    t_sim, y_sim
        Simulated times [s] and power [W], shape ``(m,)``.
    max_lag_s
        Largest offset searched, in either direction [s].
    window_s
        Instrument averaging window [s] (usually the measured period; 0: point samples).
    stamp
        Where the instrument stamps its window (:data:`STAMPS`).
    min_correlation
        Correlation below which the result is ``'weak'``.
    ambiguity_margin
        See step 4.
    grid_step_s
        Lag grid step [s]; default as in step 1.
    candidates
        Local maxima refined and compared (at least 2).
    drift_min_duration_s
        Shortest record on which the drift is estimated [s].
    feature_s
        How far [s] a candidate must lie from the winner to count as another alignment
        (step 4); default one feature width (the window or period, at least two grid
        steps). A smooth signal (velocities) has a broad peak: pass its width.
    period_s
        The median step of ``t_meas`` [s] when the caller knows it already (a long record's
        steps are then not formed again); default computed.

    Returns
    -------
    OffsetResult
        Offset, correlation, residual, runner-up, drift, status and message (see the
        module's sign convention).

    Raises
    ------
    DataError
        On malformed arrays or options (never for a poor match).
    """
    t_meas, y_meas = _series(t_meas, y_meas, 'meas')
    t_sim, y_sim = _series(t_sim, y_sim, 'sim')
    if y_meas.ndim != 1 or y_sim.ndim != 1:
        msg = 'estimate_offset takes 1-D signals (e.g. total power); sum the axes first'
        raise DataError(msg, file='<arrays>', column='y')
    for name, value in (('max_lag_s', max_lag_s), ('window_s', window_s)):
        if not (math.isfinite(value) and value >= 0.0):
            msg = f'{name} must be a finite number >= 0, got {value!r}'
            raise DataError(msg, file='<arrays>', column=name)
    if grid_step_s is not None and not (math.isfinite(grid_step_s) and grid_step_s > 0.0):
        msg = f'grid_step_s must be a finite number > 0, got {grid_step_s!r}'
        raise DataError(msg, file='<arrays>', column='grid_step_s')
    if period_s is not None and not (math.isfinite(period_s) and period_s > 0.0):
        msg = f'period_s must be a finite number > 0, got {period_s!r}'
        raise DataError(msg, file='<arrays>', column='period_s')
    # the steps' median in place (no second copy), before the prefix sums are built
    period = (float(np.median(np.diff(t_meas), overwrite_input=True)) if period_s is None
              else float(period_s))
    sig = _Signals(t_meas, y_meas, t_sim, y_sim, float(window_s), stamp_shift(window_s, stamp))
    width = min(period, window_s) if window_s > 0.0 else period
    step = 0.25 * width if grid_step_s is None else float(grid_step_s)
    step = max(step, max_lag_s / _MAX_LAG_STEPS)
    if grid_step_s is None and step < period:
        # a whole fraction of the period, so that uniform stamps take the fast path
        step = period / math.ceil(period / step - 1e-9)
    if grid_step_s is None:
        step = _grid_step(t_meas.size, step, 2.0 * max_lag_s,
                          bool(_whole_fraction(_uniform_period(t_meas), step)))
    steps = int(math.ceil(max_lag_s / step - 1e-9))
    lags = np.clip(np.arange(-steps, steps + 1) * step, -max_lag_s, max_lag_s)
    if np.ptp(y_meas) == 0.0 or np.ptp(y_sim) == 0.0:
        which = 'measured' if np.ptp(y_meas) == 0.0 else 'simulated'
        return OffsetResult(0.0, math.nan, 'weak', f'the {which} signal is constant',
                            lags, np.zeros_like(lags))
    corr = sig.grid_correlation(lags, step, steps)
    found = []
    for k in _local_maxima(corr)[:max(2, int(candidates))]:
        lo, hi = max(-max_lag_s, lags[k] - step), min(max_lag_s, lags[k] + step)
        lag, c = sig.refine(float(lags[k]), lo, hi, tol=period * 1e-4)
        found.append((lag, c, sig.rms(lag)))
    eligible = [f for f in found if f[1] >= min_correlation] or found
    offset, peak, rms = min(eligible, key=lambda f: (f[2], -f[1]))
    far = max(2.0 * step, window_s, period, 0.0 if feature_s is None else float(feature_s))
    rivals = [f for f in found if abs(f[0] - offset) > far]
    rival = min(rivals, key=lambda f: (f[2], -f[1])) if rivals else None
    status, message = 'ok', (f'correlation {peak:.3f}, residual {rms:.3g} W RMS at offset '
                             f'{offset:+.4f} s')
    if rival is not None:
        message += (f'; runner-up {rival[0]:+.4f} s (correlation {rival[1]:.3f}, residual '
                    f'{rival[2]:.3g} W RMS)')
    if peak < min_correlation:
        status = 'weak'
        message = f'correlation {peak:.3f} is below {min_correlation:g}; {message}'
    elif lags.size > 1 and abs(abs(offset) - max_lag_s) < 0.5 * step:
        status = 'edge'
        message = (f'best lag is at the end of the searched range ±{max_lag_s:g} s; '
                   f'widen max_lag_s; {message}')
    elif rival is not None and (rival[1] >= peak - ambiguity_margin
                                or rival[2] ** 2 <= (1.0 + ambiguity_margin) * rms ** 2):
        status = 'ambiguous'
        message = f'the runner-up fits almost as well; {message}'
    drift, drift_message = _drift(sig, offset, step=step, period=period,
                                  min_duration_s=drift_min_duration_s,
                                  min_correlation=min_correlation)
    nan = math.nan
    return OffsetResult(offset, peak, status, message, lags, corr, rms_w=rms,
                        runner_up_s=rival[0] if rival else nan,
                        runner_up_correlation=rival[1] if rival else nan,
                        runner_up_rms_w=rival[2] if rival else nan,
                        drift_ppm=drift, drift_message=drift_message)


def _information_centre(sig: _Signals, sel: slice, lag: float) -> float:
    """Where on the record a stretch's offset is measured [s]: its stamps weighted by the
    squared slope of the aligned model (a lag is told by the edges, not by flat stretches;
    the plain mean of the stamps would put a half whose edges bunch at one end in the
    wrong place, and the rate between two halves would come out too small)."""
    t = sig.t_meas[sel]
    num = den = 0.0
    for a in range(0, t.size, _EVAL_CHUNK):
        part = t[a:a + _EVAL_CHUNK + 1]
        if part.size < 2:
            break
        m = sig.prefix.average(part - lag + sig.shift_s, sig.window_s)
        w = (np.diff(m) / np.diff(part)) ** 2
        mid = 0.5 * (part[1:] + part[:-1])
        num += float(np.sum(w * mid))
        den += float(np.sum(w))
    return num / den if den > 0.0 else float(np.mean(t))


def _drift(sig: _Signals, offset: float, *, step: float, period: float,
           min_duration_s: float, min_correlation: float) -> tuple[float, str]:
    """Clock-rate difference from the offsets of the two halves of the record (ppm)."""
    t = sig.t_meas
    span = float(t[-1] - t[0])
    if span < min_duration_s:
        return math.nan, (f'not estimable: the record spans {span:.1f} s, drift needs at '
                          f'least {min_duration_s:g} s')
    half = int(np.searchsorted(t, t[0] + 0.5 * span))
    reach = max(2.0 * step, _MAX_DRIFT * span)
    offsets, centres = [], []
    for name, sel in (('first', slice(0, half)), ('second', slice(half, t.size))):
        if np.ptp(sig.y_meas[sel]) == 0.0:
            return math.nan, f'not estimable: the {name} half of the record is constant'
        uniform = bool(_whole_fraction(_uniform_period(t[sel]), step))
        grid_step = _grid_step(t[sel].size, step, 2.0 * reach, uniform)
        steps = int(math.ceil(reach / grid_step - 1e-9))
        grid = offset + np.arange(-steps, steps + 1) * grid_step
        corr = sig.grid_correlation(grid, grid_step, steps, sel, centre=offset)
        k = int(np.argmax(corr))
        lag, c = sig.refine(float(grid[k]), float(grid[k]) - grid_step,
                            float(grid[k]) + grid_step, tol=period * 1e-4, sel=sel)
        if c < min_correlation:
            return math.nan, (f'not estimable: the {name} half correlates only {c:.3f} '
                              f'(below {min_correlation:g})')
        offsets.append(lag)
        centres.append(_information_centre(sig, sel, lag))
    rate = (offsets[1] - offsets[0]) / (centres[1] - centres[0])
    return 1e6 * rate, (f'{1e6 * rate:+.0f} ppm from the offsets of the two halves '
                        f'({offsets[0]:+.4f} s, {offsets[1]:+.4f} s over '
                        f'{centres[1] - centres[0]:.1f} s)')
