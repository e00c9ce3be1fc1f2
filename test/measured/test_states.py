"""Residual by motion state: labels from a hand-made motion, sums and pooling."""
import math

import numpy as np
from numpy.testing import assert_array_equal
import pytest

from feed_axis_energy.measured.states import pool_states, residual_by_state, STATES, state_labels


def test_labels_of_rest_a_start_and_a_steady_move():
    # 1 kHz: rest until 1 s, accelerate at 0.5 m/s^2 for 0.1 s (to 50 mm/s), then steady
    t = np.arange(0.0, 3.0, 0.001)
    acc = np.where((t >= 1.0) & (t < 1.1), 0.5, 0.0)[:, None]
    vel = np.cumsum(acc, axis=0) * 0.001
    tau = np.array([0.5, 0.95, 1.05, 1.15, 1.3, 2.5])
    labels = state_labels(t, np.hstack([vel, 0 * vel]), tau, period_s=0.1)
    # 0.95 s sees the start within one period, 1.15 s still does, 1.3 s does not
    want = ['standstill', 'transient', 'transient', 'transient', 'steady', 'steady']
    assert [STATES[i] for i in labels] == want


def test_noise_in_acceleration_is_not_a_transient_but_a_sub_sample_start_is():
    # steady 6 mm/s on X whose velocity scatters by 0.2 mm/s (an acceleration column from it
    # would scatter by metres per second squared); Y rests, then reaches 45 mm/s within 20 ms
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 4.0, 0.001)
    vx = 0.006 + rng.normal(0.0, 2e-4, t.size)
    vy = np.clip((t - 2.5) / 0.02, 0.0, 1.0) * 0.045
    tau = np.array([1.0, 1.5, 2.0, 2.45, 2.55, 3.9])
    labels = state_labels(t, np.column_stack([vx, vy]), tau, period_s=0.1)
    # 2.45 s sees the start 50 ms later; 2.55 s sees it 50 ms earlier: a mean acceleration
    # of 0.045 m/s / 0.1 s = 0.45 m/s^2 over the period that holds it
    want = ['steady', 'steady', 'steady', 'transient', 'transient', 'steady']
    assert [STATES[i] for i in labels] == want


def test_sums_shares_and_pooling():
    labels = np.array([0, 1, 1, 2])
    one = residual_by_state(labels, np.array([1.0, 2.0, -2.0, 3.0]))
    d = {s.state: s.to_dict() for s in one}
    assert d['steady']['mean_w'] == 0.0 and d['steady']['rms_w'] == pytest.approx(2.0)
    assert d['transient']['squared_error_pct'] == pytest.approx(100.0 * 9.0 / 18.0)
    assert d['standstill']['samples_pct'] == 25.0
    two = residual_by_state(np.array([2, 2]), np.array([1.0, 1.0]))
    pooled = {s.state: s.to_dict() for s in pool_states([one, two])}
    assert pooled['transient']['n_samples'] == 3
    assert pooled['transient']['mean_w'] == pytest.approx(5.0 / 3.0)
    assert pooled['transient']['squared_error_pct'] == pytest.approx(100.0 * 11.0 / 20.0)
    empty = residual_by_state(np.array([1]), np.array([0.0]))
    assert math.isnan(empty[0].to_dict()['mean_w'])
    assert_array_equal([s.n_samples for s in empty], [0, 1, 0])
