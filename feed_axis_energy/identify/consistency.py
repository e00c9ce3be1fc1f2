"""The consistency loop of ``analyze`` and the fate of every candidate.

:func:`select_consistent` repeats forward selection (:func:`.selection.forward_select`),
pruning (:func:`prune`) and the consistency check across runs (:func:`heterogeneity`)
until no selected effect is inconsistent, at most ``max_rounds`` times. Nothing is dropped
in silence: every candidate ``(effect, axis)`` ends with one *fate* (:data:`FATES`) and a
reason, and a loop that reaches its round cap keeps the effects that were consistent in its
last round and says so.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
import math
from typing import Any

import numpy as np
from scipy import stats

from .selection import (Block, chi2_limit, Design, forward_select, gain_text, solve_normal,
                        Step)

__all__ = ['FATES', 'Fate', 'ConsistentSelection', 'select_consistent', 'noise_floor_ss',
           'WEAK_Z', 'prune', 'heterogeneity', 'label', 'mark_groups']

FATES = ('accepted', 'offered', 'rejected', 'dropped_in_pruning', 'excluded_inconsistent',
         'not_claimed', 'not_tried', 'round_cap', 'no_basis', 'equivalent')
"""Possible fates: ``accepted``; ``offered`` (selected, improves the held-out error, but not
attributed to this effect: offered as a loss of its shape, in the augmented machine);
``rejected`` (its held-out gain did not pass);
``dropped_in_pruning`` (selected, then made redundant by a later effect); ``excluded_inconsistent``
(fits, but not with one set of parameters for every run); ``not_claimed`` (selected, but
an alternative outside the catalog fits as well); ``not_tried`` (``max_effects``
reached first); ``round_cap`` (left out when the consistency loop reached its cap);
``no_basis`` (the effect adds nothing on these runs, e.g. braking loss without braking);
``equivalent`` (not selected, but part of an equivalent form of a selected effect: one
ambiguous finding, :mod:`.ambiguity`)."""


@dataclass(frozen=True)
class Fate:
    """What happened to one candidate ``(effect, axis)``.

    Attributes
    ----------
    effect, axis
        The candidate.
    fate
        One of :data:`FATES`.
    reason
        One sentence with the figures behind it.
    heldout_gain_rel, heldout_gain_se
        Its mean relative held-out gain and standard error when it was last scored
        (``nan``: never scored).
    """

    effect: str
    axis: str
    fate: str
    reason: str
    heldout_gain_rel: float = math.nan
    heldout_gain_se: float = math.nan
    group: int | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (keys in docs/analyze.md)."""
        return {'effect': self.effect, 'axis': self.axis, 'fate': self.fate,
                'reason': self.reason, 'heldout_gain_rel': self.heldout_gain_rel,
                'heldout_gain_se': self.heldout_gain_se, 'group': self.group}


@dataclass(frozen=True)
class ConsistentSelection:
    """Outcome of :func:`select_consistent`.

    Attributes
    ----------
    blocks
        The effects kept.
    steps
        The rounds of the last forward selection.
    rejected
        ``unexplained`` entries: inconsistent effects and a weak attribution.
    fates
        One :class:`Fate` per candidate key, in catalog order.
    rounds
        Consistency rounds run; ``cap_reached`` whether the last one still found an
        inconsistent effect.
    offered
        Effects whose held-out gain passed every test but that explain too little of the
        structured residual to be named (``min_explained``): offered as a loss of their
        shape, never dropped.
    """

    blocks: tuple[Block, ...]
    steps: tuple[Step, ...]
    rejected: tuple[dict[str, Any], ...]
    fates: tuple[Fate, ...]
    rounds: int
    cap_reached: bool
    offered: tuple[Block, ...] = ()


def label(key: tuple[str, str]) -> str:
    """``effect@axis``."""
    return f'{key[0]}@{key[1]}'


