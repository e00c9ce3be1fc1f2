"""The ``feed-axis-energy compare`` command, run as a user runs it."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path
import subprocess
import sys

import pytest

from feed_axis_energy.cli import main

ROOT = Path(__file__).resolve().parents[2]
_HELPER = ROOT / 'test' / 'measured' / 'test_compare.py'


def _run(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'feed_axis_energy', *argv], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


@pytest.fixture(scope='module')
def manifest(tmp_path_factory) -> Path:
    spec = importlib.util.spec_from_file_location('_synthetic_campaign', _HELPER)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.write_campaign(tmp_path_factory.mktemp('campaign'), [
        {'name': 'a', 'load_kg': 0.0, 'offset_ms': 300, 'noise_w': 0.2, 'role': 'calibrate'},
        {'name': 'b', 'load_kg': 17.336, 'offset_ms': 150, 'factor': 1.1, 'noise_w': 0.2,
         'role': 'validate'},
    ])


def test_help_exits_zero():
    proc = _run('compare', '--help')
    assert proc.returncode == 0
    assert 'usage: feed-axis-energy compare' in proc.stdout
    for option in ('--json', '--report', '--runs', '--max-lag-s', '--quiet'):
        assert option in proc.stdout


def test_json_keys_and_values(manifest, capsys):
    assert main(['compare', str(manifest), '--json', '--quiet', '--max-lag-s', '1']) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) == {'campaign', 'manifest', 'machine', 'machine_file', 'max_lag_s', 'runs',
                        'groups', 'warnings', 'residual_by_state', 'loss_range_warnings'}
    assert out['max_lag_s'] == 1.0 and out['warnings'] == []
    assert out['loss_range_warnings'] == []     # the machine records no calibrated range
    run_b = out['runs'][1]
    assert set(run_b) == {'name', 'role', 'load_kg', 'data_file', 'motion_source', 'axes',
                          'window_s', 'duration_meas_s', 'duration_sim_s', 'excluded_rows',
                          'stamp', 'filter_s', 'clock_ppm', 'sim_step_error', 'instrument',
                          'instrument_check',
                          'residual_by_state',
                          'offset', 'work_offset', 'metrics', 'quantity'}
    # what the planner's sampling changes in the meter's readings, per axis [W]: small
    # against the signal, never NaN
    step = run_b['sim_step_error']
    assert set(step) == set(run_b['axes']) == {'X', 'Y'}
    for axis, err in step.items():
        assert 0.0 <= err < 0.01 * run_b['metrics'][axis]['rmse_w'] + 0.01, (axis, err)
    # positions written from the program's own simulation: no work offset between them
    w = run_b['work_offset']
    assert w['status'] == 'ok' and w['declared_m'] is None
    assert all(abs(v) < 1e-6 for v in w['found_m'].values())
    # a power run: the quantity block in W, its RMSE the same as the Table-1 one
    q = run_b['quantity']
    assert set(q) == {'measures', 'unit', 'column', 'metrics', 'sign_check'}
    assert (q['measures'], q['unit'], q['column']) == ('shaft', 'W', 'power')
    assert q['metrics']['X']['rmse_w'] == pytest.approx(run_b['metrics']['X']['rmse_w'])
    assert set(out['groups'][0]) == {'load_kg', 'runs', 'metrics', 'quantity_metrics'}
    assert run_b['offset']['used_s'] == pytest.approx(0.150, abs=0.002)
    assert run_b['metrics']['total']['avg_pct_error_pct'] == pytest.approx(
        100.0 * (1.0 - 1.0 / 1.1), abs=0.25)
    assert [g['load_kg'] for g in out['groups']] == [0.0, 17.336]


def test_table_report_and_selection(manifest, tmp_path, capsys):
    report = tmp_path / 'rep'
    assert main(['compare', str(manifest), '--runs', 'b', '--report', str(report),
                 '--quiet', '--max-lag-s', '1']) == 0
    out = capsys.readouterr().out
    assert 'per run' in out and 'per load' in out and 'avg dP [%]' in out
    lines = [ln for ln in out.splitlines() if ln.startswith(('a ', 'b '))]
    assert len(lines) == 1 and lines[0].split()[0] == 'b'
    assert f'report: {report / "index.html"}' in out
    assert not list(report.glob('*.png'))          # plots embedded in the page
    assert (report / 'index.html').read_text().count('<img src="data:image/png;base64,') == 3


def test_role_selection(manifest, capsys):
    assert main(['compare', str(manifest), '--role', 'validate', '--json', '--quiet',
                 '--max-lag-s', '1']) == 0
    assert [r['name'] for r in json.loads(capsys.readouterr().out)['runs']] == ['b']


@pytest.mark.parametrize('argv, expect', [
    (['compare', 'no/such/manifest.yaml'], 'no/such/manifest.yaml'),
    (['compare', '{manifest}', '--runs', 'zzz'], "no run named 'zzz'"),
    (['compare', '{manifest}', '--max-lag-s', '-1'], '--max-lag-s must be'),
    (['compare', '{manifest}', '--pct-floor', '1.5'], '--pct-floor must be'),
])
def test_bad_input_exits_1_naming_the_problem(manifest, argv, expect, capsys):
    argv = [a.replace('{manifest}', str(manifest)) for a in argv]
    assert main(argv + ['--quiet']) == 1
    err = capsys.readouterr().err
    assert err.startswith('error: ') and expect in err


def test_bad_manifest_in_a_subprocess(tmp_path):
    bad = tmp_path / 'campaign.yaml'
    bad.write_text('machine: m.yaml\nruns: []\n')
    proc = _run('compare', str(bad), '--quiet')
    assert proc.returncode == 1
    assert str(bad) in proc.stderr and proc.stdout == ''


def test_pct_floor_selects_the_samples_of_the_percentual_error(manifest, capsys):
    floors = {}
    for floor in ('0.05', '0.5'):
        assert main(['compare', str(manifest), '--json', '--quiet', '--pct-floor', floor]) == 0
        total = json.loads(capsys.readouterr().out)['runs'][1]['metrics']['total']
        floors[floor] = total
    # a higher floor keeps fewer samples; the floor in watts follows the fraction
    assert floors['0.5']['n_pct_samples'] < floors['0.05']['n_pct_samples']
    assert floors['0.5']['pct_floor_w'] == pytest.approx(10.0 * floors['0.05']['pct_floor_w'])
    # differential errors do not depend on the floor
    assert floors['0.5']['avg_diff_error_w'] == floors['0.05']['avg_diff_error_w']
