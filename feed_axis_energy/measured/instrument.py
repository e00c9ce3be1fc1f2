"""Does the declared instrument model fit? Residuals of alternative meters, offsets refitted.

For a run compared at offset ``o`` with the declared meter, every alternative meter
(:data:`ALTERNATIVES`: point samples, a window of one sampling period) and the declared one
are fitted again near ``o`` (within two periods plus the window, the same estimator as the
offset search) and their residual RMS after the instrument model is recorded. The stamp
position of a window (end, centre, start) is then a pure shift in time, which the offset
absorbs: power alone cannot tell it apart, so these alternatives differ in the window length
only.

Runs whose motion comes from the data (``same_clock``) are different: the simulation runs on
the data's own stamps, where positions and power were read from the same record, so the
offset is known to be about zero and the stamp position can be told apart. There, every
meter's offset is fitted within a quarter period of zero (:data:`SAME_CLOCK_REACH`; room for
the two readings of a record to be a little apart, not for a window's length), and the
window of one period is tried stamped at its end, centre and start
(:data:`SAME_CLOCK_ALTERNATIVES`). A declared window stamped at its end on data whose meter
stamps the start (or point samples where a window averages) then leaves a clearly larger
residual.

:func:`instrument_verdict` pools the runs (mean squared residuals weighted by sample counts)
and says when an alternative fits clearly better (by more than ``margin``, 5 % of the mean
square by default) than the declared meter.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math
from typing import cast

import numpy as np

from .align import estimate_offset

__all__ = ['ALTERNATIVES', 'SAME_CLOCK_ALTERNATIVES', 'SAME_CLOCK_REACH', 'MeterFit',
           'check_instrument', 'instrument_verdict']

ALTERNATIVES = (('point', 0.0, 'end'), ('period', 1.0, 'end'))
"""Meters tried beside the declared one: label, window in sampling periods, stamp."""

SAME_CLOCK_ALTERNATIVES = ALTERNATIVES + (('period_centre', 1.0, 'centre'),
                                          ('period_start', 1.0, 'start'))
"""Meters tried on runs whose motion comes from the data (the stamp position tells)."""

SAME_CLOCK_REACH = 0.25
"""Offset search on such runs: within this fraction of a sampling period of zero."""


@dataclass(frozen=True)
class MeterFit:
    """One meter model on one run, its offset refitted near the comparison's.

    Attributes
    ----------
    label
        ``'declared'`` or the label of an alternative (``'point'``, ``'period'``,
        ``'period_centre'``, ``'period_start'``).
    window_s, stamp
        The meter: averaging window [s] (0: point samples) and stamp position.
    offset_s
        Refitted offset [s].
    rms_w
        Residual RMS after the meter model, mean removed [W].
    n_samples
        Samples compared.
    reach_s
        Half-width of the offset search [s].
    same_clock
        The offset was searched near zero (motion from the data), not near the comparison's.
    """

    label: str
    window_s: float
    stamp: str
    offset_s: float
    rms_w: float
    n_samples: int
    reach_s: float = math.nan
    same_clock: bool = False

    def to_dict(self) -> dict[str, float | str | int | bool]:
        """Plain dict; keys carry units."""
        return {'label': self.label, 'window_s': self.window_s, 'stamp': self.stamp,
                'offset_s': self.offset_s, 'rms_w': self.rms_w, 'reach_s': self.reach_s,
                'same_clock': self.same_clock}


def check_instrument(t_meas: np.ndarray, y_meas: np.ndarray, t_sim: np.ndarray,
                     y_sim: np.ndarray, *, offset_s: float, window_s: float,
                     stamp: str, same_clock: bool = False,
                     period_s: float | None = None) -> tuple[MeterFit, ...]:
    """Fit the declared meter and the alternatives near ``offset_s`` (or near 0).

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
    same_clock
        The simulation runs on the data's own stamps (motion from the data): offsets are
        searched within :data:`SAME_CLOCK_REACH` periods of zero and the stamp positions of
        :data:`SAME_CLOCK_ALTERNATIVES` are tried.
    period_s
        The median step of ``t_meas`` [s] when the caller knows it; default computed.

    Returns
    -------
    tuple of MeterFit
        The declared meter first, then the alternatives that differ from it.
    """
    period = (float(np.median(np.diff(t_meas), overwrite_input=True)) if period_s is None
              else float(period_s))
    meters = [('declared', float(window_s), stamp)]
    for label, periods, s in (SAME_CLOCK_ALTERNATIVES if same_clock else ALTERNATIVES):
        w = periods * period
        same_window = math.isclose(w, window_s, rel_tol=1e-9, abs_tol=1e-12)
        # without a shared clock the stamp is a shift the offset absorbs: windows only
        if same_window and (not same_clock or w == 0.0 or s == stamp):
            continue
        meters.append((label, w, s))
    centre = 0.0 if same_clock else offset_s
    # the stamps about the centre, once for every meter (a long record's copy)
    t_centred = t_meas - centre if centre else t_meas
    out = []
    for label, w, s in meters:
        reach = SAME_CLOCK_REACH * period if same_clock else 2.0 * period + w
        res = estimate_offset(t_centred, y_meas, t_sim, y_sim, max_lag_s=reach,
                              window_s=w, stamp=s, candidates=2,
                              drift_min_duration_s=math.inf, period_s=period)
        out.append(MeterFit(label, w, s, centre + res.offset_s, res.rms_w,
                            int(t_meas.size), reach, same_clock))
    return tuple(out)


def _name(window_s: float, stamp: str, stamps_matter: bool) -> str:
    if window_s == 0.0:
        return 'point samples'
    where = f' stamped at its {stamp}' if stamps_matter else ''
    return f'a {1e3 * window_s:g} ms window{where}'


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
    meters: dict[str, tuple[float, str]] = {}
    same_clock = reach = None
    for run in fits:
        for f in run:
            if math.isfinite(f.rms_w):
                acc = pooled.setdefault(f.label, [0.0, 0.0])
                acc[0] += f.n_samples * f.rms_w ** 2
                acc[1] += f.n_samples
                meters[f.label] = (f.window_s, f.stamp)
                same_clock = f.same_clock if same_clock is None else same_clock and f.same_clock
                reach = f.reach_s if reach is None else max(reach, f.reach_s)
    if 'declared' not in pooled or pooled['declared'][1] == 0:
        return None
    ms = {k: v[0] / v[1] for k, v in pooled.items()
          if v[1] == pooled['declared'][1]}   # only meters fitted on every run
    best = min(ms, key=ms.__getitem__)
    if best == 'declared' or ms[best] >= (1.0 - margin) * ms['declared']:
        return None
    name = _name(*meters[best], bool(same_clock))
    reach_s = cast(float, reach)        # set with same_clock, by the same fit
    how = (f'offsets within {1e3 * reach_s:.3g} ms of the data\'s own stamps, since the motion '
           'comes from the same records' if same_clock else 'offsets refitted')
    return (f'instrument model: {name} fit better than {describe} (residual RMS '
            f'{math.sqrt(ms[best]):.3g} W against {math.sqrt(ms["declared"]):.3g} W, {how}, '
            f'pooled over {len(fits)} runs); declare instrument: in the manifest')
