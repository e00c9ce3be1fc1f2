"""``simulate --csv/--parquet``: the exported tables agree with the summary and the source."""
import csv
import json
import math
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from feed_axis_energy.cli import main
from feed_axis_energy.sim.exports import EXPORT_MARKER

ROOT = Path(__file__).resolve().parents[2]
MILL = ROOT / 'config' / 'three_axis_mill.yaml'
# a comma and quotes in a comment (CSV quoting), arcs, a dwell left out of the rows
PROGRAM = """G21 G90 G94 G17 G64
G0 X0 Y0 Z20
G1 Z-2 F600 (plunge, "slow")
G1 X30 Y5 F2400
G2 X40 Y15 I0 J10
G4 P0.5
G3 X30 Y25 I-10 J0
G0 Z40
M30
"""


def _read_csv(path: Path):
    with open(path, newline='', encoding='utf-8') as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def _simulate(tmp_path, capsys, *extra):
    prog = tmp_path / 'p.nc'
    prog.write_text(PROGRAM)
    code = main(['simulate', str(prog), '--machine', str(MILL), '--load-kg', '30', '--json',
                 '--quiet', *extra])
    out = capsys.readouterr()
    return code, (json.loads(out.out) if code == 0 else None), out.err


def test_csv_series_and_blocks_add_up(tmp_path, capsys):
    # --method samples: the summary integrated over the exported samples themselves
    code, summary, _ = _simulate(tmp_path, capsys, '--csv', str(tmp_path / 'c'),
                                 '--method', 'samples')
    assert code == 0 and summary['csv'] == str(tmp_path / 'c')
    assert (tmp_path / 'c' / EXPORT_MARKER).is_file()
    header, rows = _read_csv(tmp_path / 'c' / 'timeseries.csv')
    data = np.array(rows, dtype=float)
    col = {name: data[:, i] for i, name in enumerate(header)}
    # every sample at the full rate, the dwell's left-out samples included
    assert data.shape[0] == summary['samples']
    assert np.all(np.diff(col['t [s]']) > 0)
    assert math.isclose(col['total energy [J]'][-1], summary['energy_j']['total'],
                        rel_tol=1e-12)
    causes = [f'{c} power [W]' for c in summary['causes']]
    np.testing.assert_allclose(sum(col[c] for c in causes), col['total power [W]'],
                               rtol=0, atol=1e-9 * np.abs(col['total power [W]']).max())
    np.testing.assert_allclose(col['X power [W]'] + col['Y power [W]'] + col['Z power [W]'],
                               col['total power [W]'], rtol=1e-12, atol=1e-9)

    header, rows = _read_csv(tmp_path / 'c' / 'blocks.csv')
    assert header[:4] == ['line', 'text', 'duration [s]', 'energy [J]']
    by_line = {int(r[0]): r for r in rows}
    source = PROGRAM.splitlines()
    for line, row in by_line.items():
        assert row[1] == source[line - 1].strip()
    assert by_line[3][1] == 'G1 Z-2 F600 (plunge, "slow")'
    numbers = np.array([r[2:] for r in rows], dtype=float)
    assert math.isclose(numbers[:, 1].sum(), summary['energy_j']['total'], rel_tol=1e-9)
    assert math.isclose(numbers[:, 0].sum(), summary['duration_s'], rel_tol=1e-9)
    k = 3
    np.testing.assert_allclose(numbers[:, 2:2 + k].sum(axis=1), numbers[:, 1], atol=1e-9)
    np.testing.assert_allclose(numbers[:, 2 + k:].sum(axis=1), numbers[:, 1], atol=1e-9)
    assert header[2 + 2 + k:] == [f'{c} energy [J]' for c in summary['causes']]
    # the dwell's energy and time go to its line
    assert math.isclose(float(by_line[6][2]), 0.5, abs_tol=2e-3)


def test_decimated_and_parquet_equal_csv(tmp_path, capsys):
    code, summary, _ = _simulate(tmp_path, capsys, '--csv', str(tmp_path / 'c'),
                                 '--parquet', str(tmp_path / 'p'), '--export-rate-hz', '100')
    assert code == 0
    header, rows = _read_csv(tmp_path / 'c' / 'timeseries.csv')
    data = np.array(rows, dtype=float)
    # 1000 Hz / 100 Hz: every 10th sample from the first
    assert data.shape[0] == math.ceil(summary['samples'] / 10)
    np.testing.assert_allclose(np.diff(data[:, 0]), 0.01, atol=1e-9)
    table = pq.read_table(tmp_path / 'p' / 'timeseries.parquet')
    assert table.column_names == header
    np.testing.assert_array_equal(np.column_stack(
        [table.column(c).to_numpy() for c in header]).astype(float), data)
    assert table.schema.field('line').type == 'int64'
    blocks = pq.read_table(tmp_path / 'p' / 'blocks.parquet')
    _, rows = _read_csv(tmp_path / 'c' / 'blocks.csv')
    assert blocks.column('text').to_pylist() == [r[1] for r in rows]
    np.testing.assert_array_equal(blocks.column('energy [J]').to_numpy(),
                                  np.array([r[3] for r in rows], dtype=float))


