"""Splines G5, G5.1, G5.2/G5.3: hand-checked geometry, LinuxCNC's rules and errors.

Geometry is checked by facts of the curves, not by our own output: a Bezier whose control
points are collinear and in order is the straight segment between its ends; a quadratic
Bezier is a parabola with a known vertex; a quadratic rational Bezier with the middle
weight cos(45 deg) is a quarter circle; NURBS are affine invariant. Agreement with the
reference interpreter move for move is checked in ``test/gcode/test_corpus.py`` (live
program ``splines`` and the corpus' butterfly).
"""
from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path
import random
import subprocess
import sys

from hypothesis import given, settings, strategies as st
import must_run
import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.gcode.expand.nurbs import ControlPoint
from feed_axis_energy.gcode.expand.splines import (knot_vector, MAX_ORDER,
                                                   nurbs_point, nurbs_polyline)
from feed_axis_energy.gcode.program import MoveKind

MM = 1e-3
ROOT = Path(__file__).resolve().parents[2]


def run(text: str, **kw):
    return parse_gcode('G21 G90 G17 G94 F600\n' + text + '\nM2\n', file='p.ngc', **kw)


def feeds(program, line: int | None = None):
    return [m for m in program.moves if m.kind == MoveKind.LINEAR
            and (line is None or m.line == line)]


def path_mm(moves) -> float:
    return math.fsum(m.length_m for m in moves) / MM


def chained(start, moves) -> bool:
    pos = start
    for m in moves:
        if m.start != pos:
            return False
        pos = m.end
    return True


# -- the pure curve ----------------------------------------------------------------------
def test_knot_vector_is_clamped_and_uniform():
    # 5 points, order 3: three zeros, 1, 2, then three times 5 - 3 + 1 = 3
    assert knot_vector(5, 3) == [0, 0, 0, 1, 2, 3, 3, 3]
    assert knot_vector(4, 4) == [0, 0, 0, 0, 1, 1, 1, 1]     # a cubic Bezier


def test_quadratic_bezier_midpoint_and_parabola():
    pts = [ControlPoint(0.0, 0.0, 1.0), ControlPoint(5.0, 10.0, 1.0),
           ControlPoint(10.0, 0.0, 1.0)]
    # B(1/2) = P0/4 + P1/2 + P2/4
    assert nurbs_point(pts, 3, 0.5) == pytest.approx((5.0, 5.0), abs=1e-12)
    # x = 10 t, y = 20 t (1 - t): every point lies on y = 2 x - 0.2 x^2
    for x, y in nurbs_polyline(pts, 3):
        assert y == pytest.approx(2 * x - 0.2 * x * x, abs=1e-12)


def test_weighted_quadratic_is_a_quarter_circle():
    w = math.cos(math.pi / 4)
    pts = [ControlPoint(10.0, 0.0, 1.0), ControlPoint(10.0, 10.0, w),
           ControlPoint(0.0, 10.0, 1.0)]
    path = nurbs_polyline(pts, 3)
    for x, y in path:
        assert math.hypot(x, y) == pytest.approx(10.0, rel=1e-12)
    assert nurbs_point(pts, 3, 0.5) == pytest.approx((10 / math.sqrt(2),) * 2, rel=1e-12)


def test_samples_per_control_point_and_exact_end():
    pts = [ControlPoint(float(i), float(i % 2), 1.0 + i % 3) for i in range(7)]
    path = nurbs_polyline(pts, 4)
    # 15 steps per control point: 104 or 105 points below umax (the accumulated step may
    # land just below it), plus the last control point itself
    assert len(path) in (7 * 15, 7 * 15 + 1)
    assert path[-1] == (6.0, 0.0)


# -- G5 / G5.1 -----------------------------------------------------------------------------
def test_g5_with_collinear_control_points_is_a_straight_line():
    # control points x = 0, 5, 10, 30 on Y = 0: a monotone cubic, the segment 0..30 mm
    p = run('G0 X0 Y0 Z1\nG5 X30 Y0 I5 J0 P-20 Q0')
    f = feeds(p, 3)
    assert len(f) == 60                     # LinuxCNC's preview: 15 per control point
    assert path_mm(f) == pytest.approx(30.0, rel=1e-12)
    assert all(m.end[1] == 0.0 and m.end[2] == 1 * MM for m in f)
    assert f[-1].end == (30 * MM, 0.0, 1 * MM)
    assert chained((0.0, 0.0, 1 * MM), f)
    assert all(m.feed_m_s == pytest.approx(600 * MM / 60) for m in f)


