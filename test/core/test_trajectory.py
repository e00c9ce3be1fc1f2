"""Tests of the trajectory planner (plan) and of motion_from_samples.

Limit tolerances: analytic samples within 1e-9 relative of the limits; finite differences of
sampled position (-> velocity) and velocity (-> acceleration) within 1e-6 relative, and of
acceleration (-> jerk, straight moves only) within 1e-6 relative. A difference quotient is
the mean of the derivative over the interval, so it cannot exceed a respected bound.
"""
import math

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.core.errors import DataError, PlanningError
from feed_axis_energy.core.program import Move, MoveKind, Program
from feed_axis_energy.core.trajectory import (AxisLimits, motion_from_samples, plan,
                                              PlannerOptions)

LIM_X = {'X': AxisLimits(0.6, 2.5, 50.0)}
LIM_XYZ = {'X': AxisLimits(0.5, 3.0, 60.0), 'Y': AxisLimits(0.4, 2.0, 40.0),
           'Z': AxisLimits(0.3, 1.5, 30.0)}


def _line(line, p, q, feed=0.1, stop=False, kind=MoveKind.LINEAR):
    return Move(kind, line, tuple(p), tuple(q), feed_m_s=feed, exact_stop=stop)


def _arc(line, p, q, c, ccw=True, feed=0.1, plane=17, stop=False, turns=0):
    kind = MoveKind.ARC_CCW if ccw else MoveKind.ARC_CW
    return Move(kind, line, tuple(p), tuple(q), feed_m_s=feed, center=tuple(c), plane=plane,
                exact_stop=stop, turns=turns)


def _prog(*moves):
    return Program('test.nc', tuple(moves))


def _speed(m):
    return np.linalg.norm(m.vel, axis=1)


def _mixed_program():
    """Rapid, lines, tangent arcs, a helix and arcs in G18/G19; non-tangent corners stop."""
    return _prog(
        _line(1, (0, 0, 0), (0.02, 0.01, 0.005), feed=math.inf, kind=MoveKind.RAPID),
        _line(2, (0.02, 0.01, 0.005), (0.06, 0.01, 0.005), feed=0.15),
        _arc(3, (0.06, 0.01, 0.005), (0.07, 0.02, 0.005), (0.06, 0.02, 0.005), feed=0.15),
        _line(4, (0.07, 0.02, 0.005), (0.07, 0.05, 0.005), feed=0.15, stop=True),
        _arc(5, (0.07, 0.05, 0.005), (0.07, 0.05, 0.015), (0.06, 0.05, 0.005), feed=0.2),
        _arc(6, (0.07, 0.05, 0.015), (0.06, 0.05, 0.025), (0.06, 0.05, 0.015), plane=18,
             ccw=False, feed=0.2),
        _arc(7, (0.06, 0.05, 0.025), (0.06, 0.04, 0.015), (0.06, 0.05, 0.015), plane=19,
             feed=0.2),
        _line(8, (0.06, 0.04, 0.015), (0.0, 0.0, 0.0), feed=0.3),
    )


@pytest.mark.parametrize('bad', [0.0, -1.0, math.nan, math.inf])
def test_axis_limits_validate(bad):
    with pytest.raises(ValueError, match='AxisLimits'):
        AxisLimits(bad, 1.0, 1.0)
    with pytest.raises(ValueError, match='jerk_m_s3'):
        AxisLimits(1.0, 1.0, bad)


def test_planner_options_validate():
    with pytest.raises(ValueError, match='profile'):
        PlannerOptions(profile='scurve')
    with pytest.raises(ValueError, match='rate_hz'):
        PlannerOptions(rate_hz=0.0)


def test_trapezoid_single_move_hand_calculation():
    m = plan(_prog(_line(7, (0, 0, 0), (0.4, 0, 0), feed=0.1)), LIM_X,
             options=PlannerOptions(profile='trapezoid'))
    # t = L / v + v / a for a rest-to-rest trapezoid that reaches v
    assert_allclose(m.t[-1], 0.4 / 0.1 + 0.1 / 2.5, rtol=1e-12)
    assert_allclose(np.diff(m.t)[:-1], 1e-3, rtol=1e-9)
    assert m.t[-1] - m.t[-2] <= 1e-3 + 1e-12
    assert_allclose(m.pos[-1], [0.4], atol=1e-12)
    assert_allclose(m.pos[0], [0.0], atol=0)
    assert np.all(m.line == 7)
    assert m.axes == ('X',)
    assert_allclose(m.vel.max(), 0.1, rtol=1e-12)
    assert_allclose(np.abs(m.acc).max(), 2.5, rtol=1e-12)


