"""Table-1 metrics: hand calculations on small arrays, pooling, and guarded divisions."""
import math

import numpy as np
import pytest

from feed_axis_energy.errors import DataError
from feed_axis_energy.measured.metrics import CHUNK, group_metrics, table1_metrics

T1 = [0.0, 1.0, 2.0, 3.0]
MEAS1 = [0.0, 100.0, 200.0, 100.0]
SIM1 = [10.0, 90.0, 220.0, 100.0]     # |dP| = 10, 10, 20, 0


def test_single_run_by_hand():
    m = table1_metrics(T1, MEAS1, SIM1)
    assert m.n_samples == 4 and m.duration_s == 3.0
    assert m.avg_diff_error_w == pytest.approx(10.0)
    assert m.max_diff_error_w == pytest.approx(20.0)
    assert m.rmse_w == pytest.approx(math.sqrt(600.0 / 4.0))
    # floor = 5 % of 200 W = 10 W: the 0 W sample is left out; 10 %, 10 %, 0 %
    assert m.pct_floor_w == pytest.approx(10.0) and m.n_pct_samples == 3
    assert m.avg_pct_error_pct == pytest.approx(20.0 / 3.0)
    assert m.max_pct_error_pct == pytest.approx(10.0)
    # trapezoids: 50 + 150 + 150 and 50 + 155 + 160
    assert m.energy_meas_j == pytest.approx(350.0)
    assert m.energy_sim_j == pytest.approx(365.0)
    assert m.energy_error_j == pytest.approx(15.0)
    assert m.energy_error_pct == pytest.approx(100.0 * 15.0 / 350.0)


def test_floor_fraction_selects_samples():
    m = table1_metrics(T1, MEAS1, SIM1, floor_fraction=0.6)     # floor 120 W: only 200 W
    assert m.n_pct_samples == 1 and m.avg_pct_error_pct == pytest.approx(10.0)


def test_dict_keys_carry_units():
    d = table1_metrics(T1, MEAS1, SIM1).to_dict()
    for key in ('avg_diff_error_w', 'max_diff_error_w', 'avg_pct_error_pct',
                'max_pct_error_pct', 'rmse_w', 'energy_error_j', 'energy_error_pct'):
        assert key in d
    assert d['avg_diff_error_w'] == pytest.approx(10.0)


def test_perfect_prediction_has_zero_error():
    p = np.array([5.0, -40.0, 300.0, 120.0])       # includes regenerative (negative) power
    m = table1_metrics(T1, p, p)
    assert m.max_diff_error_w == 0.0 and m.max_pct_error_pct == 0.0
    assert m.energy_error_j == 0.0 and m.n_pct_samples == 3     # 5 W is below 15 W


def test_zero_measured_power_gives_nan_percentages_not_inf():
    m = table1_metrics(T1, [0.0] * 4, [1.0] * 4)
    assert m.n_pct_samples == 0
    assert math.isnan(m.avg_pct_error_pct) and math.isnan(m.max_pct_error_pct)
    assert math.isnan(m.energy_error_pct)
    assert m.avg_diff_error_w == pytest.approx(1.0)


def test_group_pools_as_if_concatenated():
    a = table1_metrics(T1, MEAS1, SIM1)
    b = table1_metrics([0.0, 1.0], [200.0, 200.0], [190.0, 230.0])   # |dP| 10, 30; 5 %, 15 %
    g = group_metrics([a, b])
    assert g.n_samples == 6 and g.n_pct_samples == 5
    assert g.avg_diff_error_w == pytest.approx((10 + 10 + 20 + 0 + 10 + 30) / 6.0)
    assert g.max_diff_error_w == pytest.approx(30.0)
    assert g.avg_pct_error_pct == pytest.approx((10 + 10 + 0 + 5 + 15) / 5.0)
    assert g.max_pct_error_pct == pytest.approx(15.0)
    assert g.rmse_w == pytest.approx(math.sqrt((100 + 100 + 400 + 0 + 100 + 900) / 6.0))
    assert g.energy_meas_j == pytest.approx(550.0) and g.energy_sim_j == pytest.approx(575.0)
    assert g.energy_error_pct == pytest.approx(100.0 * 25.0 / 550.0)
    assert g.duration_s == pytest.approx(4.0) and math.isnan(g.pct_floor_w)
    with pytest.raises(DataError, match='no runs'):
        group_metrics([])


@pytest.mark.parametrize('t, meas, sim, column, row', [
    (T1, [0.0, float('nan'), 1.0, 1.0], SIM1, 'p_meas', 2),
    (T1, MEAS1, [1.0, 2.0, 3.0], 'p_sim', None),
    ([0.0, 1.0, 1.0, 2.0], MEAS1, SIM1, 't', 3),
])
def test_bad_arrays_are_named(t, meas, sim, column, row):
    with pytest.raises(DataError) as info:
        table1_metrics(t, meas, sim)
    assert info.value.column == column and info.value.row == row


def _long_run(seed=3):
    # two and a half chunks of irregular stamps: the sums cross chunk boundaries
    rng = np.random.default_rng(seed)
    n = 2 * CHUNK + CHUNK // 2
    t = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, n))
    meas = 200.0 * np.sin(3.0 * t) + rng.normal(0.0, 5.0, n)
    sim = meas + rng.normal(1.0, 3.0, n)
    return t, meas, sim


def test_chunked_sums_equal_whole_array_formulas():
    t, meas, sim = _long_run()
    m = table1_metrics(t, meas, sim)
    err = np.abs(meas - sim)
    floor = 0.05 * np.max(np.abs(meas))
    above = np.abs(meas) >= floor
    pct = 100.0 * err[above] / np.abs(meas[above])
    assert m.n_samples == t.size and m.n_pct_samples == int(above.sum())
    assert m.avg_diff_error_w == pytest.approx(err.mean(), rel=1e-12)
    assert m.max_diff_error_w == err.max()
    assert m.rmse_w == pytest.approx(np.sqrt(np.mean(err ** 2)), rel=1e-12)
    assert m.avg_pct_error_pct == pytest.approx(pct.mean(), rel=1e-12)
    assert m.max_pct_error_pct == pytest.approx(pct.max(), rel=1e-14)
    # the trapezoids bridging the chunks are counted once each
    assert m.energy_meas_j == pytest.approx(np.trapezoid(meas, t), rel=1e-12, abs=1e-9)
    assert m.energy_sim_j == pytest.approx(np.trapezoid(sim, t), rel=1e-12, abs=1e-9)


@pytest.mark.parametrize('where', ['inside', 'boundary'])
def test_a_late_bad_sample_names_its_row(where):
    t, meas, sim = _long_run()
    i = 2 * CHUNK + 17 if where == 'inside' else 2 * CHUNK
    t[i] = t[i - 1]                                  # a repeated stamp
    rows = np.arange(t.size) + 10
    with pytest.raises(DataError) as info:
        table1_metrics(t, meas, sim, rows=rows)
    assert info.value.column == 't' and info.value.row == i + 10
    t, meas, sim = _long_run()
    sim[i] = np.inf
    with pytest.raises(DataError) as info:
        table1_metrics(t, meas, sim, rows=rows)
    assert info.value.column == 'p_sim' and info.value.row == i + 10
