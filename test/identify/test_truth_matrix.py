"""Issue 24 §8, the fast CI subset of ``bench/truth_matrix.py`` (the matrix runs outside CI,
its figures are in docs/analyze.md): a few cells of the independent truth, one seed each,
failing on any false attribution or misaligned run; and hand checks of the new truth forms
(they are written apart from the catalog, so they are compared with it here)."""
import math
from pathlib import Path

import numpy as np
from bench_modules import load_bench
import pytest

from feed_axis_energy.effects import EffectState, get_effect

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def tm():
    return load_bench('truth_model')


@pytest.fixture(scope='module')
def matrix():
    return load_bench('truth_matrix')


def test_new_truth_forms_match_the_catalog_shapes(tm):
    # the truth writes each shape on its own; at equal parameters its extra power must be
    # the catalog's (lead 10 mm, the demonstrator's)
    axis = tm.read_axis(ROOT / 'config' / 'demonstrator.yaml')
    line = tm.stroke_timeline(0.2, axis=axis, stroke_m=0.1, cycles=1, dwell_s=0.2)
    s = tm.fine_state(line, axis=axis, load_kg=5.0, run_index=0, before_s=0.1, after_s=0.1)
    base = tm.true_power(s, axis, {})
    k = s.t.size
    col = (lambda a: np.asarray(a, dtype=float).reshape(k, 1))
    w = 2 * math.pi * s.v / 0.01
    state = EffectState(
        t=s.t, axes=('X',), position_m=col(s.x), velocity_m_s=col(s.v),
        acceleration_m_s2=col(s.a), angle_rad=col(2 * math.pi * s.x / 0.01),
        omega_rad_s=col(w), force_n=np.zeros((k, 1)), torque_nm=np.zeros((k, 1)),
        mass_kg=np.array([s.mass_kg]), load_kg=5.0, normal_force_n=np.array([1.0]),
        lead_m=np.array([0.01]), mechanical_w=col(base), power_w=col(base))
    cases = {
        'offset_force': ('offset_force', {'f0_n': 7.0}, 7.0),
        'viscous_asymmetry': ('viscous_asymmetry', {'d_n_s_m': 40.0}, 40.0),
        'stribeck_exp': ('stribeck', {'f_s_n': 9.0, 'v_s_m_s': 0.005, 'delta': 1.0}, 9.0),
        'mass_error': ('mass_error', {'dm_kg': 3.0}, 3.0),
    }
    for case, (effect_id, params, amp) in cases.items():
        extra = tm.true_power(s, axis, {case: amp}) - base
        want = get_effect(effect_id).power_w(state, params)[:, 0]
        # force effects pass the rotor's torque relation unchanged: F/k * k v = F v
        np.testing.assert_allclose(extra, want, atol=1e-9, err_msg=case)
    # torque ripple: omega * sin(phi + 0.3) = a1 sin(phi) + b1 cos(phi) with the phase split
    extra = tm.true_power(s, axis, {'torque_ripple': 0.02}) - base
    want = get_effect('torque_ripple').power_w(
        state, {'a1_nm': 0.02 * math.cos(0.3), 'b1_nm': 0.02 * math.sin(0.3)})[:, 0]
    np.testing.assert_allclose(extra, want, atol=1e-9)
    # braking loss: a share of the negative power, never more than all of it
    extra = tm.true_power(s, axis, {'braking_loss': 0.4}) - base
    np.testing.assert_allclose(extra, 0.4 * np.maximum(-base, 0.0), atol=1e-9)


def test_verdicts(matrix):
    assert matrix.verdict('gravity', ['gravity'], []) == 'right'
    assert matrix.verdict('offset_force', ['coulomb'], []) == 'group'    # exact alias
    assert matrix.verdict('stribeck_exp', ['stribeck'], []) == 'right'
    assert matrix.verdict('copper', ['copper', 'iron'], [{'copper', 'iron'}]) == 'group'
    assert matrix.verdict('copper', ['iron'], []) == 'false'
    assert matrix.verdict('copper', [], []) == 'missed'
    assert matrix.verdict('clean', ['standby'], []) == 'false'


# mass_error large: the power's own lags are pulled 25-74 ms by the missing mass; before the
# motion anchor (issue 24 s1) 15 of 15 runs were misaligned and nothing was named
# viscous power (records without motion columns): a mass_error passenger rode beside viscous
# until a pinned run's offset was refined with the effects in the model (docs/analyze.md)
# copper small: the issue's own example of a small real effect that a 1 % gate dropped (copper
# loss worth 0.5-2 % of the energy under 1.5 W of noise); it must be named, alone or in a group
CI_CELLS = [('offset_force', 'large'), ('clean', 'smooth'), ('gravity', 'large'),
            ('mass_error', 'large'), ('viscous', 'power'), ('copper', 'small')]


@pytest.mark.parametrize('case, cls', CI_CELLS)
def test_ci_subset_no_false_attribution_no_misaligned_run(matrix, case, cls):
    (r,) = matrix.run_cells([(case, cls)], range(1, 2))
    assert r['verdict'] != 'false', r
    assert r['misaligned'] == [], r
    assert r['verdict'] in ('right', 'group'), r
    if cls != 'smooth':
        # 1.5 W of noise on 50 ms samples: the planner's 1 kHz is fine enough
        assert r['sim_rate_hz'] == 1000.0, r


def test_a_passenger_the_bic_barely_supports_is_not_added(matrix):
    # standby small, seed 19: beside standby (1.1 % of the energy) viscous_asymmetry passed
    # the selection (chi-square 9.3 > 8.6) with a power 14 of 16 catalog candidates
    # reproduce within the noise; it was named, a false attribution, then offered as
    # shapeless (test_ambiguity.py tests that rule on its own). Its BIC drop is below the 2
    # of positive evidence: it is not added at all
    (r,) = matrix.run_cells([('standby', 'small')], range(19, 20))
    assert r['verdict'] == 'right' and r['named'] == ['standby'], r
    assert r['offered'] == [], r
    assert r['misaligned'] == [], r


