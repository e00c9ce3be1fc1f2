"""Issue 24 sections 2-4: noise from the data, detection by statistics, nothing dropped."""
from __future__ import annotations

import math

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.identify import AnalyzeOptions
from feed_axis_energy.identify.consistency import noise_floor_ss, select_consistent
from feed_axis_energy.identify.diagnostics import binned_structure, noise_level
from feed_axis_energy.identify.selection import Design, forward_select, loro_folds


def _white(seed: int, runs: int = 5, n: int = 3000) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.normal(0.0, 1.0, n) for _ in range(runs)]


def test_white_noise_reads_its_level_and_is_called_white() -> None:
    level = noise_level(_white(1))
    assert level.method == 'white'
    assert level.sigma_w == pytest.approx(1.0, rel=0.05)
    assert level.correlation == pytest.approx(1.0)


def test_slow_structure_does_not_raise_the_white_level() -> None:
    t = np.linspace(0.0, 30.0, 3000)
    runs = [y + 5.0 * np.sin(2 * np.pi * 0.2 * t) for y in _white(2)]
    level = noise_level(runs)
    # a cubic through the neighbours follows a 5 s sine of 5 W: the level is the noise's
    assert level.sigma_w == pytest.approx(1.0, rel=0.08)


@pytest.mark.parametrize('width', [5, 9])
def test_smooth_noise_reads_its_level_for_means_not_its_scatter(width) -> None:
    # white noise of 1 W smoothed by a moving average of `width` samples (a filtered drive
    # signal): the sample-to-sample scatter is small, but a mean of n >> width samples still
    # varies by 1/sqrt(n) W, as the unsmoothed noise's would
    runs = [np.convolve(y, np.ones(width) / width, mode='same') for y in _white(3)]
    level = noise_level(runs)
    assert level.method == 'slow'
    assert level.white_w < 0.5 / math.sqrt(width)
    assert 0.7 < level.sigma_w < 1.1
    # the level makes the bin test honest: pure (smooth) noise is not significant against
    # it, and would be, wrongly, against the sample-to-sample scatter
    x = np.concatenate([np.linspace(-0.3, 0.3, y.size) for y in runs])
    y = np.concatenate(runs)
    assert binned_structure(y, x, sigma=level.sigma_w, name='velocity',
                            axis='X').p_value > 1e-4
    assert binned_structure(y, x, sigma=level.white_w, name='velocity',
                            axis='X').p_value < 1e-10


def test_state_structure_is_not_read_as_slow_noise() -> None:
    # a missing effect that follows the state (a force times the speed) on white noise:
    # strokes at a few constant speeds, each run its own
    rng = np.random.default_rng(4)
    runs, states = [], []
    for r in range(5):
        v = np.repeat(np.tile([0.1, -0.1, 0.2, -0.2, 0.3, -0.3], 4), 20) * (1.0 + 0.1 * r)
        a = np.zeros(v.size)
        runs.append(40.0 * np.abs(v) + rng.normal(0.0, 1.0, v.size))
        states.append(np.column_stack([v, a]))
    assert noise_level(runs).sigma_w > 1.5       # without the states it reads as slow noise
    assert noise_level(runs, states=states).sigma_w == pytest.approx(1.0, rel=0.15)


def test_declared_level_replaces_the_estimate_and_keeps_it() -> None:
    level = noise_level(_white(5), declared_w=2.5)
    assert level.method == 'declared' and level.sigma_w == 2.5
    assert level.white_w == pytest.approx(1.0, rel=0.05)


def test_options_are_checked() -> None:
    with pytest.raises(ConfigError, match='min_share'):
        AnalyzeOptions(min_share=1.5)
    with pytest.raises(ConfigError, match='noise_w'):
        AnalyzeOptions(noise_w=-1.0)


def _design(seed: int, parts, noise: float = 1.0, runs: int = 6, n: int = 400):
    """Residual = sum of scale * column per run; columns named by key."""
    rng = np.random.default_rng(seed)
    cols = {k: [] for k in parts}
    ys = []
    for r in range(runs):
        y = rng.normal(0.0, noise, n)
        for key, (make, scale) in parts.items():
            c = make(rng, r, n)
            cols[key].append(c)
            y = y + scale[r] * c
        ys.append(y)
    design = Design(ys)
    for key in parts:
        design.add_block((key, 'X'), {}, ('a',), [c[:, None] for c in cols[key]])
    return design


def test_selection_tries_the_next_candidate_after_a_rejected_best() -> None:
    runs = 6
    # 'lumpy' is strong in every run but the last: fitted on the others it lowers the mean
    # held-out error most, but it makes the last run five times worse (its gain is not
    # consistent across runs); 'steady' helps every run a little
    lumpy = [2.0] * (runs - 1) + [0.0]
    parts = {
        'lumpy': (lambda rng, r, n: rng.normal(0.0, 1.0, n), lumpy),
        'steady': (lambda rng, r, n: np.sin(np.linspace(0.0, 6.0, n)), [1.5] * runs),
    }
    design = _design(7, parts, runs=runs)
    sel = forward_select(design, loro_folds(runs), sigma2=1.0)
    first = [s for s in sel.steps if s.round == 1]
    assert first[0].key == ('lumpy', 'X') and not first[0].accepted
    assert [b.key for b in sel.blocks] == [('steady', 'X')]
    assert any(s.key == ('steady', 'X') and s.accepted and s.round == 1 for s in sel.steps)


