"""Improvements of the summed power that per-axis scoring cannot confirm: offered, never named.

The selection (:mod:`.selection`) scores a candidate by the held-out error of every measured
axis's power: that is what attributing an effect to one axis needs. What ``compare``,
``fit-loss`` and ``analyze``'s own *after* report is the summed power of the measured axes.
The two can disagree when the axes trade power: on a contour at constant speed
``a_x·v_x = −a_y·v_y``, so the kinetic energy moves between the axes and a correction of one
axis's moved mass also absorbs part of the other's error in the sum. A correction of *every*
measured axis by the same effect (``mass_error`` on X and on Y) may then improve the summed
power of every unseen run while per axis it helps some runs and hurts others.

:func:`offer_summed` tries, after the selection, each catalog effect that describes the
machine and has no shape parameter, on every measured axis where it is not in the model
yet, all of them at once, beside what the selection kept and offered. It must pass the
selection's tests with the held-out error of the summed power in place of the per-axis
one: mean relative held-out gain above ``se_factor`` standard errors, the drop of the
(per-axis) residual above the chi-square limit at ``alpha / m`` for the ``m`` effects tried
(Bonferroni) plus what the simulation's own sampling leaves there (``floor_chi2``), and
a BIC lower by at least ``min_bic_drop`` (:func:`.selection.chi2_limit`, the same rules as
the selection's). What passes is *offered* (in the augmented machine, in
``offered``), never attributed: the data show that it predicts unseen runs better, not
which axis carries it. The best one is added, and the search is repeated beside it, while
the model holds fewer than ``max_effects`` effects (an offer on several axes counts once
for each axis it adds; the last one may pass the cap). With one measured axis
the summed power is that axis's power, and nothing new can pass: nothing is tried.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math

import numpy as np

from .selection import Block, chi2_limit, Design

__all__ = ['SummedOffer', 'offer_summed', 'summed_heldout_mse']


@dataclass(frozen=True)
class SummedOffer:
    """One effect offered on every measured axis by :func:`offer_summed`.

    Attributes
    ----------
    effect
        Catalog id.
    blocks
        Its block on each measured axis.
    mean_gain, se_gain
        Mean relative held-out gain of the summed power over held-out runs, its standard
        error.
    chi2, chi2_limit
        Drop of the residual sum of squares [sigma²] and its limit.
    reason
        One sentence with these figures.
    """

    effect: str
    blocks: tuple[Block, ...]
    mean_gain: float
    se_gain: float
    chi2: float
    chi2_limit: float
    reason: str


def summed_heldout_mse(design: Design, cols: Sequence[int],
                       folds: Sequence[tuple[Sequence[int], Sequence[int]]],
                       axes: int) -> dict[int, float]:
    """Mean squared held-out residual of the power summed over ``axes`` measured axes.

    The residual of a run is flattened sample by sample (``(m, axes)`` row-major), as
    :class:`.selection.Design` holds it. Returns ``{run: mse}`` [W²].
    """
    out = {}
    cols = list(cols)
    for train, test in folds:
        theta = design.fit(cols, train)
        for r in test:
            res = (design.y[r] - design.predict(cols, theta, r)).reshape(-1, axes).sum(axis=1)
            out[r] = float(res @ res) / max(res.size, 1)
    return out


def _gains(new: dict[int, float], base: dict[int, float]) -> tuple[float, float]:
    g = np.array([1.0 - new[r] / base[r] if base[r] > 0.0 else 0.0 for r in sorted(base)])
    if g.size < 2:
        return (float(g.mean()) if g.size else math.nan), math.inf
    return float(g.mean()), float(np.std(g, ddof=1) / math.sqrt(g.size))


def offer_summed(design: Design, folds: Sequence[tuple[Sequence[int], Sequence[int]]], *,
                 axes: Sequence[str], kept: Sequence[Block], effects: Sequence[str],
                 sigma2: float, se_factor: float = 2.0, alpha: float = 0.05,
                 max_effects: int = 4, min_bic_drop: float = 2.0,
                 floor_chi2: float = 0.0) -> list[SummedOffer]:
    """Effects on every measured axis that the summed power of unseen runs supports.

    Parameters
    ----------
    design
        The selection's design (residual of every measured axis, candidate blocks).
    folds
        Held-out folds.
    axes
        The measured axes, in the design's order.
    kept
        Blocks already in the model (named and offered by the selection).
    effects
        Catalog ids to try: effects that describe the machine, without shape parameters.
    sigma2
        Noise variance per sample [W²] (the level every test of ``analyze`` uses).
    se_factor, alpha, max_effects, min_bic_drop, floor_chi2
        As :func:`.selection.forward_select` (the same held-out, chi-square and BIC rules);
        ``max_effects`` counts ``kept`` too.

    Returns
    -------
    list of SummedOffer
        In the order they were added (empty with fewer than two measured axes or held-out
        runs).
    """
    n_axes = len(axes)
    n_test = len({r for _, test in folds for r in test})
    if n_axes < 2 or n_test < 2:
        return []
    by_key: dict[tuple[str, str], list[Block]] = {}
    for block in design.blocks:
        by_key.setdefault(block.key, []).append(block)
    taken = {b.key for b in kept}
    groups: dict[str, tuple[Block, ...]] = {}
    for effect in effects:
        # one block per axis (no shape variants); the axes where it is not in the model yet
        found = [by_key.get((effect, a), []) for a in axes if (effect, a) not in taken]
        if found and all(len(f) == 1 for f in found):
            groups[effect] = tuple(f[0] for f in found)
    chosen = list(kept)
    out: list[SummedOffer] = []
    known = math.isfinite(sigma2) and sigma2 > 0.0
    while groups and len(chosen) < max_effects:
        cols = [c for b in chosen for c in b.cols]
        base = summed_heldout_mse(design, cols, folds, n_axes)
        sse0 = design.total_sse(cols)
        bic0 = design.bic(cols)
        trials = []
        for effect, blocks in groups.items():
            new = cols + [c for b in blocks for c in b.cols]
            mean, se = _gains(summed_heldout_mse(design, new, folds, n_axes), base)
            trials.append((mean, effect, blocks, new, se))
        trials.sort(key=lambda t: -t[0])
        added = None
        for mean, effect, blocks, new, se in trials:
            p = len(new) - len(cols)
            limit = chi2_limit(alpha, len(groups), p, floor_chi2)
            chi2 = (sse0 - design.total_sse(new)) / sigma2 if known else math.nan
            if not (mean > se_factor * se and known and chi2 > limit
                    and design.bic(new) < bic0 - min_bic_drop):
                continue
            on = ', '.join(b.key[1] for b in blocks)
            together = ' together' if len(blocks) > 1 else ''
            reason = (f'{effect} on {on}{together}: held-out gain of the summed power '
                      f'{100 * mean:.2f} % +- {100 * se:.2f} %, residual drop '
                      f'{chi2:.1f} sigma² > {limit:.1f}; per axis not supported, so not '
                      'attributed; offered as a loss of that shape')
            added = SummedOffer(effect, blocks, mean, se, chi2, limit, reason)
            break
        if added is None:
            break
        out.append(added)
        chosen.extend(added.blocks)
        del groups[added.effect]
    return out
