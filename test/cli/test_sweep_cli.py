"""``feed-axis-energy sweep``: rows, baseline, Pareto front, outputs and errors."""
import csv
import json
import os
from pathlib import Path
import subprocess
import sys

import pytest

from feed_axis_energy.cli import main

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / 'config' / 'programs'
MILL = ROOT / 'config' / 'three_axis_mill.yaml'


def _run(*argv: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, '-m', 'feed_axis_energy', *argv], cwd=ROOT,
                          capture_output=True, text=True, timeout=300, env=env)


def _json(capsys, argv):
    rc = main(argv)
    return rc, json.loads(capsys.readouterr().out)


def test_help_lists_grammar_and_names():
    proc = _run('sweep', '--help')
    assert proc.returncode == 0
    for word in ('--vary', 'START:STOP:N', 'feed_override', 'rapid_override', 'jerk',
                 'axes.*.screw.lead_m', '--report', '--jobs', '--scheduler', '--parts'):
        assert word in proc.stdout


def test_rows_baseline_and_front(capsys):
    prog = str(PROGRAMS / 'demonstrator_f200.nc')
    rc, doc = _json(capsys, ['sweep', prog, '--vary', 'feed_override=0.5,1',
                             '--vary', 'lead*=1,2', '--rate-hz', '250', '--parts', '4',
                             '--json', '--quiet'])
    assert rc == 0 and doc['runs'] == 5 and doc['failed'] == 0
    rows = doc['rows']
    assert rows[0]['baseline'] and rows[0]['values'] is None
    assert [r['values'] for r in rows[1:]] == [
        {'feed_override': a, 'lead*': b} for a in (0.5, 1.0) for b in (1.0, 2.0)]
    # the identity variant is the baseline, to the last bit
    same = rows[3]
    assert same['energy_j'] == rows[0]['energy_j']
    assert same['d_energy_pct'] == 0.0 and same['d_time_pct'] == 0.0
    for r in rows:
        assert r['energy_per_part_j'] == pytest.approx(r['energy_j'] / 4.0)
        base_e = rows[0]['energy_j']
        assert r['d_energy_pct'] == pytest.approx(100.0 * (r['energy_j'] - base_e) / base_e)
    # the front: no row on it is beaten in both time and energy by another row
    pts = [(r['cycle_time_s'], r['energy_j']) for r in rows]
    for r, (t, e) in zip(rows, pts):
        beaten = any(t2 <= t and e2 <= e and (t2, e2) != (t, e) for t2, e2 in pts)
        assert r['pareto'] == (not beaten)
    # half the feed takes longer
    assert rows[1]['cycle_time_s'] > rows[3]['cycle_time_s']


def test_method_reaches_every_run(capsys):
    """--method samples: the runs are summed over samples (within 1e-8 of the default by
    phase here, not equal to it)."""
    prog = str(PROGRAMS / 'demonstrator_f200.nc')
    argv = ['sweep', prog, '--vary', 'load_kg=0,20', '--json', '--quiet']
    rc1, phases = _json(capsys, argv)
    rc2, samples = _json(capsys, argv + ['--method', 'samples'])
    assert rc1 == rc2 == 0
    for a, b in zip(phases['rows'], samples['rows']):
        assert a['energy_j'] == pytest.approx(b['energy_j'], rel=1e-8)
        assert a['energy_j'] != b['energy_j']


def test_table_csv_and_report(tmp_path, capsys):
    prog = str(PROGRAMS / 'three_axis_contour.nc')
    out_csv, rep = tmp_path / 's.csv', tmp_path / 'rep'
    argv = ['sweep', prog, '--machine', str(MILL), '--vary', 'axes.Z.table_mass_kg=5,40',
            '--rate-hz', '250', '--csv', str(out_csv), '--report', str(rep), '--quiet']
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert 'axes.Z.table_mass_kg' in text and '(baseline)' in text and 'energy [J]' in text
    rows = list(csv.DictReader(out_csv.open()))
    assert [r['axes.Z.table_mass_kg'] for r in rows] == ['', '5.0', '40.0']
    assert float(rows[2]['energy [J]']) > float(rows[1]['energy [J]'])   # a heavier Z lifts more
    html = (rep / 'index.html').read_text()
    assert 'data:image/png;base64,' in html and 'least energy' in html
    assert sorted(p.name for p in rep.iterdir()) == ['.feed_axis_energy_report', 'index.html']
    # a second run neither overwrites the report nor the CSV without --force
    proc = _run(*argv)
    assert proc.returncode == 1 and 'Traceback' not in proc.stderr
    assert main(argv + ['--force']) == 0


@pytest.mark.parametrize('vary, words', [
    ('axes.X.scerw.lead_m=0.01', "no key 'scerw'"),
    ('lead=-0.01', 'lead_m'),
    ('feed_override=20', '<= 10'),
    ('nonsense', 'NAME=VALUES'),
])
def test_bad_input_exit_1_no_traceback(vary, words):
    proc = _run('sweep', str(PROGRAMS / 'demonstrator_f100.nc'), '--vary', vary)
    assert proc.returncode == 1
    assert words in proc.stderr and 'Traceback' not in proc.stderr
    assert proc.stdout == ''


def test_failed_program_is_a_row(tmp_path, capsys):
    bad = tmp_path / 'bad.nc'
    bad.write_text('G21 G90\nG1 X10 F600\nG33 Z-1 K1\nM30\n')
    rc, doc = _json(capsys, ['sweep', str(bad), '--vary', 'jerk=20,40', '--json', '--quiet'])
    assert rc == 1 and doc['failed'] == 3
    assert all(r['status'] == 'failed' and 'bad.nc:3' in r['error'] for r in doc['rows'])
    assert all('energy_j' not in r for r in doc['rows'])


def test_two_processes_equal_serial(capsys):
    argv = ['sweep', str(PROGRAMS / 'demonstrator_f300.nc'),
            str(PROGRAMS / 'demonstrator_f500.nc'),
            '--vary', 'jerk*=0.5,2', '--vary', 'load_kg=0,17.336', '--rate-hz', '250', '--json',
            '--quiet']
    rc1, serial = _json(capsys, argv)
    rc2, parallel = _json(capsys, argv + ['--jobs', '2'])
    assert rc1 == rc2 == 0 and serial['runs'] == 10
    assert serial == parallel


def test_connect_timeout_checked_as_in_batch():
    proc = _run('sweep', str(PROGRAMS / 'demonstrator_f100.nc'), '--vary', 'jerk=20,40',
                '--connect-timeout', '-1')
    assert proc.returncode == 1
    assert '--connect-timeout' in proc.stderr and 'Traceback' not in proc.stderr
