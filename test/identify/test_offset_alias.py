"""Issue 24 §6 on the rig: a constant offset force is one finding with the gravity of an
inclined axis while every run moves the same mass, and separates from it when the loads
differ; with asymmetric Coulomb friction it stays one power shape (the exact alias)."""
from pathlib import Path

import pytest

from feed_axis_energy.identify import analyze_campaign, Instrument, make_campaign, RigConfig
from feed_axis_energy.identify.rig import EffectSpec
from feed_axis_energy.measured import load_campaign

ROOT = Path(__file__).resolve().parents[2]


def _analyze(tmp_path, loads):
    cfg = RigConfig(machine=ROOT / 'config' / 'demonstrator.yaml', loads_kg=loads,
                    feeds_mm_s=(100.0, 300.0, 500.0),
                    effects=(EffectSpec('offset_force', {'f0_n': 40.0}),),
                    instrument=Instrument(noise_w=1.5), seed=1)
    return analyze_campaign(load_campaign(make_campaign(tmp_path / 'c', cfg)))


@pytest.mark.parametrize('loads, gravity_in_group', [((0.0,), True),
                                                     ((0.0, 22.711), False)])
def test_offset_force_and_gravity_separate_only_when_the_mass_varies(
        tmp_path, loads, gravity_in_group):
    res = _analyze(tmp_path, loads)
    assert [e.id for e in res.effects] == ['offset_force']
    assert res.effects[0].values()['f0_n'] == pytest.approx(40.0, rel=0.05)
    (group,) = res.ambiguous
    members = {m.split('@')[0] for m in group.members}
    assert 'coulomb' in members          # F+ = F0, F- = -F0: the same power everywhere
    assert ('gravity' in members) == gravity_in_group


def test_analyze_prints_both_readings_of_an_asymmetric_coulomb(tmp_path):
    import subprocess
    import sys
    cfg = RigConfig(machine=ROOT / 'config' / 'demonstrator.yaml', loads_kg=(0.0,),
                    feeds_mm_s=(100.0, 300.0, 500.0),
                    effects=(EffectSpec('coulomb', {'f_pos_n': 60.0, 'f_neg_n': 20.0}),),
                    instrument=Instrument(noise_w=1.5), seed=2)
    manifest = make_campaign(tmp_path / 'c', cfg)
    r = subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'analyze', str(manifest),
                        '--quiet'], capture_output=True, text=True, timeout=600,
                       env={'PYTHONPATH': str(ROOT), 'PATH': '/usr/bin:/bin'})
    assert r.returncode == 0, r.stderr
    line = next(x for x in r.stdout.splitlines() if 'symmetric friction' in x)
    # F+ 60, F- 20: symmetric 40 N + a constant 20 N (fitted within a few percent)
    words = line.split()
    fc = float(words[words.index('friction') + 1])
    f0 = float(words[words.index('(offset_force)') + 1])
    assert fc == pytest.approx(40.0, rel=0.1) and f0 == pytest.approx(20.0, rel=0.1)
