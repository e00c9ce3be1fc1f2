"""Which runs' time offsets are pinned down, and pinning the others with the effects found.

``analyze`` fits effects to residuals *at an offset*; a residual at a wrong offset (one
stroke off on a periodic program) is garbage that no catalog effect explains, and it spoils
the fit of the runs aligned right. The offset of a run is estimated against the declared
model, which lacks the very effect looked for, and a large missing effect can make a
distant lag fit as well as the true one (the status :func:`.measured.estimate_offset` calls
``'ambiguous'``), fit everywhere poorly (``'weak'``: compared at offset 0 by ``compare``) or
lie at the end of the search (``'edge'``). So:

* A run is **pinned** when its offset estimate is ``'ok'`` (or ``'fixed'``: declared). Only
  pinned runs enter the fit (:func:`split_pinned`); the others are *left out* and named,
  never used at a guessed offset.
* After each analysis round, the offsets of every run are estimated anew against the
  declared model *plus the effects found* (:func:`repin`). A left-out run whose estimate is
  now decisive (:func:`decisive`: ``'ok'``, or a runner-up whose residual is clearly larger)
  is pinned there; a pinned run whose offset moved to another peak (by more
  than :func:`peak_tolerance_s`) is moved there. The declared model's residual at the new
  offset then enters the next round. Rounds end when nothing moves (at most
  :data:`MAX_PIN_ROUNDS`).

A candidate that explains the residual of wrongly aligned runs can only be selected from the
pinned runs, so a stroke-off alignment cannot pull the selection toward a false effect; and
the effect found on the pinned runs is what tells the stroke-off lags of the others apart
(on a periodic program the up and down strokes differ only through the missing effect).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
import math

import numpy as np

from ..machine import Machine
from ..measured import (Campaign, compare_one_run, DEFAULT_MAX_LAG_S, MeasuredRun, MotionCache,
                        RunComparison)

__all__ = ['PINNED_STATUSES', 'MAX_PIN_ROUNDS', 'PIN_MARGIN', 'LeftOut', 'split_pinned',
           'decisive', 'peak_tolerance_s', 'repin', 'left_out_text']

PINNED_STATUSES = ('ok', 'fixed')
"""Offset statuses a fit may use."""
MAX_PIN_ROUNDS = 3
"""Most analysis rounds with offsets estimated anew (the first included)."""
PIN_MARGIN = 0.1
"""With the effects in the model, a lag is pinned when every distant lag leaves at least this
much more residual sum of squares (relative; :func:`.measured.estimate_offset`'s
``ambiguity_margin``), even when their correlations are as close as a large common signal
makes them."""


@dataclass(frozen=True)
class LeftOut:
    """A run left out of the fit because its time offset could not be pinned down.

    Attributes
    ----------
    name
        Run name.
    status
        Its last offset estimate's status (``'weak'``, ``'edge'`` or ``'ambiguous'``).
    offset_s, runner_up_s
        The best lag and the best distant lag of that estimate [s] (NaN when none).
    message
        The estimate's sentence.
    """

    name: str
    status: str
    offset_s: float
    runner_up_s: float
    message: str

    def to_dict(self) -> dict:
        """Plain dict (JSON: NaN as ``None``)."""
        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None
        return {'name': self.name, 'status': self.status, 'offset_s': num(self.offset_s),
                'runner_up_s': num(self.runner_up_s), 'message': self.message}


def decisive(run: RunComparison) -> bool:
    """The offset of a comparison *with the effects in the model* is pinned: estimated
    ``'ok'``, or ``'ambiguous'`` only by correlation while the residual decides (the
    runner-up's residual sum of squares exceeds the best by more than :data:`PIN_MARGIN`)."""
    o = run.offset
    if o.status in PINNED_STATUSES:
        return True
    return (o.status == 'ambiguous' and math.isfinite(o.runner_up_rms_w)
            and math.isfinite(o.rms_w)
            and o.runner_up_rms_w ** 2 > (1.0 + PIN_MARGIN) * o.rms_w ** 2)


def _left(run: RunComparison) -> LeftOut:
    o = run.offset
    return LeftOut(run.name, o.status, float(o.offset_s), float(o.runner_up_s), o.message)


def split_pinned(runs: Sequence[RunComparison], *, campaign: Campaign | None = None,
                 ) -> tuple[list[RunComparison], list[LeftOut]]:
    """The runs a fit may use (offset pinned) and the ones left out, in the given order.

    A run simulated from its own measured motion (``motion_from_data`` in the manifest)
    counts as pinned whatever its status: motion and power share one clock, the lag that
    ``compare`` estimates between them is the meter's, and the stroke-off alternatives that
    make a program's simulation ambiguous do not exist.
    """
    def ok(r: RunComparison) -> bool:
        if r.offset.status in PINNED_STATUSES:
            return True
        return campaign is not None and campaign.run(r.name).motion_from_data is not None
    pinned = [r for r in runs if ok(r)]
    left = [_left(r) for r in runs if not ok(r)]
    return pinned, left


def peak_tolerance_s(run: RunComparison) -> float:
    """How far a re-estimated offset may move and still be the same peak [s].

    Adding an effect refines an offset by a fraction of a sample period; a move to another
    correlation peak (another stroke) is at least a feature's width. Five sample periods,
    at least 50 ms, separates the two.
    """
    period = float(np.median(np.diff(run.t))) if run.t.size > 1 else 0.0
    return max(5.0 * period, 0.05)


def repin(campaign: Campaign, declared: Machine, augmented: Sequence[RunComparison],
          pinned: Sequence[RunComparison], left: Sequence[LeftOut], *,
          cache: MotionCache | None = None,
          max_lag_s: float = DEFAULT_MAX_LAG_S,
          loaded: Mapping[str, MeasuredRun] | None = None,
          ) -> tuple[list[RunComparison], list[LeftOut], list[str]]:
    """Pin runs at the offsets found with the effects in the model.

    Parameters
    ----------
    campaign
        The campaign.
    declared
        The declared machine: the next round's residuals are against it.
    augmented
        Fresh comparisons of the pinned *and* the left-out runs (any order) with the machine
        plus the effects found (:func:`.realign.realigned_runs`).
    pinned, left
        This round's split.
    cache
        Motion cache shared by the comparisons.
    max_lag_s
        The offset search range of the comparisons [s].
    loaded
        Runs already loaded, by name (each CSV is parsed once per analysis).

    Returns
    -------
    (pinned, left, moved)
        The next round's pinned comparisons (declared model, at the new offsets; same order
        as before, newly pinned runs appended), the runs still left out, and the names of the
        runs whose offset changed (empty: the rounds are done).
    """
    by_name = {a.name: a for a in augmented}
    cache = MotionCache(declared) if cache is None else cache
    moved: list[str] = []
    out: list[RunComparison] = []
    for run in pinned:
        a = by_name.get(run.name)
        if (a is not None and decisive(a)
                and abs(a.offset_used_s - run.offset_used_s) > peak_tolerance_s(run)):
            out.append(_at_offset(campaign, declared, run.name, a, cache, max_lag_s,
                                  was=f'{run.offset_used_s:+.3f} s', loaded=loaded))
            moved.append(run.name)
        else:
            out.append(run)
    still: list[LeftOut] = []
    for lo in left:
        a = by_name.get(lo.name)
        if a is not None and decisive(a):
            out.append(_at_offset(campaign, declared, lo.name, a, cache, max_lag_s,
                                  was=f'left out ({lo.status})', loaded=loaded))
            moved.append(lo.name)
        else:
            still.append(_left(a) if a is not None else lo)
    return out, still, moved


def _at_offset(campaign: Campaign, declared: Machine, name: str, found: RunComparison,
               cache: MotionCache, max_lag_s: float, *, was: str,
               loaded: Mapping[str, MeasuredRun] | None = None) -> RunComparison:
    """The declared model's comparison of a run at the offset ``found`` pinned."""
    cmp = compare_one_run(campaign.run(name), declared, cache, max_lag_s=max_lag_s,
                          window_s=None, offset_s=found.offset_used_s, min_correlation=0.5,
                          floor_fraction=0.05, check_meter=False,
                          measured=(loaded or {}).get(name))
    offset = replace(found.offset, message=(
        f'{found.offset.message}; pinned with the effects found in the model (was {was})'))
    return replace(cmp, offset=offset)


def left_out_text(left: Sequence[LeftOut]) -> str:
    """One clause naming the runs left out and why (empty when none)."""
    if not left:
        return ''
    parts = []
    for lo in left:
        alt = (f' or {lo.runner_up_s:+.2f} s' if math.isfinite(lo.runner_up_s)
               and lo.status == 'ambiguous' else '')
        parts.append(f'{lo.name} ({lo.status}: {lo.offset_s:+.2f} s{alt})')
    return (f'{len(left)} run(s) left out of the fit, time offset not pinned down: '
            + ', '.join(parts))