def prune(design: Design, blocks: list[Block], folds, options,
          sigma2: float = math.nan) -> tuple[list[Block], list[tuple[Block, str]]]:
    """Backward pass: drop, one at a time, the weakest effect that no longer earns its place.

    An effect stays when, added last, its mean relative held-out gain still exceeds
    ``se_factor`` standard errors and its drop of the residual sum of squares still exceeds
    the chi-square limit of its parameters at ``alpha / m`` (``m`` candidate keys, the
    entry test's level; with a noise level): an effect picked early can be made redundant
    by a later one. Its size plays no part.

    Returns
    -------
    tuple
        The kept blocks and ``[(dropped block, reason), ...]``.
    """
    blocks = list(blocks)
    dropped: list[tuple[Block, str]] = []
    known = math.isfinite(sigma2) and sigma2 > 0.0
    # the entry test's multiple-testing level: one test per candidate key
    tests = max(len({b.key for b in design.blocks}), 1)
    while blocks:
        cols = [c for b in blocks for c in b.cols]
        full = design.heldout_mse(cols, folds)
        sse_full = design.total_sse(cols)
        worst, worst_score, why = None, math.inf, ''
        for i in range(len(blocks)):
            without = [c for k, b in enumerate(blocks) if k != i for c in b.cols]
            wo = design.heldout_mse(without, folds)
            gains = np.array([1.0 - full[r] / wo[r] if wo[r] > 0.0 else 0.0 for r in full])
            se = (float(np.std(gains, ddof=1) / math.sqrt(gains.size)) if gains.size > 1
                  else math.inf)
            mean = float(np.mean(gains))
            chi2 = (design.total_sse(without) - sse_full) / sigma2 if known else math.inf
            limit = chi2_limit(options.alpha, tests, len(blocks[i].cols),
                               options.sampling_chi2)
            keep = mean > options.se_factor * se and chi2 > limit
            score = mean - options.se_factor * se
            if not keep and score < worst_score:
                others = ', '.join(label(b.key) for k, b in enumerate(blocks) if k != i)
                worst, worst_score = i, score
                drop = f', residual drop {chi2:.1f} sigma² (limit {limit:.1f})' if known else ''
                why = (f'added last beside {others or "nothing"}, its held-out gain is '
                       f'{100 * mean:.2f} % +- {100 * se:.2f} %{drop} (needs more than '
                       f'{options.se_factor:g} standard errors and the limit)')
        if worst is None:
            break
        dropped.append((blocks[worst], why))
        del blocks[worst]
    return blocks, dropped


def heterogeneity(design: Design, blocks: Sequence[Block], which: int,
                  sigma2: float) -> tuple[float, float]:
    """How much better per-run refits of one block fit than its pooled parameters.

    Returns ``(share, p_value)``: the share of the block's explained variance that per-run
    refits (within the physical bounds) add, and the chi-square probability of that
    improvement if the parameters were the same on every run (improvement / ``sigma2``
    with ``(R - 1) p`` degrees of freedom).
    """
    cols = [c for b in blocks for c in b.cols]
    theta = design.fit(cols, range(design.runs))
    own = list(blocks[which].cols)
    pos = [cols.index(c) for c in own]
    rest = [i for i in range(len(cols)) if i not in pos]
    pooled = free = none = 0.0
    for r in range(design.runs):
        base = design.y[r] - design.columns(r, [cols[i] for i in rest]) @ theta[rest]
        xe = design.columns(r, own)
        none += float(base @ base)
        pooled_res = base - xe @ theta[pos]
        pooled += float(pooled_res @ pooled_res)
        if np.any(xe):
            sol = solve_normal(xe.T @ xe, xe.T @ base, design.lower[own], design.upper[own])
            free_res = base - xe @ sol
            free += float(free_res @ free_res)
        else:
            free += float(base @ base)
    explained = none - free
    share = float((pooled - free) / explained) if explained > 0.0 else 0.0
    dof = max((design.runs - 1) * len(own), 1)
    p = float(stats.chi2.sf((pooled - free) / sigma2, dof)) if sigma2 > 0.0 else math.nan
    return share, p


def _inconsistent(block: Block, share: float, options) -> dict[str, Any]:
    return {'diagnostic': 'inconsistent_across_runs', 'axis': block.key[1],
            'effect': block.key[0], 'statistic': share,
            'message': (f'{label(block.key)} would fit, but not with one set of parameters: '
                        f'per-run refits add {100 * share:.0f} % to what it explains (limit '
                        f'{100 * options.max_heterogeneity:.0f} %); the structure is not this '
                        'effect')}


WEAK_Z = 3.0
"""Standard deviations of the noise's own sum of squares that structure left must exceed."""


def noise_floor_ss(noise_ss: float, sigma2: float, z: float = WEAK_Z) -> float:
    """The least residual sum of squares beyond the noise's that is structure [W²].

    The residual's sum of squares over ``n`` samples of white noise fluctuates by
    ``sigma²·sqrt(2n)``, and the noise estimate it is compared with by about as much: a
    remainder within ``z·sigma²·sqrt(4n)`` of the noise's is no evidence of structure, and
    no share of it can be "unexplained" (0 when ``sigma2`` is unknown).
    """
    if not (math.isfinite(sigma2) and sigma2 > 0.0 and noise_ss > 0.0):
        return 0.0
    return z * sigma2 * math.sqrt(4.0 * noise_ss / sigma2)