def test_existing_directory_refused_then_replaced_with_force(tmp_path, capsys):
    target = tmp_path / 'c'
    target.mkdir()
    (target / 'mine.txt').write_text('keep')
    code, _, err = _simulate(tmp_path, capsys, '--csv', str(target))
    assert code == 1 and '--csv' in err and 'exists' in err
    code, _, err = _simulate(tmp_path, capsys, '--csv', str(target), '--force')
    assert code == 1 and (target / 'mine.txt').read_text() == 'keep'
    (target / 'mine.txt').unlink()
    # an empty directory, or an earlier export: only with --force
    assert _simulate(tmp_path, capsys, '--csv', str(target))[0] == 1
    assert _simulate(tmp_path, capsys, '--csv', str(target), '--force')[0] == 0
    assert _simulate(tmp_path, capsys, '--csv', str(target))[0] == 1
    assert _simulate(tmp_path, capsys, '--csv', str(target), '--force')[0] == 0
    assert sorted(p.name for p in target.iterdir()) == [EXPORT_MARKER, 'blocks.csv',
                                                        'rollups.csv', 'timeseries.csv']


def test_failure_leaves_nothing(tmp_path, capsys):
    prog = tmp_path / 'bad.nc'
    prog.write_text('G21 G90\nG1 X10 F600\nG1 X20 Q\n')
    code = main(['simulate', str(prog), '--machine', str(MILL), '--quiet',
                 '--csv', str(tmp_path / 'out' / 'c')])
    err = capsys.readouterr().err
    assert code == 1 and 'bad.nc:3' in err
    assert list(tmp_path.iterdir()) == [prog]


@pytest.mark.parametrize('argv', [['--decimate', '2'], ['--decimate', '0', '--csv', 'x'],
                                  ['--export-rate-hz', 'nan', '--csv', 'x']])
def test_usage_errors_exit_2(tmp_path, capsys, argv):
    prog = tmp_path / 'p.nc'
    prog.write_text(PROGRAM)
    with pytest.raises(SystemExit) as exc:
        main(['simulate', str(prog), '--quiet', *argv])
    assert exc.value.code == 2
    assert not (tmp_path / 'x').exists()


def test_json_top_blocks_have_their_text(tmp_path, capsys):
    long = 'G1 X1 F600 (' + 'a' * 100 + ')'
    prog = tmp_path / 'p.nc'
    prog.write_text(f'G21 G90\n{long}\nM30\n')
    assert main(['simulate', str(prog), '--machine', str(MILL), '--json', '--quiet']) == 0
    top = json.loads(capsys.readouterr().out)['top_blocks']
    assert top[0]['line'] == 2 and top[0]['text'] == long[:60] + '...'


def test_with_a_recording_the_export_still_has_every_sample(tmp_path, capsys):
    # the bag writer takes compact dwells; the export gets them at the full rate
    code, summary, _ = _simulate(tmp_path, capsys, '--csv', str(tmp_path / 'c'),
                                 '--out', str(tmp_path / 'bag'))
    assert code == 0 and (tmp_path / 'bag' / 'metadata.yaml').is_file()
    _, rows = _read_csv(tmp_path / 'c' / 'timeseries.csv')
    assert len(rows) == summary['samples']


def test_rollups_table_adds_up_and_parquet_equals_csv(tmp_path, capsys):
    prog = tmp_path / 'ops.nc'
    prog.write_text('G21 G90 G94 G17\nG0 X0 Y0 Z20\n(Rough, "outer")\nT1 M6\n'
                    'G1 X30 Y5 F2400\nG1 X0 Y0\n(Finish)\nT2 M6\nG1 X10 Y10 F1200\nM30\n')
    code = main(['simulate', str(prog), '--machine', str(MILL), '--json', '--quiet',
                 '--csv', str(tmp_path / 'c')])
    summary = json.loads(capsys.readouterr().out)
    assert code == 0
    header, rows = _read_csv(tmp_path / 'c' / 'rollups.csv')
    assert header == ['group', 'name', 'energy [J]', 'duration [s]']
    groups = {}
    for group, name, e, d in rows:
        groups.setdefault(group, {})[name] = (float(e), float(d))
    assert set(groups) == {'operation', 'subroutine', 'tool', 'axis'}
    assert set(groups['operation']) == {'(none)', 'Rough, "outer"', 'Finish'}
    assert set(groups['tool']) == {'no tool', 'T1', 'T2'}
    for group in ('operation', 'subroutine', 'tool'):
        assert math.isclose(math.fsum(e for e, _ in groups[group].values()),
                            summary['energy_j']['total'], rel_tol=1e-9)
        assert math.isclose(math.fsum(d for _, d in groups[group].values()),
                            summary['duration_s'], rel_tol=1e-9)
    # the same rows as the summary's roll-ups, full precision
    assert groups['tool']['T1'][0] == next(it['energy_j'] for it in summary['rollups']['tool']
                                           if it['name'] == 'T1')
    assert main(['simulate', str(prog), '--machine', str(MILL), '--quiet',
                 '--parquet', str(tmp_path / 'p')]) == 0
    assert 'rollups.parquet' in capsys.readouterr().out
    table = pq.read_table(tmp_path / 'p' / 'rollups.parquet')
    assert table.column('name').to_pylist() == [r[1] for r in rows]
    np.testing.assert_array_equal(table.column('energy [J]').to_numpy(),
                                  np.array([r[2] for r in rows], dtype=float))


def test_a_trajectory_csv_has_no_rollups_table(tmp_path, capsys):
    traj = tmp_path / 't.csv'
    t = np.arange(200) * 0.01
    traj.write_text('time [s],X [mm]\n' + ''.join(f'{a:.4f},{10 * np.sin(a):.6f}\n' for a in t))
    assert main(['simulate', str(traj), '--quiet', '--csv', str(tmp_path / 'c')]) == 0
    assert 'rollups' not in capsys.readouterr().out
    assert not (tmp_path / 'c' / 'rollups.csv').exists()
    assert (tmp_path / 'c' / 'timeseries.csv').is_file()