def test_jerk_single_move_hand_calculation():
    # dv = 0.1 < a^2/j: each ramp lasts 2 sqrt(dv/j), the move L/v plus one ramp
    m = plan(_prog(_line(1, (0, 0, 0), (0.4, 0, 0), feed=0.1)), LIM_X)
    assert_allclose(m.t[-1], 4.0 + 2 * math.sqrt(0.1 / 50.0), rtol=1e-12)


@pytest.mark.parametrize('profile', ['jerk', 'trapezoid'])
def test_limits_on_mixed_program(profile):
    prog = _mixed_program()
    m = plan(prog, LIM_XYZ, options=PlannerOptions(profile=profile, corner_tolerance_m=0.0))
    dt = np.diff(m.t)
    vmax = np.array([a.velocity_m_s for a in LIM_XYZ.values()])
    amax = np.array([a.acceleration_m_s2 for a in LIM_XYZ.values()])
    assert np.all(np.abs(m.vel) <= vmax * (1 + 1e-9))
    assert np.all(np.abs(m.acc) <= amax * (1 + 1e-9))
    fd_v = np.diff(m.pos, axis=0) / dt[:, None]
    fd_a = np.diff(m.vel, axis=0) / dt[:, None]
    assert np.all(np.abs(fd_v) <= vmax * (1 + 1e-6))
    assert np.all(np.abs(fd_a) <= amax * (1 + 1e-6))
    # the difference quotient of position agrees with the sampled velocity
    # (trapezoid rule: j dt^2 / 12 inside a phase, <= da dt / 8 at an acceleration step such
    # as the trapezoid's phases or the centripetal step at a tangent line-arc junction)
    mid_v = 0.5 * (m.vel[1:] + m.vel[:-1])
    tol = amax.max() * 1e-3 / 4
    assert np.max(np.abs(fd_v - mid_v)) < tol
    assert_allclose(m.pos[-1], [0, 0, 0], atol=1e-12)
    assert_allclose(m.vel[[0, -1]], 0.0, atol=1e-12)
    assert list(np.unique(m.line)) == list(range(1, 9))


def test_per_axis_jerk_on_straight_moves():
    prog = _prog(_line(1, (0, 0, 0), (0.1, 0.05, 0.02), feed=1.0),
                 _line(2, (0.1, 0.05, 0.02), (0.0, 0.08, 0.0), feed=1.0))
    m = plan(prog, LIM_XYZ, options=PlannerOptions(corner_tolerance_m=0.0))
    jmax = np.array([a.jerk_m_s3 for a in LIM_XYZ.values()])
    fd_j = np.diff(m.acc, axis=0) / np.diff(m.t)[:, None]
    assert np.all(np.abs(fd_j) <= jmax * (1 + 1e-6))
    # the limiting axis actually reaches its jerk limit (the planner is not idle)
    assert np.max(np.abs(fd_j) / jmax) > 0.99


def test_trapezoid_and_jerk_reach_the_end_jerk_slower():
    prog = _mixed_program()
    opts = dict(corner_tolerance_m=1e-4)
    mj = plan(prog, LIM_XYZ, options=PlannerOptions(profile='jerk', **opts))
    mt = plan(prog, LIM_XYZ, options=PlannerOptions(profile='trapezoid', **opts))
    for m in (mj, mt):
        assert_allclose(m.pos[-1], [0, 0, 0], atol=1e-12)
    assert mj.duration_s >= mt.duration_s
    # the S-curve adds ramps of a/j order, not more than a few tenths of a second here
    assert mj.duration_s - mt.duration_s < 0.5


def test_arcs_stay_on_circle():
    c = (0.05, 0.02, 0.0)
    r = 0.01
    prog = _prog(
        _arc(1, (0.06, 0.02, 0), (0.04, 0.02, 0), c, feed=0.1),            # half circle CCW
        _arc(2, (0.04, 0.02, 0), (0.04, 0.02, 0), c, ccw=False, feed=0.1),  # full circle CW
    )
    m = plan(prog, {'X': LIM_XYZ['X'], 'Y': LIM_XYZ['Y']})
    radius = np.hypot(m.pos[:, 0] - c[0], m.pos[:, 1] - c[1])
    assert np.max(np.abs(radius - r)) < 1e-12
    # upper half for the CCW half circle from angle 0 to pi
    assert np.all(m.pos[m.line == 1, 1] >= c[1] - 1e-12)
    # velocity is tangent: radial component zero
    radial = ((m.pos[:, 0] - c[0]) * m.vel[:, 0] + (m.pos[:, 1] - c[1]) * m.vel[:, 1]) / r
    assert np.max(np.abs(radial)) < 1e-12
    # total time at least the arc length over the feed (1.5 turns)
    assert m.duration_s > 3 * math.pi * r / 0.1


