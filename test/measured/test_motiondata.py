"""Motion rebuilt from coarse samples: invariants and a hand-calculated rapid start."""
import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.errors import DataError
from feed_axis_energy.measured.motiondata import reconstruct_motion


def _at(motion, t):
    idx = np.searchsorted(motion.t, np.asarray(t) - 1e-9)
    assert_allclose(motion.t[idx], t, atol=1e-9)
    return idx


def test_a_rapid_start_inside_one_sample_becomes_a_pulse():
    # 100 ms samples; the axis is at rest at 0.1 s and moving at 45 mm/s at 0.2 s, the
    # acceleration column reads 0 at both stamps
    t = np.array([0.0, 0.1, 0.2, 0.3])
    v = np.array([0.0, 0.0, 0.045, 0.045])[:, None]
    p = np.array([0.0, 0.0, 0.002, 0.0065])[:, None]
    m = reconstruct_motion(t, p, axes=('X',), rate_hz=1000.0, vel=v,
                           acc=np.zeros_like(v))
    i = _at(m, t)
    assert_allclose(m.acc[i, 0], 0.0, atol=1e-12)            # as sampled at the stamps
    assert_allclose(m.vel[i, 0], v[:, 0], atol=1e-15)
    assert_allclose(m.pos[i, 0], p[:, 0], atol=1e-15)
    # by hand: a = 6 c s (1 - s) with c = 0.045 / 0.1 = 0.45 m/s^2, peak 1.5 c at s = 1/2
    mid = _at(m, np.array([0.15]))[0]
    assert m.acc[mid, 0] == pytest.approx(0.675, rel=1e-9)
    assert np.all(m.acc[:i[1] + 1] == 0.0) and np.all(m.acc[i[2]:] == 0.0)


def test_each_interval_keeps_the_sampled_velocity_and_kinetic_energy_change():
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.integers(50, 150, size=40)) / 1000.0     # on the 20 kHz grid
    v = rng.normal(0.0, 0.03, size=(40, 2))
    a = rng.normal(0.0, 0.5, size=(40, 2))
    p = np.cumsum(v * 0.1, axis=0)
    m = reconstruct_motion(t, p, axes=('X', 'Y'), rate_hz=20000.0, vel=v, acc=a)
    i = _at(m, t[:-1])
    assert_allclose(m.acc[i], a[:-1], atol=1e-12)
    for j in range(len(i) - 1):
        sl = slice(i[j], i[j + 1] + 1)
        # integral of a is the velocity change; integral of a v is half the change of v^2
        dv = np.trapezoid(m.acc[sl], m.t[sl], axis=0)
        dke = np.trapezoid(m.acc[sl] * m.vel[sl], m.t[sl], axis=0)
        assert_allclose(dv, v[j + 1] - v[j], atol=1e-6)
        assert_allclose(dke, 0.5 * (v[j + 1] ** 2 - v[j] ** 2), atol=1e-7)


def test_size_is_estimated_before_allocating():
    t = np.array([0.0, 1e6])
    with pytest.raises(DataError, match='limit'):
        reconstruct_motion(t, np.zeros((2, 3)), axes=('X', 'Y', 'Z'), rate_hz=1000.0,
                           source='big.csv')
    with pytest.raises(DataError, match='rate_hz'):
        reconstruct_motion(t[:2] / 1e6, np.zeros((2, 1)), axes=('X',), rate_hz=0.0)