def test_g5_equally_spaced_control_points_give_equal_steps():
    # control points 0, 10, 20, 30: x = 30 t, so the 60 steps are 0.5 mm each
    p = run('G0 X0 Y0\nG5 X30 Y0 I10 J0 P-10 Q0')
    steps = [m.length_m / MM for m in feeds(p, 3)]
    assert steps[:59] == pytest.approx([0.5] * 59, abs=1e-9)
    assert sum(steps) == pytest.approx(30.0, rel=1e-12)


def test_g51_quadratic_vertex_and_end():
    # P0 (0, 0), P1 = P0 + (5, 10), P2 (10, 0): y = 2 x - 0.2 x^2, vertex (5, 5)
    p = run('G0 X0 Y0\nG5.1 X10 Y0 I5 J10')
    f = feeds(p, 3)
    assert len(f) == 45
    for m in f:
        x, y = m.end[0] / MM, m.end[1] / MM
        assert y == pytest.approx(2 * x - 0.2 * x * x, abs=1e-9)
    assert max(m.end[1] for m in f) <= 5 * MM
    assert f[-1].end == (10 * MM, 0.0, 0.0)


def test_g5_without_ij_continues_tangent_mirrored():
    # second G5: first offset = -(P, Q) of the first, so it is the first mirrored in Y
    p = run('G0 X0 Y0\nG5 X10 Y0 I0 J5 P0 Q5\nG5 X20 Y0 P0 Q-5')
    a, b = feeds(p, 3), feeds(p, 4)
    assert len(a) == len(b)
    for ma, mb in zip(a, b):
        assert mb.end[0] == pytest.approx(ma.end[0] + 10 * MM, abs=1e-12)
        assert mb.end[1] == pytest.approx(-ma.end[1], abs=1e-12)


def test_g5_leaves_the_motion_mode_as_it_was():
    # LinuxCNC's convert_spline does not set the motion mode: X8 is a G0 traverse
    p = run('G0 X0 Y0\nG5.1 X5 Y5 I2 J0\nX8')
    last = p.moves[-2]          # before M2's stop
    assert last.kind == MoveKind.RAPID and last.end == (8 * MM, 5 * MM, 0.0)


def test_g5_in_inches_and_work_offsets():
    # G20, G55 offset: the same curve 25.4 times larger, shifted by the offset
    mm_prog = run('G0 X0 Y0\nG5.1 X2 Y0 I1 J1')
    inch = parse_gcode('G20 G90 G17 F10\nG10 L2 P2 X100 Y50\nG55 G0 X0 Y0\n'
                       'G5.1 X2 Y0 I1 J1\nM2\n', file='p.ngc')
    a, b = feeds(mm_prog, 3), feeds(inch, 4)
    assert len(a) == len(b)
    for ma, mb in zip(a, b):
        assert mb.end[0] == pytest.approx(ma.end[0] * 25.4 + 100 * 25.4 * MM, rel=1e-12)
        assert mb.end[1] == pytest.approx(ma.end[1] * 25.4 + 50 * 25.4 * MM, rel=1e-12)


def test_g5_in_a_rotated_system_turns_offsets_too():
    # G10 L2 R90: program +X is machine +Y; the curve is the unrotated one turned by 90 deg
    plain = run('G0 X0 Y0\nG5 X10 Y0 I2 J3 P-2 Q3')
    turned = run('G10 L2 P1 R90\nG0 X0 Y0\nG5 X10 Y0 I2 J3 P-2 Q3')
    a, b = feeds(plain, 3), feeds(turned, 4)
    for ma, mb in zip(a, b):
        assert mb.end[0] == pytest.approx(-ma.end[1], abs=1e-12)
        assert mb.end[1] == pytest.approx(ma.end[0], abs=1e-12)