def select_consistent(design: Design, folds, options, *, keys: Sequence[tuple[str, str]],
                      structured0: float, noise_ss: float, sigma2: float,
                      refine: Callable[[Block, list[int]], Block]) -> ConsistentSelection:
    """Forward selection, pruning and the consistency check until consistent or capped.

    Parameters
    ----------
    design
        Residuals and candidate blocks.
    folds
        Held-out folds.
    options
        :class:`.results.AnalyzeOptions` (``se_factor``, ``alpha``, ``max_effects``,
        ``max_tries``, ``pair_pool``, ``max_heterogeneity``, ``heterogeneity_alpha``,
        ``min_explained``,
        ``max_rounds``).
    keys
        Every candidate ``(effect, axis)`` considered, in catalog order (also those without
        a block: their fate is ``no_basis``).
    structured0, noise_ss, sigma2
        Structured part of the baseline residual sum of squares, the noise's share of it and
        the noise variance per sample.
    refine
        ``refine(block, other_cols)``: the block with its shape parameter refined.

    Returns
    -------
    ConsistentSelection
        Kept blocks, the record of the last selection and every candidate's fate.
    """
    excluded: list[tuple[str, str]] = []
    rejected: list[dict[str, Any]] = []
    fate: dict[tuple[str, str], Fate] = {}
    steps: tuple[Step, ...] = ()
    blocks: list[Block] = []
    stop = ''
    cap_reached = False
    rounds = 0
    for rounds in range(1, options.max_rounds + 1):
        sel = forward_select(design, folds, exclude=excluded, se_factor=options.se_factor,
                             sigma2=sigma2, alpha=options.alpha,
                             max_effects=options.max_effects, max_tries=options.max_tries,
                             pair_pool=options.pair_pool,
                             min_bic_drop=options.min_bic_drop,
                             floor_chi2=options.sampling_chi2)
        steps, stop = sel.steps, sel.stop
        blocks = list(sel.blocks)
        for i in range(len(blocks)):
            others = [c for k, b in enumerate(blocks) if k != i for c in b.cols]
            blocks[i] = refine(blocks[i], others)
        blocks, dropped = prune(design, blocks, folds, options, sigma2)
        het = [heterogeneity(design, blocks, i, sigma2) for i in range(len(blocks))]
        bad = [i for i, (h, p) in enumerate(het)
               if h > options.max_heterogeneity and p < options.heterogeneity_alpha]
        for i in bad:
            excluded.append(blocks[i].key)
            entry = _inconsistent(blocks[i], het[i][0], options)
            rejected.append(entry)
            fate[blocks[i].key] = Fate(blocks[i].key[0], blocks[i].key[1],
                                       'excluded_inconsistent', entry['message'])
        if not bad:
            break
        if rounds == options.max_rounds:
            # The cap is a verdict: keep what was consistent in this last round (pruned
            # and checked again without the excluded ones), and say so.
            cap_reached = True
            blocks = [b for i, b in enumerate(blocks) if i not in bad]
            blocks, more = prune(design, blocks, folds, options, sigma2)
            dropped += more
            het = [heterogeneity(design, blocks, i, sigma2) for i in range(len(blocks))]
            for i, (h, p) in enumerate(het):
                if h > options.max_heterogeneity and p < options.heterogeneity_alpha:
                    fate[blocks[i].key] = Fate(
                        blocks[i].key[0], blocks[i].key[1], 'round_cap',
                        f'still inconsistent across runs ({100 * h:.0f} % from per-run '
                        f'refits) when the consistency loop reached its cap of '
                        f'{options.max_rounds} rounds')
            blocks = [b for i, b in enumerate(blocks) if fate.get(b.key) is None
                      or fate[b.key].fate != 'round_cap']
    for block, why in dropped:
        if block.key not in fate and block.key not in {b.key for b in blocks}:
            fate[block.key] = Fate(block.key[0], block.key[1], 'dropped_in_pruning', why)
    offered: list[Block] = []
    if blocks and structured0 > 0.0:
        cols = [c for b in blocks for c in b.cols]
        left = design.total_sse(cols) - noise_ss
        share = 1.0 - left / structured0
        if share < options.min_explained and left > noise_floor_ss(noise_ss, sigma2):
            # a real improvement of the held-out error is never dropped: it is offered as a
            # loss of this shape, not attributed to these effects
            msg = (f'{", ".join(label(b.key) for b in blocks)} would explain only '
                   f'{100 * share:.0f} % of the structured residual (at least '
                   f'{100 * options.min_explained:.0f} % needed to name it): not attributed; '
                   f'offered as a loss of that shape')
            rejected.append({'diagnostic': 'weak_attribution',
                             'axis': ','.join(sorted({b.key[1] for b in blocks})),
                             'effect': ','.join(b.key[0] for b in blocks), 'statistic': share,
                             'message': msg})
            for b in blocks:
                fate[b.key] = Fate(b.key[0], b.key[1], 'offered', msg)
            offered, blocks = blocks, []
    fates = _fates(keys, design, blocks, steps, stop, fate, cap_reached, options)
    return ConsistentSelection(blocks=tuple(blocks), steps=steps, rejected=tuple(rejected),
                               fates=fates, rounds=rounds, cap_reached=cap_reached,
                               offered=tuple(offered))


