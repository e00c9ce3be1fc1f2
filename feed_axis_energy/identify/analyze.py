"""Residual analysis: which catalog effect is the declared model missing, and what it is worth.

:func:`analyze_campaign`:

1. *Baseline*: :func:`.measured.compare.compare_campaign` (simulation, offset, interval
   averaging, Table-1 metrics); the residual of each run is measured minus aligned simulated
   power per measured axis.
2. *Candidates* (:mod:`.design.columns`): for every catalog effect and measured axis, the
   effect's basis is computed on the 1 kHz simulated state of each run and aligned onto the
   measured stamps with the run's offset and window (:func:`.measured.align.align_simulated`,
   the same instrument model). Shape parameters (Stribeck speed, warm-up time constant,
   spacing of the position-friction bumps) get a grid of variants; a single shape parameter
   is refined by a bounded 1-D search. Every linear parameter is fitted within its physical
   bounds.
3. *Selection* (:mod:`.selection`): forward selection scored by held-out error
   (leave-one-run-out, or the manifest's calibrate/validate roles) together with BIC.
4. *Honesty* (:mod:`.consistency`): a selected effect must be consistent across runs (its
   per-run refit may not explain much more than the pooled one: ``heterogeneity`` below
   ``max_heterogeneity``); an inconsistent one is removed, selection is redone without it
   (at most ``max_rounds`` times; reaching the cap is a stated verdict) and the structure is
   reported in ``unexplained``; every candidate ends with a fate and a reason. The final
   residual is tested for structure against velocity, position, acceleration and time and
   in its spectrum (:mod:`.diagnostics`). Loss functions and declared effects used outside
   their calibrated range are listed in ``warnings``.
5. *Before/after*: Table-1 metrics on held-out runs; each run's *after* adds the effects
   fitted without it (its fold), at the baseline offset.

Uncertainties of linear parameters: jackknife over runs (leave one run out). Shape
parameters are found by a profile search and carry no uncertainty (``None``).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
import math
from typing import Any

import numpy as np

from ..effects import EFFECTS, get_effect
from ..machine import load_machine, Machine, machine_warnings, observed_range, RangeUse
from ..errors import ConfigError
from ..measured import (Campaign, CampaignComparison, compare_campaign, load_run, MAX_FILTER_S,
                        MeasuredRun, Metrics, offset_dict, quantity_of, RunComparison)
from .alternatives import check_alternatives
from .ambiguity import AmbiguousGroup, EquivalentForm, find_groups, found_text, timing_forms
from .consistency import heterogeneity, label, mark_groups, select_consistent
from .design import (Bins, candidate_block, held_comparison, held_record, held_run, held_runs,
                     HeldRecords, prepare_runs, refine_shape, RunData, shape_grid, StateStore,
                     StatesOf)
from .diagnostics import diagnose_runs, noise_level, NoiseLevel
from .simrate import at_rate, MAX_OVERSAMPLING, rate_with_effects, sampling_left, sim_rate
from .timing import (at_common_lag, at_motion_offsets, FILTER_EXTRA_ROUNDS, FILTER_TOLERANCE,
                     filter_next, filter_step, joint_eligible, joint_start, lag_tolerance_s,
                     LeftOut, left_out_text, MAX_PIN_ROUNDS, MAX_SCREEN_COLUMNS, may_filter,
                     motion_lag_s, repin, runs_differ, ScreenCandidate, split_pinned,
                     with_filter)
from .realign import augmented_outcome, iter_realigned, machine_with
from .results import (AnalysisResult, AnalyzeOptions, FittedEffect, HOLDOUTS, ParamEstimate,
                      RunOutcome, STATE_NAMES)
from .drivecorr import common_measures, correction_bounds, declared_values, describe_correction
from .driveforms import has_current_form
from .selection import at_bounds, Design, loro_folds
from .summed import offer_summed

NOISE_PASSES = 2
"""Selections at most: on the baseline's noise level, then on the level left by its effects."""
NOISE_CHANGE = 0.1
"""Relative change of the noise level that makes the selection run again."""
LAG_MIN_SHARE = 0.01
"""Share of the baseline residual's sum of squares an effect must explain to be in the model
the meter's lag behind the motion is estimated with (a passenger that explains less may be
the trace of that very lag: a fraction of a millisecond has the shape of a moved mass)."""


RATE_CHECK_FROM = 0.95
"""Progress fraction the first analysis ends at: the rest is the analysis run again at a
finer simulation rate when the effects it found need one (:func:`.simrate.rate_with_effects`)."""

__all__ = ['analyze_campaign']


def _folds(runs: Sequence[RunData], holdout: str, file: str) -> list[tuple[list[int], list[int]]]:
    if holdout == 'loro':
        if len(runs) < 2:
            msg = (f'holdout "loro" (leave one run out) needs at least 2 runs, got '
                   f'{len(runs)}; add runs to the manifest')
            raise ConfigError(msg, file=file, key='runs')
        return loro_folds(len(runs))
    if holdout == 'roles':
        train = [i for i, r in enumerate(runs) if r.cmp.role == 'calibrate']
        test = [i for i, r in enumerate(runs) if r.cmp.role == 'validate']
        if not train or not test:
            msg = ('holdout "roles" needs runs with role calibrate and runs with role '
                   'validate in the manifest')
            raise ConfigError(msg, file=file, key='role')
        return [(train, test)]
    msg = f'holdout must be one of {", ".join(HOLDOUTS)}, got {holdout!r}'
    raise ConfigError(msg, file=file, key='holdout')


def declared_noise(campaign: Campaign, cmp_runs: Sequence[RunComparison]) -> float | None:
    """The noise level the manifest declares for the analysed runs (``instrument.noise``,
    in the trace's unit), the largest where runs differ; ``None`` unless every run declares
    one (the estimate from the data is used then)."""
    levels = [campaign.run(r.name).instrument.noise for r in cmp_runs]
    if not levels or any(v is None for v in levels):
        return None
    return max(float(v) for v in levels if v is not None)