def test_g93_spline_takes_one_over_f_minutes():
    p = run('G93 G0 X0 Y0\nG5.1 X10 Y0 I5 J0 F2')
    f = feeds(p, 3)
    length = math.fsum(m.length_m for m in f)
    assert length == pytest.approx(10 * MM, rel=1e-12)
    assert sum(m.length_m / m.feed_m_s for m in f) == pytest.approx(30.0)   # 1/2 min


# -- G5.2 / G5.3 -------------------------------------------------------------------------
def test_nurbs_quarter_circle_from_weights():
    w = math.cos(math.pi / 4)
    p = run(f'G0 X10 Y0 Z2\nG5.2 X10 Y10 P{w!r}\nX0 Y10 P1\nG5.3')
    f = feeds(p)
    assert {m.line for m in f} == {5}       # issued at the G5.3 line, as LinuxCNC does
    assert len(f) == 45
    for m in f:
        assert math.hypot(m.end[0], m.end[1]) == pytest.approx(10 * MM, rel=1e-12)
        assert m.end[2] == 2 * MM
    # chords of a quarter circle: just shorter than the arc (45 chords: relative 1e-4)
    assert 0.9999 * 5 * math.pi < path_mm(f) < 5 * math.pi
    assert f[-1].end == (0.0, 10 * MM, 2 * MM)


def test_nurbs_order_4_with_4_points_is_the_g5_curve():
    g5 = run('G0 X0 Y0\nG5 X10 Y0 I2 J4 P-3 Q4')
    nurbs = run('G0 X0 Y0\nG5.2 X2 Y4 P1 L4\nX7 Y4 P1\nX10 Y0 P1\nG5.3')
    a, b = feeds(g5), feeds(nurbs)
    assert len(a) == len(b) == 60
    for ma, mb in zip(a, b):
        assert ma.end == pytest.approx(mb.end, abs=1e-15)


def test_nurbs_incremental_points_are_relative_to_the_start():
    # G91: the position stays at the start until G5.3, so X1 and X2 are both from X5
    p = run('G0 X5 Y5\nG91 G5.2 X1 Y0 P1\nX2 Y0 P1\nG5.3')
    f = feeds(p)
    assert f[-1].end == pytest.approx((7 * MM, 5 * MM, 0.0), abs=1e-15)
    assert path_mm(f) == pytest.approx(2.0, rel=1e-12)


def test_nurbs_first_weight_order_and_continuation_lines():
    # G5.2 P3 L4: weight 3 on the start point, order 4; points on lines without a G word
    p = run('G0 X0 Y0\nG5.2 P3 L4\nX2 Y4 P1\nX6 Y4 P2\nX8 Y0 P1\nX9 Y1 P1\nG5.3')
    f = feeds(p)
    assert len(f) in (75, 76) and f[-1].end == pytest.approx((9 * MM, 1 * MM, 0.0))
    # the curve stays inside the convex hull of its control points
    assert all(-1e-12 <= m.end[1] <= 4 * MM and 0 <= m.end[0] <= 9 * MM for m in f)


def test_nurbs_in_another_plane_uses_x_and_y():
    # LinuxCNC checks no plane for G5.2: its points are X/Y in G18 too
    p = run('G18 G0 X0 Y0 Z1\nG5.2 X3 Y0 P1\nX6 Y0 P1\nG5.3')
    assert path_mm(feeds(p)) == pytest.approx(6.0, rel=1e-12)


def test_nurbs_z_word_is_ignored_with_a_warning():
    p = run('G0 X0 Y0 Z1\nG5.2 X3 Y0 P1 Z5\nX6 Y0 P1\nG5.3')
    assert all(m.end[2] == 1 * MM for m in feeds(p))
    assert any('Z words on G5.2' in w for w in p.warnings)


def test_unfinished_nurbs_is_dropped_with_a_warning():
    p = run('G0 X0 Y0\nG5.2 X3 Y0 P1\nX6 Y0 P1')
    assert not feeds(p)
    # the start point is the first control point
    assert any('p.ngc:3: the 3 control points' in w and 'never ended' in w
               for w in p.warnings)


