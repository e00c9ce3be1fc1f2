"""Tests of the trajectory planner (plan) and of motion_from_samples.

Limit tolerances: analytic samples within 1e-9 relative of the limits; finite differences of
sampled position (-> velocity) and velocity (-> acceleration) within 1e-6 relative, and of
acceleration (-> jerk, straight moves only) within 1e-6 relative. A difference quotient is
the mean of the derivative over the interval, so it cannot exceed a respected bound.
"""
import math

from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose
import pytest
from scipy.integrate import cumulative_trapezoid

from feed_axis_energy.errors import DataError, PlanningError
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.gcode.program import Move, MoveKind, Program
from feed_axis_energy.sim.simulate import simulate_program
from feed_axis_energy.plan.fromsamples import motion_from_samples
from feed_axis_energy.machine.limits import AxisLimits, PlannerOptions
from feed_axis_energy.plan.trajectory import plan

CONFIG = Path(__file__).resolve().parents[2] / 'config'

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


def _corner_sample(m, axis):
    """Index of the sample that carries a corner's velocity step (the acceleration spike)."""
    return int(np.argmax(np.abs(m.acc[:, axis])))


def test_planned_motion_does_not_depend_on_the_sample_rate():
    # A polyline with few-degree corners: the velocity-step cap (interpolation cycle 1 ms)
    # sets the corner speeds. Sampling at 250 Hz, 1 kHz or 4 kHz must not change the plan.
    pts = [(0.01 * i, 0.02 * math.sin(0.3 * i), 0.0) for i in range(40)]
    prog = _prog(*[_line(i + 1, pts[i], pts[i + 1], feed=0.2) for i in range(len(pts) - 1)])
    lim = {'X': AxisLimits(0.6, 2.5, 50.0), 'Y': AxisLimits(0.6, 2.5, 50.0)}
    rates = (250.0, 1000.0, 4000.0)
    motions = [plan(prog, lim, options=PlannerOptions(rate_hz=r)) for r in rates]
    durations = [m.t[-1] for m in motions]
    assert_allclose(durations, durations[1], rtol=0, atol=1e-9)
    # ... and a different interpolation cycle does change it (the cap really binds here)
    slow = plan(prog, lim, options=PlannerOptions(cycle_s=0.25e-3))
    assert slow.t[-1] > durations[1] + 0.01


def test_corner_speed_follows_junction_deviation():
    # 0.1 rad corner, tolerance 0.1 um: the deviation rule binds (its speed is about half of
    # the velocity-step cap a T / |du_y| = 0.025 m/s)
    phi = 0.1
    q = (0.1 + 0.1 * math.cos(phi), 0.1 * math.sin(phi), 0)
    prog = _prog(_line(1, (0, 0, 0), (0.1, 0, 0), feed=0.2), _line(2, (0.1, 0, 0), q, feed=0.2))
    lim = {'X': AxisLimits(0.6, 2.5, 50.0), 'Y': AxisLimits(0.6, 2.5, 50.0)}
    m = plan(prog, lim, options=PlannerOptions(corner_tolerance_m=1e-7))
    s = math.sin((math.pi - phi) / 2)
    v_corner = math.sqrt(2.5 * 1e-7 * s / (1 - s))
    assert v_corner < 0.6 * 2.5e-3 / math.sin(phi)
    # the speed is flat (zero acceleration) at the junction: within one sample it changes by
    # j T^2 / 2 = 2.5e-5 m/s; the corner sample itself holds the mean of in/out velocities
    near = np.hypot(m.pos[:, 0] - 0.1, m.pos[:, 1]) < 0.005
    near[_corner_sample(m, 1)] = False
    assert_allclose(_speed(m)[near].min(), v_corner, rtol=2.5e-3)


@pytest.mark.parametrize('rate_hz', [1000.0, 250.0])
def test_corner_velocity_step_is_limited_per_cycle(rate_hz):
    # right-angle corner X -> Y: du = (-1, 1); the weaker Y axis limits the step
    lim = {'X': AxisLimits(0.6, 2.5, 50.0), 'Y': AxisLimits(0.6, 1.0, 50.0)}
    prog = _prog(_line(1, (0, 0, 0), (0.1, 0, 0), feed=0.2),
                 _line(2, (0.1, 0, 0), (0.1, 0.1, 0), feed=0.2))
    T = 1.0 / rate_hz
    # the control's interpolation cycle equal to the sample period
    m = plan(prog, lim, options=PlannerOptions(corner_tolerance_m=1e-4, rate_hz=rate_hz,
                                               cycle_s=T))
    v_step = 1.0 * T                           # a_y T / |du_y|
    i = _corner_sample(m, 1)
    # the corner sample holds half of the step of each axis and dv / T in its acceleration;
    # the path's own speed changes by <= j (1.5 T)^2 / 2 from the junction to a neighbour
    tol = 50.0 * (1.5 * T) ** 2 / 2
    assert_allclose(m.vel[i], [v_step / 2, v_step / 2], atol=tol)
    assert_allclose(m.vel[i - 1], [v_step, 0.0], atol=tol)
    assert_allclose(m.vel[i + 1], [0.0, v_step], atol=tol)
    assert_allclose(m.acc[i], [-v_step / T, v_step / T], atol=50.0 * T)
    # the step happens while the tool is at the corner
    assert_allclose(m.pos[i], [0.1, 0.0], atol=v_step * T)


