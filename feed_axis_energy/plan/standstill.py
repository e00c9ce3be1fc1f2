"""Standstill: samples at rest left out of the arrays, with what is needed to count them.

A phase of the plan with zero speed, acceleration and jerk (a dwell ``G4``, the rest group of
a stop) keeps every axis at one position: all its samples have the same position, zero
velocity and acceleration and one source line, so dynamics and power are the same at each of
them. :func:`.stream.iter_motion` (with ``compact_min_samples``) samples the first and
the last samples of such a phase and leaves the ones between out (``Motion.gaps``). Every
later stage integrates by the trapezoid rule between neighbouring rows; across a gap both
rows have the same power ``P``, so the trapezoid is ``P * t`` over the gap, which is the sum
over the omitted intervals: energies, per-line energy and time need no omitted sample, and a
week of ``G4`` costs no memory or time per sample.

Sample ``i`` of the grid lies at ``i / rate_hz`` (float division, as ``numpy.arange(...) /
rate_hz`` computes it). :func:`grid_interval_counts` counts the intervals between consecutive
grid samples by value without forming them (the summary's median interval is exact).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ['first_grid_index', 'first_grid_indices', 'standstill_runs', 'grid_interval_counts',
           'STANDSTILL_MARGIN']

# Samples kept at each end of a standstill phase: the velocity step of a corner goes to the
# sample nearest to its junction, which can be the first or the last sample of a neighbouring
# rest; the second and the second-last are at rest whatever happens next to the phase.
STANDSTILL_MARGIN = 2
_DIRECT_INTERVALS = 64       # shorter runs of intervals are counted from the samples


def first_grid_indices(t: np.ndarray, rate_hz: float) -> np.ndarray:
    """Smallest ``i >= 0`` with ``i / rate_hz >= t``, element-wise (int64)."""
    t = np.asarray(t, dtype=float)
    i = np.maximum(np.ceil(t * rate_hz), 0.0).astype(np.int64)
    # t * rate_hz is rounded: the ceiling may be one off either way
    while True:
        down = (i > 0) & ((i - 1).astype(float) / rate_hz >= t)
        if not np.any(down):
            break
        i = i - down
    while True:
        up = i.astype(float) / rate_hz < t
        if not np.any(up):
            break
        i = i + up
    return i


def first_grid_index(t: float, rate_hz: float) -> int:
    """Smallest ``i >= 0`` with ``i / rate_hz >= t`` (the test the samples use)."""
    i = max(int(math.ceil(t * rate_hz)), 0)
    while i > 0 and (i - 1) / rate_hz >= t:
        i -= 1
    while i / rate_hz < t:
        i += 1
    return i


def standstill_runs(phases: tuple[np.ndarray, ...], *, rate_hz: float, lo: int, hi: int,
                    min_samples: int,
                    margin: int = STANDSTILL_MARGIN) -> list[tuple[int, int, int]]:
    """Grid sample ranges ``[a, b)`` owned by standstill phases, at least ``min_samples`` long.

    Parameters
    ----------
    phases
        The phase table of a planned window (:func:`.phases._phase_table`).
    rate_hz
        Sample rate [Hz].
    lo, hi
        Grid samples the runs may cover, ``[lo, hi)``; ``margin`` samples at both ends of a
        phase stay outside its run.
    min_samples
        Shortest run kept.
    margin
        Samples kept out of the run at each end of the phase.

    Returns
    -------
    list of (int, int, int)
        ``(a, b, phase)`` in time order; ``phase`` indexes the table.
    """
    t0, dur, _s0, v0, a0, jk, _owner = phases
    still = np.nonzero((v0 == 0.0) & (a0 == 0.0) & (jk == 0.0) & (dur > 0.0))[0]
    if still.size == 0:
        return []
    # a phase owns the samples from the first at or after its start to the next phase's start
    start = first_grid_indices(t0[still], rate_hz)
    nxt = still + 1
    end_t = np.where(nxt < t0.size, t0[np.minimum(nxt, t0.size - 1)], math.inf)
    end = np.full(still.size, hi, dtype=np.int64)
    finite = np.isfinite(end_t)
    end[finite] = first_grid_indices(end_t[finite], rate_hz)
    a = np.maximum(start + margin, lo)
    b = np.minimum(end - margin, hi)
    keep = np.nonzero(b - a >= max(int(min_samples), 1))[0]
    return list(zip(a[keep].tolist(), b[keep].tolist(), still[keep].tolist()))


def _direct_counts(i0: int, i1: int, rate_hz: float, out: dict[float, int]) -> None:
    t = np.arange(i0, i1 + 1, dtype=float) / rate_hz
    values, counts = np.unique(np.diff(t), return_counts=True)
    for v, c in zip(values.tolist(), counts.tolist()):
        out[v] = out.get(v, 0) + c


def grid_interval_counts(i0: int, i1: int, rate_hz: float) -> dict[float, int]:
    """Intervals ``t[i+1] - t[i]`` of grid samples ``i0 .. i1`` counted by value.

    Equal to ``numpy.unique(numpy.diff(numpy.arange(i0, i1 + 1) / rate_hz),
    return_counts=True)`` without forming the samples. Inside one binade ``[2^e, 2^(e+1))`` of
    the times (one spacing ``u`` of doubles) every time is ``i / rate_hz`` rounded to a
    multiple of ``u``, so every interval lies within ``u`` of ``1 / rate_hz`` and is one of
    the two multiples of ``u`` next to it (one value when ``1 / rate_hz`` is a multiple of
    ``u``: then the times are exact); their counts follow from the sum of the intervals,
    which is the difference of the end times (exact: the subtractions are exact). Intervals
    that cross a binade boundary, and short runs, are counted from the samples.

    Parameters
    ----------
    i0, i1
        First and last grid index, ``0 <= i0 <= i1``.
    rate_hz
        Sample rate [Hz].

    Returns
    -------
    dict
        ``{interval [s]: count}``; ``i1 - i0`` intervals in all.
    """
    out: dict[float, int] = {}
    i = int(i0)
    i1 = int(i1)
    while i < i1:
        if i1 - i <= _DIRECT_INTERVALS or i == 0:
            j = min(i1, i + _DIRECT_INTERVALS)
            _direct_counts(i, j, rate_hz, out)
            i = j
            continue
        t_i = i / rate_hz
        _, e = math.frexp(t_i)                  # t_i in [2^(e-1), 2^e)
        ulp = math.ldexp(1.0, e - 53)
        j = first_grid_index(math.ldexp(1.0, e), rate_hz) - 1
        j = min(j, i1)                          # samples i .. j share the binade
        n = j - i
        if n > 0:
            span = j / rate_hz - t_i            # exact: both are multiples of ulp
            c, r = divmod(int(span / ulp), n)
            for mult, count in ((c, n - r), (c + 1, r)):
                if count:
                    value = mult * ulp
                    out[value] = out.get(value, 0) + count
        if j < i1:                              # the interval that crosses into the next binade
            _direct_counts(j, j + 1, rate_hz, out)
            j += 1
        i = j
    return out
