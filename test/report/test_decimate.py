"""PowerTrace: min/max per time column, chunk by chunk, whatever the program's length."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from numpy.testing import assert_allclose, assert_array_equal
import pytest

from feed_axis_energy.report.decimate import PowerTrace


def _series(n: int, *, seed: int = 1, dt: float = 1e-3):
    """Two axes of random power with one single-sample spike, energy by the trapezoid rule."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    power = rng.normal(0.0, 10.0, (n, 2))
    spike = n // 3
    power[spike, 1] = 5000.0                    # a peak of one sample
    total = power.sum(axis=1)
    both = np.column_stack((power, total))
    energy = np.vstack((np.zeros((1, 3)),
                        np.cumsum(0.5 * (both[1:] + both[:-1]) * dt, axis=0)))
    pos = np.column_stack((np.sin(t), 0.5 * np.cos(t)))
    line = 1 + np.arange(n) // 250              # blocks of 250 samples
    line[spike] = 999                           # the spike's own line
    return t, power, total, energy, pos, line, spike


def _chunks(series, size: int):
    t, power, total, energy, pos, line, _ = series
    for lo in range(0, t.shape[0], size):
        s = slice(lo, lo + size)
        yield SimpleNamespace(
            power=SimpleNamespace(t=t[s], axes=('X', 'Y'), power_w=power[s], total_w=total[s],
                                  energy_j=energy[s, :2], total_energy_j=energy[s, 2],
                                  line=line[s]),
            motion=SimpleNamespace(pos=pos[s]))


def _feed(series, size: int, **kw) -> PowerTrace:
    trace = PowerTrace(**kw)
    for chunk in _chunks(series, size):
        trace.add(chunk)
    return trace


@pytest.mark.parametrize('kw', [dict(columns=100), dict(columns=100, duration_s=19.999),
                                dict(columns=64, start_width_s=1e-4)])
def test_every_sample_lies_in_its_column_band_and_peaks_survive(kw) -> None:
    series = _series(20000)
    t, power, total, energy, pos, line, spike = series
    tr = _feed(series, 1500, **kw).trace()
    assert kw['columns'] // 2 <= tr.t_lo.shape[0] <= kw['columns']
    assert tr.count.sum() == t.shape[0]
    both = np.column_stack((power, total))
    col = np.searchsorted(tr.t_lo, t, side='right') - 1        # the column holding each sample
    assert np.all(t <= tr.t_hi[col])
    assert np.all(both >= tr.p_min[col]) and np.all(both <= tr.p_max[col])
    # the extremes of every column are samples of that column (the band is not wider)
    for j in range(3):
        assert_allclose(np.maximum.reduceat(both[:, j], np.searchsorted(t, tr.t_lo)),
                        tr.p_max[:, j])
    assert tr.p_max[:, 1].max() == 5000.0
    assert tr.line_at_peak[col[spike]] == 999
    assert_allclose(tr.pos_at_peak[col[spike]], pos[spike])
    assert_allclose(tr.e_end[-1], energy[-1])
    assert_allclose(tr.pos_min, pos.min(axis=0))
    assert_allclose(tr.pos_max, pos.max(axis=0))


def test_chunk_size_does_not_change_the_trace() -> None:
    series = _series(12345, seed=7)
    a = _feed(series, 12345, columns=50).trace()
    b = _feed(series, 97, columns=50).trace()
    assert a.width_s == b.width_s
    for name in ('t_lo', 't_hi', 'count', 'p_min', 'p_max', 'e_end', 'pos_at_peak',
                 'line_at_peak'):
        assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_memory_is_the_columns_not_the_samples() -> None:
    series = _series(200000, seed=3)
    trace = _feed(series, 8192, columns=200)
    assert trace.p_max.shape == (200, 3)
    assert trace.trace().t_lo.shape[0] <= 200


def test_first_time_of_a_line() -> None:
    series = _series(2000)
    trace = _feed(series, 333)
    # line n covers samples 250 (n - 1) ... at 1 ms
    assert trace.first_time(1) == 0.0
    assert_allclose(trace.first_time(3), 0.5)
    assert_allclose(trace.first_time(999), series[-1] * 1e-3)
    assert np.isnan(trace.first_time(12345))


def test_fewer_than_two_columns_is_refused() -> None:
    with pytest.raises(ValueError, match='at least 2 columns'):
        PowerTrace(columns=1)