def test_a_pair_enters_when_neither_part_passes_alone() -> None:
    # y = c1 - c2 with c1, c2 = z + small parts: alone each explains almost nothing
    def part(k):
        def make(rng, r, n):
            z = np.sin(np.linspace(0.0, 9.0 + r, n)) * 50.0
            return z + np.cos(np.linspace(0.0, 3.0 + k + 0.3 * r, n)) * 2.0
        return make
    runs = 6
    parts = {'c1': (part(0), [1.0] * runs), 'c2': (part(1), [-1.0] * runs)}
    design = _design(8, parts, runs=runs)
    sel = forward_select(design, loro_folds(runs), sigma2=1.0)
    assert {b.key for b in sel.blocks} == {('c1', 'X'), ('c2', 'X')}
    assert any(s.with_key is not None and s.accepted for s in sel.steps)
    assert_allclose(design.fit(sel.cols, range(runs)), [1.0, -1.0], rtol=0.1)


def test_no_candidate_enters_on_pure_noise_of_many_candidates() -> None:
    runs = 8
    parts = {f'n{k}': (lambda rng, r, n: rng.normal(0.0, 1.0, n), [0.0] * runs)
             for k in range(30)}
    false = 0
    for seed in range(10):
        design = _design(100 + seed, parts, runs=runs)
        false += bool(forward_select(design, loro_folds(runs), sigma2=1.0).blocks)
    assert false <= 1


def test_a_weakly_attributed_improvement_is_offered_not_dropped() -> None:
    runs = 6
    parts = {'steady': (lambda rng, r, n: np.sin(np.linspace(0.0, 6.0, n)), [0.8] * runs)}
    design = _design(9, parts, runs=runs)
    # as if all of the residual were structure (no noise): the effect, clearly significant,
    # explains a quarter of it, too little to name it
    chosen = select_consistent(
        design, loro_folds(runs), AnalyzeOptions(), keys=[('steady', 'X')],
        structured0=float(design.yy.sum()), noise_ss=0.0, sigma2=1.0,
        refine=lambda block, others: block)
    assert chosen.blocks == ()
    assert [b.key for b in chosen.offered] == [('steady', 'X')]
    assert chosen.fates[0].fate == 'offered'
    assert [r['diagnostic'] for r in chosen.rejected] == ['weak_attribution']


def test_structure_left_within_the_noise_estimates_own_scatter_is_not_weak() -> None:
    # a small effect in unit noise; the noise estimate reads 5 % low, so the "structured
    # residual" holds as much noise as effect and the effect explains about half of it. What
    # is left is within the scatter of a sum of squares of 2400 noisy samples: named. With
    # the estimate 20 % low, what is left is structure by that measure: offered
    runs, n = 6, 400
    parts = {'steady': (lambda rng, r, n: np.sin(np.linspace(0.0, 6.0, n)), [0.3] * runs)}
    design = _design(11, parts, runs=runs, n=n)
    sse0 = float(design.yy.sum())
    for low, named in ((0.05, True), (0.20, False)):
        noise_ss = (1.0 - low) * runs * n
        chosen = select_consistent(
            design, loro_folds(runs), AnalyzeOptions(), keys=[('steady', 'X')],
            structured0=sse0 - noise_ss, noise_ss=noise_ss, sigma2=noise_ss / (runs * n),
            refine=lambda block, others: block)
        left = design.total_sse(list(design.blocks[0].cols)) - noise_ss
        share = 1.0 - left / (sse0 - noise_ss)
        assert share < 0.5 or not named, share      # below the share to name it either way
        assert (left <= noise_floor_ss(noise_ss, noise_ss / (runs * n))) is named
        assert bool(chosen.blocks) is named and bool(chosen.offered) is not named


def test_the_noise_floor_of_a_sum_of_squares() -> None:
    # 3 standard deviations of (residual SS - noise estimate): 3 * sigma² * sqrt(4 n)
    assert noise_floor_ss(2400.0 * 4.0, 4.0) == pytest.approx(3.0 * 4.0 * math.sqrt(9600.0))
    assert noise_floor_ss(100.0, math.nan) == 0.0 and noise_floor_ss(0.0, 1.0) == 0.0