def test_g51_takes_the_points_of_an_unfinished_nurbs_as_linuxcnc():
    # LinuxCNC keeps one list of control points: G5.1 after an open G5.2 uses its points
    p = run('G0 X0 Y0\nG5.2 X1 Y0 P1\nX2 Y0 P1\nG1 X3\nG5.1 X5 Y0 I1 J0')
    f = feeds(p, 6)
    assert len(f) in (15 * 6, 15 * 6 + 1) and f[-1].end == (5 * MM, 0.0, 0.0)
    assert f[0].start == (3 * MM, 0.0, 0.0)
    assert any('also takes the 3 control points' in w for w in p.warnings)


def test_spline_right_after_g40_makes_the_exit_move():
    # G41.1 D2: offset 1 mm to the left of +X travel, so the tool is at (20, 1) after X20;
    # after G40 the spline's first feed leaves the offset point (as LinuxCNC's reference)
    p = run('G0 X0 Y0\nG41.1 D2 G1 X10 Y0\nG1 X20\nG40\nG5.1 X30 Y5 I5 J0')
    f = feeds(p, 6)
    assert f[0].start == pytest.approx((20 * MM, 1 * MM, 0.0))
    # P0 (20, 0), P1 (25, 0), P2 (30, 5): x = 20 + 10 t, y = 5 t^2
    for m in f:
        x, y = m.end[0] / MM, m.end[1] / MM
        assert y == pytest.approx(5 * ((x - 20) / 10) ** 2, abs=1e-9)
    assert chained(f[0].start, f) and f[-1].end == (30 * MM, 5 * MM, 0.0)


def test_g5_3_leaves_no_motion_mode():
    with pytest.raises(GcodeError, match='no motion mode'):
        run('G0 X0 Y0\nG5.2 X3 Y0 P1\nX6 Y0 P1\nG5.3\nX9')


# -- errors ------------------------------------------------------------------------------
ERRORS = [
    # (program lines after the set-up line and G0 X0 Y0, line, column, message part)
    ('G18 G5 X1 Y1 I1 J1 P1 Q1', 3, 5, 'Splines must be in the XY plane'),
    ('G5 X1 Z1 I1 J1 P1 Q1', 3, 7, 'Splines may not have motion in Z'),
    ('G5 X1 Y1 I1 J1 P1', 3, 16, 'Must specify both P and Q with G5'),
    ('G5 X1 Y1 I1 P1 Q1', 3, 10, 'Must specify both I and J, or neither'),
    ('G5 X1 Y1 I1 J1 P1 Q1 K1', 3, 22, 'K word is not used by G5'),
    ('G5.1 X1 Y1 I1', 3, 12, 'Must specify both I and J with G5.1'),
    ('G5.1 X1 Y1 I1 J1 P2', 3, 18, 'P word is not used by G5.1'),
    ('G5', 3, 1, 'G5 needs an end point'),
    ('G41.1 D2 G1 X5\nG5.1 X9 Y1 I1 J0', 4, 1, 'Cannot convert spline with cutter radius'),
    ('G5.2 P1 L4\n    Y10 Z0 P1', 4, 5, 'You must specify both X and Y coordinates'),
    ('G5.2 X1 Y1', 3, 6, 'the first G5.2 control point needs a positive weight P'),
    ('G5.2 X1 Y1 P1\nX2 Y2 P0', 4, 7, 'Must specify positive weight P for every'),
    ('G5.2 X1 Y1 P1\nG5.2 P2', 4, 6, 'Can specify P without X and Y only for the first'),
    ('G5.2 X1 Y1 P1 I1', 3, 15, 'I word is not used by G5.2'),
    ('G5.2 X1 Y1 P1 L17', 3, 15, f'above {MAX_ORDER}'),
    ('G5.2 X1 Y1 P1 L2.5', 3, 15, 'L (the NURBS order) must be a whole number'),
    ('G5.3', 3, 1, 'Cannot use G5.3 without G5.2 first'),
    ('G5.2 X1 Y1 P1\nG5.3', 4, 1, 'at least equal to the order L = 3'),
    ('G5.2 X1 Y1 P1 L4\nX2 Y2 P1\nG5.3', 5, 1, 'at least equal to the order L = 4'),
    ('G5.2 X1 Y1 P1\nX2 Y2 P1\nG5.3 G1 X3', 5, 1, 'only additional G5.2 codes'),
    ('G5.2 X1 Y1 P1\nX2 Y2 P1\nX3 Y0 P1\nG5.3 X4', 6, 6, 'G5.3 ends a NURBS'),
    ('G93\nG5.2 X1 Y1 P1', 4, 1, 'inverse time (G93) is not supported'),
]


