"""Is there structure left in a residual? Binned means against a state, and the spectrum.

* Noise level (:func:`noise_level`): from the data, robustly, two ways, the larger wins.
  *White*: each sample against a cubic through its two neighbours on either side
  (``e_i = y_i - (-y_{i-2} + 4 y_{i-1} + 4 y_{i+1} - y_{i+2}) / 6``, which any cubic
  passes exactly), ``sigma_white = 1.4826 · MAD(e) / sqrt(1.944)``: the sample-to-sample
  scatter of a meter, blind to slow structure and to isolated edges. *Slow*: a smooth
  signal (a controller output, filtered drive data) has almost no sample-to-sample scatter,
  yet its noise wanders over several samples, and a mean of ``n`` samples varies by more
  than ``sigma_white² / n``. So the residual is also cut into blocks of ``m`` samples
  (``m`` in :data:`SLOW_BLOCKS`); the second differences of the block means (a local line
  removed) have variance ``6 · v_m`` when the block means are independent, and
  ``sigma_slow² = max over m of m · v_m`` (``v_m`` from the MAD, so the few blocks with a
  power edge count little): the per-sample level whose mean over a block varies as the
  data's do. The block length grows (4, 16, 64, 256 samples) as long as the level still
  grows by more than :data:`SLOW_GROWTH` in variance from one length to the next: a noise
  correlated over ``c`` samples needs blocks of several ``c`` before ``m · v_m`` settles (a
  controller output filtered at 5 ms at 1 kHz: 0.18, 0.43, 0.51-0.57 N at 4, 16, 64 samples
  under a long-run level of 0.6 N), white noise stops at 16 (the level does not grow). A
  length whose step in variance is larger than the step before it is not used (and the
  growth stops there): a noise's level settles with shrinking steps, a slow misfit of the
  model (a lag the model lacks) makes them grow. The longest length used is reported
  (``block_samples``). The level every test uses is
  ``sigma_slow`` when ``sigma_slow² > SLOW_MARGIN · sigma_white²``, else ``sigma_white``
  (below the margin the two agree within their scatter: white noise);
  ``correlation = sigma² / sigma_white²``.
  A level declared by the user replaces both.
  (Until issue 24 the level was ``1.4826 · MAD(diff(y)) / sqrt(2)`` only: on the 100 ms
  UMich power it read 0.02–0.06 W under a residual of 0.6–1.3 W RMS, and every test
  reported structure.)
* Binned means (:func:`binned_structure`): the residual is grouped into quantile bins of a
  state (velocity, position, acceleration, kinetic power ``a·v``, time); ``chi2 = sum n_b ·
  mean_b² / sigma²`` over ``B`` bins is compared with a chi-square distribution of ``B``
  degrees of freedom (an F-test of "the bin means are all zero" with the noise level known).
  ``rms_w`` is the size of the structure, ``sqrt(sum n_b mean_b² / N)``.
* Spectrum (:func:`spectrum_structure`): Welch periodograms of every run on a common
  segment length, averaged; the peak-to-median ratio of the averaged periodogram (without
  the zero frequency) is about 1.5 for white noise. Coloured noise (the slow estimate set the
  level: a filtered controller output) has no flat spectrum: its low frequencies stand far
  above the global median with no peak in them, so there each frequency is compared with
  the median of its neighbours (:data:`LOCAL_BINS` on either side, its own three bins left
  out), which a peak still exceeds.

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

__all__ = ['Diagnostic', 'NoiseLevel', 'binned_structure', 'noise_level', 'noise_sigma',
           'spectrum_structure', 'diagnose_runs', 'average_spectrum', 'LOCAL_BINS',
           'SLOW_BLOCKS', 'SLOW_GROWTH', 'SLOW_MARGIN', 'SLOW_MIN_DIFFS', 'STATE_BINS']

STATE_BINS = 6
"""Quantile bins per state of the grid whose cell means are removed before the slow estimate."""
SLOW_BLOCKS = (4, 16, 64, 256)
"""Block lengths [samples] of the slow noise estimate, tried in turn (:data:`SLOW_GROWTH`)."""
SLOW_GROWTH = 1.2
"""The next block length is tried when the level's variance grew by more than this factor
from the previous length to the last one (the first two are always tried)."""
SLOW_MIN_DIFFS = 30
"""Second differences of block means a level needs (pooled over runs)."""
LOCAL_BINS = 8
"""Neighbouring frequencies on either side whose median is a peak's reference in coloured
noise (:func:`spectrum_structure`)."""
SLOW_MARGIN = 1.5
"""The slow estimate replaces the white one when its variance is this many times larger
(below, the two agree within the scatter of the estimates: white noise)."""
_CUBIC = np.array([-1.0, 4.0, 0.0, 4.0, -1.0]) / 6.0
_CUBIC_VAR = 1.0 + float(np.sum(_CUBIC ** 2))      # var(e) / sigma² for white noise


@dataclass(frozen=True)
class Diagnostic:
    """One structure test of a residual.

    Attributes
    ----------
    name
        ``'velocity'``, ``'position'``, ``'acceleration'``, ``'kinetic_power'`` (``a·v``),
        ``'time'`` or ``'spectrum'``.
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


