"""Time windows of a run (manifest ``window``): halves of one record, held-out evaluation.

A record written here with a known row index per sample (no time column, ``period_s``, the
first column an unnamed index as in the KIT trace) is split by seconds and by fractions; the
kept rows are checked against the index, the direction each axis last moved in before the
window against the velocity written in, and bad windows against the manifest key.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from feed_axis_energy.errors import ConfigError, DataError
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.measured.manifest import campaign_from_dict

PERIOD = 0.02
N = 101          # 2.0 s


def _record(tmp_path: Path) -> Path:
    t = np.arange(N) * PERIOD
    v = np.where(t < 0.5, 0.01, np.where(t < 0.9, -0.02, 0.0))      # +, -, then at rest
    pos = np.cumsum(v) * PERIOD
    lines = [',pos_x,v_x,curr_x']
    lines += [f'{i},{1e3 * pos[i]:.9g},{1e3 * v[i]:.9g},{0.1 * i:.6g}' for i in range(N)]
    path = tmp_path / 'trace.csv'
    path.write_text('\n'.join(lines) + '\n', encoding='ascii')
    return path


def _campaign(tmp_path: Path, windows: list[dict | None]):
    data = _record(tmp_path)
    (tmp_path / 'm.yaml').write_text('name: m\n', encoding='utf-8')
    runs = []
    for i, w in enumerate(windows):
        run = {'name': f'r{i}', 'data': str(data), 'load_kg': 0.0, 'period_s': PERIOD,
               'motion': {'from_data': 'actual'},
               'instrument': {'measures': 'current', 'kt_nm_a': {'X': 1.0}},
               'axes': {'X': {'position': {'column': 'pos_x', 'unit': 'mm'},
                              'velocity': {'column': 'v_x', 'unit': 'mm/s'},
                              'current': {'column': 'curr_x', 'unit': 'A'}}}}
        if w is not None:
            run['window'] = w
        runs.append(run)
    return campaign_from_dict({'machine': 'm.yaml', 'runs': runs},
                              file=tmp_path / 'c.yaml')


def test_halves_by_fraction_share_no_sample_and_hold_all(tmp_path):
    campaign = _campaign(tmp_path, [None, {'end_fraction': 0.5}, {'start_fraction': 0.5}])
    whole, first, second = (load_run(s) for s in campaign.runs)
    # the current column is 0.1 x the row index: which rows each half holds
    index = [np.rint(10.0 * r.extra['current_a']['X']).astype(int) for r in (first, second)]
    assert index[0].tolist() == list(range(0, 50))          # t < 1.0 s
    assert index[1].tolist() == list(range(50, N))          # t >= 1.0 s
    assert first.t[0] == 0.0 and second.t[0] == 0.0
    assert second.extra['t0_s'] == pytest.approx(1.0)
    assert second.extra['rows'].tolist() == list(range(51, N + 1))    # 1-based file rows
    np.testing.assert_allclose(second.position_m, whole.position_m[50:])
    assert whole.extra.get('window_s') is None


def test_window_in_seconds_and_the_direction_before_it(tmp_path):
    campaign = _campaign(tmp_path, [{'start_s': 0.6, 'end_s': 1.2}, {'start_s': 0.2}])
    late, early = (load_run(s) for s in campaign.runs)
    assert late.t.size == 30 and late.t[-1] == pytest.approx(0.58)
    # before 0.6 s the axis last moved in - (from 0.5 s); before 0.2 s in +
    assert late.extra['direction_before'] == {'X': -1.0}
    assert early.extra['direction_before'] == {'X': 1.0}


@pytest.mark.parametrize('window, key, text', [
    ({'start_s': 1.0, 'end_s': 1.0}, 'window.end_s', 'before it starts'),
    ({'start_s': 0.2, 'end_fraction': 0.5}, 'window.end_fraction', 'not both'),
    ({'start_fraction': 1.0}, 'window.start_fraction', 'fraction'),
    ({'end_fraction': 1.5}, 'window.end_fraction', 'fraction'),
    ({'start_s': -1.0}, 'window.start_s', '>= 0'),
    ({'begin_s': 1.0}, 'window.begin_s', 'unknown key'),
    ({}, 'window', 'start_s'),
])
def test_bad_windows_name_the_key(tmp_path, window, key, text):
    with pytest.raises(ConfigError) as err:
        _campaign(tmp_path, [window])
    assert err.value.key == f'runs[0].{key}' and text in str(err.value)


def test_a_window_beyond_the_record_is_a_data_error(tmp_path):
    campaign = _campaign(tmp_path, [{'start_s': 5.0}])
    with pytest.raises(DataError) as err:
        load_run(campaign.runs[0])
    assert 'runs[0].window' in str(err.value) and '0 sample(s)' in str(err.value)
    assert 'trace.csv' in str(err.value)
