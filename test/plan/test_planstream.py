"""Streaming planner: chunks of motion from windows of blocks equal the whole-program plan."""
import math
from pathlib import Path
import tracemalloc

import must_run
import numpy as np
import pytest

from feed_axis_energy.errors import PlanningError
from feed_axis_energy.gcode.load import load_gcode, parse_gcode
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.plan.stream import concat_motion, estimate_plan, iter_motion, iter_plan
from feed_axis_energy.gcode.program import Move, MoveKind, Program
from feed_axis_energy.machine.limits import AxisLimits, PlannerOptions
from feed_axis_energy.plan.trajectory import plan
from shared_data import need_shared

REPO = Path(__file__).resolve().parents[2]
LIM_XYZ = {'X': AxisLimits(0.5, 3.0, 60.0), 'Y': AxisLimits(0.4, 2.0, 40.0),
           'Z': AxisLimits(0.3, 1.5, 30.0)}


def _line(line, p, q, feed=0.1, stop=False, kind=MoveKind.LINEAR):
    return Move(kind, line, tuple(p), tuple(q), feed_m_s=feed, exact_stop=stop)


def _arc(line, p, q, c, ccw=True, feed=0.1, plane=17):
    kind = MoveKind.ARC_CCW if ccw else MoveKind.ARC_CW
    return Move(kind, line, tuple(p), tuple(q), feed_m_s=feed, center=tuple(c), plane=plane)


def _polygon(line0, centre, r, n, z, feed):
    """A closed polygon of ``n`` short chords (a CAM-style circle): grouped blocks."""
    pts = [(centre[0] + r * math.cos(2 * math.pi * i / n),
            centre[1] + r * math.sin(2 * math.pi * i / n), z) for i in range(n + 1)]
    return [_line(line0 + i, pts[i], pts[i + 1], feed=feed) for i in range(n)]


def _program():
    """Rapids, lines, tangent arcs, a helix, chord polygons, corners, a dwell, a stop."""
    moves = [_line(1, (0, 0, 0), (0.02, 0.0, 0.005), feed=math.inf, kind=MoveKind.RAPID)]
    moves += _polygon(2, (0.0, 0.0), 0.02, 40, 0.005, 0.2)
    moves += [
        _line(50, (0.02, 0.0, 0.005), (0.06, 0.01, 0.005), feed=0.15),
        _arc(51, (0.06, 0.01, 0.005), (0.07, 0.02, 0.005), (0.06, 0.02, 0.005), feed=0.15),
        _line(52, (0.07, 0.02, 0.005), (0.07, 0.05, 0.005), feed=0.15),
        Move(MoveKind.DWELL, 53, (0.07, 0.05, 0.005), (0.07, 0.05, 0.005), dwell_s=0.7),
        _arc(54, (0.07, 0.05, 0.005), (0.07, 0.05, 0.015), (0.06, 0.05, 0.005), feed=0.2),
        _arc(55, (0.07, 0.05, 0.015), (0.06, 0.05, 0.025), (0.06, 0.05, 0.015), ccw=False,
             plane=18, feed=0.2),
        _line(56, (0.06, 0.05, 0.025), (0.03, 0.05, 0.025), feed=0.25),
        _line(57, (0.03, 0.05, 0.025), (0.03, 0.02, 0.025), feed=0.25),
        _line(58, (0.03, 0.02, 0.025), (0.03, 0.05, 0.025), feed=0.25),   # reversal
        Move(MoveKind.STOP, 59, (0.03, 0.05, 0.025), (0.03, 0.05, 0.025)),
    ]
    moves += _polygon(60, (0.03, 0.03), 0.02, 30, 0.025, 0.3)[8:]
    return Program('stream.nc', tuple(_chain(moves)))


def _chain(moves):
    """Join every move to the previous one's end with a short connecting line."""
    out, here = [], None
    for mv in moves:
        if mv.kind not in (MoveKind.DWELL, MoveKind.STOP):
            if here is not None and math.dist(mv.start, here) > 1e-9:
                out.append(_line(mv.line, here, mv.start, feed=0.1))
            here = mv.end
        out.append(mv)
    return out