@dataclass(frozen=True)
class NoiseLevel:
    """The noise level of one axis's residual and how it was found.

    Attributes
    ----------
    sigma_w
        The level every test uses [W]: a white-noise equivalent per sample (a mean of ``n``
        samples varies by ``sigma_w / sqrt(n)``).
    white_w
        Sample-to-sample scatter [W] (local cubic, see the module docstring).
    slow_w
        The level from the detrended residual and its correlation [W] (``nan``: too few
        samples).
    correlation
        ``sigma_w² / white_w²`` (1 for white noise; larger for smooth signals).
    method
        ``'white'`` or ``'slow'`` (which estimate was larger), or ``'declared'``.
    residual
        Which residual it was estimated on (``analyze``: ``'baseline'`` or ``'after the
        effects found'``).
    block_samples
        Block length [samples] of the slow estimate (the longest one tried; 0: none).
    """

    sigma_w: float
    white_w: float
    slow_w: float
    correlation: float
    method: str
    residual: str = ''
    block_samples: int = 0

    def to_dict(self) -> dict:
        """Plain dict (keys in docs/analyze.md)."""
        return asdict(self)


def _mad_scale(x: np.ndarray) -> float:
    return 1.4826 * float(np.median(np.abs(x - np.median(x)))) if x.size else math.nan


def _white(series: Sequence[np.ndarray]) -> float:
    long = [y for y in series if y.size >= 5]
    if not long:
        d = np.concatenate([np.diff(y) for y in series]) if series else np.zeros(0)
        if not d.size:
            return math.nan
        return (_mad_scale(d) or float(np.std(d))) / math.sqrt(2.0)
    # each sample against the cubic through its two neighbours on either side
    e = np.concatenate([y[2:-2] - np.convolve(y, _CUBIC, mode='valid') for y in long])
    scale = _mad_scale(e) or float(np.std(e))
    return scale / math.sqrt(_CUBIC_VAR)