def test_corner_steps_make_acceleration_integrate_to_velocity():
    """vel[i+1] - vel[i] = (acc[i] + acc[i+1]) T / 2 on every interval (trapezoid rule).

    Straight moves, jerk profile: the acceleration is linear in time inside a phase, so the
    rule is exact there; an interval where the jerk switches is off by <= |dj| T^2 / 8 per
    switch (|dj| <= 2 j_k, at most two switches per interval here: 4 j_k T^2 / 8) and a
    corner by <= a_path T |du| / 4 with a_path <= j T / 2 at the junction (<= j_k T^2 / 4).
    """
    prog = _prog(_line(1, (0, 0, 0), (0.05, 0.01, 0.0), feed=0.3),
                 _line(2, (0.05, 0.01, 0.0), (0.09, 0.03, 0.01), feed=0.3),
                 _line(3, (0.09, 0.03, 0.01), (0.1, 0.06, 0.0), feed=0.3),
                 _line(4, (0.1, 0.06, 0.0), (0.0, 0.0, 0.0), feed=0.3))
    m = plan(prog, LIM_XYZ, options=PlannerOptions(corner_tolerance_m=1e-4))
    T = 1e-3
    jmax = np.array([a.jerk_m_s3 for a in LIM_XYZ.values()])
    amax = np.array([a.acceleration_m_s2 for a in LIM_XYZ.values()])
    dv = np.diff(m.vel, axis=0)
    trap = 0.5 * (m.acc[1:] + m.acc[:-1]) * np.diff(m.t)[:, None]
    assert np.all(np.abs(dv - trap) <= (0.5 + 0.25) * jmax * T * T + 1e-15)
    # the corners are passed at speed, so there are steps that the rule has to cover
    assert np.max(np.abs(dv) / amax) > 0.4 * T


@pytest.mark.parametrize('profile', ['jerk', 'trapezoid'])
def test_finite_difference_acceleration_with_corners(profile):
    """Axis limits by finite differences with a 0.1 mm corner tolerance (corners at speed).

    Velocity: within 1e-6 relative everywhere. Acceleration, jerk profile: within 1e-6
    relative everywhere (an interval next to a corner holds half the step, <= a_k / 2, and a
    path acceleration that starts from 0 at the junction, <= 1.5 j_k T). Trapezoid profile
    (infinite jerk): half the step and a full path acceleration can share the interval, so
    next to a corner sample the bound is 1.5 a_k. Sampled acceleration: a_k + j_k T / 2 at
    a corner sample (jerk), 2 a_k (trapezoid); a_k elsewhere.
    """
    prog = _mixed_program()
    m = plan(prog, LIM_XYZ, options=PlannerOptions(profile=profile, corner_tolerance_m=1e-4))
    T = 1e-3
    dt = np.diff(m.t)
    vmax = np.array([a.velocity_m_s for a in LIM_XYZ.values()])
    amax = np.array([a.acceleration_m_s2 for a in LIM_XYZ.values()])
    jmax = np.array([a.jerk_m_s3 for a in LIM_XYZ.values()])
    fd_v = np.diff(m.pos, axis=0) / dt[:, None]
    fd_a = np.diff(m.vel, axis=0) / dt[:, None]
    assert np.all(np.abs(fd_v) <= vmax * (1 + 1e-6))
    # corner samples: those whose velocity is the mean of the neighbours' (a step around them)
    # and whose acceleration exceeds what the path alone allows is not needed: find them as
    # the samples where the trapezoid rule needs the spike
    spike = np.abs(m.acc) > amax * (1 + 1e-9)
    if profile == 'jerk':
        assert np.all(np.abs(fd_a) <= amax * (1 + 1e-6))
        assert np.all(np.abs(m.acc) <= amax + jmax * T / 2)
    else:
        near = np.zeros(m.n_samples, bool)
        corner = np.nonzero(np.any(spike, axis=1))[0]
        near[corner] = True
        next_to = near[1:] | near[:-1]
        assert np.all(np.abs(fd_a[~next_to]) <= amax * (1 + 1e-6))
        assert np.all(np.abs(fd_a) <= 1.5 * amax * (1 + 1e-6))
        assert np.all(np.abs(m.acc) <= 2.0 * amax * (1 + 1e-9))
    # the program has corners passed at speed: some interval changes an axis velocity by a
    # step far larger than the path acceleration could in one cycle from rest
    assert np.max(np.abs(fd_a) / amax) > 0.3
    assert_allclose(m.pos[-1], [0, 0, 0], atol=1e-12)


