"""``feed-axis-energy batch``: serial, local processes and a Dask cluster on loopback agree."""
import csv
import json
import math
import os
from pathlib import Path
import subprocess
import sys
import threading

import pytest

from feed_axis_energy.cli import main
from shared_data import need_shared

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / 'config' / 'programs'
MILL = ROOT / 'config' / 'three_axis_mill.yaml'


def _run(*argv: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, '-m', 'feed_axis_energy', *argv], cwd=cwd,
                          capture_output=True, text=True, timeout=300, env=env)


@pytest.fixture()
def progs(tmp_path):
    """Two shipped programs and one the parser refuses (line 3, column 1)."""
    d = tmp_path / 'progs'
    d.mkdir()
    for name in ('demonstrator_f200.nc', 'demonstrator_f400.nc'):
        (d / name).write_text((PROGRAMS / name).read_text())
    (d / 'zz_bad.nc').write_text('G21 G90\nG1 X10 F600\nG33 Z-1 K1\nM30\n')
    return d


def _json(capsys, argv):
    rc = main(argv)
    return rc, json.loads(capsys.readouterr().out)


def test_help():
    proc = _run('batch', '--help')
    assert proc.returncode == 0
    assert 'usage: feed-axis-energy batch' in proc.stdout
    for option in ('--jobs', '--scheduler', '--batch-file', '--csv', '--load-kg', '--out',
                   '--compression'):
        assert option in proc.stdout


def test_method_phases_by_default_samples_when_asked(progs, capsys):
    """The summaries are by phase unless --method samples (then as simulate --method
    samples); both within the 1 kHz samples' discretization of each other."""
    prog = str(progs / 'demonstrator_f200.nc')
    rc1, phases = _json(capsys, ['batch', prog, '--json', '--quiet'])
    rc2, samples = _json(capsys, ['batch', prog, '--json', '--quiet', '--method', 'samples'])
    assert rc1 == rc2 == 0
    by_phase, sampled = phases['results'][0]['summary'], samples['results'][0]['summary']
    assert by_phase['method'] == 'phases' and 'quadrature_error_j' in by_phase
    assert sampled['method'] == 'samples' and 'quadrature_error_j' not in sampled
    assert by_phase['energy_j']['total'] == pytest.approx(sampled['energy_j']['total'],
                                                          rel=1e-8)
    assert by_phase['energy_j']['total'] != sampled['energy_j']['total']


def test_serial_equals_two_processes(progs, capsys):
    argv = ['batch', str(progs), '--load-kg', '0,17.336', '--rate-hz', '400', '--json',
            '--quiet', '--top', '2']
    rc1, serial = _json(capsys, argv)
    rc2, parallel = _json(capsys, argv + ['--jobs', '2'])
    assert rc1 == rc2 == 1                        # one program is refused
    assert serial == parallel
    assert serial['jobs'] == 6 and serial['failed'] == 2
    assert [r['job'] for r in serial['results']] == [1, 2, 3, 4, 5, 6]
    assert [r['status'] for r in serial['results']] == ['ok'] * 4 + ['failed'] * 2
    assert len(serial['results'][0]['summary']['top_blocks']) == 2


def test_two_processes_from_a_threaded_caller(progs, capsys):
    # with another thread running the workers start from a fork server, not by fork
    argv = ['batch', str(progs / 'demonstrator_f200.nc'), str(progs / 'demonstrator_f400.nc'),
            '--rate-hz', '200', '--json', '--quiet']
    _, serial = _json(capsys, argv)
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        rc, parallel = _json(capsys, argv + ['--jobs', '2'])
    finally:
        stop.set()
        other.join()
    assert rc == 0 and parallel == serial


def test_dask_local_cluster_on_loopback_equals_serial(progs, capsys):
    distributed = pytest.importorskip('distributed')
    argv = ['batch', str(progs), '--machine', str(MILL), '--machine',
            str(ROOT / 'config' / 'demonstrator.yaml'), '--rate-hz', '400', '--json',
            '--quiet']
    _, serial = _json(capsys, argv)
    with distributed.LocalCluster(n_workers=1, processes=False, threads_per_worker=2,
                                  host='127.0.0.1', protocol='tcp',
                                  dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith('tcp://127.0.0.1:')
        rc, remote = _json(capsys, argv + ['--scheduler', cluster.scheduler_address])
    assert rc == 1
    assert remote == serial
    assert serial['jobs'] == 6 and serial['failed'] == 2


def test_unreachable_scheduler_is_a_clear_error():
    pytest.importorskip('distributed')
    proc = _run('batch', str(PROGRAMS / 'demonstrator_f500.nc'), '--scheduler',
                'tcp://127.0.0.1:9', '--connect-timeout', '1')
    assert proc.returncode == 1
    assert "cannot connect to the Dask scheduler 'tcp://127.0.0.1:9' within 1 s" in proc.stderr
    assert 'Traceback' not in proc.stderr


def test_failed_job_row_and_exit_code(progs):
    proc = _run('batch', str(progs / '*.nc'), '--rate-hz', '200')
    assert proc.returncode == 1, proc.stderr
    assert 'Traceback' not in proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].split()[:3] == ['job', 'program', 'machine']
    assert 'energy [J]' in lines[0] and 'load [kg]' in lines[0]
    assert sum(line.rstrip().endswith(' ok') for line in lines) == 2
    assert '1 of 3 jobs failed:' in proc.stdout
    assert 'zz_bad.nc:3:1: G33 is not supported' in proc.stdout
    assert '[batch] 3 jobs (1 failed)' in proc.stderr


