"""Tests of the one-dimensional seven-phase velocity profiles."""
import math

import numpy as np
from numpy.testing import assert_allclose
import pytest
import ruckig

from feed_axis_energy.plan.profiles import min_distance, plan_profiles, ramp, reach_speed


def _integrate(prof, v0):
    """Exact end state (s, v, a) of each move by integrating its constant-jerk phases."""
    s = np.zeros_like(v0)
    v = np.array(v0, dtype=float)
    a_end = np.zeros_like(v0)
    for k in range(7):
        T, a0, j = prof.duration[:, k], prof.a_start[:, k], prof.jerk[:, k]
        s = s + v * T + a0 * T ** 2 / 2 + j * T ** 3 / 6
        v = v + a0 * T + j * T ** 2 / 2
        a_end = np.where(T > 0, a0 + j * T, a_end)
    return s, v, a_end


def test_ramp_hand_calculation():
    # dv = 0.6 >= a^2/j = 0.125: T = dv/a + a/j = 0.24 + 0.05
    ap, tj, tc, tt = ramp(np.array([0.6, 0.1]), 2.5, 50.0)
    assert_allclose(ap, [2.5, math.sqrt(0.1 * 50.0)])
    assert_allclose(tt, [0.29, 2 * math.sqrt(0.1 / 50.0)])
    assert_allclose(tj, [0.05, math.sqrt(0.1 / 50.0)])
    assert_allclose(tc, [0.19, 0.0], atol=1e-15)
    assert_allclose(min_distance(np.array([0.0]), np.array([0.6]), 2.5, 50.0), [0.3 * 0.29])
    # trapezoid: v^2 / (2 a)
    assert_allclose(min_distance(np.array([0.0]), np.array([0.6]), 2.5, np.inf),
                    [0.36 / 5.0])


@pytest.mark.parametrize('jmax', [50.0, 3.0, np.inf])
def test_reach_speed_inverts_min_distance(jmax):
    rng = np.random.default_rng(1)
    for _ in range(50):
        v_end = rng.uniform(0.0, 0.5) * rng.integers(0, 2)
        length = 10 ** rng.uniform(-6, 0)
        v = reach_speed(v_end, length, 2.5, jmax)
        assert v >= v_end
        # the speed is exact to rounding: nudging it by 1e-12 brackets the length
        lo, hi = min_distance(np.array([v * (1 - 1e-12), v * (1 + 1e-12)]),
                              np.array([v_end, v_end]), 2.5, jmax)
        assert lo <= length <= hi


@pytest.mark.parametrize('jmax', [50.0, np.inf])
def test_profiles_respect_limits_and_reach_the_end(jmax):
    rng = np.random.default_rng(7)
    m = 400
    amax = rng.uniform(0.5, 5.0, m)
    vmax = rng.uniform(0.05, 1.0, m)
    v0 = vmax * rng.uniform(0, 1, m) * (rng.uniform(size=m) > 0.3)
    v1 = vmax * rng.uniform(0, 1, m) * (rng.uniform(size=m) > 0.3)
    need = min_distance(np.maximum(v0, v1), np.minimum(v0, v1), amax, jmax)
    length = need * rng.uniform(1.0, 3.0, m) + 1e-6 * rng.uniform(size=m)
    prof = plan_profiles(length, v0, v1, vmax, amax, np.full(m, jmax))
    s, v, a_end = _integrate(prof, v0)
    assert np.all(prof.duration >= 0.0)
    assert_allclose(s, length, rtol=1e-9, atol=1e-12)
    assert_allclose(v, v1, atol=1e-9)
    assert_allclose(a_end, 0.0, atol=1e-9 if np.isfinite(jmax) else 10.0)
    assert np.all(prof.v_peak <= vmax * (1 + 1e-12))
    # acceleration is extremal at phase ends; the peak is the constant-phase level
    assert np.all(np.abs(prof.a_start) <= amax[:, None] * (1 + 1e-12))
    if np.isfinite(jmax):
        assert np.all(np.abs(prof.jerk) <= jmax)
        assert_allclose(prof.a_start[:, 0], 0.0)


def test_short_move_lowers_the_peak():
    # 1 mm rest to rest cannot reach 0.6 m/s at a = 2.5
    prof = plan_profiles(np.array([0.001]), np.zeros(1), np.zeros(1), np.array([0.6]),
                         np.array([2.5]), np.array([50.0]))
    assert prof.v_peak[0] < 0.6
    assert_allclose(prof.duration[0, 3], 0.0, atol=1e-9)
    s, v, _ = _integrate(prof, np.zeros(1))
    assert_allclose(s, [0.001], rtol=1e-12)


@pytest.mark.parametrize('case', [
    (0.4, 0.0, 0.0, 0.6), (0.4, 0.1, 0.05, 0.3), (0.002, 0.0, 0.0, 0.6), (0.05, 0.2, 0.0, 0.5),
])
def test_duration_matches_ruckig(case):
    length, v0, v1, vmax = case
    inp = ruckig.InputParameter(1)
    inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [v0], [0.0]
    inp.target_position, inp.target_velocity, inp.target_acceleration = [length], [v1], [0.0]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [vmax], [2.5], [50.0]
    traj = ruckig.Trajectory(1)
    assert ruckig.Ruckig(1).calculate(inp, traj) == ruckig.Result.Working
    prof = plan_profiles(np.array([length]), np.array([v0]), np.array([v1]), np.array([vmax]),
                         np.array([2.5]), np.array([50.0]))
    # ruckig is time-optimal; with zero end accelerations our profile should be too
    assert_allclose(prof.move_duration[0], traj.duration, rtol=1e-6)