def _energy_machine():
    d = machine_to_dict(load_machine(CONFIG / 'three_axis_mill.yaml'))
    d['braking'] = 'regenerative'
    for axis in d['axes'].values():
        axis['screw']['efficiency'] = 1.0
    return machine_from_dict(d, file='three_axis_mill.yaml (regenerative, eta 1)')


def _contour_with_corners():
    """Lines with sharp corners, arcs in G17/G18 and a CAM-like polygon of 0.45 deg corners.

    The polygon (a quarter circle of 200 chords) is passed at 0.3 m/s: its corners are not
    slowed by the velocity-step rule, and along it the kinetic energy moves from X (heavier:
    it carries the Y table) to Y at the corners only.
    """
    moves = [_line(1, (0, 0, 0), (0.05, 0, 0), feed=0.25),
             _line(2, (0.05, 0, 0), (0.10, 0.004, 0.002), feed=0.25),
             _arc(3, (0.10, 0.004, 0.002), (0.12, 0.024, 0.002), (0.10, 0.024, 0.002),
                  feed=0.2),
             _line(4, (0.12, 0.024, 0.002), (0.125, 0.07, 0.002), feed=0.25),
             _arc(5, (0.125, 0.07, 0.002), (0.135, 0.07, 0.012), (0.135, 0.07, 0.002),
                  plane=18, feed=0.15),
             _line(6, (0.135, 0.07, 0.012), (0.0, 0.0, 0.01), feed=0.3)]
    r, n = 0.2, 200
    here = (0.0, 0.0, 0.01)
    for i in range(1, n + 1):
        ang = -0.5 * math.pi + 0.5 * math.pi * i / n
        q = (r * math.cos(ang), r + r * math.sin(ang), 0.01)
        moves.append(_line(6 + i, here, q, feed=0.3))
        here = q
    moves.append(_line(7 + n, here, (0.2, 0.2, 0.03), feed=0.2))
    return _prog(*moves)


def test_energy_balance_of_a_planned_contour_with_corners():
    """integral P dt = dE_kin + integral P_loss dt + dE_pot at every sample (jerk profile).

    Braking regenerative, screw efficiency 1: every joule is accounted for. E_kin uses the
    equivalent mass m + J (2 pi / lead)^2 per axis; P and P_loss are integrated by the
    trapezoid rule (as :func:`compute_power` does), E_pot from the sampled Z positions.
    Without the corner steps in ``Motion.acc`` the kinetic energy that the polygon's corners
    move from X (m_eq 912 kg) to Y (728 kg) is missing: more than 1 J here.
    Tolerance 0.05 J: what remains is sampling error of the trapezoid rule. Where the jerk
    switches inside an interval, the error is m |dj| v T^2 B2(f) / 2 with B2(f) = f^2 - f + 1/6
    and f the switch's place in the interval (Euler-Maclaurin): <= m |dj| v T^2 / 12 = 2e-3 J
    here, of either sign with mean 0 over f; the planner makes ~400 such switches (an S-curve
    per move in the speed ramps), a random walk of about 0.02 J (sd of B2: 0.075). A corner
    sample lies <= T / 2 from its junction, so E_pot from positions differs from
    integral m g v_z dt by <= m_z g |dv_z| T / 2 <= 1.8e-3 J at each of the few Z corners.
    The program ends 30 mm higher than it starts: E_pot = m_z g 0.03 m = 44 J.
    """
    mach = _energy_machine()
    prog = _contour_with_corners()
    res = simulate_program(prog, mach, options=PlannerOptions(corner_tolerance_m=1e-4))
    dyn, pw = res.dynamics, res.power
    m_eq = dyn.mass_kg + dyn.inertia_kg_m2 * (2 * math.pi / dyn.lead_m) ** 2
    kinetic = 0.5 * (m_eq * dyn.velocity_m_s ** 2).sum(axis=1)
    loss = cumulative_trapezoid(dyn.loss_power_w.sum(axis=1), pw.t, initial=0.0)
    potential = (dyn.gravity_force_n * (dyn.position_m - dyn.position_m[0])).sum(axis=1)
    residual = pw.total_energy_j - (kinetic - kinetic[0] + loss + potential)

    tol = 0.05
    assert loss[-1] > 10.0 and abs(potential[-1]) > 1.0 and kinetic.max() > 10.0
    assert np.max(np.abs(residual)) < tol
    # the middle of the polygon is passed at speed: the step rule allows 3e-3 / 7.9e-3 =
    # 0.38 m/s there; the S-curve per 1.6 mm chord (zero acceleration at every junction) is
    # what keeps it below the 0.3 m/s feed
    on_polygon = (res.motion.line > 60) & (res.motion.line < 150)
    assert np.min(np.linalg.norm(res.motion.vel[on_polygon], axis=1)) > 0.15


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


