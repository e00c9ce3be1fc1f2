"""A tiny subset of ``bench/detection_power.py`` (the study itself runs outside CI)."""
import importlib.util
import math
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


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
    rms = study.unit_rms_w('load_friction')
    params = study.scaled_params('load_friction', 4.0, 1.5, rms)
    named, others, aliasing = study.trial('load_friction', params, seed=1, noise_w=1.5,
                                          work=tmp_path)
    assert named and others == [] and aliasing == []
    named, others, aliasing = study.trial(None, None, seed=1, noise_w=1.5, work=tmp_path)
    assert not named and others == [] and aliasing == []
    assert math.isfinite(rms)
