"""Groups of effects with the same power shape (identify/ambiguity.py), on hand-made
columns whose spans are known: ``a`` = ``b`` + ``c`` exactly, ``u`` independent of them."""
import math

import numpy as np
import pytest

from feed_axis_energy.identify.ambiguity import (AmbiguousGroup, find_groups, form_text,
                                                 plausible_bounds, timing_forms)
from feed_axis_energy.identify.consistency import Fate, mark_groups
from feed_axis_energy.identify.selection import Design

SIGMA = 1.0
KEYS = [('a', 'X'), ('b', 'X'), ('c', 'X'), ('u', 'X')]


def _design(truth: str, *, amplitude: float, seed: int = 0, runs: int = 4, n: int = 400):
    """Per run: speed-like ``s``; columns a = (s, s²) [two parameters], b = s, c = s², u a
    square wave in time; the residual is the truth's power plus unit Gaussian noise."""
    rng = np.random.default_rng(seed)
    cols = {k: [] for k in 'abcu'}
    ys = []
    for r in range(runs):
        t = np.linspace(0.0, 1.0, n)
        s = (1.0 + r) * np.abs(np.sin(2 * np.pi * t))
        u = np.sign(np.sin(2 * np.pi * 7.0 * t + r))
        cols['a'].append(np.column_stack([s, s * s]))
        cols['b'].append(s[:, None])
        cols['c'].append((s * s)[:, None])
        cols['u'].append(u[:, None])
        power = {'a': s + 0.5 * s * s, 'u': u}[truth]
        ys.append(amplitude * power + SIGMA * rng.standard_normal(n))
    design = Design(ys)
    blocks = {}
    for key, names in (('a', ('p1', 'p2')), ('b', ('q',)), ('c', ('w',)), ('u', ('z',))):
        lo = np.zeros(len(names)) if key != 'u' else np.full(1, -np.inf)
        blocks[key] = design.add_block((key, 'X'), {}, names, cols[key],
                                       bounds=(lo, np.full(len(names), np.inf)))
    return design, blocks


def _groups(design, selected):
    cols = [c for b in selected for c in b.cols]
    theta = design.fit(cols, range(design.runs))
    return find_groups(design, selected, theta, sigma2=SIGMA ** 2, keys=KEYS,
                       periods_s=[0.01] * design.runs, axes=('X',))


def test_an_effect_equal_to_a_pair_is_one_group_with_power_and_energy():
    design, blocks = _design('a', amplitude=2.0)
    groups = _groups(design, [blocks['a']])
    assert len(groups) == 1
    g = groups[0]
    assert g.selected == ('a@X',)
    # b alone (s) or c alone (s²) cannot make s + 0.5 s²; the pair can, exactly
    assert [f.members for f in g.forms] == [('b@X', 'c@X')]
    assert g.forms[0].relative_residual < 1e-6
    assert form_text(g) == 'a = b + c'
    # the pair's fitted values are a's: q = p1, w = p2
    theta = design.fit(list(blocks['a'].cols), range(design.runs))
    params = g.forms[0].parameters
    assert params['b@X']['q'] == pytest.approx(theta[0], rel=1e-6)
    assert params['c@X']['w'] == pytest.approx(theta[1], rel=1e-6)
    # energy of the fitted power, by hand: sum over runs of sum(p) * period
    power = [design.predict(list(blocks['a'].cols), theta, r) for r in range(design.runs)]
    assert g.energy_j == pytest.approx(sum(float(p.sum()) * 0.01 for p in power))
    rms = math.sqrt(sum(float(p @ p) for p in power) / sum(p.size for p in power))
    assert g.power_rms_w == pytest.approx(rms)
    assert 'a = b + c' in g.message


def test_a_pair_selected_for_one_effect_is_one_group():
    # b and c selected together: a replaces both, so they are one finding, not two
    design, blocks = _design('a', amplitude=2.0, seed=1)
    groups = _groups(design, [blocks['b'], blocks['c']])
    assert len(groups) == 1
    assert groups[0].selected == ('b@X', 'c@X')
    assert ('a@X',) in [f.members for f in groups[0].forms]


def test_a_unique_effect_stays_named():
    design, blocks = _design('u', amplitude=1.0)
    assert _groups(design, [blocks['u']]) == []


