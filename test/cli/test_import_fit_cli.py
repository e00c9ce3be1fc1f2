"""The ``import`` and ``fit-loss`` commands, run as a user runs them."""
import json
import math
from pathlib import Path
import subprocess
import sys

import numpy as np
from numpy.testing import assert_allclose
import pytest
import yaml

from feed_axis_energy.cli import main
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.csvload import load_run

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / 'test' / 'fixtures' / 'measured'
SAMPLES = ROOT / 'bags' / 'umich_samples.yaml'


@pytest.mark.parametrize('command', ['import', 'fit-loss'])
def test_help_exits_zero(command):
    proc = subprocess.run([sys.executable, '-m', 'feed_axis_energy', command, '--help'],
                          cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0
    assert 'usage: feed-axis-energy ' + command in proc.stdout


def test_import_writes_bags_and_manifest(tmp_path, capsys):
    out = tmp_path / 'bags'
    assert main(['import', str(FIXTURES / 'campaign.yaml'), '--out', str(out), '--json',
                 '--quiet']) == 0
    report = json.loads(capsys.readouterr().out)
    assert [r['name'] for r in report['runs']] == ['a', 'b']
    campaign = load_campaign(report['manifest'])
    run = load_run(campaign.run('b'))
    assert_allclose(run.t, [0.0, 0.05, 0.10, 0.15])
    # a second import into the same place is refused and changes nothing
    assert main(['import', str(FIXTURES / 'campaign.yaml'), '--out', str(out),
                 '--quiet']) == 1
    assert 'exists already' in capsys.readouterr().err
    assert main(['import', str(FIXTURES / 'campaign.yaml'), '--out', str(tmp_path / 'x'),
                 '--runs', 'nope']) == 1
    assert "no run 'nope'" in capsys.readouterr().err


def _campaign(tmp_path, feeds_mm_s, a=0.3, b=0.4, scatter=()):
    """A CSV campaign: one run per feed, strokes back and forth, power a·x^(1+b) when steady
    (times ``scatter[i]`` for the i-th feed, if given)."""
    runs = []
    for i, feed in enumerate(feeds_mm_s):
        v = np.concatenate([np.zeros(20), np.linspace(0, feed, 10), np.full(300, feed),
                            np.linspace(feed, 0, 10), np.zeros(20)])
        v = np.concatenate([v, -v])
        t = np.arange(v.shape[0]) * 0.01
        x = np.cumsum(v) * 0.01
        acc = np.gradient(v, t)
        p = a * np.abs(v) ** (1 + b) * (scatter[i] if scatter else 1.0) + 0.02 * acc * v
        rows = [f'{pi:.17g},{xi:.17g},{vi:.17g}' for pi, xi, vi in zip(p, x, v)]
        lines = ['P_W,X_mm,V_mm_s'] + rows
        (tmp_path / f'f{feed}.csv').write_text('\n'.join(lines) + '\n')
        runs.append({'name': f'f{feed}', 'data': f'f{feed}.csv'})
    doc = {'machine': str(ROOT / 'config' / 'demonstrator.yaml'),
           'defaults': {'load_kg': 0.0, 'period_s': 0.01, 'motion': {'from_data': 'actual'},
                        'axes': {'X': {'power': {'column': 'P_W', 'unit': 'W'},
                                       'position': {'column': 'X_mm', 'unit': 'mm'},
                                       'velocity': {'column': 'V_mm_s', 'unit': 'mm/s'}}}},
           'runs': runs}
    (tmp_path / 'c.yaml').write_text(yaml.safe_dump(doc))
    return tmp_path / 'c.yaml'


def test_fit_loss_writes_a_machine_that_loads(tmp_path, capsys):
    manifest = _campaign(tmp_path, [50, 150, 300])
    out = tmp_path / 'fitted.yaml'
    assert main(['fit-loss', str(manifest), '--json', '--out-machine', str(out)]) == 0
    report = json.loads(capsys.readouterr().out)
    fit = report['fits']['X']
    assert fit['status'] == 'ok' and fit['r2_space'].startswith('log-log')
    assert_allclose([fit['a'], fit['b']], [0.3, 0.4], rtol=1e-6)
    assert sorted(round(f) for f in fit['feeds_mm_s']) == [50, 150, 300]
    loss = load_machine(out).axis('X').loss
    assert_allclose([loss.a, loss.b], [fit['a'], fit['b']])
    # exact synthetic power: no scatter, so no uncertainty; the range is the steady feeds
    assert fit['b_se'] == pytest.approx(0.0, abs=1e-6)
    calibrated = load_machine(out).axis('X').loss_calibrated
    assert_allclose(calibrated.feed_mm_s, [50.0, 300.0], rtol=0.01)
    assert fit['calibrated']['feed_mm_s'] == list(calibrated.feed_mm_s)
    # the table form names the units, the uncertainties and the calibrated range
    assert main(['fit-loss', str(manifest)]) == 0
    text = capsys.readouterr().out
    assert 'W/(mm/s)' in text and '+-' in text and 'axis X: calibrated at 50-300 mm/s' in text


def test_fit_loss_with_too_few_feeds_exits_1_and_writes_nothing(tmp_path, capsys):
    manifest = _campaign(tmp_path, [50, 150])
    out = tmp_path / 'fitted.yaml'
    assert main(['fit-loss', str(manifest), '--out-machine', str(out)]) == 1
    err = capsys.readouterr().err
    assert 'insufficient' in err and '2 distinct feed' in err and 'not written' in err
    assert not out.exists()
    assert main(['fit-loss', str(manifest), '--min-feeds', '2', '--out-machine',
                 str(out)]) == 0


def test_fit_loss_samples_writes_loss_and_inertia(tmp_path, capsys):
    # power = Fc·|v| + cv·v² + M·a·v on every sample, M the effective mass of a motor inertia
    # J: the samples method must find Fc, cv and J and write them into a machine that loads
    demo = load_machine(ROOT / 'config' / 'demonstrator.yaml')
    spec = demo.axis('X')
    motor = 3.0e-4
    j = motor + spec.inertias.coupling_kg_m2 + spec.screw_inertia_kg_m2
    mass = spec.table_mass_kg + j * (2.0 * math.pi / spec.screw.lead_m) ** 2
    assert spec.rides_on is None and spec.inclination_deg == 0.0
    manifest = _campaign(tmp_path, [50, 150, 300], a=0.0)
    for csv in tmp_path.glob('f*.csv'):
        data = np.loadtxt(csv, delimiter=',', skiprows=1)
        v = data[:, 2] / 1000.0
        t = np.arange(v.size) * 0.01
        p = 20.0 * np.abs(v) + 80.0 * v * v + mass * np.gradient(v, t) * v
        rows = [f'{pi:.17g},{xi:.17g},{vi:.17g}' for pi, xi, vi in zip(p, data[:, 1], data[:, 2])]
        csv.write_text('\n'.join(['P_W,X_mm,V_mm_s'] + rows) + '\n')
    out = tmp_path / 'fitted.yaml'
    assert main(['fit-loss', str(manifest), '--method', 'samples', '--json', '--out-machine',
                 str(out)]) == 0
    report = json.loads(capsys.readouterr().out)
    fit = report['fits']['X']
    assert report['method'] == 'samples' and report['velocity'] == ['actual'] * 3
    assert fit['status'] == 'ok' and fit['inertia_fitted']
    assert_allclose([fit['coulomb_n'], fit['viscous_n_s_m'], fit['motor_kg_m2']],
                    [20.0, 80.0, motor], rtol=1e-6)
    axis = load_machine(out).axis('X')
    assert axis.loss.to_dict() == {'model': 'coulomb_viscous', 'coulomb_n': fit['coulomb_n'],
                                   'viscous_n_s_m': fit['viscous_n_s_m'], 'mu': 0.0}
    assert axis.inertias.motor_kg_m2 == fit['motor_kg_m2']
    assert_allclose(axis.loss_calibrated.feed_mm_s, [50.0, 300.0], rtol=0.01)
    # the table names every parameter with its unit; a second write is refused
    assert main(['fit-loss', str(manifest), '--method', 'samples', '--out-machine',
                 str(out)]) == 1
    captured = capsys.readouterr()
    assert 'exists' in captured.err
    assert main(['fit-loss', str(manifest), '--method', 'samples']) == 0
    text = capsys.readouterr().out
    assert 'coulomb [N]' in text and 'motor [kg m2]' in text and 'eff. mass [kg]' in text


@pytest.mark.skipif(not SAMPLES.is_file(), reason='sample bags not generated')
def test_fit_loss_on_the_sample_bags(capsys):
    assert main(['fit-loss', str(SAMPLES), '--json']) in (0, 1)
    report = json.loads(capsys.readouterr().out)
    assert set(report['fits']) == {'X', 'Y'}
    for fit in report['fits'].values():
        if fit['status'] != 'insufficient':
            assert math.isfinite(fit['r2_log'])


def test_fit_loss_writes_the_covariance_and_simulate_shows_the_uncertainty(tmp_path, capsys):
    manifest = _campaign(tmp_path, [50, 100, 150, 300], scatter=(1.04, 0.97, 1.02, 0.98))
    out = tmp_path / 'fitted.yaml'
    assert main(['fit-loss', str(manifest), '--json', '--out-machine', str(out)]) == 0
    fit = json.loads(capsys.readouterr().out)['fits']['X']
    cov = load_machine(out).axis('X').loss_covariance
    assert cov.params == ('a', 'b') and cov.units == ('W/(mm/s)/(mm/s)^b', '1')
    # (ln a, b) of the log-log fit taken to (a, b): var(a) = a²·var(ln a)
    (c00, c01), (_, c11) = fit['cov_ln_a_b']
    a = fit['a']
    assert_allclose(cov.array(), [[a * a * c00, a * c01], [a * c01, c11]], rtol=1e-12)
    assert_allclose(math.sqrt(cov.matrix[0][0]), fit['a_se'], rtol=1e-12)
    assert_allclose(math.sqrt(cov.matrix[1][1]), fit['b_se'], rtol=1e-12)
    assert main(['fit-loss', str(manifest)]) == 0
    assert 'covariance of a and b as loss_covariance' in capsys.readouterr().out
    program = str(ROOT / 'config' / 'programs' / 'demonstrator_f300.nc')
    assert main(['simulate', program, '--machine', str(out), '--json', '--quiet']) == 0
    summary = json.loads(capsys.readouterr().out)
    u = summary['energy_uncertainty']
    assert u['axes'] == ['X'] and u['energy_sd_j']['total'] > 0.0
    assert_allclose(u['relative_pct'],
                    100.0 * u['energy_sd_j']['total'] / summary['energy_j']['total'])
    assert main(['simulate', program, '--machine', str(out), '--quiet']) == 0
    text = capsys.readouterr().out
    assert 'energy uncertainty: ±' in text and '% of the total)' in text
    # the machine as shipped has no covariance: nothing is shown
    assert main(['simulate', program, '--quiet']) == 0
    assert 'uncertainty' not in capsys.readouterr().out
    # compare names each run's uncertainty from the covariance, and only where it is known
    assert main(['compare', str(manifest), '--machine', str(out)]) == 0
    text = capsys.readouterr().out
    line = [ln for ln in text.splitlines() if ln.startswith('energy uncertainty')]
    assert len(line) == 1 and line[0].count('±') == 4 and 'f50 ±' in line[0]
    assert main(['compare', str(manifest)]) == 0
    assert 'energy uncertainty' not in capsys.readouterr().out


def test_fit_loss_samples_writes_the_covariance_of_its_loss(tmp_path, capsys):
    manifest = _campaign(tmp_path, [50, 100, 150, 300], scatter=(1.04, 0.97, 1.02, 0.98))
    out = tmp_path / 'fitted.yaml'
    assert main(['fit-loss', str(manifest), '--method', 'samples', '--json',
                 '--out-machine', str(out)]) == 0
    fit = json.loads(capsys.readouterr().out)['fits']['X']
    cov = load_machine(out).axis('X').loss_covariance
    assert cov.params == ('coulomb_n', 'viscous_n_s_m') and cov.units == ('N', 'N*s/m')
    assert_allclose(np.sqrt(np.diag(cov.array())), [fit['coulomb_se'], fit['viscous_se']],
                    rtol=1e-12)
