"""offer_summed: an improvement of the summed power per-axis scoring cannot confirm is offered."""
import numpy as np
import pytest

from feed_axis_energy.identify.selection import Design, forward_select, loro_folds
from feed_axis_energy.identify.summed import offer_summed, summed_heldout_mse

RUNS, SAMPLES = 6, 400


def _design(seed: int, *, effect: float, shared: float, noise: float, axes: int = 2):
    """Residual ``effect·z + d`` per axis; ``d`` of the two axes cancels in their sum
    (``+shared`` on the first, ``-shared`` on the second: power traded between the axes)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 20.0, SAMPLES)
    ys, zs, ws = [], [], []
    for r in range(RUNS):
        z = np.column_stack([np.sin(1.3 * t + r) * np.cos(0.7 * t), np.cos(1.1 * t - r)])[:, :axes]
        w = np.column_stack([np.abs(np.sin(0.4 * t + 2 * r)), np.abs(np.cos(0.9 * t))])[:, :axes]
        d = shared * rng.normal(size=SAMPLES)[:, None] * np.array([1.0, -1.0])[:axes]
        y = effect * z + d + noise * rng.normal(size=(SAMPLES, axes))
        ys.append(y.reshape(-1))
        zs.append(z)
        ws.append(w)
    design = Design(ys)
    names = ('X', 'Y')[:axes]
    for key, cols in (('mass_error', zs), ('copper', ws)):
        for j, a in enumerate(names):
            per_run = []
            for c in cols:
                col = np.zeros((SAMPLES, axes))
                col[:, j] = c[:, j]
                per_run.append(col.reshape(-1, 1))
            design.add_block((key, a), {}, ('k',), per_run)
    return design, names


def test_summed_mse_is_the_mse_of_the_axes_sum() -> None:
    design, _ = _design(1, effect=0.0, shared=1.0, noise=0.1)
    folds = loro_folds(RUNS)
    got = summed_heldout_mse(design, [], folds, 2)
    for r in range(RUNS):
        total = design.y[r].reshape(-1, 2).sum(axis=1)
        assert got[r] == pytest.approx(float(total @ total) / SAMPLES)


def test_what_per_axis_selection_misses_under_traded_power_is_offered() -> None:
    # per axis, the traded power (2 W) buries the effect (0.3 W on each axis); in the sum it
    # cancels. Over 8 seeds the per-axis selection misses one axis or both several times;
    # the summed offer adds the missing ones in some, and never the absent copper.
    folds = loro_folds(RUNS)
    missed = completed = 0
    for seed in range(2, 10):
        design, axes = _design(seed, effect=0.3, shared=2.0, noise=0.1)
        selected = list(forward_select(design, folds, sigma2=4.0).blocks)
        offers = offer_summed(design, folds, axes=axes, kept=selected,
                              effects=['mass_error', 'copper'], sigma2=4.0)
        keys = {b.key for b in selected} | {b.key for o in offers for b in o.blocks}
        assert all(k[0] == 'mass_error' for k in keys), (seed, keys)
        for o in offers:
            assert o.mean_gain > 2.0 * o.se_gain and o.chi2 > o.chi2_limit
            assert 'not attributed' in o.reason
            assert not {b.key for b in o.blocks} & {b.key for b in selected}
        missed += len(selected) < 2
        completed += len(selected) < 2 and len(keys) == 2
    assert missed >= 4 and completed >= 2, (missed, completed)
    # where the selection finds nothing, both axes are offered together, near the truth
    design, axes = _design(6, effect=0.3, shared=2.0, noise=0.1)
    assert forward_select(design, folds, sigma2=4.0).blocks == ()
    offers = offer_summed(design, folds, axes=axes, kept=[], effects=['mass_error', 'copper'],
                          sigma2=4.0)
    assert [b.key for o in offers for b in o.blocks] == [('mass_error', 'X'),
                                                         ('mass_error', 'Y')]
    cols = [c for b in offers[0].blocks for c in b.cols]
    assert design.fit(cols, range(RUNS)) == pytest.approx([0.3, 0.3], rel=0.35)


@pytest.mark.parametrize('seed', range(5))
def test_noise_alone_gets_no_offer(seed) -> None:
    design, axes = _design(10 + seed, effect=0.0, shared=1.0, noise=1.0)
    offers = offer_summed(design, loro_folds(RUNS), axes=axes, kept=[],
                          effects=['mass_error', 'copper'], sigma2=2.0)
    assert offers == []


def test_one_axis_or_an_effect_already_in_the_model() -> None:
    design, axes = _design(3, effect=0.3, shared=0.0, noise=0.1, axes=1)
    assert offer_summed(design, loro_folds(RUNS), axes=axes, kept=[],
                        effects=['mass_error'], sigma2=0.01) == []
    design, axes = _design(4, effect=0.3, shared=3.0, noise=0.1)
    kept = [b for b in design.blocks if b.key == ('mass_error', 'X')]
    offers = offer_summed(design, loro_folds(RUNS), axes=axes, kept=kept,
                          effects=['mass_error', 'copper'], sigma2=9.0)
    # only the axis where it is not in the model yet is tried
    assert all(b.key != ('mass_error', 'X') for o in offers for b in o.blocks)


def test_the_selections_floor_and_bic_rule_hold_for_offers() -> None:
    # the offer of seed 6 (both axes' mass_error) passes by a known margin; the sampling
    # floor and the BIC drop that analyze asks of every candidate take it away beyond it
    design, axes = _design(6, effect=0.3, shared=2.0, noise=0.1)
    folds = loro_folds(RUNS)
    args = dict(axes=axes, kept=[], effects=['mass_error'], sigma2=4.0)
    offer, = offer_summed(design, folds, **args, min_bic_drop=0.0)
    margin = offer.chi2 - offer.chi2_limit
    assert margin > 2.0
    near, = offer_summed(design, folds, **args, min_bic_drop=0.0, floor_chi2=margin - 1.0)
    assert near.chi2_limit == pytest.approx(offer.chi2_limit + margin - 1.0)
    assert offer_summed(design, folds, **args, min_bic_drop=0.0, floor_chi2=margin + 1.0) == []
    cols = [c for b in offer.blocks for c in b.cols]
    drop = design.bic([]) - design.bic(cols)
    assert drop > 1.0
    assert offer_summed(design, folds, **args, min_bic_drop=drop - 1.0) != []
    assert offer_summed(design, folds, **args, min_bic_drop=drop + 1.0) == []
