"""Groups of effects with the same power shape (identify/ambiguity.py), on hand-made
columns whose spans are known: ``a`` = ``b`` + ``c`` exactly, ``u`` independent of them."""
import math

import numpy as np
import pytest

from feed_axis_energy.identify.ambiguity import find_groups, form_text, plausible_bounds
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
