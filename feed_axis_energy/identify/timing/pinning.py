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
  is pinned there; a pinned run whose decisive estimate moved (to another peak, or, for a
  run simulated from its program, by more than :func:`lag_tolerance_s` within its peak) is
  moved there. The declared model's residual at the new offset then enters the next round.
  Rounds end when nothing moves (at most :data:`MAX_PIN_ROUNDS`). The small moves matter:
  a power correlation against a model that lacks an effect is pulled by it (a missing
  viscous drag or inertia shifts the best lag by milliseconds), and that timing error is
  what a small passenger of the shape ``dm·a·v`` then fits; with the effects in the model
  the lag is not pulled.

**Runs aligned on their measured motion** (``offset.anchor == 'motion'``,
:func:`.measured.spatial.motion_anchor`) are pinned by it: the motion tells the strokes
apart whatever the power lacks. Only the power's refinement near the anchor (the meter's lag
behind the motion columns) is still pulled by a missing effect, each run its own way (a
missing inertia makes the power of fast strokes look earlier than that of slow ones), and
on a 50 ms meter a lag is not told apart from a missing inertia at all. That lag is a
property of the instrument, one for the campaign. So ``analyze`` first compares every
motion-anchored run at the motion's offset itself (:func:`at_common_lag` with lag 0: the
instrument model's window and stamp already describe the meter's averaging), and estimates
the meter's lag only with the effects found in the model: :func:`repin` moves these runs to
their anchor plus the median lag of the comparisons with the effects
(:func:`motion_lag_s`), by any amount above :func:`lag_tolerance_s` (a thousandth of a
sample period: with a large effect in the model a fraction of a millisecond still decides
whether a small passenger enters). A lag the effects do not explain is the ``time_offset``
candidate in the meantime.

A candidate that explains the residual of wrongly aligned runs can only be selected from the
pinned runs, so a stroke-off alignment cannot pull the selection toward a false effect; and
the effect found on the pinned runs is what tells the stroke-off lags of the others apart
(on a periodic program the up and down strokes differ only through the missing effect).
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
import math

import numpy as np

from ...machine import Machine
from ...measured import (Campaign, compare_one_run, DEFAULT_MAX_LAG_S, MeasuredRun,
                         MotionCache, RunComparison)

__all__ = ['PINNED_STATUSES', 'MAX_PIN_ROUNDS', 'PIN_MARGIN', 'LeftOut', 'split_pinned',
           'decisive', 'repin', 'left_out_text', 'motion_lag_s',
           'at_common_lag', 'at_motion_offsets', 'at_offsets', 'lag_tolerance_s']

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


def _period_s(run: RunComparison) -> float:
    """A run's median sampling period [s] (0 for a single sample)."""
    return float(np.median(np.diff(run.t))) if run.t.size > 1 else 0.0


def _move_tolerance_s(campaign: Campaign, run: RunComparison) -> float:
    """How far a pinned, power-aligned run's re-estimated offset must move to be moved [s].

    A run simulated from its program: :func:`lag_tolerance_s` (its power's lag was pulled by
    the missing effect, and is not with the effect in the model). A run simulated from its
    own measured motion: another correlation peak only, five sample periods and at least
    50 ms (its lag is the meter's between two channels of one record, not moved by what
    the model lacks).
    """
    if campaign.run(run.name).motion_program is not None:
        return lag_tolerance_s(run)
    return max(5.0 * _period_s(run), 0.05)