def _assert_same(ref, got):
    assert got.t.shape == ref.t.shape
    assert got.axes == ref.axes
    np.testing.assert_array_equal(got.line, ref.line)
    for name in ('t', 'pos', 'vel', 'acc'):
        a, b = getattr(ref, name), getattr(got, name)
        scale = max(float(np.max(np.abs(a))), 1e-300)
        assert float(np.max(np.abs(a - b))) <= 1e-12 * scale, name


def _boundary_lines(chunks):
    """Source lines of the samples on both sides of every chunk boundary."""
    return [(a.line[-1], b.line[0]) for a, b in zip(chunks[:-1], chunks[1:])]


@pytest.mark.parametrize('profile', ['jerk', 'trapezoid'])
@pytest.mark.parametrize('window,chunk', [(2, 37), (3, 250), (5, 1000), (256, 4096)])
def test_chunks_equal_whole_plan(profile, window, chunk):
    prog = _program()
    opts = PlannerOptions(profile=profile)
    ref = plan(prog, LIM_XYZ, options=opts)
    windows = list(iter_plan(prog.moves, LIM_XYZ, options=opts, window_blocks=window))
    if window < 10:
        assert len(windows) > 5            # really planned window by window
    assert windows[-1].final and not any(w.final for w in windows[:-1])
    chunks = list(iter_motion(prog.moves, LIM_XYZ, options=opts, file=prog.file,
                              chunk_samples=chunk, window_blocks=window))
    assert all(c.n_samples <= chunk for c in chunks)
    _assert_same(ref, concat_motion(chunks))
    if chunk == 37:
        # boundaries fall inside the dwell (53), an arc (51, 54, 55) and a line
        inside = {a for a, b in _boundary_lines(chunks) if a == b}
        assert {53, 51, 54, 55} <= inside


@pytest.mark.parametrize('window,chunk', [(2, 37), (3, 250), (256, 4096)])
def test_steps_spread_over_the_cycle_equal_whole_plan(window, chunk):
    """At 20 kHz a corner's velocity step is spread over the 20 samples of its 1 ms cycle;
    windows of two blocks and chunks of 37 samples cut through those ramps, and the rows
    are still those of the whole plan."""
    prog = _program()
    opts = PlannerOptions(rate_hz=20_000.0)
    ref = plan(prog, LIM_XYZ, options=opts)
    chunks = list(iter_motion(prog.moves, LIM_XYZ, options=opts, file=prog.file,
                              chunk_samples=chunk, window_blocks=window))
    _assert_same(ref, concat_motion(chunks))
    # the ramps are there: the trapezoid rule of the acceleration gives the velocity on
    # every interval up to the jerk switches (no single-sample spikes of dv / T_s)
    T = 1.0 / opts.rate_hz
    trap = 0.5 * (ref.acc[1:] + ref.acc[:-1]) * T
    jmax = np.array([a.jerk_m_s3 for a in LIM_XYZ.values()])
    amax = np.array([a.acceleration_m_s2 for a in LIM_XYZ.values()])
    step = np.abs(np.diff(ref.vel, axis=0) - trap)
    assert np.all(step <= jmax * T * T + 1e-15 + (np.abs(ref.acc[1:] - ref.acc[:-1]) * T))
    # a step within its cycle asks at most a_k (the look-ahead's rule); with the path's own
    # acceleration beside it at most 1.5 a_k; all of it in one sample (the rule before the
    # steps were spread) is up to 20 a_k here
    assert np.max(np.abs(ref.acc) / amax) <= 1.5


def test_window_boundaries_fall_inside_the_program():
    prog = _program()
    windows = list(iter_plan(prog.moves, LIM_XYZ, window_blocks=2))
    times = [w.t_end for w in windows[:-1]]
    assert all(0.0 < a < b for a, b in zip(times, times[1:]))


