"""Time alignment of simulated and measured power.

Instrument model: a measured sample stamped ``t`` is the mean of the true signal over the
window ``[t - window_s, t]`` (a power analyser that averages over its sampling period). The
simulated signal is treated as piecewise linear between its samples and held at its first
and last value outside its time range (the machine is at rest before and after a program).

Sign convention: ``offset_s`` is how much *later* the measured record is than the simulated
one, i.e. ``y_meas(t) ~= mean of y_sim over [t - offset_s - window_s, t - offset_s]``. An
event at simulated time 2.0 s that the instrument stamps 2.5 s gives ``offset_s = +0.5``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import minimize_scalar

from ..errors import DataError

__all__ = ['OffsetResult', 'align_simulated', 'estimate_offset', 'interval_average']

_MAX_LAG_STEPS = 100_000
_CHUNK_ELEMENTS = 2_000_000


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
        ``'ok'``; ``'weak'`` (peak below ``min_correlation`` or a constant signal);
        ``'edge'`` (best lag at the end of the searched range: the true offset may lie
        outside); ``'ambiguous'`` (another, distant lag correlates almost as well, as with
        repeated identical movements).
    message
        A sentence saying why.
    lags_s, correlation
        The searched lag grid [s] and the correlation at each lag (for plots).
    """

    offset_s: float
    peak_correlation: float
    status: str
    message: str
    lags_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    correlation: np.ndarray = field(default_factory=lambda: np.zeros(0))


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


def _cumulative(t: np.ndarray, y: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Exact integral of the piecewise-linear ``y`` from ``t[0]`` to each ``tau``."""
    dt = np.diff(t)
    seg = 0.5 * (y[1:] + y[:-1]) * (dt if y.ndim == 1 else dt[:, None])
    big_f = np.concatenate([np.zeros((1,) + y.shape[1:]), np.cumsum(seg, axis=0)])
    i = np.clip(np.searchsorted(t, tau, side='right') - 1, 0, t.size - 2)
    h = np.clip(tau, t[0], t[-1]) - t[i]
    slope = (y[i + 1] - y[i]) / (dt[i] if y.ndim == 1 else dt[i][:, None])
    if y.ndim > 1:
        h = h[:, None]
    out = big_f[i] + y[i] * h + 0.5 * slope * h * h
    before = np.minimum(tau - t[0], 0.0)
    after = np.maximum(tau - t[-1], 0.0)
    if y.ndim > 1:
        before, after = before[:, None], after[:, None]
    return out + y[0] * before + y[-1] * after


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
    flat = tau.ravel()
    if window_s == 0.0:
        if y_sim.ndim == 1:
            out = np.interp(flat, t_sim, y_sim)
        else:
            out = np.column_stack([np.interp(flat, t_sim, col) for col in y_sim.T])
    else:
        out = (_cumulative(t_sim, y_sim, flat)
               - _cumulative(t_sim, y_sim, flat - window_s)) / window_s
    return out.reshape(tau.shape + y_sim.shape[1:])


def align_simulated(t_sim: ArrayLike, y_sim: ArrayLike, t_meas: ArrayLike, *,
                    offset_s: float, window_s: float) -> np.ndarray:
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
        Instrument averaging window [s].

    Returns
    -------
    numpy.ndarray
        ``interval_average(t_sim, y_sim, t_meas - offset_s, window_s=window_s)``.
    """
    shifted = np.asarray(t_meas, dtype=np.float64) - offset_s
    return interval_average(t_sim, y_sim, shifted, window_s=window_s)


def _correlation(y: np.ndarray, model: np.ndarray) -> np.ndarray:
    """Pearson correlation of ``y`` (n,) with every row of ``model`` (l, n); 0 if flat."""
    yc = y - y.mean()
    mc = model - model.mean(axis=-1, keepdims=True)
    den = np.sqrt((yc @ yc) * np.einsum('...i,...i->...', mc, mc))
    num = mc @ yc
    with np.errstate(invalid='ignore', divide='ignore'):
        return np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), 0.0)


