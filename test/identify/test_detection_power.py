"""A tiny subset of ``bench/detection_power.py`` (the study itself runs outside CI)."""
import importlib.util
import math
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def study():
    spec = importlib.util.spec_from_file_location('fae_bench_detection',
                                                  ROOT / 'bench' / 'detection_power.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_scaling_gives_the_requested_rms(study):
    # the power is linear in mu: twice the size is twice mu; RMS at the example is positive
    rms = study.unit_rms_w('load_friction')
    assert rms > 0.0
    one = study.scaled_params('load_friction', 1.0, 1.5, rms)
    two = study.scaled_params('load_friction', 2.0, 1.5, rms)
    assert two['mu'] == pytest.approx(2.0 * one['mu'])
    assert one['mu'] == pytest.approx(0.05 * 1.5 / rms)
    # beyond the physical bounds: refused, not run
    assert study.scaled_params('gravity', 1e6, 1.5, study.unit_rms_w('gravity')) is None


def test_a_clearly_detectable_effect_is_named_and_a_clean_campaign_gets_nothing(
        study, tmp_path):
    # standby (a constant power, also at rest) has no other form in the catalog: named alone
    rms = study.unit_rms_w('standby')
    params = study.scaled_params('standby', 4.0, 1.5, rms)
    o = study.trial('standby', params, seed=1, noise_w=1.5, work=tmp_path)
    assert o.named and not o.group and o.false == () and o.aliasing == ()
    o = study.trial(None, None, seed=1, noise_w=1.5, work=tmp_path)
    assert not o.named and not o.group and o.false == () and o.aliasing == ()
    assert math.isfinite(rms)


def test_iron_is_one_ambiguous_finding_never_a_wrong_effect(study, tmp_path):
    # iron's power k_h|w| + k_e w² is symmetric coulomb plus viscous: before the ambiguity
    # step (20 seeds) coulomb or position_friction was named beside or instead of it in 5-10
    # of 20 seeds. Now never a wrong effect; iron is reported as one ambiguous finding, or
    # nothing is named when a meter gain (analyze step 6) fits as well (seed 1 here: iron's
    # shape is close to a scale of the demonstrator's loss power, docs/analyze.md Limits)
    params = study.scaled_params('iron', 2.0, 1.5, study.unit_rms_w('iron'))
    outcomes = [study.trial('iron', params, seed=seed, noise_w=1.5, work=tmp_path)
                for seed in (1, 2, 3)]
    for o in outcomes:
        assert o.false == () and o.aliasing == (), o
        assert not o.named, o
    assert sum(o.group for o in outcomes) >= 2, outcomes


def test_score_counts_groups(study):
    # a result-like object: iron selected, in a group with coulomb and viscous; a separate
    # copper effect outside the group is a false attribution
    class G:
        members = ('iron@X', 'coulomb@X', 'viscous@X')
        selected = ('iron@X',)

    class E:
        def __init__(self, i):
            self.id, self.axis, self.aliases = i, 'X', ()

        def values(self):
            return {}

    class R:
        axes = ('X',)
        ambiguous = (G,)
        effects = (E('iron'), E('copper'))

    o = study.score(R, 'viscous')
    assert o.group and not o.named and o.false == ('copper',)
    o = study.score(R, 'standby')
    assert not o.group and o.false == ('group(iron@X, coulomb@X, viscous@X)', 'copper')