def test_all_ok_exits_zero_and_batch_file(tmp_path):
    (tmp_path / 'a.nc').write_text((PROGRAMS / 'demonstrator_f500.nc').read_text())
    camp = tmp_path / 'c.yaml'
    camp.write_text(f'programs: [a.nc]\nmachines: [{str(MILL)!r}]\nloads_kg: [0, 50]\n'
                    'rate_hz: 100\n')
    proc = _run('batch', '--batch-file', str(camp), '--json', '--quiet')
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc['failed'] == 0 and [r['load_kg'] for r in doc['results']] == [0.0, 50.0]
    assert doc['results'][0]['summary']['rate_hz'] == pytest.approx(100.0)
    # a command-line option replaces the file's value
    proc = _run('batch', '--batch-file', str(camp), '--load-kg', '7', '--json', '--quiet')
    assert [r['load_kg'] for r in json.loads(proc.stdout)['results']] == [7.0]


def test_csv_written_safely(progs, tmp_path, capsys):
    out = tmp_path / 'res.csv'
    rc, doc = _json(capsys, ['batch', str(progs), '--rate-hz', '300', '--csv', str(out),
                             '--json', '--quiet'])
    assert rc == 1
    with open(out, newline='') as fh:
        rows = list(csv.DictReader(fh))
    assert [r['status'] for r in rows] == ['ok', 'ok', 'failed']
    for row, res in zip(rows, doc['results']):
        assert int(row['job']) == res['job'] and row['program'] == res['program']
        if res['status'] == 'ok':
            # full precision: the CSV text reads back as the same number
            assert float(row['energy [J]']) == res['summary']['energy_j']['total']
            assert float(row['energy X [J]']) == res['summary']['energy_j']['X']
            assert int(row['samples']) == res['summary']['samples']
        else:
            assert 'G33' in row['error'] and row['energy [J]'] == ''
    assert len({len(r) for r in rows}) == 1
    # an existing file is refused (before any job runs) unless --force
    before = out.read_text()
    proc = _run('batch', str(progs), '--csv', str(out))
    assert proc.returncode == 1 and 'exists already' in proc.stderr
    assert out.read_text() == before
    assert main(['batch', str(progs / 'demonstrator_f200.nc'), '--rate-hz', '300', '--csv',
                 str(out), '--force', '--quiet']) == 0
    assert len(out.read_text().splitlines()) == 2
    link = tmp_path / 'link.csv'
    link.symlink_to(tmp_path / 'elsewhere.csv')
    proc = _run('batch', str(progs), '--csv', str(link), '--force')
    assert proc.returncode == 1 and 'symbolic link' in proc.stderr
    assert not (tmp_path / 'elsewhere.csv').exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ['link.csv', 'progs', 'res.csv']


@pytest.mark.parametrize('argv, code, message', [
    (['batch'], 1, 'no programs'),
    (['batch', 'nowhere/*.nc'], 1, "no program file matches 'nowhere/*.nc'"),
    (['batch', 'config/programs/demonstrator_f100.nc', '--machine', 'README.md'], 1,
     'README.md'),
    (['batch', 'config/programs/demonstrator_f100.nc', '--rate-hz', 'nan'], 1, '--rate-hz'),
    (['batch', 'config/programs/demonstrator_f100.nc', '--scheduler', 'inproc://x'], 1,
     'expected a scheduler address tcp://HOST:PORT'),
    (['batch', 'config/programs/demonstrator_f100.nc', '--batch-file', 'c.yaml'], 1,
     'either on the command line or in --batch-file'),
    (['batch', 'config/programs/demonstrator_f100.nc', '--load-kg', '1,abc'], 2,
     "expected masses [kg] separated by commas, got 'abc'"),
    (['batch', 'config/programs/demonstrator_f100.nc', '--load-kg', '-1'], 2, '0 to 1e6 kg'),
    (['batch', 'config/programs/demonstrator_f100.nc', '--jobs', '-2'], 2, '>= 0'),
    (['batch', 'config/programs/demonstrator_f100.nc', '--method', 'trapezoid'], 2,
     "argument --method: invalid choice: 'trapezoid'"),
    (['batch', 'config/programs/demonstrator_f100.nc', '--jobs', '2', '--scheduler',
      'tcp://127.0.0.1:8786'], 2, 'not allowed with argument'),
])
def test_bad_input_is_a_clear_error(argv, code, message):
    proc = _run(*argv)
    assert proc.returncode == code, proc.stderr
    assert message in proc.stderr
    assert 'Traceback' not in proc.stderr