def test_motion_from_samples_prefers_measured_derivatives():
    t = np.linspace(0.0, 1.0, 11)
    pos = np.round(0.3 * t**2, 2)[:, None]          # coarsely rounded positions
    vel = (0.6 * t)[:, None]                          # the exact measured velocity
    m = motion_from_samples(t, pos, axes=('X',), vel=vel)
    np.testing.assert_array_equal(m.vel, vel)
    np.testing.assert_allclose(m.acc[1:-1], 0.6, rtol=1e-12)   # gradient of the given velocity
    acc = np.full((11, 1), 0.6)
    m = motion_from_samples(t, pos, axes=('X',), vel=vel, acc=acc)
    np.testing.assert_array_equal(m.acc, acc)
    bad = vel.copy()
    bad[4, 0] = np.nan
    with pytest.raises(DataError, match='velocity is not finite') as err:
        motion_from_samples(t, pos, axes=('X',), vel=bad, source='run.csv')
    assert err.value.row == 5 and err.value.column == 'X'
    with pytest.raises(DataError, match='acceleration has shape'):
        motion_from_samples(t, pos, axes=('X',), vel=vel, acc=acc[:5])


def test_motion_from_samples_rejects_bad_input():
    t = np.array([0.0, 0.1, 0.1, 0.3])
    with pytest.raises(DataError, match=r'row 3.*strictly increasing'):
        motion_from_samples(t, np.zeros(4), axes=('X',), source='m.csv')
    with pytest.raises(DataError, match='shape'):
        motion_from_samples(np.arange(4.0), np.zeros((4, 2)), axes=('X',))
    with pytest.raises(DataError, match='at least 2'):
        motion_from_samples(np.zeros(1), np.zeros(1), axes=('X',))


# --- groups of short blocks: one speed profile across tangent junctions ---------------------

def _short_collinear(n=200, step=0.0015, feed=0.3):
    return [_line(i + 1, (i * step, 0, 0), ((i + 1) * step, 0, 0), feed=feed) for i in range(n)]


@pytest.mark.parametrize('profile', ['jerk', 'trapezoid'])
def test_short_collinear_blocks_move_like_one_long_line(profile):
    # 200 blocks of 1.5 mm at 0.3 m/s: a block alone could add only ~0.1 m/s with zero
    # acceleration at both ends, the 0.3 m long line reaches the feed after 24 mm
    opts = PlannerOptions(profile=profile)
    many = plan(_prog(*_short_collinear()), LIM_X, options=opts)
    one = plan(_prog(_line(1, (0, 0, 0), (0.3, 0, 0), feed=0.3)), LIM_X, options=opts)
    # same profile up to the rounding of the summed block lengths
    assert_allclose(many.duration_s, one.duration_s, rtol=1e-9)
    assert_allclose(many.pos[:, 0], one.pos[:, 0], atol=1e-12)
    assert_allclose(many.vel, one.vel, atol=1e-9)
    assert_allclose(_speed(many).max(), 0.3, rtol=1e-12)
    assert_allclose(many.pos[-1], [0.3], atol=1e-12)
    # each sample names the block that contains it (a sample at a junction: the next block)
    x = many.pos[:, 0]
    expected = np.minimum(np.floor(x / 0.0015 + 1e-9).astype(int) + 1, 200)
    inner = np.abs(x / 0.0015 - np.rint(x / 0.0015)) > 1e-6
    assert np.array_equal(many.line[inner], expected[inner])
    assert np.all(np.diff(many.line) >= 0)