@pytest.mark.parametrize('text, line, column, message', ERRORS)
def test_errors_name_line_and_column(text, line, column, message):
    with pytest.raises(GcodeError) as info:
        run('G0 X0 Y0\n' + text)
    err = info.value
    assert message in str(err)
    assert (err.file, err.line, err.column) == ('p.ngc', line, column)


def test_too_many_control_points_is_refused(monkeypatch):
    import feed_axis_energy.gcode.expand.splines as splines
    monkeypatch.setattr(splines, 'MAX_CONTROL_POINTS', 3)
    with pytest.raises(GcodeError, match='more than 3 control points') as info:
        run('G0 X0 Y0\nG5.2 X1 Y1 P1\nX2 Y0 P1\nX3 Y1 P1\nG5.3')
    assert info.value.line == 5


# -- properties ----------------------------------------------------------------------------
_COORD = st.floats(-500, 500, allow_nan=False).map(lambda v: round(v, 4))
_WEIGHT = st.floats(0.01, 100, allow_nan=False).map(lambda v: round(v, 4))


@settings(max_examples=150, derandomize=True, deadline=None, database=None)
@given(points=st.lists(st.tuples(_COORD, _COORD, _WEIGHT), min_size=1, max_size=12),
       order=st.integers(0, 8), start=st.tuples(_COORD, _COORD))
def test_random_nurbs_stays_in_the_hull_and_ends_on_the_last_point(points, order, start):
    """Positive weights: every point of a NURBS is a convex combination of its control
    points, so it stays in their bounding box; the last feed ends on the last point."""
    body = [f'G0 X{start[0]} Y{start[1]} Z1', f'G5.2 X{points[0][0]} Y{points[0][1]} '
            f'P{points[0][2]} L{order}']
    body += [f'X{x} Y{y} P{w}' for x, y, w in points[1:]]
    body.append('G5.3')
    count = len(points) + 1
    text = '\n'.join(body)
    if count < max(order, 3):
        with pytest.raises(GcodeError, match='at least equal to the order'):
            run(text)
        return
    f = feeds(run(text))
    xs = [start[0]] + [p[0] for p in points]
    ys = [start[1]] + [p[1] for p in points]
    assert len(f) in (15 * count, 15 * count + 1)
    assert f[-1].end == pytest.approx((xs[-1] * MM, ys[-1] * MM, 1 * MM), abs=1e-15)
    assert chained(f[0].start, f)
    for m in f:
        assert all(math.isfinite(v) for v in m.end) and m.length_m >= 0.0
        assert min(xs) * MM - 1e-12 <= m.end[0] <= max(xs) * MM + 1e-12
        assert min(ys) * MM - 1e-12 <= m.end[1] <= max(ys) * MM + 1e-12


# -- against the reference interpreter (where linuxcnc-uspace is installed) --------------------
def _random_program(rng: random.Random) -> str:
    """G5, G5.1 and G5.2 curves mixed with G90/G91, G20/G21, rotated systems and G92."""
    def num(lo: float = -20.0, hi: float = 20.0) -> str:
        return f'{rng.uniform(lo, hi):.3f}'
    out = [rng.choice(['G21', 'G20']) + ' G17 F' + num(10, 500)]
    if rng.random() < 0.4:
        out.append(f'G10 L2 P1 X{num()} Y{num()} R{rng.choice(["0", num(-90, 90)])}')
    out.append(f'G0 X{num()} Y{num()} Z{num(0, 5)}')
    for _ in range(rng.randint(2, 6)):
        r = rng.random()
        dist = rng.choice(['G90 ', 'G91 ', ''])
        if r < 0.3:
            ij = f'I{num(-5, 5)} J{num(-5, 5)} ' if rng.random() < 0.7 else ''
            out.append(f'{dist}G5 X{num()} Y{num()} {ij}P{num(-5, 5)} Q{num(-5, 5)}')
        elif r < 0.5:
            out.append(f'{dist}G5.1 X{num()} Y{num()} I{num(-5, 5)} J{num(-5, 5)}')
        elif r < 0.85:
            n = rng.randint(3, 8)
            order = rng.choice(['', 'L3', 'L4', 'L5'])
            out.append(f'{dist}G5.2 X{num()} Y{num()} P{num(0.2, 3)} {order}')
            out += [f'X{num()} Y{num()} P{num(0.2, 3)}' for _ in range(n - 1)]
            out.append('G5.3')
        else:
            out.append(f'G92 X{num()} Y{num()}')
        out.append(f'G1 X{num()}')
    return '\n'.join(out + ['G90 G0 Z10', 'M2']) + '\n'


