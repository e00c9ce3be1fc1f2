"""Alignment: exact interval averages and recovery of a known offset to a fraction of a period."""
import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.core.errors import DataError
from feed_axis_energy.core.measured.align import (
    align_simulated, estimate_offset, interval_average)

# piecewise-linear signal: 0 -> 2 on [0, 1], 2 on [1, 2], 2 -> -2 on [2, 4]
T_PL = np.array([0.0, 1.0, 2.0, 4.0])
Y_PL = np.array([0.0, 2.0, 2.0, -2.0])


@pytest.mark.parametrize('stamp, expected', [
    (0.5, 0.25),     # integral of 2t over [0, 0.5] = 0.25, zero before t=0
    (1.5, 1.75),     # (1 + 1) - 0.25
    (3.0, 1.0),      # mean of the ramp 2 -> 0 on [2, 3]
    (4.5, -1.75),    # ramp -1 -> -2 on [3.5, 4] (-0.75) then held at -2 for 0.5 s (-1)
    (5.0, -2.0),     # after the end: last value held
    (-1.0, 0.0),     # before the start: first value held
])
def test_interval_average_matches_hand_integrals(stamp, expected):
    got = interval_average(T_PL, Y_PL, np.array([stamp]), window_s=1.0)
    assert_allclose(got, [expected], atol=1e-12)


def test_interval_average_columns_shapes_and_zero_window():
    y2 = np.column_stack([Y_PL, 10.0 * Y_PL])
    stamps = np.array([[0.5, 1.5], [3.0, 5.0]])
    got = interval_average(T_PL, y2, stamps, window_s=1.0)
    assert got.shape == (2, 2, 2)
    assert_allclose(got[..., 0], [[0.25, 1.75], [1.0, -2.0]], atol=1e-12)
    assert_allclose(got[..., 1], 10.0 * got[..., 0], atol=1e-12)
    assert_allclose(interval_average(T_PL, Y_PL, [0.5, 3.0], window_s=0.0), [1.0, 0.0])


def test_interval_average_of_a_ramp_is_its_midpoint_value():
    t = np.linspace(0.0, 10.0, 37)               # uneven with respect to the stamps
    y = 3.0 * t - 1.0
    stamps = np.array([1.0, 2.345, 9.9])
    got = interval_average(t, y, stamps, window_s=0.7)
    assert_allclose(got, 3.0 * (stamps - 0.35) - 1.0, rtol=1e-12)


def test_interval_average_rejects_bad_input():
    with pytest.raises(DataError, match='window_s'):
        interval_average(T_PL, Y_PL, [1.0], window_s=-0.1)
    with pytest.raises(DataError, match='increase strictly') as info:
        interval_average([0.0, 1.0, 1.0], [0.0, 1.0, 2.0], [1.0], window_s=0.1)
    assert info.value.column == 't_sim' and info.value.row == 3


def _profile(t):
    """Irregular power bursts (accelerations and steady feeds), not periodic."""
    bumps = [(1.0, 300.0, 0.15), (2.7, -120.0, 0.2), (4.1, 220.0, 0.1), (6.8, 90.0, 0.6),
             (8.2, -250.0, 0.12), (11.5, 180.0, 0.3), (13.9, 60.0, 1.0)]
    y = np.zeros_like(t)
    for centre, amp, width in bumps:
        y += amp * np.exp(-0.5 * ((t - centre) / width) ** 2)
    return y


@pytest.mark.parametrize('true_offset', [0.537, -1.234, 0.05])
def test_known_offset_recovered_to_a_fraction_of_the_period(true_offset):
    period = 0.1
    t_sim = np.arange(0.0, 16.0, 0.001)
    y_sim = _profile(t_sim)
    t_meas = np.arange(0.0, 16.0, period)
    rng = np.random.default_rng(7)
    clean = align_simulated(t_sim, y_sim, t_meas, offset_s=true_offset, window_s=period)
    # gain and bias errors of the model must not move the offset
    y_meas = 1.3 * clean + 5.0 + rng.normal(scale=3.0, size=t_meas.size)
    res = estimate_offset(t_meas, y_meas, t_sim, y_sim, max_lag_s=2.0, window_s=period)
    assert res.status == 'ok', res.message
    assert abs(res.offset_s - true_offset) < 0.1 * period
    assert res.peak_correlation > 0.95
    assert res.lags_s.shape == res.correlation.shape


def test_uncorrelated_measurement_is_weak_not_an_error():
    t_sim = np.arange(0.0, 16.0, 0.01)
    t_meas = np.arange(0.0, 16.0, 0.1)
    noise = np.random.default_rng(3).normal(size=t_meas.size)
    res = estimate_offset(t_meas, noise, t_sim, _profile(t_sim), max_lag_s=1.0, window_s=0.1)
    assert res.status == 'weak' and 'below' in res.message


def test_constant_signal_is_weak():
    t = np.arange(0.0, 5.0, 0.1)
    res = estimate_offset(t, np.ones_like(t), t, np.sin(t), max_lag_s=1.0, window_s=0.1)
    assert res.status == 'weak' and np.isnan(res.peak_correlation)


def test_offset_outside_the_searched_range_is_flagged_edge():
    t_sim = np.arange(0.0, 16.0, 0.01)
    y_sim = np.exp(-0.5 * ((t_sim - 8.0) / 2.0) ** 2)   # broad: still correlates at 1 s
    t_meas = np.arange(0.0, 16.0, 0.1)
    y_meas = align_simulated(t_sim, y_sim, t_meas, offset_s=3.0, window_s=0.1)
    res = estimate_offset(t_meas, y_meas, t_sim, y_sim, max_lag_s=1.0, window_s=0.1)
    assert res.status == 'edge' and 'widen max_lag_s' in res.message
    assert res.offset_s == pytest.approx(1.0)


def test_repeated_identical_moves_are_ambiguous():
    t_sim = np.arange(0.0, 20.0, 0.01)
    y_sim = np.sin(2.0 * np.pi * t_sim / 2.0) ** 2       # reciprocating, period 1 s
    t_meas = np.arange(0.0, 20.0, 0.1)
    y_meas = align_simulated(t_sim, y_sim, t_meas, offset_s=0.3, window_s=0.1)
    res = estimate_offset(t_meas, y_meas, t_sim, y_sim, max_lag_s=1.6, window_s=0.1)
    assert res.status == 'ambiguous'
