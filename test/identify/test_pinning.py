"""Offsets that cannot be pinned down: left out of the fit, pinned anew with the effects found.

Truth: the paper's reciprocating program on an axis inclined by 15 deg that the declared
machine calls horizontal (m*g*sin 15 deg = 30-88 N), recorded only over the middle of each
run (the meter started 2.5 s late and stopped 3 s early), so that no record edge tells the
strokes apart and on the faster runs a lag one stroke off fits the declared model as well
as the true one (issue 24). The truth's offsets (truth.json) are read only to check.

The rig's records hold the carriage's position and velocity too; the pinning rules are for
records of the power alone, so those columns are dropped from the manifest here, except in
the last test, where the motion pins every run from the start (issue 24 s1).
"""
import json
from pathlib import Path

import pytest
import yaml

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.identify import analyze_campaign, make_campaign, parse_effects, RigConfig
from feed_axis_energy.identify.rig import Instrument
from feed_axis_energy.measured import compare_campaign, load_campaign

ROOT = Path(__file__).resolve().parents[2]
MACHINE = ROOT / 'config' / 'demonstrator.yaml'
SIN_15 = 0.2588


def _campaign(tmp_path: Path, feeds, loads=(0.0, 17.336, 22.711), window=(2.5, 3.0), *,
              motion: bool = False):
    cfg = RigConfig(machine=MACHINE, loads_kg=loads, feeds_mm_s=feeds,
                    effects=parse_effects(f'gravity=sin_theta:{SIN_15}'),
                    instrument=Instrument(noise_w=2.0), seed=1, record_window_s=window)
    manifest = make_campaign(tmp_path / 'rig', cfg)
    if not motion:
        doc = yaml.safe_load(manifest.read_text(encoding='utf-8'))
        for axis in doc['defaults']['axes'].values():
            axis.pop('position', None)
            axis.pop('velocity', None)
        manifest.write_text(yaml.safe_dump(doc, sort_keys=False), encoding='utf-8')
    truth = json.loads((tmp_path / 'rig' / 'truth.json').read_text())
    return load_campaign(manifest), {r['name']: r['offset_s'] for r in truth['runs']}


def test_stroke_off_runs_are_left_out_then_pinned_with_gravity(tmp_path):
    campaign, truth = _campaign(tmp_path, feeds=(100.0, 400.0, 500.0))
    baseline = compare_campaign(campaign)
    statuses = {r.name: r.offset.status for r in baseline.runs}
    # the premise: the declared model cannot pin the fast runs (a stroke-off lag fits as well)
    assert sum(s != 'ok' for s in statuses.values()) >= 3, statuses
    res = analyze_campaign(campaign)
    found = {e.id: e for e in res.effects}
    assert set(found) == {'gravity'}, res.message
    assert found['gravity'].values()['sin_theta'] == pytest.approx(SIN_15, rel=0.02)
    assert res.pin_rounds >= 2
    assert res.left_out == ()
    # every run ends up compared at its true offset (a quarter of the 50 ms meter period)
    for a in res.augmented:
        assert a['offset']['used_s'] == pytest.approx(truth[a['name']], abs=0.0125), a['name']
    # every run was fitted (held out in its fold)
    assert len(res.runs) == len(truth)


def test_too_few_pinned_runs_is_an_error_naming_them(tmp_path):
    # only fast runs: none can be pinned against the declared model
    campaign, _ = _campaign(tmp_path, feeds=(500.0,), loads=(0.0, 22.711))
    statuses = [r.offset.status for r in compare_campaign(campaign).runs]
    if statuses.count('ok') >= 2:
        pytest.fail(f'premise: expected fewer than 2 pinned runs, got {statuses}')
    with pytest.raises(ConfigError, match='time offset is pinned down') as err:
        analyze_campaign(campaign)
    assert 'f500_load0kg' in str(err.value) and 'left out' in str(err.value)


def test_record_window_is_checked(tmp_path):
    with pytest.raises(ConfigError, match='record window'):
        RigConfig(machine=MACHINE, record_window_s=(-1.0, 0.0))
    with pytest.raises(ConfigError, match='fewer than 2'):
        _campaign(tmp_path, feeds=(500.0,), loads=(0.0,), window=(500.0, 0.0))


def test_the_measured_motion_pins_the_stroke_off_runs_at_once(tmp_path):
    # the same records with the carriage's velocity: its sign tells the strokes apart
    campaign, truth = _campaign(tmp_path, feeds=(100.0, 400.0, 500.0), motion=True)
    baseline = compare_campaign(campaign)
    for r in baseline.runs:
        assert r.offset.anchor == 'motion' and r.offset.status == 'ok', r.offset.message
        assert r.offset.motion_s == pytest.approx(truth[r.name], abs=0.0125), r.name
    res = analyze_campaign(campaign)
    assert {e.id for e in res.effects} == {'gravity'}, res.message
    assert {e.id: e for e in res.effects}['gravity'].values()['sin_theta'] == pytest.approx(
        SIN_15, rel=0.02)
    assert res.left_out == ()
    for a in res.augmented:
        assert a['offset']['used_s'] == pytest.approx(truth[a['name']], abs=0.0125), a['name']