def _noise(data: Sequence[RunData], residuals: Sequence[np.ndarray], options: AnalyzeOptions,
           *, stage: str) -> dict[str, NoiseLevel]:
    """The noise level of each measured axis (:func:`.diagnostics.noise_level`) on the
    analysis grid.

    A declared level is per measured sample; on bins of ``k`` samples it is the white
    noise's ``sigma / sqrt(k)``, pooled over the runs by their bin counts.
    """
    axes = data[0].cmp.axes
    declared = options.noise_w
    if declared is not None and any(r.bins.size > 1 for r in data):
        bins = sum(r.bins.count for r in data)
        declared *= math.sqrt(sum(r.bins.count / r.bins.size for r in data) / bins)
    return {a: replace(noise_level(
        [res[:, j] for res in residuals], declared_w=declared,
        states=[np.column_stack([r.states['velocity'][:, j], r.states['acceleration'][:, j]])
                for r in data]), residual=stage) for j, a in enumerate(axes)}


def _summable(effect_id: str) -> bool:
    """An effect of the machine without shape parameters (:func:`.summed.offer_summed`)."""
    effect = get_effect(effect_id)
    return bool(effect.machine_property) and all(p.linear for p in effect.params)


# ----------------------------------------------------------------------------- main

def analyze_campaign(campaign: Campaign, *, machine: Machine | None = None,
                     runs: Sequence[str] | None = None,
                     options: AnalyzeOptions = AnalyzeOptions(),
                     progress: Callable[[float], None] | None = None) -> AnalysisResult:
    """Find the catalog effects the declared model misses; before/after on held-out runs.

    Parameters
    ----------
    campaign
        From :func:`.measured.manifest.load_campaign`.
    machine
        The declared model; default: the manifest's machine config.
    runs
        Names of the runs to use (default: all).
    options
        See :class:`AnalyzeOptions`.
    progress
        Called with the finished fraction (0..1).

    Returns
    -------
    AnalysisResult
        Effects, unexplained structure, diagnostics, before/after metrics.

    Raises
    ------
    ConfigError, DataError, GcodeError, PlanningError
        Unusable inputs (never for a poor fit or for finding nothing).
    """
    machine_file = ''
    if machine is None:
        machine = load_machine(campaign.machine)
        machine_file = str(campaign.machine)
    ids = tuple(EFFECTS) if options.effects is None else tuple(options.effects)
    for effect_id in ids:
        get_effect(effect_id)
    selected = campaign.runs if runs is None else [r for r in campaign.runs if r.name in runs]

    def report(x: float) -> None:
        if progress is not None:
            progress(x)

    with StateStore(options.state_memory_bytes) as records:
        # every run is compared several times (baseline, each fold, the augmented machine,
        # the pinning rounds): its data file is parsed once and its arrays held within the
        # budget, the rest memory-mapped (one run's samples in memory at a time when read)
        loaded = HeldRecords({spec.name: held_record(load_run(spec), records)
                              for spec in selected}, records)
        return _analyze_loaded(campaign, machine, machine_file, ids, options, report, loaded,
                               runs, records)


