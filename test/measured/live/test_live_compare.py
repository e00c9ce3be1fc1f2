"""The running comparison: lag recovered, energies as Table 1's, alarm, bounded memory."""
import math
import tracemalloc

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.errors import DataError
from feed_axis_energy.measured import align_simulated, interval_average, table1_metrics
from feed_axis_energy.measured.live import LiveComparison, LiveSettings


def pulses(t, seed=3):
    """A power trace with structure at every lag: smooth pulses of random height and time."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(t[0], t[-1], size=int((t[-1] - t[0]) / 2) + 4)
    heights = rng.uniform(10.0, 80.0, size=centres.size)
    out = np.zeros((t.size, 2))
    for c, h in zip(centres, heights):
        bump = h * np.exp(-0.5 * ((t - c) / 0.3) ** 2)
        out[:, 0] += bump
        out[:, 1] += 0.5 * np.roll(bump, 7)
    return out


def run(core, t_pred, y_pred, t_meas, y_meas, *, chunk=100):
    """Feed both streams as they would arrive: prediction a chunk ahead of the measurement."""
    j = 0
    for i, t in enumerate(t_meas):
        while j < t_pred.size and t_pred[j] <= t + 1.0:
            core.add_prediction(t_pred[j:j + chunk], y_pred[j:j + chunk])
            j += chunk
        core.add_measured(float(t), y_meas[i])
    core.add_prediction(t_pred[j:], y_pred[j:])
    return core.finish()


@pytest.mark.parametrize('lag_s, window_s', [(0.37, 0.0), (-1.234, 0.1), (0.0, 0.1)])
def test_a_known_lag_is_recovered(lag_s, window_s):
    t_pred = np.arange(0.0, 80.0, 0.001)
    y_pred = pulses(t_pred)
    t_meas = np.arange(2.0, 78.0, 0.1)
    # the instrument: averages over its window, stamps the end, lag_s later than the model
    y_meas = interval_average(t_pred, y_pred, t_meas - lag_s, window_s=window_s)
    core = LiveComparison(('X', 'Y'), LiveSettings(window_s=window_s, max_lag_s=3.0))
    out = run(core, t_pred, y_pred, t_meas, y_meas)
    assert out['lag']['status'] == 'ok'
    assert abs(out['lag']['lag_s'] - lag_s) < 1e-3
    # a model without error: energies agree, the residual is nil, no alarm
    assert abs(out['energy_error_pct']['total']) < 0.05
    assert out['alarm']['count'] == 0


def test_energies_are_table1_energies_at_the_lag_used():
    t_pred = np.arange(0.0, 40.0, 0.001)
    y_pred = pulses(t_pred, seed=5)
    t_meas = np.arange(1.0, 39.0, 0.1)
    y_meas = 1.1 * interval_average(t_pred, y_pred, t_meas - 0.25, window_s=0.0) + 1.0
    core = LiveComparison(('X', 'Y'), LiveSettings(max_lag_s=2.0))
    out = run(core, t_pred, y_pred, t_meas, y_meas)
    lag = out['lag']['lag_s']
    aligned = align_simulated(t_pred, y_pred, t_meas, offset_s=lag, window_s=0.0)
    table = table1_metrics(t_meas, y_meas.sum(1), aligned.sum(1))
    assert_allclose(out['measured_energy_j']['total'], table.energy_meas_j, rtol=1e-12)
    assert_allclose(out['predicted_energy_j']['total'], table.energy_sim_j, rtol=1e-12)
    assert_allclose(out['energy_error_pct']['total'], table.energy_error_pct, rtol=1e-9)
    for j, axis in enumerate('XY'):
        assert_allclose(out['measured_energy_j'][axis], np.trapezoid(y_meas[:, j], t_meas))


def test_rows_leaving_the_ring_are_settled_into_the_same_sums():
    """A ring shorter than the run: old rows kept as sums, the total unchanged."""
    t_pred = np.arange(0.0, 60.0, 0.001)
    y_pred = pulses(t_pred, seed=7)
    t_meas = np.arange(1.0, 59.0, 0.1)
    y_meas = interval_average(t_pred, y_pred, t_meas - 0.5, window_s=0.0) * 0.9
    settings = LiveSettings(max_lag_s=1.0, freeze_count=2, freeze_tol_s=1e-3, ring_s=15.0)
    core = LiveComparison(('X', 'Y'), settings)
    out = run(core, t_pred, y_pred, t_meas, y_meas)
    assert out['lag']['frozen'] and core.settled_rows > 0
    assert core.meas.size <= 1.05 * 15.0 / 0.1 + 1      # the ring's span, 5 % slack
    aligned = align_simulated(t_pred, y_pred, t_meas, offset_s=out['lag']['lag_s'],
                              window_s=0.0)
    assert_allclose(out['predicted_energy_j']['total'], np.trapezoid(aligned.sum(1), t_meas),
                    rtol=1e-9)
    assert_allclose(out['energy_error_pct']['total'], 100.0 / 9.0, atol=0.05)   # 1 / 0.9 - 1


def stream_with_residual(step_w, *, seconds=60.0, step_at=30.0, noise_w=2.0, seed=1):
    t_pred = np.arange(0.0, seconds, 0.01)
    y_pred = pulses(t_pred, seed=seed)
    t_meas = np.arange(0.5, seconds - 0.5, 0.1)
    rng = np.random.default_rng(seed)
    y_meas = interval_average(t_pred, y_pred, t_meas, window_s=0.0)
    y_meas += rng.normal(0.0, noise_w, size=y_meas.shape)
    y_meas[t_meas >= step_at, 0] += step_w
    settings = LiveSettings(max_lag_s=1.0, band_floor_w=5.0, band_pct=10.0)
    return run(LiveComparison(('X', 'Y'), settings), t_pred, y_pred, t_meas, y_meas)


def test_the_alarm_fires_on_a_step_in_the_residual():
    out = stream_with_residual(40.0)
    assert out['alarm']['count'] == 1 and out['alarm']['active']
    assert out['alarm']['residual_w'] > out['alarm']['band_w']
    assert out['alarm']['band_source'] == 'default'


def test_the_alarm_stays_quiet_on_noise():
    out = stream_with_residual(0.0, noise_w=4.0)
    assert out['alarm']['count'] == 0 and not out['alarm']['active']


def test_the_alarm_releases_with_hysteresis():
    core = LiveComparison(('X',), LiveSettings(band_floor_w=10.0, band_pct=0.0, fixed_lag_s=0.0,
                                               alarm_window_s=0.5, alarm_hold_s=1.0))
    core.add_prediction(np.array([0.0, 100.0]), np.zeros((2, 1)))
    residual = [0.0] * 50 + [20.0] * 50 + [9.0] * 50 + [7.0] * 50
    states = []
    for i, r in enumerate(residual):
        core.add_measured(0.1 * i, np.array([r]))
        states.append(core.snapshot()['alarm']['active'])
    assert not any(states[:60])
    assert states[99]                  # on after the hold
    assert states[149]                 # 9 W: inside the band, not inside 80 % of it: held on
    assert not states[-1]              # 7 W < 8 W for the hold: released
    assert core.snapshot()['alarm']['count'] == 1


def test_memory_is_bounded_over_a_long_stream():
    settings = LiveSettings(max_lag_s=1.0, ring_s=30.0, realign_every_s=120.0)
    core = LiveComparison(('X', 'Y'), settings)
    t_block = np.arange(0.0, 60.0, 0.01)
    y_block = pulses(t_block, seed=11)
    peaks = []
    tracemalloc.start()
    try:
        for block in range(12):                           # 12 minutes, 7 200 rows
            t0 = 60.0 * block
            core.add_prediction(t0 + t_block, y_block)
            for i in range(0, t_block.size, 10):
                core.add_measured(t0 + t_block[i], y_block[i])
            if block in (3, 11):
                peaks.append(tracemalloc.get_traced_memory()[0])
    finally:
        tracemalloc.stop()
    assert core.meas.size <= 1.05 * 300 + 1                  # 30 s at 10 Hz, 5 % slack
    assert core.pred.size <= 1.05 * 3200 + 1                 # 30 + 1 + 1 s at 100 Hz
    assert peaks[1] < peaks[0] + 256 * 1024, peaks
    out = core.snapshot()
    assert math.isfinite(out['energy_error_pct']['total'])


def test_prediction_out_of_order_is_counted():
    core = LiveComparison(('X',))
    core.add_prediction(np.array([0.0, 1.0]), np.zeros((2, 1)))
    core.add_prediction(np.array([0.5, 2.0, np.nan]), np.zeros((3, 1)))
    assert core.prediction_late == 2 and core.pred.size == 3


def test_bad_settings_are_refused():
    with pytest.raises(DataError, match='ring_s'):
        LiveSettings(ring_s=0.0)
    with pytest.raises(DataError, match='stamp'):
        LiveSettings(stamp='middle')