def _fates(keys, design: Design, blocks, steps: Sequence[Step], stop: str,
           fate: dict[tuple[str, str], Fate], cap_reached: bool, options) -> tuple[Fate, ...]:
    """One fate per candidate key: the decided ones, then what the last selection says."""
    kept = {b.key for b in blocks}
    with_block = {b.key for b in design.blocks}
    scored = {}
    tried: dict[tuple[str, str], Step] = {}
    for step in steps:
        for key, gain, se in step.candidates:
            scored[key] = (step.round, gain, se)
        tried[step.key] = step
        if step.with_key is not None:
            tried[step.with_key] = step
    last_round = steps[-1].round if steps else 0
    out = []
    for key in keys:
        n, gain, se = scored.get(key, (0, math.nan, math.nan))
        found = tried.get(key)
        if key in kept:
            why = found.reason if found is not None and found.accepted else 'kept'
            n = found.round if found is not None else n
            out.append(Fate(key[0], key[1], 'accepted', f'round {n}: {why}', gain, se))
        elif key in fate:
            f = fate[key]
            out.append(Fate(f.effect, f.axis, f.fate, f.reason, gain, se))
        elif key not in with_block:
            out.append(Fate(key[0], key[1], 'no_basis',
                            'the effect adds no power on these runs (its basis is zero)'))
        elif cap_reached:
            out.append(Fate(key[0], key[1], 'round_cap',
                            f'not re-examined: the consistency loop reached its cap of '
                            f'{options.max_rounds} rounds', gain, se))
        elif stop == 'max_effects':
            out.append(Fate(key[0], key[1], 'not_tried',
                            f'not added: max_effects ({options.max_effects}) was reached',
                            gain, se))
        elif found is not None and found.round == last_round:
            pair = ''
            if found.with_key is not None:
                other = found.key if found.with_key == key else found.with_key
                pair = f' (tried together with {label(other)})'
            out.append(Fate(key[0], key[1], 'rejected',
                            f'round {n}: {found.reason}{pair}', gain, se))
        elif steps:
            out.append(Fate(key[0], key[1], 'rejected',
                            f'round {n}: {gain_text(gain, se)}; '
                            f'not tried: the round tries the {options.max_tries} best by '
                            'held-out error, then pairs of the '
                            f'{options.pair_pool} best', gain, se))
        else:
            out.append(Fate(key[0], key[1], 'rejected', 'no selection round ran'))
    return tuple(out)


def mark_groups(fates: Sequence[Fate], groups: Sequence[Any]) -> tuple[Fate, ...]:
    """Record each member's part in an ambiguous finding (:mod:`.ambiguity`).

    A selected member stays ``accepted`` (its fitted values are the finding's, and go into
    the augmented machine), with the finding added to its reason; a member that was not
    selected becomes ``equivalent`` (whatever stopped it before: it fits as well as the
    selected one). Both carry the group's index.
    """
    where: dict[str, tuple[int, Any]] = {}
    for n, g in enumerate(groups):
        for m in g.members:
            where.setdefault(m, (n, g))
    out = []
    for f in fates:
        hit = where.get(label((f.effect, f.axis)))
        if hit is None:
            out.append(f)
            continue
        n, g = hit
        forms = [' + '.join(form.members) for form in g.forms
                 if label((f.effect, f.axis)) in form.members]
        if f.fate == 'accepted':
            out.append(replace(f, reason=(f'{f.reason}; ambiguous (finding {n + 1}): '
                                          f'{g.message}'), group=n))
        else:
            what = (f'part of the form {"; ".join(forms)}' if forms else 'a member')
            out.append(replace(f, fate='equivalent', group=n, reason=(
                f'{what} of finding {n + 1}, which reproduces the selected '
                f'{", ".join(g.selected)} within the noise (was: {f.fate}: '
                f'{f.reason[:120]})')))
    return tuple(out)