def _analyze_loaded(campaign: Campaign, machine: Machine, machine_file: str,
                    ids: tuple[str, ...], options: AnalyzeOptions,
                    report: Callable[[float], None], loaded: Mapping[str, MeasuredRun],
                    runs: Sequence[str] | None, store: StateStore) -> AnalysisResult:
    """:func:`analyze_campaign` on runs already loaded; ``store`` holds the records and the
    comparisons at the declared model (each set's arrays beyond its budget memory-mapped)."""
    declared = machine
    cmp = held_comparison(compare_campaign(campaign, machine=machine, runs=runs,
                                           progress=lambda f: report(0.3 * f), loaded=loaded),
                          store)
    factor, chi2 = sim_rate(cmp.runs, machine)
    if factor > 1:
        # data this precise resolve the simulation's sampling: the analysis simulates finer
        machine = at_rate(declared, factor)
        cmp = held_comparison(compare_campaign(campaign, machine=machine, runs=runs,
                                               loaded=loaded), store)
    # what the sampling still leaves at the rate used (the rate at its cap): the selection's
    # chi-square limits rise by it
    left = sampling_left(chi2, factor)
    result = _analysis(campaign, machine, machine_file, cmp, ids,
                       replace(options, sampling_chi2=left),
                       lambda f: report(min(f, RATE_CHECK_FROM)), loaded, runs, store)
    notes = ([f'at {declared.planner.rate_hz:g} Hz its sampling would put a sum of squares '
              f'of {chi2:.3g} noise variances into the residual, which these data resolve']
             if factor > 1 else [])
    more, chi2_found = ((1, 0.0) if factor >= MAX_OVERSAMPLING else
                        rate_with_effects(campaign, result, machine, loaded))
    more = min(more, MAX_OVERSAMPLING // factor)
    if more > 1:
        # the effects found have power the declared model lacks (the spikes of a large
        # Stribeck friction): their own sampling at this rate is resolved by these data too,
        # and a candidate would be fitted to it; the analysis runs again finer
        factor *= more
        machine = at_rate(declared, factor)
        cmp = held_comparison(compare_campaign(campaign, machine=machine, runs=runs,
                                               loaded=loaded), store)
        left = max(sampling_left(chi2, factor), sampling_left(chi2_found, more))
        result = _analysis(campaign, machine, machine_file, cmp, ids,
                           replace(options, sampling_chi2=left),
                           lambda f: report(RATE_CHECK_FROM + (1.0 - RATE_CHECK_FROM)
                                            * max(f - 0.3, 0.0) / 0.7), loaded, runs,
                           store)
        notes.append(f'with the effects first found in the model, its sampling at '
                     f'{machine.planner.rate_hz / more:g} Hz would put {chi2_found:.3g} noise '
                     'variances into the residual')
    if left:
        notes.append(f'at {machine.planner.rate_hz:g} Hz, the finest it simulates at, its '
                     f'sampling still puts about {left:.3g} noise variances into the '
                     'residual: a candidate had to drop the residual by that much beyond its '
                     'chi-square limit')
    report(1.0)
    result = replace(result, machine=declared, sim_rate_hz=machine.planner.rate_hz)
    if factor > 1:
        result = replace(result, message=(
            f'{result.message}; simulated at {machine.planner.rate_hz:g} Hz, {factor} times '
            f'the planner\'s rate_hz: {"; ".join(notes)}'))
    return result


def _analysis(campaign: Campaign, machine: Machine, machine_file: str, cmp: CampaignComparison,
              ids: tuple[str, ...], options: AnalyzeOptions, report: Callable[[float], None],
              loaded: Mapping[str, MeasuredRun],
              runs: Sequence[str] | None, store: StateStore) -> AnalysisResult:
    """The starts of the analysis (:func:`_from_start`) at the rate of ``machine``, with
    the baseline comparisons ``cmp``, the best by BIC (progress from 0.3 to 1); ``store``
    holds each start's comparisons."""
    # runs aligned on their measured motion start at the motion's offset, the meter's lag
    # behind it found only with the effects in the model (:mod:`.timing.pinning`); when that start
    # leaves the residual unsettled and the power's own lags say otherwise, the analysis is
    # also run from their median lag; and a positive lag is also tried as a meter that
    # smooths (a first-order filter). The best model of the data wins (BIC)
    lag = motion_lag_s(cmp.runs)
    differ = lag is not None and runs_differ(cmp.runs, lag)
    # progress: the first start, then the lag start and the filter start when they run (or
    # the start from a candidate's offsets, on records of the power alone)
    joint = joint_eligible(campaign, cmp.runs)
    spans = ([(0.3, 0.55), (0.55, 0.8), (0.8, 1.0)] if lag is not None else
             [(0.3, 0.75), (0.75, 1.0)] if joint else [(0.3, 1.0)])
    result = _from_start(campaign, machine, machine_file, cmp, 0.0, ids, options, report,
                         spans[0], loaded, store)
    a = _bic(result, 0)
    # the filter's first guess: the lag the first start found with its effects in the model
    # (a large missing effect pulls the power's own lags anywhere), else the power's own
    tau = _fitted_lag_s(result) if lag is not None else None
    tau = lag if tau is None else tau
    # (the power's own lags may sit at the motion's offsets, pulled there by a missing
    # effect, while the first start's lag with its effects says the meter lags)
    smooth = tau is not None and may_filter(campaign, cmp.runs, tau)
    if differ and lag is not None and _unsettled(result):
        other = _from_start(campaign, machine, machine_file, cmp, lag, ids, options, report,
                            spans[1], loaded, store)
        b = _bic(other, 1)
        if b < a:
            result = replace(other, message=(
                f'{other.message}; fitted at the common meter lag {1e3 * lag:+.1f} ms behind '
                f'the measured motion (BIC {b:.1f} against {a:.1f} from the motion\'s offset)'))
            a = b
    if smooth and tau is not None:
        # the lag as a meter that smooths (first-order, time constant = the lag) rather than
        # one that delays: it also rounds every edge, which a pure delay leaves as structure
        # that an inertia or a friction term would take
        filtered = with_filter(campaign, tau)
        fcmp = held_comparison(compare_campaign(filtered, machine=machine, runs=runs,
                                                loaded=loaded), store)
        other = _from_start(filtered, machine, machine_file, fcmp, 0.0, ids, options, report,
                            spans[2], loaded, store, filter_s=tau)
        c = _bic(other, 1)
        if c < a:
            result = replace(other, message=(
                f'{other.message}; fitted with a meter that smooths the signal, a first-order '
                f'filter of {1e3 * other.meter_filter_s:.1f} ms estimated from the power\'s '
                f'lag behind the measured motion with the effects in the model (BIC {c:.1f} '
                f'against {a:.1f} for a meter without it)'))
            a = c
    if joint and _unsettled(result):
        # records of the power alone: a large missing effect pulls the power's lags, and at
        # the pulled lags nothing it could be is supported; the offsets each run would have
        # with a candidate in the model start an analysis of their own
        start = joint_start(campaign, machine, cmp, _screen_candidates(ids, options), loaded)
        if start is not None:
            jcmp, fit = start
            other = _from_start(campaign, machine, machine_file, jcmp, 0.0, ids, options,
                                report, spans[1], loaded, store)
            d = _bic(other, 1)
            if d < a:
                result = replace(other, aligned_with={
                    'effect': fit.key[0], 'axis': fit.key[1],
                    'median_move_s': fit.median_move_s,
                    'largest_move_s': fit.largest_move_s}, message=(
                    f'{other.message}; fitted from the offsets each run has with '
                    f'{label(fit.key)} in the model (the power\'s own lags against the '
                    f'declared model were pulled by a median {1e3 * fit.median_move_s:.1f} '
                    f'ms, at most {1e3 * fit.largest_move_s:.1f} ms; BIC {d:.1f} against '
                    f'{a:.1f} from those lags)'))
    return result


def _screen_candidates(ids: tuple[str, ...], options: AnalyzeOptions,
                       ) -> Callable[[Sequence[str]], list[ScreenCandidate]]:
    """The candidates a joint start screens on given axes (:func:`.timing.joint_start`): every
    catalog effect of ``ids`` but the record's own timing and standby, with at most
    :data:`.timing.MAX_SCREEN_COLUMNS` columns, at each point of its shape grid."""
    def on(axes: Sequence[str]) -> list[ScreenCandidate]:
        return [ScreenCandidate((e, axis), shape)
                for e in ids if e not in ('time_offset', 'standby')
                and len(get_effect(e).linear_params()) <= MAX_SCREEN_COLUMNS
                for axis in axes
                for shape in shape_grid(e, (), 0, options.shape_grid_points)]
    return on


def _fitted_lag_s(result: AnalysisResult) -> float | None:
    """The lag behind the measured motion [s] an analysis ended at with its effects in the
    model: the median over its motion-anchored runs of (offset used - motion's offset), plus
    the ``time_offset`` fitted beside the effects; ``None`` when it named no effect (only
    offers: losses that no effect claims may be what a wrong meter leaves, and they pull the
    lag with them) or its runs never moved from the motion's offsets."""
    lags = [float(o['used_s']) - float(o['motion_s']) for o in
            (r.offset_before for r in result.runs)
            if o is not None and o.get('anchor') == 'motion' and o.get('motion_s') is not None
            and math.isfinite(float(o['motion_s'])) and o.get('used_s') is not None]
    delay = _fitted_delay_s(result)
    named = [e for e in result.effects if e.id != 'time_offset']
    # (runs kept within their tolerance of the motion's offset sit a microsecond or less
    # off it: not moved)
    if not lags or not named or (delay is None and max(abs(x) for x in lags) <= 1e-6):
        return None
    return float(np.median(lags)) + (delay or 0.0)


def _fitted_delay_s(result: AnalysisResult) -> float | None:
    """The mean ``delta_s`` [s] of the ``time_offset`` effects named or offered, if any."""
    deltas = [float(e.values()['delta_s']) for e in result.effects + result.offered
              if e.id == 'time_offset']
    return float(np.mean(deltas)) if deltas else None


def _unsettled(result: AnalysisResult) -> bool:
    """An analysis that leaves structure or offers a loss it cannot attribute."""
    return result.status in ('unexplained', 'partial') or bool(result.offered)


def _bic(result: AnalysisResult, meter_params: int) -> float:
    """BIC of an analysis's in-sample model of the data: ``n ln(SSE/n) + k ln n`` over the
    fitted runs' residuals after its effects, ``k`` the effects' and offered losses'
    parameters plus ``meter_params`` (1 for a meter lag or filter estimated)."""
    res = [np.asarray(r.residual_after_w, dtype=float).ravel() for r in result.runs]
    n = sum(r.size for r in res)
    if n == 0:
        return math.inf
    sse = sum(float(np.sum(r * r)) for r in res)
    k = sum(len(e.values()) for e in result.effects + result.offered) + meter_params
    return n * math.log(max(sse, 1e-300) / n) + k * math.log(n)


def _from_start(campaign: Campaign, machine: Machine, machine_file: str,
                cmp: CampaignComparison, lag: float, ids: tuple[str, ...],
                options: AnalyzeOptions, report: Callable[[float], None],
                span: tuple[float, float],
                loaded: Mapping[str, MeasuredRun], store: StateStore,
                filter_s: float = 0.0) -> AnalysisResult:
    """The analysis rounds with the motion-anchored runs starting at ``lag`` [s]; with
    ``filter_s`` [s] (the campaign read through meters with that first-order filter) the
    filter's time constant is estimated anew after each round instead of the lag.
    ``store`` holds the comparisons the rounds start from."""
    cmp = held_comparison(replace(cmp, runs=tuple(at_common_lag(
        campaign, machine, cmp.runs, lag_s=lag, loaded=loaded))), store)
    # only runs whose offset is pinned down are fitted; after each round the offsets are
    # estimated anew with the effects found (:mod:`.timing.pinning`)
    pinned, left = split_pinned(cmp.runs, campaign=campaign)
    w = span[1] - span[0]
    spans = [(span[0], span[0] + 0.7 * w), (span[0] + 0.7 * w, span[0] + 0.9 * w),
             (span[0] + 0.9 * w, span[1])]
    # (a start with a filter may take a few more rounds while only the filter moves)
    rounds = MAX_PIN_ROUNDS + (FILTER_EXTRA_ROUNDS if filter_s else 0)
    last_step: float | None = None      # the previous plain filter step, for extrapolation
    for round_no in range(rounds):
        lo, hi = spans[min(round_no, len(spans) - 1)]
        _require_pinned(pinned, left, options.holdout, str(campaign.file))

        def scaled(f: float, lo: float = lo, hi: float = hi) -> None:
            report(lo + (hi - lo) * f)
        result, augmented, full_machine = _analyze_round(
            campaign, machine, machine_file, cmp, pinned, ids, options, scaled, loaded)
        if round_no + 1 == rounds:
            break
        refresh = False
        if filter_s:
            # a meter that smooths: its time constant is estimated anew with the effects in
            # the model (a Gauss-Newton step on the comparisons at the motion's offsets:
            # a delay fitted beside the effects, on the derivative of the declared power
            # alone, overshot by a fifth and left passengers), the runs stay at the motion's
            # offsets
            model = _timing_model(result) or full_machine
            delta = filter_step(at_motion_offsets(campaign, model, pinned, loaded=loaded),
                                filter_s)
            if (delta is not None and pinned
                    and abs(delta) > FILTER_TOLERANCE * lag_tolerance_s(pinned[0])):
                step, last_step = filter_next(delta, last_step)
                filter_s = min(max(filter_s + step, 0.0), MAX_FILTER_S)
                campaign = with_filter(campaign, filter_s)
                refresh = True
        if round_no + 1 >= MAX_PIN_ROUNDS and not refresh:
            break       # the rounds beyond MAX_PIN_ROUNDS are the filter's
        if full_machine is machine and not refresh:
            break
        extra = [held_run(c, store) for c in iter_realigned(
            campaign, full_machine, [r.name for r in left], loaded=loaded)]
        pinned, left, moved = repin(campaign, machine, list(augmented) + extra, pinned, left,
                                    loaded=loaded,
                                    lag_s=0.0 if filter_s else _meter_lag_s(
                                        campaign, result, pinned, loaded),
                                    refresh=refresh)
        if not moved:
            break
        pinned = held_runs(pinned, store)
    result = replace(result, pin_rounds=round_no + 1, meter_filter_s=filter_s)
    if not left:
        return result
    return replace(result, left_out=tuple(left),
                   message=f'{result.message}; {left_out_text(left)}')


def _meter_lag_s(campaign: Campaign, result: AnalysisResult,
                 pinned: Sequence[RunComparison],
                 loaded: Mapping[str, MeasuredRun]) -> float | None:
    """The meter's lag behind the motion [s] with only the effects that explain at least
    :data:`LAG_MIN_SHARE` of the baseline residual in the model (:func:`_timing_model`),
    when the round also found smaller ones and motion-anchored runs are pinned; else
    ``None`` (:func:`.timing.pinning.repin` then takes the lag of the comparisons with every
    effect found)."""
    anchored = [r.name for r in pinned if r.offset.anchor == 'motion']
    machine = _timing_model(result)
    if not anchored or machine is None:
        return None
    # each comparison is let go once its offsets are read (one run's at a time)
    return motion_lag_s(iter_realigned(campaign, machine, anchored, loaded=loaded))


def _timing_model(result: AnalysisResult) -> Machine | None:
    """The augmented machine with only the effects and offers that explain at least
    :data:`LAG_MIN_SHARE` of the baseline residual: what the meter's timing (its lag, its
    filter) is estimated with, since a passenger that explains less may be the trace of
    that very timing (a fraction of a millisecond has the shape of a moved mass); ``None``
    when every effect found is that large (the round's augmented machine is the model)."""
    def big(found: Sequence[FittedEffect]) -> tuple[FittedEffect, ...]:
        return tuple(e for e in found if e.share_of_residual >= LAG_MIN_SHARE)
    effects, offered = big(result.effects), big(result.offered)
    if len(effects) + len(offered) == len(result.effects + result.offered):
        return None
    return replace(result, effects=effects, offered=offered).augmented_machine()


def _require_pinned(pinned: Sequence[RunComparison], left: Sequence[LeftOut], holdout: str,
                    file: str) -> None:
    """Refuse a fit with too few pinned runs, naming the ones left out."""
    enough = (len(pinned) >= 2 if holdout == 'loro' else
              {r.role for r in pinned} >= {'calibrate', 'validate'} if holdout == 'roles'
              else True)
    if enough or not left:
        return      # enough runs, or nothing left out: _folds says what is missing
    msg = (f'too few runs whose time offset is pinned down for holdout "{holdout}" '
           f'({len(pinned)} pinned); {left_out_text(left)}. Record the program\'s start and '
           'end, or map the axes\' velocity or position columns in the manifest (the '
           'measured motion pins the offset; docs/compare.md, "Aligned on the measured '
           'motion")')
    raise ConfigError(msg, file=file, key='runs')


def _analyze_round(campaign: Campaign, machine: Machine, machine_file: str,
                   cmp: CampaignComparison, cmp_runs: Sequence[RunComparison],
                   ids: tuple[str, ...], options: AnalyzeOptions,
                   report: Callable[[float], None], loaded: Mapping[str, MeasuredRun],
                   ) -> tuple[AnalysisResult, list[RunComparison], Machine]:
    """One analysis of the runs ``cmp_runs`` at their offsets; also returns the fresh
    comparisons with the effects found and the machine they were made with."""
    # each run's simulation within a memory budget, the rest memory-mapped (.statestore);
    # the store's files are gone when the round ends, also on an error
    with StateStore(options.state_memory_bytes) as store:
        return _analyze_round_in(campaign, machine, machine_file, cmp, cmp_runs, ids, options,
                                 report, loaded, store)


def _analyze_round_in(campaign: Campaign, machine: Machine, machine_file: str,
                      cmp: CampaignComparison, cmp_runs: Sequence[RunComparison],
                      ids: tuple[str, ...], options: AnalyzeOptions,
                      report: Callable[[float], None], loaded: Mapping[str, MeasuredRun],
                      store: StateStore) -> tuple[AnalysisResult, list[RunComparison], Machine]:
    # copper and iron as corrections of declared drives (motor-terminal meters, .drivecorr)
    measures = common_measures(campaign.run(r.name).instrument.measures for r in cmp_runs)
    drive = [r for r in cmp_runs if not quantity_of(r.measures).is_power]
    if drive and measures is None:
        # a residual in N beside one in W has no common noise level or unit
        msg = (f'run {drive[0].name!r} measures {drive[0].measures}, other runs measure '
               'something else: analyze needs one quantity for the runs of a drive trace '
               '(current, torque or force); analyze them in separate manifests')
        raise ConfigError(msg, file=str(campaign.file), key='instrument.measures')
    if options.noise_w is None:
        options = replace(options, noise_w=declared_noise(campaign, cmp_runs))
    data = prepare_runs(campaign, cmp_runs, machine, loaded=loaded,
                        period_s=options.analysis_period_s, store=store)
    axes = cmp_runs[0].axes
    if any(r.cmp.axes != axes for r in data):
        msg = 'analyze needs the same measured axes in every run'
        raise ConfigError(msg, file=str(campaign.file), key='axes')
    folds = _folds(data, options.holdout, str(campaign.file))
    report(0.5)

    design = Design([r.residual.reshape(-1) for r in data], store=store)
    if measures is not None and not quantity_of(measures).is_power:
        ids = tuple(e for e in ids if has_current_form(e))
    for effect_id in ids:
        for j, axis in enumerate(axes):
            for shape in shape_grid(effect_id, data, j, options.shape_grid_points):
                names, cols, bounds = candidate_block(data, effect_id, j, shape)
                bounds = correction_bounds(names, bounds, declared_values(
                    machine, axis, effect_id, measures))
                if names:
                    design.add_block((effect_id, axis), shape, names, cols, bounds=bounds)
    # the cross products read every column held before; what is read next is a few at a time
    store.drop_pages()
    report(0.7)

    # one noise level per axis for every test: the bin and spectrum tests, the selection's
    # chi-square, the consistency check and the equivalence limit (.diagnostics). It is
    # estimated on the baseline residual, then once more on the residual left by the effects
    # selected with it (a large missing effect reads as slow noise in the baseline); the
    # selection is redone when that moves the level by more than NOISE_CHANGE.
    noise = _noise(data, [r.residual for r in data], options, stage='baseline')
    n_total = float(design.n.sum())
    sse0 = float(design.yy.sum())
    keys = [(e, a) for e in ids for a in axes]      # every candidate, in catalog order
    for noise_pass in range(NOISE_PASSES):
        sigmas = {a: n.sigma_w for a, n in noise.items()}
        noise_ss = sum(sigmas[a] ** 2 * sum(r.residual.shape[0] for r in data) for a in axes)
        structured0 = max(sse0 - noise_ss, 0.0)
        # one noise variance for the whole design (axes pooled by their sample counts)
        sigma2 = noise_ss / n_total if n_total > 0 else math.nan
        chosen = select_consistent(
            design, folds, options, keys=keys, structured0=structured0, noise_ss=noise_ss,
            sigma2=sigma2,
            refine=lambda block, others: refine_shape(design, data, block, others))
        found = [c for b in chosen.blocks + chosen.offered for c in b.cols]
        if options.noise_w is not None or not found or noise_pass + 1 == NOISE_PASSES:
            break
        theta0 = design.fit(found, range(design.runs))
        left = [r.residual - design.predict(found, theta0, q).reshape(r.residual.shape)
                for q, r in enumerate(data)]
        fresh = _noise(data, left, options, stage='after the effects found')
        if all(abs(fresh[a].sigma_w - noise[a].sigma_w) <= NOISE_CHANGE * noise[a].sigma_w
               for a in axes):
            break
        noise = fresh
    blocks, steps, rejected = list(chosen.blocks), chosen.steps, list(chosen.rejected)
    offered = list(chosen.offered)
    fates = chosen.fates
    if measures != 'current':
        # what the summed power of unseen runs supports and per axis cannot be confirmed
        # (axes trading power on a contour): offered on every axis, never named (.summed)
        summed = offer_summed(design, folds, axes=axes, kept=blocks + offered,
                              effects=[e for e in ids if _summable(e)], sigma2=sigma2,
                              se_factor=options.se_factor, alpha=options.alpha,
                              max_effects=options.max_effects,
                              min_bic_drop=options.min_bic_drop,
                              floor_chi2=options.sampling_chi2)
        reasons = {(b.key, s.reason) for s in summed for b in s.blocks}
        offered.extend(b for s in summed for b in s.blocks)
        why = dict(reasons)
        fates = tuple(replace(f, fate='offered', reason=why[(f.effect, f.axis)])
                      if (f.effect, f.axis) in why else f for f in fates)
    alt = check_alternatives(design, blocks, StatesOf(data), axes=axes)
    if alt is not None:
        # something outside the catalog fits as well: no catalog effect is named; what the
        # selection improves is offered as a loss of that shape, not dropped
        rejected.append(alt)
        claimed = {b.key for b in blocks}
        fates = tuple(replace(f, fate='offered', reason=(
            f'{alt["message"]}; offered as a loss of that shape'))
            if (f.effect, f.axis) in claimed else f for f in fates)
        # (a time_offset beside them corrected the alignment for them: it goes with them)
        offered = [b for b in blocks if get_effect(b.key[0]).machine_property] + offered
        blocks = []
    n_claimed = len(blocks)
    blocks = blocks + offered       # fitted together; the first n_claimed are named
    report(0.85)

    cols = [c for b in blocks for c in b.cols]
    all_runs = list(range(design.runs))
    theta = design.fit(cols, all_runs)
    jack = np.array([design.fit(cols, [q for q in all_runs if q != r]) for r in all_runs])
    if len(all_runs) > 1 and cols:
        se = np.sqrt((len(all_runs) - 1) / len(all_runs)
                     * np.sum((jack - jack.mean(axis=0)) ** 2, axis=0))
    else:
        se = np.full(len(cols), math.nan)
    mse_full = design.heldout_mse(cols, folds)
    sse_full = design.total_sse(cols)

    # per-effect figures
    fitted: list[FittedEffect] = []
    periods = [float(np.median(np.diff(r.t))) if r.t.size > 1 else 0.0 for r in data]
    energy_meas = sum(r.cmp.metrics.energy_meas_j for r in data)
    pos = 0
    for i, block in enumerate(blocks):
        effect = get_effect(block.key[0])
        params = []
        bound = at_bounds(theta[pos:pos + len(block.cols)], design.lower[list(block.cols)],
                          design.upper[list(block.cols)])
        for name, on in zip(block.names, bound):
            unit = next(p.unit for p in effect.params if p.name == name)
            params.append(ParamEstimate(name, float(theta[pos]), unit,
                                        float(se[pos]) if math.isfinite(se[pos]) else None,
                                        'jackknife over runs', at_bound=on))
            pos += 1
        for name, value in block.shape.items():
            unit = next(p.unit for p in effect.params if p.name == name)
            params.append(ParamEstimate(name, float(value), unit, None, 'profile search'))
        without = [c for k, b in enumerate(blocks) if k != i for c in b.cols]
        drop = design.total_sse(without) - sse_full
        mse_wo = design.heldout_mse(without, folds)
        gain = float(np.mean([mse_wo[r] - mse_full[r] for r in mse_full]))
        rel = float(np.mean([(mse_wo[r] - mse_full[r]) / mse_wo[r] for r in mse_full
                             if mse_wo[r] > 0.0]))
        aliases = []
        seen = set()
        for other in design.blocks:
            if other.key in seen or other.key in {b.key for b in blocks}:
                continue
            alt_mse = design.heldout_mse(without + list(other.cols), folds)
            alt_mean = float(np.mean(list(alt_mse.values())))
            full_mean = float(np.mean(list(mse_full.values())))
            wo_mean = float(np.mean(list(mse_wo.values())))
            if alt_mean <= full_mean + 0.1 * (wo_mean - full_mean):
                aliases.append(label(other.key))
                seen.add(other.key)
        corrects = declared_values(machine, block.key[1], block.key[0], measures) is not None
        own = theta[pos - len(block.cols):pos]
        energy = sum(float(design.predict(list(block.cols), own, r).sum()) * periods[r]
                     for r in range(design.runs))
        share = abs(energy) / energy_meas if energy_meas > 0.0 else math.nan
        fitted.append(FittedEffect(
            id=block.key[0], axis=block.key[1], params=tuple(params),
            correction=describe_correction(machine, block.key[0], block.key[1],
                                           {p.name: p.value for p in params})
            if corrects else None,
            share_of_residual=drop / sse0 if sse0 > 0 else 0.0,
            share_of_structured=min(max(drop / structured0, 0.0), 1.0) if structured0 > 0
            else 0.0,
            heldout_gain_w2=gain, heldout_gain_rel=rel,
            heterogeneity=heterogeneity(design, blocks, i, sigma2)[0],
            aliases=tuple(aliases), energy_j=energy, energy_share=share,
            matters=bool(share >= options.min_share), attributed=i < n_claimed))
    # selected effects whose power other candidates reproduce within the noise: one finding
    n_cols = sum(len(b.cols) for b in blocks[:n_claimed])
    groups = find_groups(design, blocks[:n_claimed], theta[:n_cols], sigma2=sigma2,
                         keys=keys, periods_s=periods, axes=axes)
    # a finding most of the catalog reproduces has no shape to name, and an effect a shift
    # of the records reproduces cannot be told from the alignment: their losses are offered
    unnamed: dict[str, str] = {m: _shapeless_text(g) for g in groups if g.shapeless
                               for m in g.selected}
    timed = timing_forms(design, blocks[:n_claimed], theta[:n_cols], sigma2=sigma2,
                         keys=keys)
    unnamed.update({m: _timing_text(f) for m, f in timed.items() if m not in unnamed})
    for g in groups:
        # a finding goes with any of its selected effects (one fitted power)
        hit = next((unnamed[m] for m in g.selected if m in unnamed), None)
        if hit is not None:
            for m in g.selected:
                unnamed.setdefault(m, hit)
    groups = [g for g in groups if not set(g.selected) & set(unnamed)]
    named = [i for i in range(n_claimed) if label(blocks[i].key) not in unnamed]
    moved = [replace(fitted[i], attributed=False) for i in range(n_claimed)
             if label(blocks[i].key) in unnamed]
    fitted, offered_fx = [fitted[i] for i in named], moved + fitted[n_claimed:]
    fates = tuple(replace(f, fate='offered', reason=unnamed[lab])
                  if (lab := label((f.effect, f.axis))) in unnamed else f for f in fates)
    offered_gain = math.nan
    if offered_fx:
        # what the offered loss as a whole does to the held-out error, beside the named ones
        mse_named = design.heldout_mse([c for i in named for c in blocks[i].cols], folds)
        offered_gain = float(np.mean([1.0 - mse_full[r] / mse_named[r] for r in mse_full
                                      if mse_named[r] > 0.0]))

    # in-sample residual after (diagnostics, at the baseline offset); the before/after
    # figures are fresh comparisons with the effects declared, offsets estimated anew
    # (:mod:`.realign`)
    names = [r.cmp.name for r in data]
    full_machine = (machine_with(machine, blocks, theta, measures=measures) if options.realign
                    else machine)
    # (held by the round's store as each is made: the next round re-pins its runs from them)
    augmented = [held_run(c, store) for c in iter_realigned(
        campaign, full_machine, names, baseline=cmp_runs if full_machine is machine else (),
        loaded=loaded)]
    # what a run's *after* keeps of its comparison: metrics, offset, the binned simulation
    # (a long run's fresh comparison is let go as soon as it is summed up)
    after_of: dict[int, tuple[Metrics, dict[str, Any], np.ndarray]] = {
        r: _after(c, data[r].bins) for r, c in enumerate(augmented)}
    for train, test in folds if options.realign else ():
        fold_machine = machine_with(machine, blocks, design.fit(cols, train),
                                    measures=measures)
        base = cmp_runs if fold_machine is machine else ()
        for r, c in zip(test, iter_realigned(campaign, fold_machine, [names[r] for r in test],
                                             baseline=base, loaded=loaded)):
            after_of[r] = _after(c, data[r].bins)
    held = {r for _, test in folds for r in test}
    outcomes = []
    residual_after = []
    for r, run in enumerate(data):
        m, k = run.residual.shape
        insample = design.predict(cols, theta, r).reshape(m, k)
        residual_after.append(run.residual - insample)
        c = run.cmp
        after_metrics, after_offset, after_w = after_of[r]
        outcomes.append(RunOutcome(
            name=c.name, load_kg=c.load_kg, role=c.role, heldout=r in held, before=c.metrics,
            after=after_metrics, t=run.t, meas_w=run.bins.mean(c.total_meas_w),
            sim_w=run.bins.mean(c.total_sim_w), after_w=after_w,
            residual_before_w=run.residual, residual_after_w=residual_after[-1],
            states=run.states, offset_before=offset_dict(c.offset, used_s=c.offset_used_s),
            offset_after=after_offset))

    unit = 'W' if measures is None else quantity_of(measures).unit
    coloured = {a: n.method == 'slow' for a, n in noise.items()}
    diag_before, spectra_before = diagnose_runs(data, [r.residual for r in data], sigmas,
                                                names=STATE_NAMES, unit=unit, coloured=coloured)
    diag_after, spectra_after = diagnose_runs(data, residual_after, sigmas, names=STATE_NAMES,
                                              unit=unit, coloured=coloured)
    spectra = {a: (spectra_before[a][0], spectra_before[a][1], spectra_after[a][1])
               for a in axes}
    unexplained = list(rejected)
    for d in diag_after:
        if d.structured:
            unexplained.append({'diagnostic': d.name, 'axis': d.axis, 'effect': None,
                                'statistic': d.statistic, 'message': d.message})
    explained = (min(max(1.0 - (sse_full - noise_ss) / structured0, 0.0), 1.0)
                 if structured0 > 0 else math.nan)
    uses = {axis: [RangeUse(run=r.cmp.name, load_kg=r.cmp.load_kg,
                            speed_m_s=np.abs(r.states['velocity'][:, j]),
                            accel_m_s2=r.states['acceleration'][:, j],
                            position_m=r.states['position'][:, j]) for r in data]
            for j, axis in enumerate(axes)}
    warnings = machine_warnings(machine, uses)
    status, message = _verdict(fitted, unexplained, steps, data, folds, explained, groups,
                               offered=offered_fx, offered_gain=offered_gain,
                               min_share=options.min_share)
    if chosen.cap_reached:
        message += (f'; the consistency loop reached its cap of {options.max_rounds} rounds '
                    '(kept the effects consistent in its last round; see candidates)')
    report(1.0)
    return AnalysisResult(
        status=status, message=message, campaign=cmp.campaign, manifest=cmp.manifest,
        machine=machine, machine_file=machine_file, holdout=options.holdout, axes=axes,
        noise_sigma_w=sigmas, noise=noise, runs=tuple(outcomes), effects=tuple(fitted),
        offered=tuple(offered_fx), offered_gain_rel=offered_gain,
        min_share=options.min_share,
        unexplained=tuple(unexplained), diagnostics_before=tuple(diag_before),
        diagnostics_after=tuple(diag_after), steps=steps, spectra=spectra,
        augmented=tuple(augmented_outcome(c) for c in augmented),
        alignment_warnings=tuple(cmp.warnings),
        candidates=mark_groups(fates, groups), warnings=tuple(warnings),
        ambiguous=tuple(groups),
        calibrated={a: observed_range(u) for a, u in uses.items()}, rounds=chosen.rounds,
        cap_reached=chosen.cap_reached, residual_unit=unit,
        analysis_period_s=options.analysis_period_s,
        samples_per_bin={r.cmp.name: r.bins.size for r in data}), augmented, full_machine


def _after(cmp: RunComparison, bins: Bins) -> tuple[Metrics, dict[str, Any], np.ndarray]:
    """A run's *after*: metrics, offset (``compare --json``'s) and binned simulated total."""
    return (cmp.metrics, offset_dict(cmp.offset, used_s=cmp.offset_used_s),
            bins.mean(cmp.total_sim_w))


def _shapeless_text(group: AmbiguousGroup) -> str:
    """Why the selected effects of a shapeless finding are offered, not named."""
    return (f'its fitted power ({group.power_rms_w:.3g} W RMS) is reproduced within the noise '
            f'by {len(group.members)} of the {group.candidates} catalog candidates on '
            f'{group.axis}: no shape these data single out; offered as a loss, not named')


def _timing_text(form: EquivalentForm) -> str:
    """Why an effect that a shift of the records reproduces is offered, not named."""
    delta = next(iter(form.parameters.values()), {}).get('delta_s', math.nan)
    return (f'its power is what a shift of the records by {1e3 * delta:+.2g} ms gives '
            f'({form.members[0]} reproduces it within the noise): a loss and an error of '
            'the alignment these data cannot tell apart; offered as a loss, not named')


def _size_text(effects: Sequence[FittedEffect], min_share: float) -> str:
    """``; below 1 % of the energy: copper on X (0.4 %)`` for effects that do not matter."""
    # a time_offset corrects the records; its energy is nobody's loss
    small = [f'{e.id} on {e.axis} ({100 * e.energy_share:.2g} %)' for e in effects
             if not e.matters and get_effect(e.id).machine_property]
    if not small:
        return ''
    return (f'; detected, below {100 * min_share:g} % of the energy: ' + ', '.join(small))


def _record_text(effect: FittedEffect) -> str:
    return ', '.join(f'{p.name} {p.value:+.3g} {p.unit}' for p in effect.params)


def _verdict(fitted, unexplained, steps, data, folds, explained,
             groups=(), *, offered: Sequence[FittedEffect] = (),
             offered_gain: float = math.nan, min_share: float = 0.01) -> tuple[str, str]:
    n_test = len({r for _, test in folds for r in test})
    names = found_text(fitted, groups) + _size_text(fitted, min_share)
    share = (f' ({100 * explained:.0f} % of the structured residual explained)'
             if math.isfinite(explained) else '')
    offer = ''
    if offered:
        gain = offered_gain
        offer = ('; offered, not attributed to one effect: a loss of the shape of '
                 + ' + '.join(f'{e.id} on {e.axis}' for e in offered)
                 + f' (mean squared error on held-out runs {100 * gain:.0f} % lower; '
                 + ', '.join(f'{100 * e.energy_share:.2g} %' for e in offered)
                 + ' of the energy; in the augmented machine)')
    if n_test < 2:
        return 'too_few_runs', ('fewer than 2 held-out runs: no effect can be shown to '
                                'improve held-out error')
    if fitted and unexplained:
        return 'partial', (f'added {names}{share}; structure remains that no catalog effect '
                           f'explains: {"; ".join(u["diagnostic"] for u in unexplained)}'
                           f'{offer}')
    if fitted and not any(get_effect(e.id).machine_property for e in fitted):
        # only a correction of the records (time_offset): the machine lacks nothing
        fixes = ', '.join(f'{e.id} on {e.axis} ({_record_text(e)})' for e in fitted)
        return 'clean', (f'no effect added; the alignment was corrected by {fixes}; no '
                         f'structure beyond the noise{offer}')
    if fitted:
        return 'effects', f'added {names}{share}; no structure left beyond the noise{offer}'
    if unexplained:
        return 'unexplained', ('the residual has structure ('
                               + '; '.join(u['diagnostic'] for u in unexplained)
                               + f') that no catalog effect explains consistently{offer}')
    last = steps[-1].reason if steps else 'no candidate'
    return 'clean', f'no effect added ({last}); no structure beyond the noise{offer}'
