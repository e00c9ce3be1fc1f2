"""gcode/stats: counts, lengths and the exact bounding box, checked by hand."""
from __future__ import annotations

import math

from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.gcode.stats import arc_extremes, arc_geometry, MoveStats, summarize
from feed_axis_energy.gcode.program import Move, MoveKind


def _line(start, end, kind=MoveKind.LINEAR, line=1):
    return Move(kind=kind, line=line, start=start, end=end, feed_m_s=0.01,
                length_m=math.dist(start, end))


def _arc(start, end, center, *, ccw, plane=17, turns=0, length=0.0, line=1):
    return Move(kind=MoveKind.ARC_CCW if ccw else MoveKind.ARC_CW, line=line, start=start,
                end=end, feed_m_s=0.01, center=center, plane=plane, turns=turns,
                length_m=length)


def test_square_counts_lengths_and_box():
    # 10 mm square at Z -1 mm after a rapid from the origin: feed 40 mm, rapid |(0,0,-1)|.
    pts = [(0.0, 0.0, -1e-3), (0.01, 0.0, -1e-3), (0.01, 0.01, -1e-3), (0.0, 0.01, -1e-3),
           (0.0, 0.0, -1e-3)]
    moves = [_line((0.0, 0.0, 0.0), pts[0], MoveKind.RAPID)]
    moves += [_line(a, b) for a, b in zip(pts, pts[1:])]
    s = summarize(moves)
    assert (s.n_traverses, s.n_feed_moves, s.n_arcs, s.n_dwells) == (1, 4, 0, 0)
    assert_allclose(s.feed_length_m, 0.04, rtol=1e-15)
    assert_allclose(s.traverse_length_m, 1e-3, rtol=1e-15)
    assert s.final_position == (0.0, 0.0, -1e-3)
    assert s.bbox_min == (0.0, 0.0, -1e-3)
    assert s.bbox_max == (0.01, 0.01, 0.0)


def test_zero_length_moves_dwells_and_stops_are_counted():
    p = (0.001, 0.002, 0.003)
    moves = [_line(p, p, MoveKind.RAPID), _line(p, p),
             Move(kind=MoveKind.DWELL, line=2, start=p, end=p, dwell_s=1.5),
             Move(kind=MoveKind.DWELL, line=3, start=p, end=p, dwell_s=0.25),
             Move(kind=MoveKind.STOP, line=4, start=p, end=p)]
    s = summarize(moves, start=p)
    assert (s.n_traverses, s.n_feed_moves, s.n_dwells, s.n_stops) == (1, 1, 2, 1)
    assert s.feed_length_m == 0.0 and s.traverse_length_m == 0.0
    assert s.dwell_s == 1.75
    assert s.bbox_min == p and s.bbox_max == p


def test_no_motion_gives_no_box_and_the_start_as_final_position():
    p = (0.0, 0.0, 0.0)
    s = summarize([Move(kind=MoveKind.DWELL, line=1, start=p, end=p, dwell_s=2.0)])
    assert s.bbox_min is None and s.bbox_max is None
    assert s.final_position == p and s.n_motions == 0
    assert summarize([]).final_position == p


def test_box_includes_the_start_point_once_the_tool_moves():
    start = (0.05, 0.05, 0.05)
    s = summarize([_line(start, (0.06, 0.04, 0.05), MoveKind.RAPID)], start=start)
    assert s.bbox_min == (0.05, 0.04, 0.05)
    assert s.bbox_max == (0.06, 0.05, 0.05)


def test_full_circle_g2_box_is_the_circle_and_length_is_taken_from_the_move():
    # Start at (r, 0), centre at the origin, end == start: one revolution clockwise.
    r = 0.005
    length = 2 * math.pi * r
    arc = _arc((r, 0.0, 0.0), (r, 0.0, 0.0), (0.0, 0.0, 0.0), ccw=False, length=length)
    (a, b, n), theta0, sweep, r0, r1 = arc_geometry(arc)
    assert (a, b, n) == (0, 1, 2)
    assert theta0 == 0.0 and sweep == pytest.approx(-2 * math.pi) and r0 == r1 == r
    s = summarize([arc], start=(r, 0.0, 0.0))
    assert s.n_arcs == 1 and s.n_feed_moves == 0
    assert s.feed_length_m == length
    assert_allclose(s.bbox_min, (-r, -r, 0.0), atol=1e-18)
    assert_allclose(s.bbox_max, (r, r, 0.0), atol=1e-18)


