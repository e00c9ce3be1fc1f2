"""Alignment: exact interval averages and recovery of a known offset to a fraction of a period."""
import math

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.errors import DataError
from feed_axis_energy.measured.align import (align_simulated, clock_corrected, estimate_offset,
                                             first_order_lag, interval_average,
                                             step_error_rms)

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


@pytest.mark.parametrize('stamp, shift', [('end', -0.35), ('centre', 0.0), ('start', 0.35)])
def test_stamp_position_of_the_window(stamp, shift):
    # the mean of a ramp over a 0.7 s window is its value at the window's centre
    t = np.linspace(0.0, 10.0, 37)
    y = 3.0 * t - 1.0
    stamps = np.array([1.0, 2.345, 9.0])
    got = align_simulated(t, y, stamps, offset_s=0.0, window_s=0.7, stamp=stamp)
    assert_allclose(got, 3.0 * (stamps + shift) - 1.0, rtol=1e-12)
    with pytest.raises(DataError, match='stamp must be one of'):
        align_simulated(t, y, stamps, offset_s=0.0, window_s=0.7, stamp='middle' * 40)


def _strokes(t, n=8, level=2.0):
    """Identical strokes dominated by narrow start peaks and braking dips (12 ms wide)."""
    y = np.zeros_like(t)
    for k in range(n):
        start = 0.5 + 1.6 * k
        y += level * ((t > start) & (t < start + 1.2))
        y += 300.0 * np.exp(-0.5 * ((t - start - 0.05) / 0.012) ** 2)
        y -= 150.0 * np.exp(-0.5 * ((t - start - 1.15) / 0.012) ** 2)
    return y


def test_narrow_peaks_and_repeated_strokes_align_within_a_quarter_period():
    # peaks narrower than the 50 ms sample, strokes repeating every 1.6 s inside a +-3 s
    # search: every offset must come out within a quarter of the period
    t_sim = np.arange(0.0, 14.0, 0.001)
    y_sim = _strokes(t_sim)
    t_meas = np.arange(0.0, 14.0, 0.05)
    rng = np.random.default_rng(11)
    for true in rng.uniform(-2.0, 2.0, size=12):
        y = align_simulated(t_sim, 1.1 * y_sim, t_meas, offset_s=true, window_s=0.05)
        y = y + rng.normal(scale=1.5, size=y.size)
        res = estimate_offset(t_meas, y, t_sim, y_sim, max_lag_s=3.0, window_s=0.05)
        assert abs(res.offset_s - true) < 0.0125, res.message
        at_true = y - align_simulated(t_sim, y_sim, t_meas, offset_s=true, window_s=0.05)
        assert res.rms_w <= 1.05 * np.std(at_true)


def test_runner_up_is_reported_one_stroke_away():
    t_sim = np.arange(0.0, 20.0, 0.01)
    y_sim = np.sin(2.0 * np.pi * t_sim / 2.0) ** 2
    t_meas = np.arange(0.0, 20.0, 0.1)
    y_meas = align_simulated(t_sim, y_sim, t_meas, offset_s=0.3, window_s=0.1)
    res = estimate_offset(t_meas, y_meas, t_sim, y_sim, max_lag_s=1.6, window_s=0.1)
    assert res.offset_s == pytest.approx(0.3, abs=0.01)
    # the best other candidate is a whole period (1 s) away and fits worse
    assert min(abs(res.runner_up_s - 1.3), abs(res.runner_up_s + 0.7)) < 0.01
    assert res.runner_up_rms_w > res.rms_w
    assert 'runner-up' in res.message


@pytest.mark.parametrize('ppm', [400.0, -250.0])
def test_clock_drift_is_estimated_on_a_long_record(ppm):
    # the meter's clock runs ppm faster: the offset grows by ppm * 1e-6 s per second
    t_sim = np.arange(0.0, 130.0, 0.001)
    y_sim = sum(_profile(t_sim - 16.0 * k) for k in range(8))
    t_meas = np.arange(0.0, 128.0, 0.05)
    rate = ppm * 1e-6
    y_meas = interval_average(t_sim, y_sim, t_meas - 0.4 - rate * t_meas, window_s=0.05)
    res = estimate_offset(t_meas, y_meas, t_sim, y_sim, max_lag_s=1.0, window_s=0.05)
    assert res.drift_ppm == pytest.approx(ppm, abs=20.0), res.drift_message


def test_the_drift_is_timed_where_the_edges_are():
    # the first half's strokes bunch at its start, the second's at its end: the halves'
    # offsets are measured 108 s apart, not the 64 s between their mean stamps (which read
    # +82 ppm for the 50 ppm here)
    t_sim = np.arange(0.0, 130.0, 0.001)
    y_sim = (sum(_profile(t_sim - 2.5 * k) for k in range(8))
             + sum(_profile(t_sim - 106.0 - 2.5 * k) for k in range(8)))
    t_meas = np.arange(0.0, 128.0, 0.05)
    rate = 50e-6
    y_meas = interval_average(t_sim, y_sim, t_meas - 0.4 - rate * t_meas, window_s=0.05)
    res = estimate_offset(t_meas, y_meas, t_sim, y_sim, max_lag_s=1.0, window_s=0.05)
    assert res.drift_ppm == pytest.approx(50.0, abs=2.0), res.drift_message


