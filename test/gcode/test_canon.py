"""Canonical moves and the arc rules shared by parser and planner (hand calculations)."""
from __future__ import annotations

import math

from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.gcode.canon import (arc_sweep_rad, CENTER_ARC_RADIUS_TOLERANCE_MM,
                                          radius_error, straight_feed)
from feed_axis_energy.gcode.program import MoveKind, Program
from feed_axis_energy.plan.segments import collect_segments, segment_geometry

MM = 1e-3


def arcs(prog) -> list:
    return [m for m in prog.moves if m.kind in (MoveKind.ARC_CW, MoveKind.ARC_CCW)]


def planner_sweeps(prog) -> tuple[list[float], list[float]]:
    """(sweep, length) of every arc as the planner's geometry sees it."""
    geo = segment_geometry(collect_segments(Program(prog.file, tuple(arcs(prog)))), prog.file)
    return list(geo.sweep), list(geo.length)


def test_constants_are_linuxcncs():
    assert CENTER_ARC_RADIUS_TOLERANCE_MM == pytest.approx(0.02828427, rel=1e-7)
    assert not radius_error(10e-3, 10.028e-3, 0.0282843e-3)
    assert radius_error(10e-3, 10.029e-3, 0.0282843e-3)


def test_straight_feed_length():
    m = straight_feed(7, (0.0, 0.0, 0.0), (3e-3, 4e-3, 0.0), 0.01)
    assert (m.kind, m.line, m.feed_m_s) == (MoveKind.LINEAR, 7, 0.01)
    assert m.length_m == pytest.approx(5e-3)


@pytest.mark.parametrize('turn, expected', [(1, 2 * math.pi), (-1, -2 * math.pi),
                                            (3, 6 * math.pi)])
def test_end_at_start_is_whole_turns(turn, expected):
    assert arc_sweep_rad(1.0, 0.0, 1.0, 0.0, turn) == expected


def test_near_full_circle_is_the_same_arc_for_parser_and_planner():
    # End 1 um below the start on a 10 mm circle about the origin: for G2 (clockwise) that
    # is a sliver of 1e-4 rad; for G3 it is all of the circle but that sliver.
    g2 = parse_gcode('G21 G0 X10 Y0\nG2 X10 Y-0.001 I-10 F100\n')
    g3 = parse_gcode('G21 G0 X10 Y0\nG3 X10 Y-0.001 I-10 F100\n')
    sliver = math.atan2(0.001, 10)
    (a2,), (a3,) = arcs(g2), arcs(g3)
    assert a2.sweep_rad == pytest.approx(-sliver, rel=1e-9)
    assert a3.sweep_rad == pytest.approx(2 * math.pi - sliver, rel=1e-12)
    assert a2.length_m == pytest.approx(sliver * 10 * MM, rel=1e-6)
    assert a3.sweep_rad == arc_sweep_rad(10.0, 0.0, 10.0, -0.001, 1)      # canon's own rule
    for prog, move in ((g2, a2), (g3, a3)):
        sweeps, lengths = planner_sweeps(prog)
        assert sweeps == [move.sweep_rad]
        # the planner adds the spiral term (dr/dtheta) under the root: 1e-9 here
        assert_allclose(lengths, [move.length_m], rtol=1e-8)


def test_full_circle_from_centre_offsets_only():
    # LinuxCNC accepts a full circle without axis words (G2 I5: centre 5 mm to the right).
    prog = parse_gcode('G21 G0 X1 Y2\nG2 I5 F100\n')
    (m,) = arcs(prog)
    assert m.start == m.end
    assert m.sweep_rad == -2 * math.pi
    assert m.length_m == pytest.approx(2 * math.pi * 5 * MM, rel=1e-12)
    assert_allclose(m.center, (6 * MM, 2 * MM, 0.0))


def test_r_form_with_a_very_large_radius():
    # R = 5 km over a 10 mm chord: the sagitta is r - sqrt(r^2 - 25 mm^2) = 2.5 nm; the
    # arc is as long as the chord to within (chord^3 / 24 r^2) = 1.7e-9 mm.
    prog = parse_gcode('G21 G0 X0 Y0\nG2 X10 R5000000 F100\n')
    (m,) = arcs(prog)
    assert m.length_m == pytest.approx(10 * MM, rel=1e-9)
    assert abs(m.sweep_rad) == pytest.approx(2 * math.asin(5 / 5e6), rel=1e-9)
    assert m.sweep_rad < 0


@pytest.mark.parametrize('text, column, reason', [
    ('G2 X10 R4.99', 8, 'smaller than half the chord'),
    ('G2 X0 Y0 R5', 10, 'ending where it starts'),
    ('G2 X0 I0.0005', 1, 'radius is zero'),
    ('G2 X20.03 I10', 4, 'not on the circle'),
])
def test_arc_refusals(text, column, reason):
    with pytest.raises(GcodeError) as info:
        parse_gcode(f'G21 G0 X0 Y0\n{text} F100\n')
    assert (info.value.line, info.value.column) == (2, column), str(info.value)
    assert reason in info.value.reason


def test_r_within_reach_tolerance_is_a_half_circle():
    # LinuxCNC lets R fall short of half the chord by RADIUS_TOLERANCE (0.00127 mm).
    prog = parse_gcode('G21 G0 X0 Y0\nG2 X10 R4.999 F100\n')
    (m,) = arcs(prog)
    assert abs(m.sweep_rad) == pytest.approx(math.pi, rel=1e-9)
    assert_allclose(m.center, (5 * MM, 0.0, 0.0), atol=1e-12)
