"""CSV import: unit conversion, row filters, and DataErrors naming file, column and row."""
import copy
from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose, assert_array_equal
import pytest

from feed_axis_energy.errors import DataError
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.measured.manifest import campaign_from_dict, load_campaign

FIXTURES = Path(__file__).resolve().parents[1] / 'fixtures' / 'measured'


def test_fixture_run_a_filtered_and_in_si():
    run = load_run(load_campaign(FIXTURES / 'campaign.yaml').run('a'))
    # data row 3 (PROG = 4) is excluded by the manifest; stamps were in ms
    assert run.extra['excluded_rows'] == 1
    assert_array_equal(run.extra['rows'], [1, 2, 4, 5, 6])
    assert_allclose(run.t, [0.0, 0.1, 0.3, 0.4, 0.5])
    assert run.axes == ('X', 'Y') and run.power_axes == ('X', 'Y')
    assert_allclose(run.power_w[:, 0], [10.0, 12.0, 14.0, 16.0, 18.0])       # kW -> W
    assert_allclose(run.total_power_w, [30.0, 30.0, 28.0, 28.0, 28.0])
    assert_allclose(run.position_m[:, 0], [0.100, 0.101, 0.103, 0.104, 0.105])  # mm -> m
    assert_allclose(run.velocity_m_s[1:, 0], 0.01)                            # 600 mm/min
    assert_allclose(run.extra['current_a']['X'], [0.1, 0.12, 0.13, 0.14, 0.15])
    assert run.acceleration_m_s2 is None and run.command_position_m is None
    assert run.positions('actual') is run.position_m
    with pytest.raises(DataError, match='no commanded position'):
        run.positions('commanded')
    assert run.load_kg == 2.5


def test_gap_left_by_filter_is_reported_for_period_runs(tmp_path):
    # run_a has a time column, so the excluded row leaves 0.2 s; here the period decides
    text = 'P,X,F\n1,0,0\n2,1,9\n3,2,0\n4,3,0\n5,4,0\n'
    spec = _spec(tmp_path, text,
                 rows={'exclude_where': [{'column': 'F', 'equal': 9}]})
    with pytest.raises(DataError) as info:
        load_run(spec)
    assert info.value.row == 3 and 'gap' in str(info.value)
    ok = load_run(_spec(tmp_path, text, allow_gaps=True,
                        rows={'exclude_where': [{'column': 'F', 'equal': 9}]}))
    assert_allclose(ok.t, [0.0, 0.2, 0.3, 0.4])     # original row index x period


def test_fixture_run_b_uses_period():
    run = load_run(load_campaign(FIXTURES / 'campaign.yaml').run('b'))
    assert_allclose(run.t, [0.0, 0.05, 0.10, 0.15])
    assert_allclose(run.power_w, [[1, 2], [2, 3], [3, 4], [4, 5]])
    assert run.extra['excluded_rows'] == 0


def _spec(tmp_path, text, *, name='d.csv', **run_changes):
    (tmp_path / name).write_text(text)
    run = {'name': 'r', 'load_kg': 0, 'data': name, 'period_s': 0.1,
           'motion': {'from_data': 'actual'},
           'axes': {'X': {'power': {'column': 'P', 'unit': 'W'},
                          'position': {'column': 'X', 'unit': 'mm'}}}}
    run.update(copy.deepcopy(run_changes))
    if 'time' in run_changes:
        del run['period_s']
    d = {'machine': 'm.yaml', 'runs': [run]}
    return campaign_from_dict(d, file=tmp_path / 'c.yaml', check_files=False).runs[0]


TIME = {'time': {'column': 't', 'unit': 's'}}