def test_clock_corrected_stamps_keep_the_middle_and_undo_the_rate():
    t = np.arange(0.0, 20.0, 0.05)      # 400 stamps: the middle is 9.975 s
    c = clock_corrected(t, 100.0)
    assert 0.5 * (c[0] + c[-1]) == pytest.approx(9.975, abs=1e-12)
    assert c[0] == pytest.approx(9.975e-4, abs=1e-12)    # 100 ppm of 9.975 s later
    assert (c[-1] - c[0]) == pytest.approx((t[-1] - t[0]) * (1.0 - 1e-4), rel=1e-12)
    assert np.array_equal(clock_corrected(t, 0.0), t)


def test_drift_on_a_short_record_is_not_estimable():
    t_sim = np.arange(0.0, 16.0, 0.001)
    t_meas = np.arange(0.0, 16.0, 0.1)
    y_meas = align_simulated(t_sim, _profile(t_sim), t_meas, offset_s=0.2, window_s=0.1)
    res = estimate_offset(t_meas, y_meas, t_sim, _profile(t_sim), max_lag_s=1.0,
                          window_s=0.1)
    assert np.isnan(res.drift_ppm) and 'not estimable' in res.drift_message


def test_rig_runs_with_random_offsets_over_stroke_cycles_are_aligned():
    # a small subset of bench/bench_align.py: the demonstrator's X axis, reciprocating
    # strokes, load friction the declared model lacks, 50 ms meter, 1.5 W noise
    from feed_axis_energy.gcode.load import parse_gcode
    from feed_axis_energy.machine.file import load_machine
    from feed_axis_energy.identify.rig import (EffectSpec, instrument_record, Instrument,
                                               simulate_run)
    from feed_axis_energy.identify.rig import stroke_program
    from feed_axis_energy.sim.simulate import simulate_program
    from feed_axis_energy.paths import config_dir
    machine = load_machine(config_dir() / 'demonstrator.yaml')
    meter = Instrument(window_s=0.05, period_s=0.05, noise_w=1.5, quantum_w=1.0)
    rng = np.random.default_rng(5)
    for feed, load in ((500.0, 22.711), (200.0, 0.0)):
        text = stroke_program(feed, axis='X', cycles=3)
        truth = simulate_run(machine, text, load_kg=load,
                             effects=(EffectSpec('load_friction', {'mu': 0.1}),),
                             instrument=Instrument(), offset_s=4.5)
        declared = simulate_program(parse_gcode(text), machine, load_kg=load)
        for true in rng.uniform(-4.5, 4.5, size=3):
            stamps, rec = instrument_record(truth.result.power.t, truth.truth_w.sum(axis=1),
                                            instrument=meter, offset_s=true, rng=rng,
                                            end_s=float(declared.power.t[-1]) + 1.0)
            res = estimate_offset(stamps, rec, declared.power.t,
                                  declared.power.power_w.sum(axis=1), max_lag_s=5.0,
                                  window_s=0.05)
            assert abs(res.offset_s - true) < 0.25 * meter.period_s, res.message


@pytest.mark.parametrize('period, q, window, stamp', [
    (0.05, 4, 0.05, 'end'), (0.1, 3, 0.0, 'end'), (0.1, 5, 0.03, 'centre')])
def test_uniform_fast_grid_equals_the_direct_correlation(period, q, window, stamp):
    from feed_axis_energy.measured.align import _Signals, stamp_shift
    rng = np.random.default_rng(1)
    t_sim = np.arange(0.0, 20.0, 0.001)
    y_sim = _profile(t_sim) + rng.normal(scale=0.1, size=t_sim.size)
    t = 0.37 + np.arange(150) * period
    y = np.interp(t, t_sim, y_sim) + rng.normal(size=t.size)
    sig = _Signals(t, y, t_sim, y_sim, window, stamp_shift(window, stamp))
    steps = 37
    fast = sig.uniform_correlation(period / q, steps)
    direct = sig.correlation(np.arange(-steps, steps + 1) * period / q)
    assert_allclose(fast, direct, atol=1e-12)
    # irregular stamps take the direct path
    jitter = t + rng.uniform(0.0, 0.2 * period, size=t.size)
    assert _Signals(jitter, y, t_sim, y_sim, window, 0.0).uniform_correlation(
        period / q, steps) is None