def test_the_limit_follows_the_noise():
    # a small s² part: at amplitude 2, b alone misses it by far more than the noise; scaled
    # down until the missing part is below the noise, b alone becomes an equivalent form
    design, blocks = _design('a', amplitude=2.0, seed=2)
    forms = [f.members for f in _groups(design, [blocks['a']])[0].forms]
    assert ('b@X',) not in forms
    design, blocks = _design('a', amplitude=0.01, seed=2)
    groups = _groups(design, [blocks['a']])
    assert groups and ('b@X',) in [f.members for f in groups[0].forms]


def test_fates_record_every_member():
    design, blocks = _design('a', amplitude=2.0)
    groups = _groups(design, [blocks['a']])
    fates = [Fate('a', 'X', 'accepted', 'round 1'), Fate('b', 'X', 'rejected', 'round 2'),
             Fate('c', 'X', 'rejected', 'round 2'), Fate('u', 'X', 'rejected', 'round 2')]
    out = {f.effect: f for f in mark_groups(fates, groups)}
    assert out['a'].fate == 'accepted' and out['a'].group == 0
    assert 'ambiguous' in out['a'].reason
    assert out['b'].fate == 'equivalent' and out['c'].fate == 'equivalent'
    assert out['u'].fate == 'rejected' and out['u'].group is None


def test_forms_are_bounded_by_the_catalog_range():
    # coulomb's forces are unbounded physically but plausible within +-500 N; iron >= 0
    design = Design([np.zeros(3)])
    design.add_block(('coulomb', 'X'), {}, ('f_pos_n', 'f_neg_n'), [np.ones((3, 2))])
    design.add_block(('iron', 'X'), {}, ('k_h_w_s_rad',), [np.ones((3, 1))],
                     bounds=([0.0], [np.inf]))
    lower, upper = plausible_bounds(design)
    assert list(lower) == [-500.0, -500.0, 0.0]
    assert list(upper) == [500.0, 500.0, 1.0]


def test_a_power_most_of_the_catalog_reproduces_is_shapeless():
    # ten candidates of distinct shapes; the data hold one of them (t0) and noise. A second
    # selected effect fitted to the noise alone has a power far below the noise, which
    # almost any candidate reproduces: its finding is shapeless; t0's own shape is not
    rng = np.random.default_rng(5)
    n, runs = 400, 4
    keys = [(f't{i}', 'X') for i in range(10)]
    t = np.linspace(0.0, 1.0, n)
    shapes = [np.sin(2 * np.pi * (i + 1) * t + 0.4 * i) for i in range(10)]
    design = Design([3.0 * shapes[0] * (1 + r) + rng.standard_normal(n) for r in range(runs)])
    blocks = [design.add_block(k, {}, ('g',), [(s * (1 + r))[:, None] for r in range(runs)],
                               bounds=(np.full(1, -np.inf), np.full(1, np.inf)))
              for k, s in zip(keys, shapes)]
    selected = [blocks[0], blocks[7]]
    theta = design.fit([c for b in selected for c in b.cols], range(runs))
    groups = find_groups(design, selected, theta, sigma2=1.0, keys=keys,
                         periods_s=[0.01] * runs, axes=('X',))
    wide = [g for g in groups if g.shapeless]
    assert [g.selected for g in wide] == [('t7@X',)]
    assert wide[0].candidates == 10 and len(wide[0].members) >= 6
    assert not any('t0@X' in g.selected for g in wide)
    assert wide[0].to_dict()['candidates'] == 10


def test_shapeless_needs_half_the_axis_and_six_members():
    def group(members: int, candidates: int) -> AmbiguousGroup:
        return AmbiguousGroup(axis='X', selected=('m0@X',),
                              members=tuple(f'm{i}@X' for i in range(members)), forms=(),
                              power_rms_w=0.0, power_mean_w=0.0, energy_j=0.0,
                              candidates=candidates)
    assert group(8, 16).shapeless and not group(7, 16).shapeless
    # a short catalog: three of four is a shape (iron = coulomb + viscous), not noise
    assert not group(3, 4).shapeless and not group(5, 6).shapeless and group(6, 6).shapeless
    assert not group(8, 0).shapeless       # candidates unknown: never shapeless


