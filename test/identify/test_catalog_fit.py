"""Bounded fits, physical forms and every candidate's fate, on truth rigs with known effects."""
from dataclasses import replace
import json
import math
from pathlib import Path

import numpy as np
import pytest

from feed_axis_energy.effects.catalog import EFFECTS
from feed_axis_energy.identify.analyze import analyze_campaign
from feed_axis_energy.identify.results import AnalyzeOptions
from feed_axis_energy.identify.consistency import FATES
from feed_axis_energy.identify.selection import at_bounds, Design, solve_normal
from feed_axis_energy.machine.declared import DeclaredEffect
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.identify.rig import Instrument, parse_effects
from feed_axis_energy.identify.rig import make_campaign, RigConfig

ROOT = Path(__file__).resolve().parents[2]
MACHINE = ROOT / 'config' / 'demonstrator.yaml'


def _campaign(tmp_path: Path, effects: str, *, loads=(0.0, 22.711), feeds=(150.0, 300.0, 450.0),
              noise_w=1.0, seed=1, cycles=1):
    cfg = RigConfig(machine=MACHINE, loads_kg=loads, feeds_mm_s=feeds, cycles=cycles,
                    effects=parse_effects(effects), instrument=Instrument(noise_w=noise_w),
                    seed=seed)
    return load_campaign(make_campaign(tmp_path / 'rig', cfg))


# ----------------------------------------------------------------------------- solver

def test_bounded_solve_clips_a_negative_coefficient_to_zero() -> None:
    # y = -3 x1 + 2 x2 exactly: unconstrained gives (-3, 2); with x1 >= 0 the best is
    # (0, 2 + (-3) * <x1,x2>/<x2,x2>) by hand for the reduced problem
    rng = np.random.default_rng(0)
    x = rng.normal(size=(200, 2))
    y = -3.0 * x[:, 0] + 2.0 * x[:, 1]
    g, b = x.T @ x, x.T @ y
    free = solve_normal(g, b)
    np.testing.assert_allclose(free, [-3.0, 2.0], rtol=1e-10)
    bounded = solve_normal(g, b, np.array([0.0, -math.inf]), np.array([math.inf, math.inf]))
    want2 = float(x[:, 1] @ y) / float(x[:, 1] @ x[:, 1])
    np.testing.assert_allclose(bounded, [0.0, want2], rtol=1e-8, atol=1e-12)
    assert at_bounds(bounded, np.array([0.0, -math.inf]), np.array([math.inf, math.inf])) == [
        'lower', None]


def test_bounded_solve_of_collinear_columns_takes_the_smallest_solution() -> None:
    # iron's eddy term k_e ω² and viscous c v² are the same column on a screw axis (ω = 2π v
    # / lead), computed differently; iron's hysteresis k_h |ω| is bounded at 0 and the data
    # push it below, so the bounded solver runs. Without a rule for the free direction it
    # stopped anywhere along it: k_e and c of 1e12 and opposite signs (seen on a truth cell)
    rng = np.random.default_rng(0)
    lower, upper = np.array([0.0, 0.0, -math.inf]), np.full(3, math.inf)
    for _ in range(50):
        v = rng.uniform(-0.5, 0.5, 2000)
        x = np.column_stack([np.abs(v), v * v, (2.0 * math.pi * v / 0.01) ** 2])
        y = 3.0 * v * v - 0.1 * np.abs(v) + rng.normal(0.0, 0.01, v.size)
        theta = solve_normal(x.T @ x, x.T @ y, lower, upper)
        assert theta[0] == pytest.approx(0.0, abs=1e-9)
        assert np.max(np.abs(theta)) < 10.0, theta
        best = np.linalg.lstsq(x[:, 1:], y, rcond=None)[0]
        np.testing.assert_allclose(x @ theta, x[:, 1:] @ best, atol=1e-6)


def test_design_fit_respects_the_block_bounds() -> None:
    rng = np.random.default_rng(1)
    cols = [rng.normal(size=(50, 1)) for _ in range(3)]
    design = Design([-2.0 * c[:, 0] + rng.normal(scale=0.01, size=50) for c in cols])
    free = design.add_block(('a', 'X'), {}, ('k',), cols)
    bounded = design.add_block(('b', 'X'), {}, ('k',), cols, bounds=([0.0], [math.inf]))
    assert design.fit(free.cols, range(3))[0] == pytest.approx(-2.0, rel=0.01)
    assert design.fit(bounded.cols, range(3))[0] == 0.0


# ----------------------------------------------------------------------------- analyze