def test_first_order_lag_is_exact_on_ramps_steps_and_sines():
    tau = 0.02
    t = np.arange(0.0, 1.0, 0.001)
    # a ramp from rest: z = y - tau*slope*(1 - exp(-(t - t0)/tau)) after its start
    y = np.where(t > 0.2, 3.0 * (t - 0.2), 0.0)
    want = np.where(t > 0.2, 3.0 * (t - 0.2) - 3.0 * tau * (1.0 - np.exp(-(t - 0.2) / tau)),
                    0.0)
    assert_allclose(first_order_lag(t, y, tau), want, atol=1e-12)
    # a sine in steady state: gain 1/sqrt(1 + (w tau)^2), phase -atan(w tau) (to the
    # discretisation of a sine as straight lines between 1 ms samples)
    w = 7.0
    y2 = np.column_stack([np.sin(w * t), np.full(t.size, 4.0)])
    z = first_order_lag(t, y2, tau)
    late = t > 0.5
    ss = np.sin(w * t - math.atan(w * tau)) / math.sqrt(1.0 + (w * tau) ** 2)
    assert_allclose(z[late, 0], ss[late], atol=1e-5)
    assert_allclose(z[:, 1], 4.0, rtol=1e-12)      # a signal at rest stays there
    assert_allclose(first_order_lag(t, y, 0.0), y)


def test_first_order_lag_on_an_irregular_time_base_matches_the_uniform_one():
    tau = 0.01
    t = np.arange(0.0, 1.0, 0.001)
    y = np.where(t > 0.3, 2.0 * (t - 0.3), 0.0)
    uneven = np.r_[np.arange(0.0, 0.5, 0.001), np.arange(0.5, 0.8, 0.0005),
                   np.arange(0.8, 1.0, 0.002)]
    y_uneven = np.interp(uneven, t, y)
    inside = t <= uneven[-1]
    got = np.interp(t[inside], uneven, first_order_lag(uneven, y_uneven, tau))
    assert_allclose(got, first_order_lag(t, y, tau)[inside], atol=1e-10)


@pytest.mark.parametrize('tau', [-0.001, math.nan, 11.0])
def test_first_order_lag_refuses_a_time_constant_out_of_range(tau):
    t = np.arange(0.0, 1.0, 0.1)
    with pytest.raises(DataError, match='filter_s'):
        first_order_lag(t, t, tau)


def test_a_filtered_meter_is_read_through_its_filter_not_a_delay():
    # measured = the true signal through a 20 ms first-order filter, point samples at 10 ms;
    # align_simulated with filter_s reproduces it, the best pure delay does not
    tau = 0.02
    t = np.arange(0.0, 4.0, 0.001)
    y = np.clip(np.sin(3.0 * t), -0.5, 0.5) + (t > 2.0)       # kinks and a steep edge
    stamps = np.arange(0.5, 3.5, 0.01)
    meas = np.interp(stamps, t, first_order_lag(t, y, tau))
    filtered = align_simulated(t, y, stamps, offset_s=0.0, window_s=0.0, filter_s=tau)
    assert_allclose(filtered, meas, atol=1e-12)
    delayed = align_simulated(t, y, stamps, offset_s=tau, window_s=0.0)
    assert np.sqrt(np.mean((delayed - meas) ** 2)) > 1e-3


@pytest.mark.parametrize('filter_s', [0.0, 0.005])
@pytest.mark.parametrize('window_s', [0.01, 0.05])
def test_step_error_estimate_matches_the_error_against_a_fine_simulation(filter_s, window_s):
    # a smooth part, kinks between the samples (|sin|) and curvature: what the 1 ms
    # sampling changes in the meter's readings, against the same signal sampled 64 times
    # finer; the estimate is the half-rate reading's difference / 3 (the error goes with h^2)
    def sig(t):
        return (40 * np.sin(2 * np.pi * 1.3 * t) + 25 * np.abs(np.sin(2 * np.pi * 0.77 * t + 0.1))
                + 3 * t ** 2)
    h = 1e-3
    t_sim = np.arange(0.0, 6.0 + h / 2, h)
    t_fine = np.arange(0.0, 6.0 + h / 128, h / 64)
    t_meas = np.arange(0.2, 5.8, 0.01) + 0.0037
    kw = {'offset_s': 0.0, 'window_s': window_s, 'filter_s': filter_s}
    full = align_simulated(t_sim, sig(t_sim), t_meas, **kw)
    truth = align_simulated(t_fine, sig(t_fine), t_meas, **kw)
    actual = float(np.sqrt(np.mean((full - truth) ** 2)))
    est = step_error_rms(t_sim[::2], sig(t_sim)[::2], t_meas, full, **kw)
    assert est.shape == () and actual > 1e-4
    assert float(est) == pytest.approx(actual, rel=0.1)
    # columns, and a straight line, which the samples carry exactly
    line = np.column_stack([2.0 * t_sim, sig(t_sim)])
    both = align_simulated(t_sim, line, t_meas, **kw)
    est2 = step_error_rms(t_sim[::2], line[::2], t_meas, both, **kw)
    assert est2.shape == (2,) and est2[0] < 1e-9 and est2[1] == pytest.approx(float(est))
    # nothing to estimate from: zeros, not NaN
    assert step_error_rms(t_sim[:1], line[:1], t_meas, both, **kw).tolist() == [0.0, 0.0]
