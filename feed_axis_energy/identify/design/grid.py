"""The analysis grid: measured samples averaged in bins, so that ``analyze`` costs what the
effects need, not what the meter delivers.

A drive trace at 1 kHz carries nothing about a missing loss that a 50 ms average does not
(the catalog's shapes follow speed, position, acceleration and time, all far slower), but
it multiplies the design of every candidate column by the sample rate. So ``analyze``
selects effects on *bins* of ``k`` consecutive measured samples, ``k`` the whole number of
sample periods in the analysis period (at least 1): the bin value is the exact mean of the
``k`` samples, of the measured residual and of every aligned candidate column and state
alike. Everything that is linear in the samples (the least-squares fits, the held-out
errors) keeps its meaning; the statistics keep theirs because the noise level is estimated
on the same bins (a white noise of ``sigma`` per sample is ``sigma / sqrt(k)`` per bin, and
so is a declared level converted). A trailing partial bin (less than one analysis period of
data) is left out. Data sampled at the analysis period or slower are used as they are
(``k = 1``: the same arrays, bit for bit).

Memory then grows with the campaign's length over the analysis period, times the candidate
columns; the 1 kHz series of a run are needed only while its columns are averaged.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

__all__ = ['ABUT_TOLERANCE', 'ANALYSIS_PERIOD_S', 'Bins', 'bins_for', 'bin_windows']

ANALYSIS_PERIOD_S = 0.05
"""Default analysis period [s]: the rig's and the paper's 50 ms meter period."""
ABUT_TOLERANCE = 1e-6
"""Largest difference between the window and a sample period, relative to the window, at
which consecutive windows count as abutting (:func:`bin_windows`)."""


@dataclass(frozen=True)
class Bins:
    """``size`` consecutive samples per bin, ``count`` bins from the first sample.

    Attributes
    ----------
    size
        Samples per bin (1: no averaging).
    count
        Number of whole bins.
    samples
        Number of samples of the series the bins are taken from.
    """

    size: int
    count: int
    samples: int

    def mean(self, x: np.ndarray) -> np.ndarray:
        """Bin means of ``x`` (first axis: the samples, ``samples`` long).

        With ``size == 1`` the array itself is returned (no copy).
        """
        if self.size == 1:
            return x
        arr = np.asarray(x, dtype=float)
        used = arr[:self.count * self.size]
        return used.reshape((self.count, self.size) + arr.shape[1:]).mean(axis=1)


def bins_for(t: np.ndarray, period_s: float) -> Bins:
    """The bins of a series stamped ``t`` [s] for an analysis period of ``period_s``.

    ``size`` is the whole number of median sample periods in ``period_s`` (at least 1), so a
    bin never spans more than the analysis period of regularly sampled data.
    """
    n = int(t.shape[0])
    step = float(np.median(np.diff(t))) if n > 1 else 0.0
    size = 1
    if step > 0.0 and math.isfinite(period_s) and period_s > 0.0:
        size = max(1, int(math.floor(period_s / step + 1e-6)))
    if n // size < 2:
        size = 1
    return Bins(size=size, count=n // size, samples=n)


def bin_windows(t: np.ndarray, bins: Bins, *, window_s: float,
                shift_s: float) -> tuple[np.ndarray, float] | None:
    """One wide window per bin, when the bin's sample windows abut.

    A meter whose window equals its sample period (a 1 kHz drive trace averaging over 1 ms)
    tiles the time axis: the mean of ``k`` consecutive window averages is then the average
    over their union, one window ``(k - 1) h + w`` long ending where the last one ends. An
    interval average per bin instead of per sample is the same to rounding (window and
    periods agree within :data:`ABUT_TOLERANCE`) at ``1/k`` of the cost.

    Parameters
    ----------
    t
        Measured stamps [s], ``bins.samples`` long.
    bins
        The run's bins.
    window_s
        The instrument's window [s].
    shift_s
        How far after its stamp a sample's window ends [s] (:func:`..measured.stamp_shift`).

    Returns
    -------
    (ends, span) or None
        Per bin the end of the union of its windows [s] and the union's length [s]; ``None``
        when the windows do not abut (point samples, windows shorter or longer than the
        period, irregular stamps) or nothing is binned.
    """
    if bins.size == 1 or not window_s > 0.0:
        return None
    used = t[:bins.count * bins.size]
    steps = np.diff(used)
    if steps.size == 0 or float(np.max(np.abs(steps - window_s))) > ABUT_TOLERANCE * window_s:
        return None
    first = used[::bins.size]
    last = used[bins.size - 1::bins.size]
    span = float(np.median(last - first)) + window_s
    return last + shift_s, span