def test_generator_input_and_rate():
    prog = _program()
    opts = PlannerOptions(rate_hz=333.0)
    ref = plan(prog, LIM_XYZ, options=opts)
    got = concat_motion(iter_motion((mv for mv in prog.moves), LIM_XYZ, options=opts,
                                    file=prog.file, chunk_samples=100, window_blocks=3))
    _assert_same(ref, got)


def test_estimate_matches_samples():
    prog = _program()
    for rate in (1000.0, 333.0):
        opts = PlannerOptions(rate_hz=rate)
        ref = plan(prog, LIM_XYZ, options=opts)
        est = estimate_plan(prog.moves, LIM_XYZ, options=opts)
        assert est.samples == ref.n_samples
        assert est.duration_s == pytest.approx(ref.duration_s, rel=1e-12)
        assert est.moves == len(prog.moves)


def test_empty_and_single_axis():
    lim = {'X': AxisLimits(0.6, 2.5, 50.0)}
    empty = Program('e.nc', ())
    _assert_same(plan(empty, lim), concat_motion(iter_motion(empty.moves, lim)))
    prog = parse_gcode('G1 X0.05 F3000\nG4 P0.25\nG1 X0\nM2\n', file='x.nc')
    _assert_same(plan(prog, lim), concat_motion(iter_motion(prog.moves, lim, chunk_samples=7)))


def test_errors_name_the_line():
    prog = parse_gcode('G1 X0.05 F3000\nG1 Y0.05\n', file='y.nc')
    with pytest.raises(PlanningError, match='y.nc:2'):
        list(iter_motion(prog.moves, {'X': AxisLimits(0.6, 2.5, 50.0)}, file=prog.file))


def test_week_long_dwell_is_sampled_lazily():
    prog = parse_gcode('G1 X0.01 F600\nG4 P604800\nG1 X0\n', file='week.nc')
    lim = {'X': AxisLimits(0.6, 2.5, 50.0)}
    est = estimate_plan(prog.moves, lim)
    assert est.duration_s > 604800.0
    assert est.samples == pytest.approx(604800e3, rel=1e-4)
    tracemalloc.start()
    try:
        chunks = iter_motion(prog.moves, lim, chunk_samples=1 << 14)
        for i, chunk in enumerate(chunks):
            if i == 20:
                break
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert chunk.t[0] > 1.0 and np.all(chunk.vel == 0.0)
    assert peak < 20 * (1 << 20)          # a few chunks, not 604.8 M samples


def test_corpus_programs_equal_whole_plan():
    root = need_shared('corpus', 'gcode')
    machine = load_machine(REPO / 'config' / 'three_axis_mill.yaml')
    opts = machine.planner.options()
    names = ['CauldronDevelopmentLLC__CAMotics/examples__locket__engrave.ngc']
    paths = [root / n for n in names if (root / n).is_file()]
    if not paths:
        must_run.skip('shared', f'corpus programs not found in {root}: {names}')
    for path in paths:
        prog = load_gcode(path, home=machine.home_point())
        ref = plan(prog, machine.limits(), options=opts)
        got = concat_motion(iter_motion(prog.moves, machine.limits(), options=opts,
                                        file=prog.file, chunk_samples=5000,
                                        window_blocks=2))
        _assert_same(ref, got)


def test_progress_advances_through_a_dwell():
    prog = parse_gcode('G1 X0.01 F600\nG4 P30\nG1 X0\n', file='d.nc')
    lim = {'X': AxisLimits(0.6, 2.5, 50.0)}
    est = estimate_plan(prog.moves, lim)
    seen = []
    chunks = list(iter_motion(prog.moves, lim, chunk_samples=5000, duration_s=est.duration_s,
                              progress=seen.append))
    assert len(seen) == len(chunks) - 1 >= 5          # one report per full chunk
    assert seen == sorted(seen) and 0.0 < seen[0] and seen[-1] <= 1.0