def test_a_passenger_a_shift_of_the_records_reproduces_is_offered_not_named(matrix):
    # torque_ripple small, seed 15: a mass_error of -2.4 kg passed beside the ripple (held-out
    # gain 4.70 %, time_offset 4.69 %): the 0.25 ms by which the truth's meter delays its
    # readings, which a moved mass reproduces on this program. Offered, not named
    (r,) = matrix.run_cells([('torque_ripple', 'small')], range(15, 16))
    assert r['verdict'] == 'right' and r['named'] == ['torque_ripple'], r
    assert r['offered'] == ['mass_error'], r
    assert r['misaligned'] == [], r


def test_a_meter_that_smooths_is_estimated_and_the_effect_named_alone(matrix):
    # the smooth class records through a 5 ms first-order lag; read as a pure delay it left
    # the rounded edges to mass_error, stribeck and viscous beside coulomb (docs/analyze.md,
    # "A meter that smooths"); with the filter estimated coulomb is named alone
    (r,) = matrix.run_cells([('coulomb', 'smooth')], range(1, 2))
    assert r['verdict'] in ('right', 'group'), r
    assert r['misaligned'] == [], r
    assert abs(r['meter_filter_s'] - 0.005) < 2e-4, r
    # a clean campaign through the same meter: the filter, and nothing else
    (r,) = matrix.run_cells([('clean', 'smooth')], range(1, 2))
    assert r['named'] == [] and r['status'] == 'clean', r
    assert abs(r['meter_filter_s'] - 0.005) < 2e-4, r
    # 0.05 W of noise on 10 ms samples resolves what the planner's 1 kHz sampling changes
    # in the meter's readings (a 0.02 N s/m viscous loss was offered at 1 kHz): the
    # analysis simulates finer
    assert r['sim_rate_hz'] in (2000.0, 4000.0, 8000.0), r
    assert r['augmented_rate_hz'] == 1000.0, r      # the machine file keeps its own rate


def test_a_large_inertia_on_records_of_the_power_alone_is_named_at_the_true_offsets(matrix):
    # mass_error power: the power's own lags are pulled 30-80 ms early by the missing mass
    # and nothing is supported at them ('unexplained', 15 of 15 runs misaligned) until the
    # offsets are also searched with each candidate in the model (.jointalign)
    (r,) = matrix.run_cells([('mass_error', 'power')], range(1, 2))
    assert r['verdict'] == 'right' and r['named'] == ['mass_error'], r
    assert r['misaligned'] == [] and r['left_out'] == [], r
    assert r['largest_error_s'] < 0.002, r
    assert r['aligned_with']['effect'] == 'mass_error', r
    assert 0.02 < r['aligned_with']['median_move_s'] < 0.1, r


def test_a_large_stribeck_that_pulls_only_the_slow_runs_starts_from_its_offsets(matrix):
    # stribeck power, seed 6 (111 kN at v_s 20 mm/s, 5.6 % of the energy): the low-speed
    # spikes pull the power's own lags of three slow runs by 36-46 ms and leave two more
    # ambiguous; the median run moves 3.9 ms. The start from the offsets with stribeck in
    # the model ran only when the median moved a grid step: 'unexplained', 2 runs left out
    (r,) = matrix.run_cells([('stribeck', 'power')], range(6, 7))
    assert r['verdict'] == 'right' and r['named'] == ['stribeck'], r
    assert r['misaligned'] == [] and r['left_out'] == [], r
    assert r['aligned_with']['effect'] == 'stribeck', r
    assert r['aligned_with']['median_move_s'] < 0.005 < r['aligned_with']['largest_move_s'], r


def test_the_truth_rate_option_is_checked_and_set(matrix, capsys, monkeypatch):
    with pytest.raises(SystemExit) as exit_info:
        matrix.main(['--truth-hz', '10', '--cases', 'clean', '--classes', 'smooth'])
    assert exit_info.value.code == 2
    assert '--truth-hz must be within' in capsys.readouterr().err
    tm = matrix.tm      # the truth model the matrix itself runs
    seen = []
    monkeypatch.setattr(matrix, 'run_cells', lambda *a, **k: seen.append(tm.RATE_HZ) or [])
    monkeypatch.setattr(matrix, 'print_table', lambda *a, **k: None)
    monkeypatch.setattr(tm, 'RATE_HZ', tm.RATE_HZ)      # restored after the test
    assert matrix.main(['--truth-hz', '20000', '--cases', 'clean', '--classes', 'smooth',
                        '--seeds', '1']) == 0
    assert seen == [20000.0]


def test_the_rate_is_raised_again_when_the_effects_found_need_it(matrix, monkeypatch):
    # stribeck_exp smooth, seed 2, the truth at 20 kHz: the declared model's sampling asked
    # for 2 kHz, but the 636 kN Stribeck spikes found then last a few milliseconds, and
    # their own sampling at 2 kHz left a residual a -16 g mass_error took (named beside
    # stribeck: false). With the effects found in the model the rate is chosen again
    monkeypatch.setattr(matrix.tm, 'RATE_HZ', 20000.0)
    (r,) = matrix.run_cells([('stribeck_exp', 'smooth')], range(2, 3))
    assert r['verdict'] == 'right' and r['named'] == ['stribeck'], r
    assert r['sim_rate_hz'] > 2000.0, r
    assert r['misaligned'] == [], r