def test_g18_arc_direction_and_helix():
    # G18: plane ZX seen from +Y; CCW from X+ (angle 90 deg in Z,X) to Z- (180 deg)
    ccw = plan(_prog(_arc(1, (0.01, 0, 0), (0, 0, -0.01), (0, 0, 0), plane=18)), LIM_XYZ)
    mid = ccw.pos[ccw.n_samples // 2]
    # half the time of a symmetric rest-to-rest move; one sample is 0.1 mm at 0.1 m/s
    assert_allclose(mid, [0.01 / math.sqrt(2), 0, -0.01 / math.sqrt(2)], atol=1e-4)
    cw = plan(_prog(_arc(1, (0.01, 0, 0), (0, 0, -0.01), (0, 0, 0), plane=18, ccw=False)),
              LIM_XYZ)
    # CW goes the long way round (270 deg): its middle is at -45 deg in (Z, X)
    assert_allclose(cw.pos[cw.n_samples // 2], [-0.01 / math.sqrt(2), 0, 0.01 / math.sqrt(2)],
                    atol=1e-4)
    assert cw.duration_s > ccw.duration_s
    # helix in G17: one full turn plus one extra, rising 4 mm
    h = plan(_prog(_arc(1, (0.01, 0, 0), (0.01, 0, 0.004), (0, 0, 0), turns=1)), LIM_XYZ)
    assert_allclose(np.hypot(h.pos[:, 0], h.pos[:, 1]), 0.01, atol=1e-12)
    assert_allclose(h.pos[-1], [0.01, 0, 0.004], atol=1e-12)
    assert np.all(np.diff(h.pos[:, 2]) >= 0)
    length = math.hypot(2 * 2 * math.pi * 0.01, 0.004)
    assert h.duration_s > length / 0.1


def test_exact_stop_and_collinear_junction():
    moves = [_line(1, (0, 0, 0), (0.1, 0, 0)), _line(2, (0.1, 0, 0), (0.2, 0, 0))]
    free = plan(_prog(*moves), LIM_X)
    assert np.all(_speed(free)[np.abs(free.pos[:, 0] - 0.1) < 0.01] > 0.1 - 1e-12)
    stop = plan(_prog(_line(1, (0, 0, 0), (0.1, 0, 0), stop=True), moves[1]), LIM_X)
    boundary = np.nonzero(stop.line == 2)[0][0]
    # at rest at the end of line 1 (jerk-limited ramp: v = j tau^2 / 2 within one sample)
    assert _speed(stop)[boundary - 1: boundary + 1].max() < 50.0 * 1e-6 / 2
    assert_allclose(stop.pos[boundary - 1, 0], 0.1, atol=1e-9)
    assert stop.duration_s > free.duration_s


def test_reversal_stops():
    one = plan(_prog(_line(1, (0, 0, 0), (0.1, 0, 0))), LIM_X)
    two = plan(_prog(_line(1, (0, 0, 0), (0.1, 0, 0)), _line(2, (0.1, 0, 0), (0, 0, 0))), LIM_X)
    assert_allclose(two.duration_s, 2 * one.duration_s, rtol=1e-12)
    assert_allclose(two.pos[:, 0].max(), 0.1, atol=1e-12)


def test_corner_speed_follows_junction_deviation():
    prog = _prog(_line(1, (0, 0, 0), (0.1, 0, 0), feed=0.2), _line(2, (0.1, 0, 0), (0.1, 0.1, 0),
                                                                   feed=0.2))
    lim = {'X': AxisLimits(0.6, 2.5, 50.0), 'Y': AxisLimits(0.6, 2.5, 50.0)}
    m = plan(prog, lim, options=PlannerOptions(corner_tolerance_m=1e-4))
    s = math.sin(math.pi / 4)
    v_corner = math.sqrt(2.5 * 1e-4 * s / (1 - s))
    # the speed is flat (zero acceleration) at the junction, so sampling meets it closely
    near = np.hypot(m.pos[:, 0] - 0.1, m.pos[:, 1]) < 0.005
    assert_allclose(_speed(m)[near].min(), v_corner, rtol=2e-3)


def test_tangent_line_arc_junction_does_not_slow_down():
    prog = _prog(_line(1, (0, 0, 0), (0.05, 0, 0), feed=0.05),
                 _arc(2, (0.05, 0, 0), (0.06, 0.01, 0), (0.05, 0.01, 0), feed=0.05),
                 _line(3, (0.06, 0.01, 0), (0.06, 0.06, 0), feed=0.05))
    m = plan(prog, {'X': LIM_XYZ['X'], 'Y': LIM_XYZ['Y']})
    middle = (m.t > 0.2) & (m.t < m.t[-1] - 0.2)
    assert_allclose(_speed(m)[middle], 0.05, rtol=1e-9)
    assert set(np.unique(m.line[middle])) == {1, 2, 3}


def test_dwell_duration_and_rest():
    moves = [_line(1, (0, 0, 0), (0.1, 0, 0)),
             Move(MoveKind.DWELL, 2, (0.1, 0, 0), (0.1, 0, 0), dwell_s=1.0),
             _line(3, (0.1, 0, 0), (0.2, 0, 0))]
    with_dwell = plan(_prog(*moves), LIM_X)
    stopped = plan(_prog(_line(1, (0, 0, 0), (0.1, 0, 0), stop=True), moves[2]), LIM_X)
    assert_allclose(with_dwell.duration_s, stopped.duration_s + 1.0, rtol=1e-12)
    rest = with_dwell.line == 2
    assert abs(rest.sum() - 1000) <= 1
    assert np.all(with_dwell.vel[rest] == 0.0) and np.all(with_dwell.acc[rest] == 0.0)
    assert_allclose(with_dwell.pos[rest, 0], 0.1, atol=1e-12)


def test_sample_lines_point_to_the_right_move():
    prog = _prog(_line(10, (0, 0, 0), (0.1, 0, 0)), _line(20, (0.1, 0, 0), (0.3, 0, 0)),
                 _line(30, (0.3, 0, 0), (0.35, 0, 0)), Move(MoveKind.STOP, 40, (0.35, 0, 0),
                                                            (0.35, 0, 0)))
    m = plan(prog, LIM_X)
    x = m.pos[:, 0]
    expected = np.where(x < 0.1, 10, np.where(x < 0.3, 20, 30))
    # a sample exactly at a junction belongs to the next move
    inner = (np.abs(x - 0.1) > 1e-9) & (np.abs(x - 0.3) > 1e-9) & (x < 0.35 - 1e-9)
    assert np.array_equal(m.line[inner], expected[inner])
    assert np.all(np.diff(m.line) >= 0)
    assert m.line.dtype == np.int32


def test_missing_axis_raises_with_place():
    prog = _prog(_line(1, (0, 0, 0), (0.1, 0, 0)), _line(5, (0.1, 0, 0), (0.1, 0.1, 0)))
    with pytest.raises(PlanningError, match=r'test\.nc:5: .*axis Y') as info:
        plan(prog, LIM_X)
    assert info.value.line == 5
    arc = _prog(_arc(3, (0.01, 0, 0), (0, 0.01, 0), (0, 0, 0)))
    with pytest.raises(PlanningError, match=r'test\.nc:3:'):
        plan(arc, LIM_X)


def test_discontinuous_program_raises():
    prog = _prog(_line(1, (0, 0, 0), (0.1, 0, 0)), _line(2, (0.2, 0, 0), (0.3, 0, 0)))
    with pytest.raises(PlanningError, match=r'test\.nc:2:'):
        plan(prog, LIM_X)


def test_progress_called_a_few_times():
    seen = []
    plan(_mixed_program(), LIM_XYZ, progress=seen.append)
    assert 2 <= len(seen) <= 20
    assert seen == sorted(seen) and seen[-1] == 1.0


def test_empty_program_is_one_sample_at_rest():
    m = plan(_prog(), LIM_XYZ)
    assert m.n_samples == 1 and np.all(m.vel == 0)


def test_motion_from_samples_sine():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.8e-3, 1.2e-3, 3000))
    w, amp = 2 * math.pi * 2.0, 0.05
    pos = np.stack([amp * np.sin(w * t), amp * np.cos(w * t)], axis=1)
    m = motion_from_samples(t, pos, axes=('X', 'Y'), source='sine.csv')
    inner = slice(2, -2)
    v_ref = np.stack([amp * w * np.cos(w * t), -amp * w * np.sin(w * t)], axis=1)
    a_ref = -w * w * pos
    # second-order differences: error ~ h^2 w^3 amp / 6 plus the non-uniformity term
    assert np.max(np.abs(m.vel[inner] - v_ref[inner])) < 1e-3 * amp * w
    assert np.max(np.abs(m.acc[inner] - a_ref[inner])) < 1e-2 * amp * w * w
    smooth = motion_from_samples(t, pos, axes=('X', 'Y'), smooth_samples=5)
    assert np.max(np.abs(smooth.vel[inner] - v_ref[inner])) < 1e-2 * amp * w
    assert m.source == 'sine.csv' and np.all(m.line == 0)


def test_motion_from_samples_rejects_bad_input():
    t = np.array([0.0, 0.1, 0.1, 0.3])
    with pytest.raises(DataError, match=r'row 3.*strictly increasing'):
        motion_from_samples(t, np.zeros(4), axes=('X',), source='m.csv')
    with pytest.raises(DataError, match='shape'):
        motion_from_samples(np.arange(4.0), np.zeros((4, 2)), axes=('X',))
    with pytest.raises(DataError, match='at least 2'):
        motion_from_samples(np.zeros(1), np.zeros(1), axes=('X',))