@pytest.mark.parametrize('ccw, expect_y', [(True, (0.0, 1.0)), (False, (-1.0, 0.0))])
def test_half_circle_reaches_the_extreme_on_its_own_side(ccw, expect_y):
    # From (1, 0) to (-1, 0) about the origin: G3 passes (0, 1), G2 passes (0, -1).
    arc = _arc((1.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 0.0, 0.0), ccw=ccw, length=math.pi)
    s = summarize([arc], start=(1.0, 0.0, 0.0))
    assert_allclose((s.bbox_min[1], s.bbox_max[1]), expect_y, atol=1e-15)
    assert_allclose((s.bbox_min[0], s.bbox_max[0]), (-1.0, 1.0), atol=1e-15)


def test_quarter_arc_between_extremes_adds_none():
    arc = _arc((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 0.0), ccw=True)
    assert arc_extremes(arc) == []


def test_arc_from_45_to_135_degrees_reaches_y_equal_radius():
    c = math.sqrt(0.5)
    arc = _arc((c, c, 0.0), (-c, c, 0.0), (0.0, 0.0, 0.0), ccw=True)
    pts = arc_extremes(arc)
    assert len(pts) == 1
    assert_allclose(pts[0], (0.0, 1.0, 0.0), atol=1e-15)


def test_helix_extremes_interpolate_the_axial_coordinate():
    # One full turn (+1 extra) in G17 from (1, 0, 0) rising 2: the +Y extreme of the first
    # revolution lies a quarter of a turn in, i.e. at 1/8 of the total sweep -> Z = 0.25.
    arc = _arc((1.0, 0.0, 0.0), (1.0, 0.0, 2.0), (0.0, 0.0, 0.0), ccw=True, turns=1)
    (_, _, _), _, sweep, _, _ = arc_geometry(arc)
    assert sweep == pytest.approx(4 * math.pi)
    pts = arc_extremes(arc)
    assert_allclose(pts[0], (0.0, 1.0, 0.25), atol=1e-15)
    assert len(pts) <= 5   # one revolution holds all four extremes (plus the repeat)


def test_g18_arc_uses_z_then_x():
    # G18: first axis Z, second X; G3 from Z = +1 to Z = -1 about the origin goes through
    # +X (angle 90 degrees from the Z axis towards X).
    arc = _arc((0.0, 0.0, 1.0), (0.0, 0.0, -1.0), (0.0, 0.0, 0.0), ccw=True, plane=18)
    pts = arc_extremes(arc)
    assert_allclose(pts, [(1.0, 0.0, 0.0)], atol=1e-15)


def test_g19_arc_uses_y_then_z():
    arc = _arc((0.0, 1.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, 0.0), ccw=True, plane=19)
    assert_allclose(arc_extremes(arc), [(0.0, 0.0, 1.0)], atol=1e-15)


def test_spiral_radius_is_interpolated_along_the_sweep():
    # From radius 1 at 0 deg to radius 2 at 180 deg (CCW): at 90 deg the radius is 1.5.
    arc = _arc((1.0, 0.0, 0.0), (-2.0, 0.0, 0.0), (0.0, 0.0, 0.0), ccw=True)
    assert_allclose(arc_extremes(arc), [(0.0, 1.5, 0.0)], atol=1e-15)


def test_sweep_rad_of_the_move_wins_over_the_derived_one():
    # A near-full circle the parser decided is a short arc: end 1e-9 rad past the start.
    eps = 1e-9
    end = (math.cos(eps), math.sin(eps), 0.0)
    arc = _arc((1.0, 0.0, 0.0), end, (0.0, 0.0, 0.0), ccw=True)
    arc = Move(**{**arc.__dict__, 'sweep_rad': eps})
    assert arc_geometry(arc)[2] == eps
    assert arc_extremes(arc) == []


def test_streaming_accumulator_equals_summarize():
    moves = [_line((0.0, 0.0, 0.0), (0.001, 0.0, 0.0)),
             _arc((0.001, 0.0, 0.0), (-0.001, 0.0, 0.0), (0.0, 0.0, 0.0), ccw=True,
                  length=math.pi * 1e-3)]
    acc = MoveStats()
    for m in moves:
        acc.add(m)
    assert acc.result() == summarize(moves)