def _bic_window_design(runs: int = 6, n: int = 400) -> tuple[Design, float]:
    """One candidate whose in-sample drop passes the chi-square test (one candidate, one
    parameter: 3.84 sigma²) and lowers the BIC by exactly 1: ``y = s·c + e`` with ``e``
    orthogonal to ``c`` in every run, so the fit is ``s`` on any runs."""
    rng = np.random.default_rng(11)
    cs = [np.sin(np.linspace(0.0, 7.0 + r, n)) for r in range(runs)]
    es = []
    for c in cs:
        e = rng.normal(0.0, 1.0, n)
        es.append(e - c * (c @ e) / (c @ c))
    big_n = runs * n
    sse1 = sum(float(e @ e) for e in es)
    # N ln(SSE0 / SSE1) - ln N = 1
    sse0 = sse1 * math.exp((math.log(big_n) + 1.0) / big_n)
    s = math.sqrt((sse0 - sse1) / sum(float(c @ c) for c in cs))
    design = Design([s * c + e for c, e in zip(cs, es)])
    design.add_block(('weak', 'X'), {}, ('a',), [c[:, None] for c in cs])
    return design, sse1 / big_n


def test_a_bic_drop_below_positive_evidence_is_not_enough() -> None:
    design, sigma2 = _bic_window_design()
    bic0, bic1 = design.bic([]), design.bic(design.blocks[0].cols)
    assert bic0 - bic1 == pytest.approx(1.0, abs=1e-6)
    sel = forward_select(design, loro_folds(6), sigma2=sigma2)
    assert sel.blocks == ()
    (step,) = sel.steps
    assert 'BIC drops by 1.0' in step.reason and 'positive evidence' in step.reason
    assert step.chi2 > step.chi2_limit and step.mean_gain > 2.0 * step.se_gain
    # the same data with any drop allowed (the rule before issue 24's 0-false target)
    loose = forward_select(design, loro_folds(6), sigma2=sigma2, min_bic_drop=0.0)
    assert [b.key for b in loose.blocks] == [('weak', 'X')]
    with pytest.raises(ConfigError, match='min_bic_drop'):
        AnalyzeOptions(min_bic_drop=-1.0)


def test_a_drop_within_the_simulations_own_sampling_error_is_not_enough() -> None:
    # the same candidate (chi-square drop ~8.8 against a limit of 3.84): when the simulation
    # still puts 10 noise variances of its own sampling into the residual (a rate at its
    # cap), that drop may be numerics, and the limit rises by it
    design, sigma2 = _bic_window_design()
    loose = forward_select(design, loro_folds(6), sigma2=sigma2, min_bic_drop=0.0)
    assert [b.key for b in loose.blocks] == [('weak', 'X')]
    (step,) = forward_select(design, loro_folds(6), sigma2=sigma2, min_bic_drop=0.0,
                             floor_chi2=10.0).steps
    assert not step.accepted and step.chi2_limit == pytest.approx(3.84 + 10.0, abs=0.01)
    assert 'not above 13.8' in step.reason


def test_a_design_whose_columns_are_on_disk_fits_predicts_and_reads_them_equal() -> None:
    """The selection's columns held by a store that keeps none in memory (every block a
    read-only map of a gone file) give the same cross products, fits, held-out errors,
    predictions and columns as columns kept in memory; a column set within one block is read
    as it is, across blocks it is gathered in the order asked."""
    from feed_axis_energy.identify.design import StateStore

    rng = np.random.default_rng(7)
    n = [400, 350, 500]
    blocks = [[rng.normal(size=(k, p)) for k in n] for p in (1, 3, 2)]
    ys = [rng.normal(size=k) + blocks[1][r] @ np.array([0.5, -0.2, 0.1]) for r, k in
          enumerate(n)]

    def built(store):
        d = Design(ys, store=store)
        for b, cols in enumerate(blocks):
            names = [f'p{i}' for i in range(cols[0].shape[1])]
            d.add_block((f'e{b}', 'X'), {}, names, cols)
        return d

    with StateStore(0) as store:
        disk = built(store)
        mem = built(None)
        assert all(not np.shares_memory(disk.columns(r, [1, 2, 3]), blocks[1][r])
                   for r in range(3))
        assert disk.columns(0, [1, 2, 3]).flags.writeable is False      # a map, as it is
        for r in range(3):
            assert_allclose(disk.gram[r], mem.gram[r], rtol=1e-12, atol=1e-12)
            assert_allclose(disk.columns(r, [5, 0, 2]),
                            np.column_stack([blocks[2][r][:, 1], blocks[0][r][:, 0],
                                             blocks[1][r][:, 1]]))
        cols = [0, 1, 2, 3, 4, 5]
        theta = disk.fit(cols, range(3))
        assert_allclose(theta, mem.fit(cols, range(3)), rtol=1e-10)
        assert_allclose(theta[1:4], [0.5, -0.2, 0.1], atol=0.15)
        folds = loro_folds(3)
        assert disk.heldout_mse(cols, folds) == pytest.approx(mem.heldout_mse(cols, folds))
        for r in range(3):
            assert_allclose(disk.predict(cols, theta, r), mem.predict(cols, theta, r))
        assert disk.columns(1, []).shape == (350, 0)