def test_acceleration_is_continuous_across_tangent_block_boundaries():
    # collinear 1.5 mm blocks along (0.6, 0.8, 0): the ramp crosses several junctions while
    # accelerating; the path jerk limit is min_k j_k / |u_k| = 40 / 0.8 = 50 m/s^3
    u = np.array([0.6, 0.8, 0.0])
    moves = [_line(i + 1, tuple(0.0015 * i * u), tuple(0.0015 * (i + 1) * u), feed=0.3)
             for i in range(100)]
    m = plan(_prog(*moves), LIM_XYZ)
    T = 1e-3
    jmax = np.array([a.jerk_m_s3 for a in LIM_XYZ.values()])
    amax = np.array([a.acceleration_m_s2 for a in LIM_XYZ.values()])
    fd_j = np.diff(m.acc, axis=0) / np.diff(m.t)[:, None]
    assert np.all(np.abs(fd_j) <= jmax * (1 + 1e-6))
    assert np.all(np.abs(m.acc) <= amax * (1 + 1e-9))
    change = np.nonzero(np.diff(m.line) != 0)[0]
    a_path = m.acc @ u
    # during the ramp-up the path acceleration at a junction is far from 0 (the S-curve per
    # block would bring it back to 0 at every junction): 2 m/s^2 = path limit 2 / 0.8 = 2.5
    # reached after a / j = 0.05 s, i.e. beyond the 3rd junction
    ramp_up = change[m.t[change] < 0.1]
    assert ramp_up.size >= 3
    assert np.max(a_path[ramp_up]) > 2.0
    # no jump at the junction: the neighbours differ by at most the jerk times T
    assert np.all(np.abs(a_path[ramp_up + 1] - a_path[ramp_up]) <= 50.0 * T * (1 + 1e-9))
    assert_allclose(m.pos[-1], 0.15 * u, atol=1e-12)


def _quarter_polygon(n=200, r=0.2, feed=0.3):
    moves, here = [], (0.0, 0.0, 0.0)
    for i in range(1, n + 1):
        ang = -0.5 * math.pi + 0.5 * math.pi * i / n
        q = (r * math.cos(ang), r + r * math.sin(ang), 0.0)
        moves.append(_line(i, here, q, feed=feed))
        here = q
    return moves, 2 * n * r * math.sin(0.25 * math.pi / n)


@pytest.mark.parametrize('profile', ['jerk', 'trapezoid'])
def test_near_tangent_polygon_reaches_the_feed(profile):
    """200 chords of 1.57 mm, 0.45 deg corners, rest to rest at F = 0.3 m/s (X, Y: a = 3).

    The corners allow 0.38 m/s (step rule) and the chords' speed is feed-limited, so the
    polygon is one group. Its acceleration keeps at least a quarter of the path limit
    (3 m/s^2 along an axis): the duration is at most L / F + F / (0.25 * 3) + 0.75 / 50
    (one ramp at the lowest acceleration the grouping allows, rest to rest).
    Limits as in ``test_finite_difference_acceleration_with_corners`` (jerk): finite
    differences within 1e-6 relative; sampled acceleration within a_k + j_k T / 2.
    """
    lim = {'X': AxisLimits(0.5, 3.0, 50.0), 'Y': AxisLimits(0.5, 3.0, 50.0)}
    moves, length = _quarter_polygon()
    m = plan(_prog(*moves), lim, options=PlannerOptions(profile=profile))
    T = 1e-3
    feed = 0.3
    assert m.duration_s <= length / feed + feed / (0.25 * 3.0) + 0.75 / 50.0
    assert m.duration_s >= length / feed
    speed = _speed(m)
    # the samples away from the corner steps run at the feed for most of the time
    at_feed = np.abs(speed - feed) < 1e-9
    assert at_feed.sum() * T > 0.5 * length / feed
    assert speed.max() <= feed * (1 + 1e-9)
    vmax = np.array([0.5, 0.5])
    amax = np.array([3.0, 3.0])
    dt = np.diff(m.t)
    fd_v = np.diff(m.pos, axis=0) / dt[:, None]
    fd_a = np.diff(m.vel, axis=0) / dt[:, None]
    assert np.all(np.abs(fd_v) <= vmax * (1 + 1e-6))
    assert np.all(np.abs(fd_a) <= amax * (1 + 1e-6))
    assert np.all(np.abs(m.acc) <= amax + 50.0 * T / 2)
    assert_allclose(m.pos[-1], [0.2, 0.2], atol=1e-12)
    assert_allclose(m.vel[[0, -1]], 0.0, atol=1e-12)
    assert list(np.unique(m.line)) == list(range(1, 201))