def test_real_corpus_directory_every_job_a_row():
    corpus = need_shared('corpus', 'gcode', 'LinuxCNC__linuxcnc')
    proc = _run('batch', str(corpus), '--machine', str(MILL), '--rate-hz', '100',
                '--max-samples', '2000000', '--jobs', '2', '--json', '--quiet')
    assert proc.returncode in (0, 1), proc.stderr
    assert 'Traceback' not in proc.stderr
    doc = json.loads(proc.stdout)
    programs = sorted(p for p in os.listdir(corpus) if p.endswith(('.nc', '.ngc', '.gcode')))
    assert doc['jobs'] == len(programs) == len(doc['results'])
    for row in doc['results']:
        if row['status'] == 'failed':
            # the message names the program (and line:column where the parser stopped)
            assert os.path.basename(row['program']) in row['error']
            assert len(row['error']) < 600
        else:
            assert math.isfinite(row['summary']['energy_j']['total'])
            assert row['summary']['samples'] <= 2_000_000


# --- recordings: batch --out DIR -------------------------------------------------------------

def _bag_contents(directory: Path) -> dict:
    """Per recording: metadata (paths left out) and every message (topic, time, bytes)."""
    from mcap.reader import make_reader

    from feed_axis_energy.record import bagio
    out = {}
    for bag in sorted(p for p in directory.iterdir()):
        info = bagio.read_metadata(bag)
        info.pop('relative_file_paths')
        for f in info['files']:
            f.pop('path')
        (mcap,) = bag.glob('*.mcap')
        with open(mcap, 'rb') as fh:
            msgs = sorted((c.topic, m.log_time, m.data) for _, c, m in
                          make_reader(fh, validate_crcs=True).iter_messages())
        out[bag.name] = (info, bagio.bag_topics(bag), msgs)
    return out


def test_out_one_recording_per_job_serial_equals_two_processes(progs, tmp_path, capsys):
    (progs / 'zz_bad.nc').unlink()
    base = ['batch', str(progs), '--load-kg', '0,17.336', '--rate-hz', '400', '--json',
            '--quiet']
    rc1, serial = _json(capsys, base + ['--out', str(tmp_path / 'serial')])
    rc2, parallel = _json(capsys, base + ['--out', str(tmp_path / 'parallel'), '--jobs', '2'])
    assert rc1 == rc2 == 0
    names = ['1-demonstrator_f200-0kg', '2-demonstrator_f200-17.336kg',
             '3-demonstrator_f400-0kg', '4-demonstrator_f400-17.336kg']
    assert sorted(p.name for p in (tmp_path / 'serial').iterdir()) == names
    a, b = _bag_contents(tmp_path / 'serial'), _bag_contents(tmp_path / 'parallel')
    assert a == b                                  # same names, counts and message bytes
    for name, (info, topics, _) in a.items():
        assert topics['/power'][1] > 10
    for r in serial['results']:
        assert Path(r['summary']['bag']).parent == tmp_path / 'serial'
    # the bag holds the job's summary
    from feed_axis_energy.record import bagio
    stored = bagio.read_custom_data(tmp_path / 'serial' / names[1], 'feed_axis_energy/summary')
    summary = dict(serial['results'][1]['summary'])
    summary.pop('bag')
    summary.pop('warnings', None)
    assert stored == summary