def repin(campaign: Campaign, declared: Machine, augmented: Sequence[RunComparison],
          pinned: Sequence[RunComparison], left: Sequence[LeftOut], *,
          cache: MotionCache | None = None,
          max_lag_s: float = DEFAULT_MAX_LAG_S,
          loaded: Mapping[str, MeasuredRun] | None = None,
          lag_s: float | None = None, refresh: bool = False,
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
        plus the effects found (:func:`..realign.iter_realigned`).
    pinned, left
        This round's split.
    cache
        Motion cache shared by the comparisons.
    max_lag_s
        The offset search range of the comparisons [s].
    loaded
        Runs already loaded, by name (each CSV is parsed once per analysis).
    lag_s
        The common lag [s] behind the motion the motion-anchored runs are moved to; default
        :func:`motion_lag_s` of ``augmented`` (``analyze`` gives 0 when it puts that lag
        into a meter's filter instead).
    refresh
        Compare every motion-anchored run anew, moved or not (the campaign's instrument
        changed).

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
    lag = motion_lag_s(augmented) if lag_s is None else lag_s
    for run in pinned:
        a = by_name.get(run.name)
        if (lag is not None and a is not None and run.offset.anchor == 'motion'
                and a.offset.anchor == 'motion'):
            target = a.offset.motion_s + lag
            if refresh or abs(target - run.offset_used_s) > lag_tolerance_s(run):
                out.append(_moved(
                    campaign, declared, a, target, cache, max_lag_s, loaded,
                    note=(f'used at the common meter lag behind the motion found with the '
                          f'effects in the model, {1e3 * lag:+.1f} ms: {target:+.4f} s (was '
                          f'{run.offset_used_s:+.4f} s)')))
                moved.append(run.name)
            else:
                out.append(run)
            continue
        if (a is not None and decisive(a)
                and abs(a.offset_used_s - run.offset_used_s) > _move_tolerance_s(campaign, run)):
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


def motion_lag_s(runs: Iterable[RunComparison]) -> float | None:
    """The campaign's meter lag behind the motion columns [s]: the median over the
    motion-anchored runs of (offset found - motion anchor); ``None`` when there is none.
    ``runs`` is read once (an iterator of fresh comparisons keeps one of them at a time)."""
    lags = [r.offset.offset_s - r.offset.motion_s for r in runs
            if r.offset.anchor == 'motion' and math.isfinite(r.offset.motion_s)
            and math.isfinite(r.offset.offset_s)]
    return float(np.median(lags)) if lags else None


def lag_tolerance_s(run: RunComparison) -> float:
    """How far a motion-anchored run's offset may be from its target and stay [s]: a
    thousandth of its sample period (compared anew above that: a large missing effect
    turns a fraction of a period into structure the selection would fit)."""
    return 1.0e-3 * _period_s(run)


def at_common_lag(campaign: Campaign, declared: Machine, runs: Sequence[RunComparison], *,
                  lag_s: float | None = None, cache: MotionCache | None = None,
                  max_lag_s: float = DEFAULT_MAX_LAG_S,
                  loaded: Mapping[str, MeasuredRun] | None = None) -> list[RunComparison]:
    """The comparisons with every motion-anchored run at its anchor plus the common lag.

    Parameters
    ----------
    campaign
        The campaign.
    declared
        The machine the comparisons are made with.
    runs
        Comparisons (any anchors; runs anchored on the power are returned as they are).
    lag_s
        The common lag [s]; default :func:`motion_lag_s` of ``runs``.
    cache
        Motion cache for the comparisons made anew.
    max_lag_s
        The offset search range of the comparisons [s].
    loaded
        Runs already read from their files, by name (each file is parsed once).

    Returns
    -------
    list of RunComparison
        Same order; a run already within :func:`lag_tolerance_s` of its target is kept.
    """
    lag = motion_lag_s(runs) if lag_s is None else lag_s
    if lag is None:
        return list(runs)
    cache = MotionCache(declared) if cache is None else cache
    out = []
    for run in runs:
        o = run.offset
        if o.anchor != 'motion' or not math.isfinite(o.motion_s):
            out.append(run)
            continue
        target = o.motion_s + lag
        if abs(run.offset_used_s - target) <= lag_tolerance_s(run):
            out.append(run)
            continue
        out.append(_moved(campaign, declared, run, target, cache, max_lag_s, loaded, note=(
            f'used at the campaign\'s common meter lag behind the motion, '
            f'{1e3 * lag:+.1f} ms: {target:+.4f} s')))
    return out


def at_offsets(campaign: Campaign, declared: Machine, runs: Sequence[RunComparison],
               offsets: Mapping[str, float], *, why: str,
               cache: MotionCache | None = None, max_lag_s: float = DEFAULT_MAX_LAG_S,
               loaded: Mapping[str, MeasuredRun] | None = None) -> list[RunComparison]:
    """The comparisons with the runs named in ``offsets`` moved to those offsets [s].

    A moved run keeps its offset estimate's status and anchor (it stays pinned); its offset
    becomes the new one and its message says ``why``. Runs not named, or within
    :func:`lag_tolerance_s` of their new offset, are returned as they are (same order).
    """
    cache = MotionCache(declared) if cache is None else cache
    out = []
    for run in runs:
        target = offsets.get(run.name)
        if target is None or abs(target - run.offset_used_s) <= lag_tolerance_s(run):
            out.append(run)
            continue
        out.append(_moved(campaign, declared, run, float(target), cache, max_lag_s, loaded,
                          note=f'used at {float(target):+.4f} s, {why}'))
    return out


def at_motion_offsets(campaign: Campaign, machine: Machine, runs: Sequence[RunComparison], *,
                      loaded: Mapping[str, MeasuredRun] | None = None,
                      ) -> Iterator[RunComparison]:
    """``machine``'s comparisons of the motion-anchored ``runs`` at exactly their motion's
    offsets (on their clocks), every one made anew, one at a time (a caller that sums them
    up holds one run's comparison, not every run's); other runs are left out.

    What a meter's own timing is estimated on (a comparison kept within
    :func:`lag_tolerance_s` of its target may still be a few microseconds off it)."""
    cache = MotionCache(machine)
    for run in runs:
        if run.offset.anchor == 'motion' and math.isfinite(run.offset.motion_s):
            yield _moved(campaign, machine, run, float(run.offset.motion_s), cache,
                         DEFAULT_MAX_LAG_S, loaded, note='compared at the motion\'s offset')


def _compared_at(campaign: Campaign, declared: Machine, name: str, offset_s: float,
                 cache: MotionCache, max_lag_s: float,
                 loaded: Mapping[str, MeasuredRun] | None, *,
                 clock_ppm: float = 0.0) -> RunComparison:
    """The declared model's comparison of a run at a fixed offset (``compare``'s defaults;
    the meter check is left to the baseline), its stamps on the clock an earlier comparison
    of it corrected (``clock_ppm``)."""
    return compare_one_run(campaign.run(name), declared, cache, max_lag_s=max_lag_s,
                           window_s=None, offset_s=offset_s, min_correlation=0.5,
                           floor_fraction=0.05, check_meter=False,
                           measured=(loaded or {}).get(name), clock_ppm=clock_ppm)


def _moved(campaign: Campaign, declared: Machine, run: RunComparison, target: float,
           cache: MotionCache, max_lag_s: float,
           loaded: Mapping[str, MeasuredRun] | None, *, note: str) -> RunComparison:
    """The declared model's comparison of ``run`` at ``target`` [s] (on its clock), its
    offset estimate kept with ``offset_s`` the target and ``note`` added to its message."""
    cmp = _compared_at(campaign, declared, run.name, target, cache, max_lag_s, loaded,
                       clock_ppm=run.clock_ppm)
    return replace(cmp, offset=replace(run.offset, offset_s=target,
                                       message=f'{run.offset.message}; {note}'))


def _at_offset(campaign: Campaign, declared: Machine, name: str, found: RunComparison,
               cache: MotionCache, max_lag_s: float, *, was: str,
               loaded: Mapping[str, MeasuredRun] | None = None) -> RunComparison:
    """The declared model's comparison of a run at the offset ``found`` pinned."""
    cmp = _compared_at(campaign, declared, name, found.offset_used_s, cache, max_lag_s, loaded,
                       clock_ppm=found.clock_ppm)
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