def _slow(series: Sequence[np.ndarray]) -> tuple[float, int]:
    """The slow level and the longest block length tried (module docstring)."""
    best, used = math.nan, 0
    levels: list[float] = []
    for m in SLOW_BLOCKS:
        if len(levels) >= 2 and not levels[-1] ** 2 > SLOW_GROWTH * levels[-2] ** 2:
            break       # the level has settled: the blocks are longer than the correlation
        # means of m consecutive samples; their second differences remove a local line
        parts = []
        for y in series:
            n = (y.size // m) * m
            if n >= 3 * m:
                b = y[:n].reshape(-1, m).mean(axis=1)
                parts.append(b[:-2] - 2.0 * b[1:-1] + b[2:])
        d = np.concatenate(parts) if parts else np.zeros(0)
        if d.size < (SLOW_MIN_DIFFS if levels else 1):
            break
        # independent block means of variance v: var(second difference) = 6 v
        level = math.sqrt(m * (_mad_scale(d) ** 2) / 6.0)
        if len(levels) >= 2 and level ** 2 * levels[-2] ** 2 > levels[-1] ** 4:
            # the level grows faster than from the previous length: a correlated noise
            # settles with shrinking steps, so this is structure on that scale, not noise
            break
        levels.append(level)
        used = m
        best = level if not best >= level else best
    return best, used


def _state_bins(x: np.ndarray, bins: int) -> np.ndarray:
    """Index of each sample's cell in a grid of quantile bins of every state column."""
    cell = np.zeros(x.shape[0], dtype=np.int64)
    for col in np.asarray(x, dtype=float).reshape(x.shape[0], -1).T:
        edges = np.unique(np.quantile(col, np.linspace(0.0, 1.0, bins + 1)))
        k = np.clip(np.searchsorted(edges, col, side='right') - 1, 0, max(edges.size - 2, 0))
        cell = cell * bins + k
    return cell


def _without_state_means(y: np.ndarray, x: np.ndarray, bins: int) -> np.ndarray:
    """The residual less its mean in each cell of the state grid, rescaled for the cells."""
    cell = np.unique(_state_bins(x, bins), return_inverse=True)[1].reshape(-1)
    counts = np.bincount(cell).astype(float)
    means = np.bincount(cell, weights=y) / counts
    used = int(np.count_nonzero(counts))
    if y.size <= used:
        return np.zeros(0)
    # subtracting a cell's mean removes 1/n_cell of each sample's noise variance
    return (y - means[cell]) * math.sqrt(y.size / (y.size - used))


def noise_level(residuals: Sequence[np.ndarray], *, declared_w: float | None = None,
                states: Sequence[np.ndarray] | None = None) -> NoiseLevel:
    """Robust noise level of residual series, pooled over runs (see the module docstring).

    Parameters
    ----------
    residuals
        One residual series per run [W].
    declared_w
        A level the user declared [W]; it replaces the estimate (which is still reported).
    states
        Per run the states ``(n, q)`` a missing effect depends on (velocity,
        acceleration): the slow estimate is taken after each run's mean in every cell of a
        grid of :data:`STATE_BINS` quantile bins per state is subtracted, so that structure
        that follows the state is not read as slow noise.

    Returns
    -------
    NoiseLevel
        ``sigma_w`` NaN when no series has two samples.
    """
    keep = [i for i, y in enumerate(residuals) if np.size(y) > 1]
    series = [np.asarray(residuals[i], dtype=float) for i in keep]
    white = _white(series)
    flat = series
    if states is not None:
        flat = [_without_state_means(series[n], np.asarray(states[i]), STATE_BINS)
                for n, i in enumerate(keep)]
    slow, block = _slow(flat)
    if declared_w is not None:
        sigma, method = float(declared_w), 'declared'
    elif math.isfinite(slow) and slow ** 2 > SLOW_MARGIN * white ** 2:
        sigma, method = slow, 'slow'
    else:
        sigma, method = white, 'white'
    corr = sigma ** 2 / white ** 2 if white > 0.0 and math.isfinite(sigma) else math.nan
    return NoiseLevel(sigma_w=sigma, white_w=white, slow_w=slow, correlation=corr,
                      method=method, block_samples=block)


def noise_sigma(residuals: Sequence[np.ndarray]) -> float:
    """The noise level [W] every test uses: ``noise_level(residuals).sigma_w``."""
    return noise_level(residuals).sigma_w


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
                       min_rms_fraction: float = 0.3, unit: str = 'W',
                       coloured: bool = False) -> Diagnostic:
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
    coloured
        The noise is not white (its slow estimate set ``sigma``): each frequency is compared
        with the median of its neighbours instead of the global median.

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
    base = _local_median(inner) if coloured else np.full(inner.size, np.median(inner))
    with np.errstate(divide='ignore', invalid='ignore'):
        ratios = np.where(base > 0.0, inner / np.where(base > 0.0, base, 1.0), math.inf)
    k = int(np.argmax(ratios))
    median = float(base[k])
    ratio = float(ratios[k])
    # scaling='spectrum' gives the power of a sine, A²/2, spread over a few bins (Hann)
    lo, hi = max(k - 1, 0), min(k + 2, inner.size)
    amplitude = math.sqrt(2.0 * max(float(inner[lo:hi].sum()) - 3.0 * median, 0.0))
    peak = float(f[k + 1])
    structured = ratio > max_ratio and amplitude > min_rms_fraction * sigma
    message = (f'spectral peak at {peak:.2f} Hz, {ratio:.1f} x the median level '
               f'(sine of about {amplitude:.2f} {unit})' if structured else
               f'no dominant frequency (peak {ratio:.1f} x the median at {peak:.2f} Hz)')
    return Diagnostic('spectrum', axis, ratio, math.nan, amplitude, peak, structured, message)


def _local_median(psd: np.ndarray) -> np.ndarray:
    """Per frequency the median of its :data:`LOCAL_BINS` neighbours on either side, its own
    bin and the two next to it left out (a windowed sine spreads over three bins)."""
    out = np.empty(psd.size)
    for i in range(psd.size):
        near = [j for j in range(max(i - LOCAL_BINS, 0), min(i + LOCAL_BINS + 1, psd.size))
                if abs(j - i) > 1]
        out[i] = float(np.median(psd[near])) if near else float(psd[i])
    return out


def diagnose_runs(runs: Sequence, residuals: Sequence[np.ndarray], sigmas: Mapping[str, float],
                  *, names: Sequence[str], unit: str = 'W',
                  coloured: Mapping[str, bool] | None = None) -> tuple[list[Diagnostic], dict]:
    """Binned structure against each state of ``names`` and the spectrum, per measured axis.

    ``runs`` carry ``cmp`` (``axes``), the residuals' stamps ``t`` and ``states``
    (``{name: (m, k)}``);
    ``residuals[r]`` is ``(m, k)`` in ``unit`` (``'W'``; ``'A'``, ``'N·m'``, ``'N'`` for a
    drive trace). ``coloured``: per axis, the noise is not white (the spectrum test compares
    each frequency with its neighbours, :func:`spectrum_structure`).
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
        period = float(np.median([np.median(np.diff(r.t)) for r in runs]))
        out.append(spectrum_structure([res[:, j] for res in residuals], period_s=period,
                                      sigma=sigmas[axis], axis=axis, unit=unit,
                                      coloured=bool((coloured or {}).get(axis, False))))
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