def test_random_spline_programs_agree_with_the_reference(tmp_path):
    oracle = must_run.oracle_script()
    spec = importlib.util.spec_from_file_location('fae_bench_corpus_splines',
                                                  ROOT / 'bench' / 'corpus.py')
    corpus = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = corpus
    spec.loader.exec_module(corpus)
    rng = random.Random(2026)
    for k in range(12):
        path = tmp_path / f'random{k}.ngc'
        path.write_text(_random_program(rng))
        proc = subprocess.run([sys.executable, str(oracle), '--one', str(path)],
                              cwd='/', capture_output=True, text=True, timeout=300)
        ref = json.loads(proc.stdout.strip().splitlines()[-1])
        ours = corpus.run_ours(path, dialect='linuxcnc', search_path=[tmp_path])
        if ref['status'] != 'ok':
            assert ours.status == 'error', (path.read_text(), ref['error'])
            assert ref['error'] in ours.error
            continue
        assert ours.status == 'ok', ours.error
        diffs = corpus.compare(path.name, ours, ref)
        assert not diffs, path.read_text() + '\n'.join(d.text() for d in diffs)


@pytest.mark.parametrize('dialect', ['fanuc', 'haas', 'grbl', 'mach3'])
@pytest.mark.parametrize('text', ['G05.1 Q1', 'G5 X1 Y1 I1 J1 P1 Q1', 'G5.2 X1 Y1 P1', 'G5.3'])
def test_other_dialects_refuse_g5_codes(dialect, text):
    # grbl, Mach3, Haas have no G5 spline; on Fanuc G05/G05.1 are high-speed machining
    # modes (accepted with a warning: test_fanuc_high_speed_modes_are_accepted_with_a_warning)
    if dialect == 'fanuc' and text.split()[0] in ('G05.1', 'G5'):
        return
    with pytest.raises(GcodeError, match=f'not simulated in the {dialect} dialect') as info:
        parse_gcode('G21 F100\n' + text + '\nM30\n', dialect=dialect, file='f.nc')
    assert (info.value.line, info.value.column) == (2, 1)


@pytest.mark.parametrize('dialect, codes', [
    ('fanuc', ['G05.1 Q1', 'G05 P10000', 'G08 P1', 'G05.1 Q0', 'G05 P0', 'G08 P0']),
    ('haas', ['G187 P1 E0.05', 'G103 P4', 'G187'])])
def test_control_modes_are_accepted_with_one_warning_each(dialect, codes):
    text = 'G21 G90\n' + ''.join(f'{c}\nG1 X{i + 1} F600\n' for i, c in enumerate(codes))
    prog = parse_gcode(text + 'M30\n', dialect=dialect, file='f.nc')
    # the modes change nothing of the path: one feed per G1 line, in order
    ends = [round(m.end[0] * 1e3, 9) for m in prog.moves if m.kind.name == 'LINEAR']
    assert ends == [float(i + 1) for i in range(len(codes))]
    names = {c.split()[0].replace('G05.1', 'G5.1').replace('G05', 'G5').replace('G08', 'G8')
             for c in codes}
    assert len(prog.warnings) == len(names)
    assert all('not modelled' in w and w.startswith('f.nc:') for w in prog.warnings)


def test_control_modes_belong_to_their_dialect():
    with pytest.raises(GcodeError, match='unknown G code G187'):
        parse_gcode('G21\nG187 P1\n', dialect='fanuc', file='f.nc')
    # LinuxCNC's G8 is lathe radius mode: no P word there
    with pytest.raises(GcodeError, match='P word'):
        parse_gcode('G21\nG08 P1\n', dialect='linuxcnc', file='f.nc')
