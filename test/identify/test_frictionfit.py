"""The richer friction fit on a force trace (issue 24 §5): an independent truth stand
(``bench/truth_stand.py``: its own physics, asymmetric Coulomb and viscous friction, an
exponential Stribeck excess and a constant offset force), recovery within 5 %, the augmented
machine, a linear (direct) stand, and the errors."""
from dataclasses import replace
import json
from pathlib import Path
import subprocess
import sys

import numpy as np
from bench_modules import load_bench
import pytest
import yaml

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.identify import fit_drive_friction, machine_with_friction_fits
from feed_axis_energy.machine import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.measured import load_campaign, load_run

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def stand():
    return load_bench('truth_stand')


@pytest.fixture(scope='module')
def campaign(stand, tmp_path_factory):
    return stand.write_campaign(tmp_path_factory.mktemp('stand') / 'c', seed=3)


@pytest.fixture(scope='module')
def fit(stand, campaign):
    return stand.fit_campaign(campaign)


def test_truth_force_by_hand(stand):
    truth = stand.StandTruth()
    # cruising at +0.1 m/s: F+ + c+ v + Stribeck tail + offset; at rest only the offset
    f = stand.true_force(np.array([0.1, -0.1, 0.0]), np.zeros(3), truth)
    tail = 12.0 * np.exp(-0.1 / 0.004)
    np.testing.assert_allclose(f, [30.0 + 6.0 + tail + 15.0, -(22.0 + 5.0) - tail + 15.0,
                                   15.0])


def test_recovers_mass_friction_and_offset_within_5_percent(stand, fit):
    assert fit.ok, fit.message
    for name, (got, want) in stand.recovery(fit, stand.StandTruth()).items():
        assert got == pytest.approx(want, rel=0.05), name
    # the split of the alias: the moving samples see offset + Coulomb asymmetry together
    assert fit.moving_offset_n == pytest.approx(fit.offset_n + fit.coulomb_asymmetry_n)


def test_validation_beats_the_symmetric_fit(stand, campaign, fit):
    ref = stand.fit_reference(campaign)
    val = stand.validation(fit, stand.StandTruth(), seed=3, reference=ref)
    assert val['rmse_w'] <= 0.95 * val['reference_rmse_w']
    assert abs(val['energy_error_pct']) <= 2.0


def test_augmented_machine_round_trips_with_the_catalog_effects(campaign, fit, tmp_path):
    machine = load_machine(load_campaign(campaign).machine)
    out = machine_with_friction_fits(machine, {'X': fit})
    ids = {e.id: e.values for e in out.effects}
    assert ids['offset_force']['f0_n'] == pytest.approx(fit.offset_n)
    assert ids['coulomb']['f_pos_n'] == pytest.approx(-ids['coulomb']['f_neg_n'])
    assert ids['stribeck']['delta'] == fit.stribeck_delta
    assert out.axis('X').loss.coulomb_n == pytest.approx(fit.coulomb_n)
    path = tmp_path / 'fitted.yaml'
    path.write_text(yaml.safe_dump(machine_to_dict(out), sort_keys=False))
    assert load_machine(path) == out
    # applied twice: the effects of the axis are replaced, not duplicated
    again = machine_with_friction_fits(out, {'X': fit})
    assert len(again.effects) == len(out.effects)


def test_without_resting_samples_the_constant_is_reported_whole(stand, campaign):
    c = load_campaign(campaign)
    runs = [load_run(s) for s in c.runs if s.role == 'calibrate']
    machine = load_machine(c.machine)
    moving = []
    for run in runs:
        keep = np.abs(run.velocity_m_s[:, 0]) > 0.0
        moving.append(replace(run, t=run.t[keep], velocity_m_s=run.velocity_m_s[keep],
                              acceleration_m_s2=run.acceleration_m_s2[keep],
                              position_m=run.position_m[keep],
                              extra={k: ({a: v[keep] for a, v in d.items()}
                                         if isinstance(d, dict) else d)
                                     for k, d in run.extra.items()}))
    f = fit_drive_friction(moving, machine=machine, measures='force', gains={'X': 0.01 / (
        2 * np.pi)}, velocity='actual')['X']
    assert f.ok and f.coulomb_asymmetry_n is None and f.n_rest == 0
    assert f.offset_n == pytest.approx(15.0 + 4.0, rel=0.05)
    assert 'asymmetric Coulomb friction would look the same' in f.message


def test_direct_linear_stand(stand, tmp_path):
    # a linear motor: no screw, the force is the torque (gain 1), the mass is the carriage
    truth = stand.StandTruth(rotor_kg_m2=0.0)
    manifest = stand.write_campaign(tmp_path / 'lin', seed=5, truth=truth, direct=True)
    machine = load_machine(load_campaign(manifest).machine)
    assert machine.axis('X').direct
    f = stand.fit_campaign(manifest)
    for name, (got, want) in stand.recovery(f, truth).items():
        assert got == pytest.approx(want, rel=0.05), name
    out = machine_with_friction_fits(machine, {'X': f})
    assert machine_from_dict(machine_to_dict(out), file='copy') == out


def test_power_trace_and_unknown_kt_are_refused(campaign):
    c = load_campaign(campaign)
    runs = [load_run(c.runs[0])]
    machine = load_machine(c.machine)
    with pytest.raises(ConfigError, match='needs a drive trace'):
        fit_drive_friction(runs, machine=machine, measures='shaft', gains={})
    with pytest.raises(ConfigError, match='torque constant'):
        fit_drive_friction(runs, machine=machine, measures='force', gains={'X': None})


def _cli(*args):
    return subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'fit-loss', *args],
                          capture_output=True, text=True, timeout=300,
                          env={'PYTHONPATH': str(ROOT), 'PATH': '/usr/bin:/bin'})


def test_cli_json_and_out_machine(campaign, tmp_path):
    out = tmp_path / 'fitted.yaml'
    r = _cli(str(campaign), '--method', 'samples', '--friction', 'extended', '--json',
             '--out-machine', str(out))
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert doc['friction'] == 'extended'
    x = doc['fits']['X']
    for key in ('effective_mass_kg', 'coulomb_n', 'offset_n', 'coulomb_asymmetry_n',
                'viscous_n_s_m', 'viscous_asymmetry_n_s_m', 'stribeck_n', 'stribeck_v_m_s'):
        assert np.isfinite(x[key]), key
    assert doc['out_machine'] == str(out) and load_machine(out).effects
    bad = _cli(str(campaign), '--friction', 'extended')
    assert bad.returncode == 1 and '--method samples' in bad.stderr