def estimate_offset(t_meas: ArrayLike, y_meas: ArrayLike, t_sim: ArrayLike, y_sim: ArrayLike,
                    *, max_lag_s: float, window_s: float, min_correlation: float = 0.5,
                    ambiguity_margin: float = 0.1) -> OffsetResult:
    """Find the time offset of the measured record by cross-correlation.

    The measured power is correlated with the interval-averaged simulated power shifted by
    every lag on a grid of the median measured period within ``±max_lag_s`` (a coarser grid
    if that needs more than 100 000 lags per side); the best grid
    lag is then refined to a fraction of a period by a bounded scalar maximisation of the
    correlation over the continuous offset (interval averaging makes it smooth in the lag).
    Correlation, not squared error, is used so that a gain error of the model does not bias
    the offset.

    Parameters
    ----------
    t_meas, y_meas
        Measured stamps [s] and power [W], shape ``(n,)``.
    t_sim, y_sim
        Simulated times [s] and power [W], shape ``(m,)``.
    max_lag_s
        Largest offset searched, in either direction [s].
    window_s
        Instrument averaging window [s] (usually the measured period).
    min_correlation
        Peak correlation below which the result is ``'weak'``.
    ambiguity_margin
        A distant local maximum within this much of the peak makes the result
        ``'ambiguous'``.

    Returns
    -------
    OffsetResult
        Offset, peak correlation, status and message (see the module's sign convention).

    Raises
    ------
    DataError
        On malformed arrays (never for a poor match).
    """
    t_meas, y_meas = _series(t_meas, y_meas, 'meas')
    t_sim, y_sim = _series(t_sim, y_sim, 'sim')
    if y_meas.ndim != 1 or y_sim.ndim != 1:
        msg = 'estimate_offset takes 1-D signals (e.g. total power); sum the axes first'
        raise DataError(msg, file='<arrays>', column='y')
    if not (math.isfinite(max_lag_s) and max_lag_s >= 0.0):
        msg = f'max_lag_s must be a finite number >= 0, got {max_lag_s!r}'
        raise DataError(msg, file='<arrays>', column='max_lag_s')
    # the grid step is the measured period, coarsened when that would need more than
    # _MAX_LAG_STEPS lags per side (a sub-microsecond period against a lag range of
    # seconds asked for 10^10 lags); the refinement below then searches +-one step
    period = max(float(np.median(np.diff(t_meas))), max_lag_s / _MAX_LAG_STEPS)
    steps = int(math.ceil(max_lag_s / period - 1e-9))
    lags = np.clip(np.arange(-steps, steps + 1) * period, -max_lag_s, max_lag_s)
    if np.ptp(y_meas) == 0.0 or np.ptp(y_sim) == 0.0:
        which = 'measured' if np.ptp(y_meas) == 0.0 else 'simulated'
        return OffsetResult(0.0, math.nan, 'weak', f'the {which} signal is constant',
                            lags, np.zeros_like(lags))
    corr = np.empty(lags.size)
    per_chunk = max(1, _CHUNK_ELEMENTS // t_meas.size)
    for start in range(0, lags.size, per_chunk):
        part = lags[start:start + per_chunk]
        model = interval_average(t_sim, y_sim, t_meas[None, :] - part[:, None],
                                 window_s=window_s)
        corr[start:start + per_chunk] = _correlation(y_meas, model)
    k = int(np.argmax(corr))

    def negative(lag: float) -> float:
        model = interval_average(t_sim, y_sim, t_meas - lag, window_s=window_s)
        return -float(_correlation(y_meas, model[None, :])[0])

    lo = max(-max_lag_s, lags[k] - period)
    hi = min(max_lag_s, lags[k] + period)
    offset, peak = float(lags[k]), float(corr[k])
    if hi > lo:
        res = minimize_scalar(negative, bounds=(lo, hi), method='bounded',
                              options={'xatol': period * 1e-4})
        if -res.fun >= peak:
            offset, peak = float(res.x), float(-res.fun)
    status, message = 'ok', f'correlation {peak:.3f} at offset {offset:+.4f} s'
    rival = _rival_peak(corr, k, lags, distance_s=max(2.0 * period, window_s))
    if peak < min_correlation:
        status = 'weak'
        message = f'peak correlation {peak:.3f} is below {min_correlation:g}; {message}'
    elif lags.size > 1 and k in (0, lags.size - 1):
        status = 'edge'
        message = (f'best lag is at the end of the searched range ±{max_lag_s:g} s; '
                   f'widen max_lag_s; {message}')
    elif rival is not None and corr[rival] >= peak - ambiguity_margin:
        status = 'ambiguous'
        message = (f'lag {lags[rival]:+.4f} s correlates almost as well '
                   f'({corr[rival]:.3f}); {message}')
    return OffsetResult(offset, peak, status, message, lags, corr)


def _rival_peak(corr: np.ndarray, k: int, lags: np.ndarray, *,
                distance_s: float) -> int | None:
    """Index of the best local maximum farther than ``distance_s`` from the peak."""
    if corr.size < 3:
        return None
    inner = np.flatnonzero((corr[1:-1] >= corr[:-2]) & (corr[1:-1] >= corr[2:])) + 1
    far = inner[np.abs(lags[inner] - lags[k]) > distance_s]
    if far.size == 0:
        return None
    return int(far[np.argmax(corr[far])])