def test_negative_copper_is_never_reported_as_found(tmp_path) -> None:
    # The declared model holds copper losses k = 3 W/(N·m)² that the truth does not have:
    # the residual is -3·M², an unconstrained fit gives k ≈ -3. Bounded, it is not a finding.
    campaign = _campaign(tmp_path, 'none')
    declared = load_machine(campaign.machine)
    machine = replace(declared, effects=(DeclaredEffect('copper', None, (('k_w_nm2', 3.0),)),))
    res = analyze_campaign(campaign, machine=machine)
    for e in res.effects:
        for p in e.params:
            lo, hi = next(q.bounds for q in EFFECTS[e.id].params if q.name == p.name)
            assert lo <= p.value <= hi, (e.id, p.name, p.value)
        assert e.id != 'copper' or e.values()['k_w_nm2'] >= 0.0
    copper = [f for f in res.candidates if f.effect == 'copper']
    assert copper and all(f.fate != 'accepted' for f in copper), copper


def test_gravity_is_one_angle_across_loads(tmp_path) -> None:
    # truth: an axis inclined by 2 degrees, declared horizontal; the weight differs per load
    s = math.sin(math.radians(2.0))
    campaign = _campaign(tmp_path, f'gravity=sin_theta:{s}', loads=(0.0, 17.336, 22.711))
    res = analyze_campaign(campaign)
    found = {e.id: e for e in res.effects}
    assert 'gravity' in found, res.message
    assert found['gravity'].values()['sin_theta'] == pytest.approx(s, rel=0.05)
    assert res.status == 'effects', res.message


def test_thermal_warm_up_time_constant_is_found(tmp_path) -> None:
    # warm-up of 40 N with tau = 20 s over runs of several strokes (the runs last ~10-30 s)
    campaign = _campaign(tmp_path, 'thermal_drift=rate_n_s:2.0,tau_s:20', cycles=3)
    res = analyze_campaign(campaign)
    found = {e.id: e for e in res.effects}
    assert 'thermal_drift' in found, res.message
    values = found['thermal_drift'].values()
    assert values['rate_n_s'] * values['tau_s'] == pytest.approx(40.0, rel=0.25)
    assert values['tau_s'] == pytest.approx(20.0, rel=0.5)


def test_rough_spot_is_localised(tmp_path) -> None:
    # a 30 N rough spot centred at x = 150 mm, 30 mm spacing (about 42 mm wide at half height)
    campaign = _campaign(tmp_path, 'position_friction=c6_n:30,spacing_m:0.03', noise_w=1.0,
                         loads=(0.0, 22.711), feeds=(150.0, 300.0, 450.0))
    res = analyze_campaign(campaign)
    found = {e.id: e for e in res.effects}
    assert 'position_friction' in found, res.message
    assert res.status == 'effects', res.message
    assert res.after.rmse_w < 0.8 * res.before.rmse_w


def test_every_candidate_has_a_fate_in_the_json(tmp_path) -> None:
    res = analyze_campaign(_campaign(tmp_path, 'standby=p0_w:20'))
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    keys = {(c['effect'], c['axis']) for c in d['candidates']}
    assert keys == {(e, 'X') for e in EFFECTS}
    assert all(c['fate'] in FATES and c['reason'] for c in d['candidates'])
    assert [c['effect'] for c in d['candidates'] if c['fate'] == 'accepted'] == ['standby']
    assert d['consistency'] == {'rounds': 1, 'cap_reached': False}


def test_round_cap_is_a_stated_verdict_not_an_emptied_selection(tmp_path) -> None:
    # max_rounds=1 with a strict consistency limit: whatever is inconsistent in the one
    # round is excluded, the consistent rest is kept, and the message says the cap was hit
    campaign = _campaign(tmp_path, 'load_friction=mu:0.2,standby=p0_w:20')
    strict = AnalyzeOptions(max_rounds=1, max_heterogeneity=-1.0, heterogeneity_alpha=1.1)
    res = analyze_campaign(campaign, options=strict)
    assert res.cap_reached
    assert 'cap of 1 rounds' in res.message
    fates = {f.fate for f in res.candidates}
    assert 'excluded_inconsistent' in fates
    assert all(f.reason for f in res.candidates)


def test_a_column_the_training_runs_barely_touch_is_not_fitted() -> None:
    # run 0 holds the column, run 1 only its far tail (1e-140): fitted on run 1 alone the
    # coefficient stays 0 instead of y/1e-140
    rng = np.random.default_rng(2)
    c0 = rng.normal(size=(40, 1))
    c1 = np.full((40, 1), 1e-140)
    design = Design([2.0 * c0[:, 0], rng.normal(size=40)])
    block = design.add_block(('position_friction', 'X'), {}, ('c1_n',), [c0, c1])
    assert design.fit(block.cols, [1])[0] == 0.0
    assert design.fit(block.cols, [0])[0] == pytest.approx(2.0)
    assert all(math.isfinite(v) for v in design.heldout_mse(block.cols,
                                                            [([0], [1]), ([1], [0])]).values())