def test_out_failed_job_leaves_no_recording_and_existing_ones_are_refused(progs, tmp_path,
                                                                          capsys):
    out = tmp_path / 'bags'
    argv = ['batch', str(progs), '--out', str(out), '--quiet', '--jobs', '2', '--json']
    rc, doc = _json(capsys, argv)
    assert rc == 1 and doc['failed'] == 1
    kept = ['1-demonstrator_f200', '2-demonstrator_f400']            # not 3-zz_bad
    assert sorted(p.name for p in out.iterdir()) == kept
    before = {p: p.stat().st_mtime_ns for p in out.rglob('*')}
    # a second run refuses before any job runs: nothing changes
    assert main(['batch', str(progs), '--out', str(out), '--quiet']) == 1
    assert 'exists already' in capsys.readouterr().err
    assert {p: p.stat().st_mtime_ns for p in out.rglob('*')} == before
    # --force replaces the recordings (bag directories only)
    rc, doc = _json(capsys, argv + ['--force'])
    assert rc == 1 and doc['failed'] == 1
    assert sorted(p.name for p in out.iterdir()) == kept
    (out / '1-demonstrator_f200' / 'extra').mkdir()         # not a bag any more
    assert main(['batch', str(progs), '--out', str(out), '--quiet', '--force']) == 1
    assert 'not an earlier output' in capsys.readouterr().err


def test_out_that_only_fails_leaves_no_directory(tmp_path, capsys):
    bad = tmp_path / 'bad.nc'
    bad.write_text('G21 G90\nG5.2 X1 Y2\nM30\n')
    out = tmp_path / 'new' / 'bags'
    assert main(['batch', str(bad), '--out', str(out), '--quiet']) == 1
    assert not (tmp_path / 'new').exists()
    (tmp_path / 'file').write_text('x')
    assert main(['batch', str(bad), '--out', str(tmp_path / 'file'), '--quiet']) == 1
    assert 'not a directory' in capsys.readouterr().err


def test_rollups_per_operation_and_tool_in_json_and_csv(tmp_path, capsys):
    prog = tmp_path / 'ops.nc'
    prog.write_text('(two operations, two tools)\nG21 G90 G94\nG0 X0\n(Rough; pass, "one")\n'
                    'T1 M6\nG1 X50 F3000\nG1 X0\n(Finish)\nT2 M6\nG1 X20 F1200\nM30\n')
    out = tmp_path / 'res.csv'
    rc, doc = _json(capsys, ['batch', str(prog), '--rate-hz', '300', '--csv', str(out),
                             '--json', '--quiet'])
    assert rc == 0
    summary = doc['results'][0]['summary']
    total = summary['energy_j']['total']
    ops = {it['name']: it['energy_j'] for it in summary['rollups']['operation']}
    tools = {it['name']: it['energy_j'] for it in summary['rollups']['tool']}
    assert set(ops) >= {'Rough; pass, "one"', 'Finish'} and set(tools) >= {'T1', 'T2'}
    assert math.isclose(math.fsum(ops.values()), total, rel_tol=1e-9)
    # the rough pass moves 100 mm at 50 mm/s, the finish 30 mm at 20 mm/s: T1 takes more
    assert tools['T1'] > tools['T2'] > 0.0
    with open(out, newline='') as fh:
        row = next(csv.DictReader(fh))
    # one compact cell per group: a JSON object that reads back with the names intact
    assert json.loads(row['energy by operation [J]']) == ops
    assert json.loads(row['energy by tool [J]']) == tools
    assert row['energy uncertainty [J]'] == ''      # the demonstrator has no covariance


def test_electrical_energy_columns_where_drives_are_declared(tmp_path, capsys):
    """A job on a machine with drives has its motor-terminal and supply energy in the CSV and
    a supply column in the table; a job on a machine without drives has empty cells."""
    prog = PROGRAMS / 'three_axis_contour.nc'
    drives = ROOT / 'config' / 'three_axis_mill_drives.yaml'
    out = tmp_path / 'res.csv'
    argv = ['batch', str(prog), '--machine', str(MILL), '--machine', str(drives),
            '--rate-hz', '300', '--csv', str(out), '--json', '--quiet']
    rc, doc = _json(capsys, argv)
    assert rc == 0
    plain, declared = (r['summary'] for r in doc['results'])
    assert 'electrical' not in plain
    with open(out, newline='') as fh:
        rows = list(csv.DictReader(fh))
    assert rows[0]['motor energy [J]'] == rows[0]['supply energy [J]'] == ''
    elec = declared['electrical']
    assert float(rows[1]['motor energy [J]']) == elec['motor_energy_j']['total']
    assert float(rows[1]['supply energy [J]']) == elec['supply_energy_j']['total']
    # the supply side carries every loss on top of the shafts' energy
    assert float(rows[1]['supply energy [J]']) > float(rows[1]['energy [J]']) > 0.0
    assert main(argv[:8] + ['--quiet']) == 0
    table = capsys.readouterr().out.splitlines()
    assert 'supply energy [J]' in table[0]
    cells = [line.split() for line in table[2:4]]
    assert cells[0][-2] == '-'
    assert math.isclose(float(cells[1][-2]), elec['supply_energy_j']['total'], abs_tol=0.006)