@pytest.mark.parametrize('text, changes, column, row, words', [
    ('P,x\n1,2\n3,4\n', {}, 'X', None, "did you mean 'x'"),
    ('P,X_pos\n1,2\n3,4\n', {'axes': {'X': {
        'power': {'column': 'P', 'unit': 'W'}, 'position': {'column': 'Xpos', 'unit': 'mm'}}}},
     'Xpos', None, "did you mean 'X_pos'"),
    ('P,X\n1,2\n3,abc\n4,5\n', {}, 'X', 2, "'abc' is not a number"),
    ('P,X\n1,2\n,4\n4,5\n', {}, 'P', 2, 'empty cell'),
    ('P,X\n1,2\n3,4\n4,nan\n', {}, 'X', 3, 'not a finite number'),
    ('t,P,X\n0,1,2\n0.1,1,2\n0.1,1,2\n', TIME, 't', 3, 'repeats the previous time'),
    ('t,P,X\n0,1,2\n0.2,1,2\n0.1,1,2\n', TIME, 't', 3, 'goes back in time'),
    ('t,P,X\n0,1,2\n0.1,1,2\n0.2,1,2\n0.5,1,2\n0.6,1,2\n', TIME, 't', 4, 'gap of 0.3 s'),
    ('P,X\n1,2\n3,4,5\n', {}, '', 2, 'has 3 fields'),
    ('P,X,G\n1,2,x\n3,4,0\n', {'rows': {'exclude_where': [{'column': 'G', 'less': 1}]}},
     'G', 1, "'x' is not a number"),
])
def test_bad_data_names_file_column_row(tmp_path, text, changes, column, row, words):
    spec = _spec(tmp_path, text, **changes)
    with pytest.raises(DataError) as info:
        load_run(spec)
    err = info.value
    assert err.file == str(tmp_path / 'd.csv') and str(tmp_path / 'd.csv') in str(err)
    assert err.column == column and err.row == row
    assert words in str(err)


def test_bad_row_excluded_by_filter_is_not_an_error(tmp_path):
    text = 'P,X,Stage\n1,2,ok\n3,abc,junk\n4,5,ok\n'
    spec = _spec(tmp_path, text, rows={'exclude_where': [{'column': 'Stage', 'equal': 'junk'}]})
    run = load_run(spec)
    assert_allclose(run.power_w[:, 0], [1.0, 4.0])
    assert run.extra['excluded_rows'] == 1
    assert_array_equal(run.extra['rows'], [1, 3])


@pytest.mark.parametrize('text, words', [
    ('', 'empty file'),
    ('P,X\n', 'header only'),
    ('P,X\n1,2\n', 'at least 2 data rows'),
])
def test_empty_and_too_short_files(tmp_path, text, words):
    with pytest.raises(DataError, match=words) as info:
        load_run(_spec(tmp_path, text))
    assert info.value.file == str(tmp_path / 'd.csv')


def test_all_rows_excluded(tmp_path):
    spec = _spec(tmp_path, 'P,X\n1,2\n3,4\n',
                 rows={'exclude_where': [{'column': 'P', 'greater': 0}]})
    with pytest.raises(DataError, match='2 excluded by the manifest filter'):
        load_run(spec)


def test_minimum_duration(tmp_path):
    spec = _spec(tmp_path, 'P,X\n1,2\n3,4\n5,6\n', min_duration_s=0.5)
    with pytest.raises(DataError, match='shorter than the minimum 0.5 s'):
        load_run(spec)
    assert load_run(spec, min_duration_s=0.2).t[-1] == pytest.approx(0.2)


def test_duplicate_header_column(tmp_path):
    with pytest.raises(DataError, match='2 times') as info:
        load_run(_spec(tmp_path, 'P,X,P\n1,2,3\n4,5,6\n'))
    assert info.value.column == 'P'


def test_missing_file(tmp_path):
    spec = _spec(tmp_path, 'P,X\n1,2\n3,4\n')
    (tmp_path / 'd.csv').unlink()
    with pytest.raises(DataError, match='cannot read'):
        load_run(spec)


def test_five_thousand_rows_load_exactly(tmp_path):
    # Speed is a benchmark's business (bench/bench_compare.py prints it), not a timed test.
    n = 5000
    rng = np.random.default_rng(1)
    cols = rng.normal(size=(n, 12))
    header = 'P,X,' + ','.join(f'c{i}' for i in range(10))
    body = '\n'.join(','.join(f'{v:.6e}' for v in row) for row in cols)
    spec = _spec(tmp_path, header + '\n' + body + '\n')
    run = load_run(spec)
    assert run.t.shape == (n,)
    assert_allclose(run.position_m[:, 0], cols[:, 1] * 1e-3, rtol=1e-6)
