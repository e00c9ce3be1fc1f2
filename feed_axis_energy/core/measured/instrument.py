"""Does the declared instrument model fit? Residuals of alternative meters, offsets refitted.

For a run compared at offset ``o`` with the declared meter, every alternative meter
(:data:`ALTERNATIVES`: point samples, a window of one sampling period) and the declared one
are fitted again near ``o`` (within two periods plus the window, the same estimator as the
offset search) and their residual RMS after the instrument model is recorded. The stamp
position of a window (end, centre, start) is a pure shift in time, which the offset absorbs:
power alone cannot tell it apart, so alternatives differ in the window length only.

:func:`instrument_verdict` pools the runs (mean squared residuals weighted by sample counts)
and says when an alternative fits clearly better (by more than ``margin``, 5 % of the mean
square by default) than the declared meter.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math

import numpy as np

from .align import estimate_offset

__all__ = ['ALTERNATIVES', 'MeterFit', 'check_instrument', 'instrument_verdict']

ALTERNATIVES = ('point', 'period')
"""Meters tried beside the declared one: point samples, one sampling period stamped at its end."""


@dataclass(frozen=True)
class MeterFit:
    """One meter model on one run, its offset refitted near the comparison's.

    Attributes
    ----------
    label
        ``'declared'``, ``'point'`` or ``'period'``.
    window_s, stamp
        The meter: averaging window [s] (0: point samples) and stamp position.
    offset_s
        Refitted offset [s].
    rms_w
        Residual RMS after the meter model, mean removed [W].
    n_samples
        Samples compared.
    """

    label: str
    window_s: float
    stamp: str
    offset_s: float
    rms_w: float
    n_samples: int

    def to_dict(self) -> dict[str, float | str | int]:
        """Plain dict; keys carry units."""
        return {'label': self.label, 'window_s': self.window_s, 'stamp': self.stamp,
                'offset_s': self.offset_s, 'rms_w': self.rms_w}


def check_instrument(t_meas: np.ndarray, y_meas: np.ndarray, t_sim: np.ndarray,
                     y_sim: np.ndarray, *, offset_s: float, window_s: float,
                     stamp: str) -> tuple[MeterFit, ...]:
    """Fit the declared meter and the alternatives near ``offset_s``.

    Parameters
    ----------
    t_meas, y_meas
        Measured stamps [s] and summed power [W], ``(n,)``.
    t_sim, y_sim
        Simulated times [s] and summed power [W], ``(m,)``.
    offset_s
        The comparison's offset [s].
    window_s, stamp
        The declared meter.

    Returns
    -------
    tuple of MeterFit
        The declared meter first, then the alternatives whose window differs from it.
    """
    period = float(np.median(np.diff(t_meas)))
    meters = [('declared', float(window_s), stamp)]
    for label, w in zip(ALTERNATIVES, (0.0, period)):
        if not math.isclose(w, window_s, rel_tol=1e-9, abs_tol=1e-12):
            meters.append((label, w, 'end'))
    out = []
    for label, w, s in meters:
        reach = 2.0 * period + w
        res = estimate_offset(t_meas - offset_s, y_meas, t_sim, y_sim, max_lag_s=reach,
                              window_s=w, stamp=s, candidates=2,
                              drift_min_duration_s=math.inf)
        out.append(MeterFit(label, w, s, offset_s + res.offset_s, res.rms_w,
                            int(t_meas.size)))
    return tuple(out)


def instrument_verdict(fits: Sequence[Sequence[MeterFit]], *, margin: float = 0.05,
                       describe: str = 'the declared meter') -> str | None:
    """A warning when an alternative meter fits the pooled runs clearly better, else None.

    Parameters
    ----------
    fits
        Per run, the output of :func:`check_instrument`.
    margin
        Relative reduction of the pooled mean squared residual that counts as clearly better.
    describe
        Words for the declared meter in the message.

    Returns
    -------
    str or None
        One sentence naming both meters and their pooled residual RMS [W].
    """
    pooled: dict[str, list[float]] = {}
    windows: dict[str, float] = {}
    for run in fits:
        for f in run:
            if math.isfinite(f.rms_w):
                acc = pooled.setdefault(f.label, [0.0, 0.0])
                acc[0] += f.n_samples * f.rms_w ** 2
                acc[1] += f.n_samples
                windows[f.label] = f.window_s
    if 'declared' not in pooled or pooled['declared'][1] == 0:
        return None
    ms = {k: v[0] / v[1] for k, v in pooled.items()
          if v[1] == pooled['declared'][1]}   # only meters fitted on every run
    best = min(ms, key=ms.get)
    if best == 'declared' or ms[best] >= (1.0 - margin) * ms['declared']:
        return None
    name = 'point samples' if best == 'point' else f'a {1e3 * windows[best]:g} ms window'
    return (f'instrument model: {name} fit better than {describe} (residual RMS '
            f'{math.sqrt(ms[best]):.3g} W against {math.sqrt(ms["declared"]):.3g} W, offsets '
            f'refitted, pooled over {len(fits)} runs); declare instrument: in the manifest')
