"""Is there structure left in a residual? Binned means against a state, and the spectrum.

* Noise level: ``sigma = 1.4826 · MAD(diff(y)) / sqrt(2)`` pooled over runs; first
  differences remove slow structure and the median ignores the few samples at power edges,
  so this is the white-noise level of the instrument even when structure remains.
* Binned means (:func:`binned_structure`): the residual is grouped into quantile bins of a
  state (velocity, position, acceleration, time); ``chi2 = sum n_b · mean_b² / sigma²`` over
  ``B`` bins is compared with a chi-square distribution of ``B`` degrees of freedom (an F-test
  of "the bin means are all zero" with the noise level known). ``rms_w`` is the size of the
  structure, ``sqrt(sum n_b mean_b² / N)``.
* Spectrum (:func:`spectrum_structure`): Welch periodograms of every run on a common
  segment length, averaged; the peak-to-median ratio of the averaged periodogram (without
  the zero frequency) is about 1.5 for white noise.

A diagnostic is *structured* when it is significant (``p < alpha`` or ratio above
``max_ratio``) and large (``rms_w`` above ``min_rms_fraction · sigma``, or the peak's
amplitude above that): tiny but detectable structure on long records is not worth a claim.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
import math

import numpy as np
from scipy import signal, stats

__all__ = ['Diagnostic', 'binned_structure', 'noise_sigma', 'spectrum_structure',
           'diagnose_runs', 'average_spectrum']


@dataclass(frozen=True)
class Diagnostic:
    """One structure test of a residual.

    Attributes
    ----------
    name
        ``'velocity'``, ``'position'``, ``'acceleration'``, ``'time'`` or ``'spectrum'``.
    axis
        The measured axis.
    statistic
        ``chi2 / dof`` for binned means; peak-to-median ratio for the spectrum.
    p_value
        Chi-square tail probability (NaN for the spectrum).
    rms_w
        Size of the structure [W] (binned: RMS of the bin means; spectrum: amplitude of the
        peak's sine).
    peak_hz
        Frequency of the spectral peak [Hz] (NaN for binned tests).
    structured
        Significant and large (see the module docstring).
    message
        One sentence.
    """

    name: str
    axis: str
    statistic: float
    p_value: float
    rms_w: float
    peak_hz: float
    structured: bool
    message: str

    def to_dict(self) -> dict:
        """Plain dict."""
        return asdict(self)


def noise_sigma(residuals: Sequence[np.ndarray]) -> float:
    """Robust white-noise level [W] of residual series (see the module docstring)."""
    diffs = [np.diff(np.asarray(y, dtype=float)) for y in residuals if np.size(y) > 1]
    if not diffs:
        return math.nan
    d = np.concatenate(diffs)
    mad = float(np.median(np.abs(d - np.median(d))))
    sigma = 1.4826 * mad / math.sqrt(2.0)
    if sigma == 0.0:
        sigma = float(np.std(d)) / math.sqrt(2.0)
    return sigma


def binned_structure(residual: np.ndarray, state: np.ndarray, *, sigma: float, name: str,
                     axis: str, bins: int = 12, alpha: float = 1e-4,
                     min_rms_fraction: float = 0.3, unit: str = 'W') -> Diagnostic:
    """Test whether the residual's mean depends on a state (quantile bins).

    Parameters
    ----------
    residual, state
        Pooled samples, ``(N,)`` each.
    sigma
        Noise level [W] (:func:`noise_sigma`).
    name, axis
        Labels.
    bins
        Number of quantile bins (ties merge bins).
    alpha, min_rms_fraction
        Significance level and the smallest structure worth reporting, as a fraction of
        ``sigma``.

    Returns
    -------
    Diagnostic
        ``statistic = chi2 / dof``.
    """
    y = np.asarray(residual, dtype=float)
    x = np.asarray(state, dtype=float)
    edges = np.unique(np.quantile(x, np.linspace(0.0, 1.0, bins + 1)))
    if edges.size < 2:  # a constant state (e.g. a run of two equal samples): no bins
        return Diagnostic(name, axis, math.nan, math.nan, math.nan, math.nan, False,
                          f'{name} is constant; nothing to bin')
    idx = np.clip(np.searchsorted(edges, x, side='right') - 1, 0, max(edges.size - 2, 0))
    counts = np.bincount(idx, minlength=max(edges.size - 1, 1)).astype(float)
    sums = np.bincount(idx, weights=y, minlength=counts.size)
    used = counts > 0
    means = sums[used] / counts[used]
    dof = int(used.sum())
    if not (sigma > 0.0) or dof == 0:
        return Diagnostic(name, axis, math.nan, math.nan, math.nan, math.nan, False,
                          'no noise level or no samples')
    chi2 = float(np.sum(counts[used] * means ** 2) / sigma ** 2)
    p = float(stats.chi2.sf(chi2, dof))
    rms = math.sqrt(float(np.sum(counts[used] * means ** 2)) / float(counts.sum()))
    structured = p < alpha and rms > min_rms_fraction * sigma
    worst = int(np.argmax(np.abs(means)))
    lo, hi = edges[np.flatnonzero(used)[worst]], edges[np.flatnonzero(used)[worst] + 1]
    u = unit
    message = (f'residual mean depends on {name} (chi2/dof {chi2 / dof:.1f}, p {p:.2g}, '
               f'RMS of bin means {rms:.2f} {u} vs noise {sigma:.2f} {u}; largest '
               f'{means[worst]:+.2f} {u} for {name} in [{lo:.4g}, {hi:.4g}])'
               if structured else
               f'no structure against {name} (chi2/dof {chi2 / dof:.2f}, '
               f'RMS of bin means {rms:.2f} {u} vs noise {sigma:.2f} {u})')
    return Diagnostic(name, axis, chi2 / dof, p, rms, math.nan, structured, message)


def spectrum_structure(residuals: Sequence[np.ndarray], *, period_s: float, sigma: float,
                       axis: str, nperseg: int = 256, max_ratio: float = 8.0,
                       min_rms_fraction: float = 0.3, unit: str = 'W') -> Diagnostic:
    """Peak-to-median ratio of the run-averaged Welch periodogram of the residual.

    Parameters
    ----------
    residuals
        One residual series per run, sampled every ``period_s``.
    period_s
        Sampling period [s].
    sigma
        Noise level [W].
    axis
        Label.
    nperseg
        Segment length (shortened to the shortest run).
    max_ratio, min_rms_fraction
        A peak is structure when its ratio exceeds ``max_ratio`` and the amplitude of the
        sine it represents exceeds ``min_rms_fraction · sigma``.

    Returns
    -------
    Diagnostic
        ``statistic`` = ratio, ``peak_hz``, ``rms_w`` = amplitude of the peak.
    """
    runs = [np.asarray(y, dtype=float) for y in residuals if np.size(y) >= 16]
    if not runs:
        return Diagnostic('spectrum', axis, math.nan, math.nan, math.nan, math.nan, False,
                          'runs too short for a spectrum')
    seg = int(min(nperseg, min(y.size for y in runs)))
    fs = 1.0 / period_s
    psd = []
    weights = []
    for y in runs:
        f, p = signal.welch(y, fs=fs, nperseg=seg, detrend='constant', scaling='spectrum')
        psd.append(p)
        weights.append(y.size)
    avg = np.average(np.array(psd), axis=0, weights=np.array(weights, dtype=float))
    inner = avg[1:]
    k = int(np.argmax(inner))
    median = float(np.median(inner))
    ratio = float(inner[k] / median) if median > 0.0 else math.inf
    # scaling='spectrum' gives the power of a sine, A²/2, spread over a few bins (Hann)
    lo, hi = max(k - 1, 0), min(k + 2, inner.size)
    amplitude = math.sqrt(2.0 * max(float(inner[lo:hi].sum()) - 3.0 * median, 0.0))
    peak = float(f[k + 1])
    structured = ratio > max_ratio and amplitude > min_rms_fraction * sigma
    message = (f'spectral peak at {peak:.2f} Hz, {ratio:.1f} x the median level '
               f'(sine of about {amplitude:.2f} {unit})' if structured else
               f'no dominant frequency (peak {ratio:.1f} x the median at {peak:.2f} Hz)')
    return Diagnostic('spectrum', axis, ratio, math.nan, amplitude, peak, structured, message)


def diagnose_runs(runs: Sequence, residuals: Sequence[np.ndarray], sigmas: Mapping[str, float],
                  *, names: Sequence[str], unit: str = 'W') -> tuple[list[Diagnostic], dict]:
    """Binned structure against each state of ``names`` and the spectrum, per measured axis.

    ``runs`` carry ``cmp`` (``axes``, stamps ``t``) and ``states`` (``{name: (m, k)}``);
    ``residuals[r]`` is ``(m, k)`` in ``unit`` (``'W'``, ``'A'`` for a current trace).
    Returns the diagnostics and ``{axis: (f, psd)}``.
    """
    out: list[Diagnostic] = []
    spectra = {}
    axes = runs[0].cmp.axes
    for j, axis in enumerate(axes):
        y = np.concatenate([res[:, j] for res in residuals])
        for name in names:
            x = np.concatenate([r.states[name][:, j] for r in runs])
            out.append(binned_structure(y, x, sigma=sigmas[axis], name=name, axis=axis,
                                        unit=unit))
        # the sampling period (the window may be 0: point samples)
        period = float(np.median([np.median(np.diff(r.cmp.t)) for r in runs]))
        out.append(spectrum_structure([res[:, j] for res in residuals], period_s=period,
                                      sigma=sigmas[axis], axis=axis, unit=unit))
        spectra[axis] = average_spectrum([res[:, j] for res in residuals], period)
    return out, spectra


def average_spectrum(series: Sequence[np.ndarray],
                     period: float) -> tuple[np.ndarray, np.ndarray]:
    """Welch spectrum (``scaling='spectrum'``) averaged over runs: ``(f, psd)``."""
    runs = [s for s in series if s.size >= 16]
    if not runs:
        return np.zeros(0), np.zeros(0)
    seg = int(min(256, min(s.size for s in runs)))
    psd = [signal.welch(s, fs=1.0 / period, nperseg=seg, scaling='spectrum')[1] for s in runs]
    f = signal.welch(runs[0], fs=1.0 / period, nperseg=seg)[0]
    return f, np.mean(psd, axis=0)