def test_an_effect_a_shift_of_the_records_reproduces_is_timing_equivalent():
    # the data hold a small shift of the records (delta * dP/dt); a candidate 'm' of nearly
    # the derivative's shape was selected for it. The time_offset candidate reproduces its
    # power within the noise; the independent 'u' is evidence of its own shape
    rng = np.random.default_rng(3)
    n, runs = 500, 4
    t = np.linspace(0.0, 2.0, n)
    keys = [('m', 'X'), ('u', 'X'), ('time_offset', 'X')]
    ys, cols = [], {k: [] for k, _ in keys}
    for r in range(runs):
        power = (1 + r) * np.sin(2 * np.pi * t) ** 2 * 50.0
        deriv = np.gradient(power, t)
        u = np.sign(np.sin(2 * np.pi * 5.0 * t + r))
        cols['time_offset'].append(deriv[:, None])
        cols['m'].append((deriv + 0.01 * np.abs(deriv))[:, None])
        cols['u'].append(u[:, None])
        ys.append(0.004 * deriv + 2.0 * u + rng.standard_normal(n))
    design = Design(ys)
    names = {'m': 'g', 'u': 'z', 'time_offset': 'delta_s'}
    blocks = {k: design.add_block((k, 'X'), {}, (names[k],), cols[k],
                                  bounds=(np.full(1, -np.inf), np.full(1, np.inf)))
              for k, _ in keys}
    selected = [blocks['u'], blocks['m']]
    theta = design.fit([c for b in selected for c in b.cols], range(runs))
    timed = timing_forms(design, selected, theta, sigma2=1.0, keys=keys)
    assert list(timed) == ['m@X']
    form = timed['m@X']
    assert form.members == ('time_offset@X',)
    assert form.parameters['time_offset@X']['delta_s'] == pytest.approx(0.004, rel=0.1)
    assert form.relative_residual <= form.limit or form.data_increase <= form.data_limit
    # selected itself, the shift is no form of anything
    selected = [blocks['u'], blocks['time_offset']]
    theta = design.fit([c for b in selected for c in b.cols], range(runs))
    assert timing_forms(design, selected, theta, sigma2=1.0, keys=keys) == {}


def test_two_selected_powers_that_cancel_are_one_finding():
    # a = s and b = s + 0.05 u: data 0.1 u (plus noise) make a fit of -2 s + 2 (s + 0.05 u);
    # each power is 20 times their sum, so neither is determined alone
    rng = np.random.default_rng(7)
    n, runs = 400, 4
    t = np.linspace(0.0, 1.0, n)
    keys = [('a', 'X'), ('b', 'X')]
    ys, ca, cb = [], [], []
    for r in range(runs):
        s = (1.0 + r) * np.abs(np.sin(2 * np.pi * t))
        u = np.sign(np.sin(2 * np.pi * 7.0 * t + r))
        ca.append(s[:, None])
        cb.append((s + 0.05 * u)[:, None])
        ys.append(4.0 * u + 0.1 * rng.standard_normal(n))
    design = Design(ys)
    free = (np.full(1, -np.inf), np.full(1, np.inf))
    a = design.add_block(('a', 'X'), {}, ('p',), ca, bounds=free)
    b = design.add_block(('b', 'X'), {}, ('q',), cb, bounds=free)
    theta = design.fit(list(a.cols) + list(b.cols), range(runs))
    assert theta[0] < 0.0 < theta[1]
    (g,) = find_groups(design, [a, b], theta, sigma2=0.01, keys=keys,
                       periods_s=[0.01] * runs, axes=('X',))
    assert g.selected == ('a@X', 'b@X')
    cancel = [f for f in g.forms if not f.members]
    assert len(cancel) == 1 and cancel[0].relative_residual < 0.1
    assert 'cancel' in form_text(g)
    # the same two effects fitted to data of their own, unlike shapes: no finding
    design2 = Design([2.0 * c[:, 0] + 0.1 * rng.standard_normal(n) for c in ca])
    a2 = design2.add_block(('a', 'X'), {}, ('p',), ca, bounds=free)
    u2 = design2.add_block(('b', 'X'), {}, ('q',),
                           [np.sign(np.sin(2 * np.pi * 7.0 * t + r))[:, None]
                            for r in range(runs)], bounds=free)
    theta2 = design2.fit(list(a2.cols) + list(u2.cols), range(runs))
    assert not any(not f.members for g2 in find_groups(
        design2, [a2, u2], theta2, sigma2=0.01, keys=keys, periods_s=[0.01] * runs,
        axes=('X',)) for f in g2.forms)
