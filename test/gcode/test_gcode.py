"""Tests of the G-code parser: modal state, units, arcs (hand-computed), errors with places."""
from __future__ import annotations

import math
from pathlib import Path

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.load import load_gcode, parse_gcode
from feed_axis_energy.gcode.program import MoveKind
import numpy as np
from numpy.testing import assert_allclose
import pytest

FIXTURES = Path(__file__).resolve().parents[1] / 'fixtures' / 'gcode'
MM = 1e-3
INCH = 0.0254


def moves(text: str, **kw):
    return [m for m in parse_gcode(text, **kw).moves]


def motion_moves(text: str, **kw):
    return [m for m in moves(text, **kw) if m.kind not in (MoveKind.DWELL, MoveKind.STOP)]


def radius(m, point) -> float:
    return float(np.linalg.norm(np.subtract(point, m.center)[list(_in_plane(m.plane))]))


def _in_plane(plane: int) -> tuple[int, int]:
    return {17: (0, 1), 18: (2, 0), 19: (1, 2)}[plane]


def assert_chain(program_moves, start=(0.0, 0.0, 0.0)) -> None:
    """Every move starts where the previous one ended (no lost or invented motion)."""
    pos = start
    for m in program_moves:
        assert_allclose(m.start, pos, atol=1e-12)
        pos = m.end


# -- the paper's demonstrator ---------------------------------------------------------------
def test_demonstrator_program():
    text = 'G21 G90 G94\nG1 X400 F6000\nG4 P1\nG1 X0\nG4 P1\n'
    prog = parse_gcode(text, file='demo.nc')
    kinds = [m.kind for m in prog.moves]
    assert kinds == [MoveKind.LINEAR, MoveKind.DWELL, MoveKind.LINEAR, MoveKind.DWELL]
    out, d1, back, d2 = prog.moves
    # 6000 mm/min = 0.1 m/s; 400 mm = 0.4 m.
    assert out.line == 2 and back.line == 4
    assert_allclose(out.end, (0.4, 0.0, 0.0))
    assert_allclose([out.feed_m_s, back.feed_m_s], [0.1, 0.1])
    assert_allclose([out.length_m, back.length_m], [0.4, 0.4])
    assert_allclose(back.end, (0.0, 0.0, 0.0))
    assert d1.dwell_s == 1.0 and d2.dwell_s == 1.0
    assert_allclose(d1.start, (0.4, 0.0, 0.0))
    assert prog.file == 'demo.nc' and prog.n_lines == 5 and prog.warnings == ()
    assert_chain(prog.moves)


# -- modal state ----------------------------------------------------------------------------
def test_motion_mode_and_feed_persist():
    ms = motion_moves('G1 X1 F600\nY1\nG0 Z1\nX2\nG1 Y3\n')
    assert [m.kind for m in ms] == [MoveKind.LINEAR, MoveKind.LINEAR, MoveKind.RAPID,
                                    MoveKind.RAPID, MoveKind.LINEAR]
    assert_allclose([ms[0].feed_m_s, ms[1].feed_m_s, ms[4].feed_m_s], 0.01)
    assert math.isinf(ms[2].feed_m_s) and math.isinf(ms[3].feed_m_s)
    assert_allclose(ms[-1].end, (2 * MM, 3 * MM, 1 * MM))


def test_units_and_distance_mode_persist():
    ms = motion_moves('G20 G91 G1 X1 F10\nX1\nG21 X1\nG90 X0\n')
    assert_allclose(ms[0].end[0], INCH)
    assert_allclose(ms[1].end[0], 2 * INCH)
    assert_allclose(ms[2].end[0], 2 * INCH + MM)
    assert_allclose(ms[3].end[0], 0.0)
    # F10 in/min keeps its physical speed after G21.
    assert_allclose([m.feed_m_s for m in ms], 10 * INCH / 60)


def test_feed_in_the_units_of_its_line():
    ms = motion_moves('G20 F10\nG1 X1\nG21 F10 X0\n')
    assert_allclose(ms[0].feed_m_s, 10 * INCH / 60)
    assert_allclose(ms[1].feed_m_s, 10 * MM / 60)


def test_plane_persists_and_incremental_arc_centre():
    ms = motion_moves('G18 F100\nG2 X10 I5\nG3 X20 I5\nG17\nG3 X30 I5\n')
    assert [m.plane for m in ms] == [18, 18, 17]
    assert_allclose(ms[0].center, (5 * MM, 0, 0))
    assert_allclose(ms[1].center, (15 * MM, 0, 0))
    assert_allclose(ms[2].center, (25 * MM, 0, 0))


def test_start_position_and_incremental():
    ms = motion_moves('G91 G0 X1 Y-1 Z.5\n', start=(0.1, 0.2, 0.3))
    assert_allclose(ms[0].start, (0.1, 0.2, 0.3))
    assert_allclose(ms[0].end, (0.101, 0.199, 0.3005))


@pytest.mark.parametrize('line, x', [
    ('G1 X.5', 0.5), ('G1 X-1.', -1.0), ('g1 x10', 10.0), ('G1 X 10', 10.0),
    ('G1X+2', 2.0), ('G01 X1 0', 10.0), ('G1 X - 3', -3.0), ('G1\tX7', 7.0),
    ('G1 X1 1', 11.0), ('G1 X00.25', 0.25),
])
def test_number_forms(line, x):
    ms = motion_moves(f'F100\n{line}\n')
    assert len(ms) == 1
    assert_allclose(ms[0].end[0], x * MM)


def test_exact_stop_modes():
    ms = motion_moves('F100\nG1 X1\nG9 X2\nX3\nG61 X4\nG0 X5\nG64 P0.02 Q0.01 G1 X6\n')
    assert [m.exact_stop for m in ms] == [False, True, False, True, True, False]


def test_g80_clears_motion_mode():
    with pytest.raises(GcodeError, match='no motion mode') as info:
        parse_gcode('G1 X1 F100\nG80\nX2\n')
    assert (info.value.line, info.value.column) == (3, 1)


def test_zero_length_moves_are_issued_as_linuxcnc_does():
    # LinuxCNC issues STRAIGHT_FEED/TRAVERSE for them (the reference counts them); the
    # planner drops them. An explicit G0/G1 without axis words is such a move too.
    zero = motion_moves('G1 X1 F100\nX1\nG0 X1\nG0\n')[1:]
    assert [m.kind for m in zero] == [MoveKind.LINEAR, MoveKind.RAPID, MoveKind.RAPID]
    assert [m.length_m for m in zero] == [0.0, 0.0, 0.0]
    assert all(m.start == m.end == (1 * MM, 0.0, 0.0) for m in zero)


# -- arcs -----------------------------------------------------------------------------------
@pytest.mark.parametrize('g, end, r_word, ij, angle', [
    ('G3', (0, 10), 'R10', 'I-10 J0', math.pi / 2),       # quarter, CCW from (10, 0)
    ('G2', (0, 10), 'R-10', 'I-10 J0', 3 * math.pi / 2),  # the long way round, CW
    ('G2', (0, -10), 'R10', 'I-10 J0', math.pi / 2),
    ('G3', (7.0710678118654755, 7.0710678118654755), 'R10', 'I-10 J0', math.pi / 4),
])
def test_r_and_ijk_forms_agree(g, end, r_word, ij, angle):
    head = 'G0 X10 Y0\nF100\n'
    target = f'{g} X{end[0]!r} Y{end[1]!r}'
    m_r = motion_moves(f'{head}{target} {r_word}\n')[-1]
    m_c = motion_moves(f'{head}{target} {ij}\n')[-1]
    assert_allclose(m_r.center, (0, 0, 0), atol=1e-12)
    assert_allclose(m_c.center, (0, 0, 0), atol=1e-12)
    assert_allclose([m_r.length_m, m_c.length_m], angle * 10 * MM, rtol=1e-9)


@pytest.mark.parametrize('program, n_half_turns', [
    ('G2 X20 Y0 I10 J0', 1),            # half circle, r = 10 mm
    ('G2 X0 Y0 I10 J0', 2),             # full circle: end == start
    ('G3 X0 Y0 I10 J0 P3', 6),          # three full turns
    ('G2 X20 Y0 I10 P2', 3),            # half circle plus one turn
])
def test_circle_lengths(program, n_half_turns):
    m = motion_moves(f'F100\n{program}\n')[0]
    assert_allclose(m.length_m, n_half_turns * math.pi * 10 * MM, rtol=1e-12)
    assert m.turns == (n_half_turns - 1) // 2


def test_helix_length():
    # Three turns of r = 5 mm while Z falls 10 mm.
    m = motion_moves('G0 X10 Y10 Z-2\nG17 G2 X10 Y10 Z-12 I-5 J0 P3 F100\n')[-1]
    assert_allclose(m.length_m, math.hypot(3 * 2 * math.pi * 5 * MM, 10 * MM), rtol=1e-12)
    assert_allclose(m.center, (5 * MM, 10 * MM, -2 * MM))
    assert m.turns == 2


@pytest.mark.parametrize('program, ccw_end', [
    # CCW (G3) seen from the positive end of the plane normal: a quarter turn.
    ('G0 X0 Y10 Z0\nG17 G3 X-10 Y0 I0 J-10', (-10, 0, 0)),
    ('G0 X0 Y0 Z10\nG18 G3 X10 Z0 I0 K-10', (10, 0, 0)),    # Z towards X about +Y
    ('G0 X0 Y10 Z0\nG19 G3 Y0 Z10 J-10 K0', (0, 0, 10)),    # Y towards Z about +X
])
def test_arc_direction_in_every_plane(program, ccw_end):
    ccw = motion_moves(f'F100\n{program}\n')[-1]
    cw = motion_moves(f'F100\n{program.replace("G3", "G2")}\n')[-1]
    assert_allclose(ccw.end, np.multiply(ccw_end, MM), atol=1e-15)
    assert_allclose(ccw.length_m, math.pi / 2 * 10 * MM, rtol=1e-12)
    assert_allclose(cw.length_m, 3 * math.pi / 2 * 10 * MM, rtol=1e-12)
    assert_allclose(ccw.center, (0, 0, 0), atol=1e-15)


def test_absolute_arc_centres():
    m = motion_moves('G0 X10 Y5\nG90.1 G3 X0 Y15 I0 J5 F100\n')[-1]
    assert_allclose(m.center, (0, 5 * MM, 0))
    assert_allclose(m.length_m, math.pi / 2 * 10 * MM)


def test_arc_within_tolerance_and_outside():
    # LinuxCNC 2.9 (G21): the radii may differ by 2 * 0.01 * sqrt(2) = 0.028284 mm, or by
    # more if within 0.1 % of the radius, but never by more than 2.8284 mm.
    m = motion_moves('G0 X10\nG3 X-10.028 Y0 I-10 F100\n')[-1]
    assert_allclose(m.length_m, math.pi * 10.014 * MM, rtol=1e-12)
    with pytest.raises(GcodeError, match='not on the circle'):
        parse_gcode('G0 X10\nG3 X-10.029 Y0 I-10 F100\n')
    parse_gcode('G0 X100\nG3 X-100.099 Y0 I-100 F100\n')          # 0.099 %
    with pytest.raises(GcodeError, match='not on the circle'):
        parse_gcode('G0 X100\nG3 X-100.101 Y0 I-100 F100\n')
    parse_gcode('G0 X5000\nG3 X-5002.8 Y0 I-5000 F100\n')         # 0.056 %, < 2.8284 mm
    with pytest.raises(GcodeError, match='not on the circle'):
        parse_gcode('G0 X5000\nG3 X-5002.9 Y0 I-5000 F100\n')
    # G20: 0.002828 inch.
    parse_gcode('G20 G0 X1\nG3 X-1.0028 I-1 F10\n')
    with pytest.raises(GcodeError, match='not on the circle'):
        parse_gcode('G20 G0 X1\nG3 X-1.0029 I-1 F10\n')
    # The absolute tolerance can be narrowed (or widened) by the caller.
    parse_gcode('G0 X1\nG3 X-1.004 I-1 F100\n')
    with pytest.raises(GcodeError, match='not on the circle'):
        parse_gcode('G0 X1\nG3 X-1.004 I-1 F100\n', arc_tolerance_m=0.002 * MM)


def test_every_arc_end_is_on_its_circle():
    prog = load_gcode(FIXTURES / 'good' / 'pocket_arcs.nc')
    arcs = [m for m in prog.moves if m.kind in (MoveKind.ARC_CW, MoveKind.ARC_CCW)]
    assert len(arcs) == 7
    for m in arcs:
        assert_allclose(radius(m, m.end), radius(m, m.start), rtol=1e-9)
        normal = 3 - sum(_in_plane(m.plane))
        assert m.center[normal] == m.start[normal]


# -- feed modes, dwell, stops ---------------------------------------------------------------
def test_inverse_time_feed():
    ms = motion_moves('G93 G1 X30 Y40 F2\nG2 X30 Y40 I10 F6\n')
    # 50 mm in 60/2 = 30 s; full circle of r = 10 mm in 10 s.
    assert_allclose(ms[0].feed_m_s, 50 * MM / 30)
    assert_allclose(ms[1].feed_m_s, 2 * math.pi * 10 * MM / 10)


def test_switching_feed_mode_clears_f():
    # LinuxCNC clears F on a G93/G94 switch; a feed move without F is then refused as on
    # the control, at the line's G word; allow_no_feed runs it at the machine's limits
    # (feed inf), with one warning (LinuxCNC's preview accepts it).
    text = 'G1 X1 F100\nG93 G1 X2 F1\nG94 G1 X3\nX4\n'
    with pytest.raises(GcodeError) as err:
        parse_gcode(text, file='t.nc')
    assert (err.value.line, err.value.column) == (3, 5)
    assert 'no feed rate (F) set' in err.value.reason and '--allow-no-feed' in err.value.reason
    prog = parse_gcode(text, file='t.nc', allow_no_feed=True)
    assert [m.feed_m_s for m in prog.moves[2:]] == [math.inf, math.inf]
    assert [w for w in prog.warnings if 'no feed rate' in w] == [
        't.nc:3: feed move with no feed rate (F) set: it runs at the machine\'s axis '
        'limits (--allow-no-feed; the control refuses this, LinuxCNC\'s preview accepts it)']


def test_dwell_and_stops():
    prog = parse_gcode('G4 P2.5\nG1 X1 F60\nM0\nM1\nG0 X2\nM30\n')
    expected = [MoveKind.DWELL, MoveKind.LINEAR, MoveKind.STOP, MoveKind.STOP, MoveKind.RAPID,
                MoveKind.STOP]
    assert [m.kind for m in prog.moves] == expected
    assert prog.moves[0].dwell_s == 2.5
    assert_allclose(prog.moves[2].start, (MM, 0, 0))


def test_program_end_ignores_rest_with_warning():
    prog = parse_gcode('G0 X1\nM2\n(comment)\n\nG0 X5\n', file='p.nc')
    assert prog.moves[-1].kind == MoveKind.STOP
    assert len(prog.moves) == 2
    assert len(prog.warnings) == 1 and prog.warnings[0].startswith('p.nc:5:')
    assert parse_gcode('G0 X1\nM30\n(only a comment)\n%\n').warnings == ()


def test_headers_comments_block_delete_percent():
    text = ('%\nO1234 (NAME)\nG17 G21 G40 G49 G80 G90 G54 G94 G97 G98 G64 ; header\n'
            'T1 M6\nS1000 M3 M8\n/G0 X99\nN10 G0 X1 (a) Y2 (b)\nM5 M9\n%\nG0 X7\n')
    prog = parse_gcode(text)
    assert len(prog.moves) == 1
    assert_allclose(prog.moves[0].end, (MM, 2 * MM, 0))
    assert len(prog.warnings) == 1


def test_crlf_fixture_and_good_fixtures_chain():
    prog = load_gcode(FIXTURES / 'good' / 'crlf.nc')
    assert_allclose(prog.moves[0].end, (MM, 0, 0))
    for path in sorted((FIXTURES / 'good').glob('*.nc')):
        prog = load_gcode(path)
        assert prog.file == str(path)
        assert_chain(prog.moves)
        for m in prog.moves:
            if m.kind in (MoveKind.RAPID, MoveKind.LINEAR):
                assert_allclose(m.length_m, math.dist(m.start, m.end))
            assert m.feed_m_s > 0


def test_inch_inverse_time_fixture():
    ms = load_gcode(FIXTURES / 'good' / 'inch_inverse_time.nc').moves
    plunge, line_x, arc, back, g9, dwell, stop = ms[1:]
    assert_allclose(plunge.feed_m_s, 0.15 * INCH / 1.0)          # F60: one second
    assert_allclose(line_x.feed_m_s, 1.0 * INCH / 2.0)           # F30: two seconds
    assert_allclose(arc.length_m, 1.5 * math.pi * INCH)          # CW from -90 deg to 0 deg
    assert_allclose(arc.feed_m_s, arc.length_m / 4.0)            # F15: four seconds
    assert_allclose(back.feed_m_s, 20 * INCH / 60)
    assert g9.exact_stop and not back.exact_stop
    assert dwell.dwell_s == 0.5 and stop.kind == MoveKind.STOP


# -- errors ---------------------------------------------------------------------------------
BAD = {
    'unknown_letter.nc': (3, 10, 'E word with no M66'),
    'missing_feed.nc': (3, 10, 'feed rate is zero'),
    'arc_off_circle.nc': (2, 4, 'not on the circle'),
    'r_too_small.nc': (2, 11, 'smaller than half the chord'),
    'bad_number.nc': (2, 5, 'bad number'),
    'not_a_number.nc': (2, 8, 'where a value was expected'),
    'motion_conflict.nc': (2, 4, 'same modal group'),
    'distance_conflict.nc': (3, 11, 'same modal group'),
    'repeated_axis.nc': (2, 7, 'repeated'),
    'unclosed_comment.nc': (2, 4, 'unclosed comment'),
    'canned_cycle.nc': (2, 5, 'R clearance plane unspecified'),
    'rotary_axis.nc': (2, 4, 'axis A is not supported'),
    'inverse_time_no_f.nc': (3, 1, 'G93'),
    'nested_comment.nc': (1, 15, 'nested comment'),
    'axis_without_motion.nc': (2, 1, 'no motion mode'),
    'expression.nc': (2, 4, 'divide by zero'),
}


def test_every_bad_fixture_is_listed():
    assert sorted(p.name for p in (FIXTURES / 'bad').glob('*.nc')) == sorted(BAD)


@pytest.mark.parametrize('name', sorted(BAD))
def test_bad_fixture_place(name):
    line, column, reason = BAD[name]
    path = FIXTURES / 'bad' / name
    with pytest.raises(GcodeError) as info:
        load_gcode(path)
    err = info.value
    assert (err.line, err.column) == (line, column), str(err)
    assert reason in err.reason
    assert str(path) in str(err) and err.file == str(path)
    assert str(err).startswith(f'{path}:{line}:{column}: ')


def test_g43_tool_length_offset_comes_from_the_tool_table():
    # G43 H1 applies tool 1's length to Z (moves are in machine coordinates); a tool the
    # table lacks is an error at its H word under strict_tools (more cases in
    # test/gcode/test_coords.py and test/gcode/test_missing_tools.py).
    tools = {1: (0.0, 0.1), 2: (0.0, 0.02)}
    prog = parse_gcode('G21 G90\nG0 G43 H1 Z50\nG1 Z10 F600\nG43 H2\nG49\n', file='t.nc',
                       tools=tools)
    assert [m.end[2] for m in prog.moves] == pytest.approx([0.15, 0.11])
    assert prog.warnings == ()
    with pytest.raises(GcodeError) as err:
        parse_gcode('G21 G90\nG0 G43 H1 Z50\n', file='t.nc', strict_tools=True)
    assert (err.value.line, err.value.column) == (2, 8) and 'tool table' in str(err.value)


@pytest.mark.parametrize('text, line, column, reason', [
    ('G1 X1 F100\nG2 X3 Y0 R0', 2, 10, 'R0'),
    ('F100\nG2 X0 Y0 R5', 2, 10, 'full circle'),
    ('F100\nG2 X10 R5 I5', 2, 8, 'not both'),
    ('F100\nG1 X10 I5', 2, 8, 'no G2/G3'),
    ('F100\nG2 R5', 2, 4, 'needs an end point'),
    ('F100\nG2 X10 I5 K1', 2, 11, 'not an in-plane'),
    ('F100\nG2 X10 I5 P1.5', 2, 11, 'number of turns'),
    ('G4', 1, 1, 'needs a P'),
    ('G4 P-1', 1, 4, 'negative dwell'),
    ('G1 X1 P2 F100', 1, 7, 'P word'),
    ('G1 X1 F-5', 1, 7, 'negative feed'),
    ('G1 X1 F0', 1, 7, 'zero'),
    ('G93 G1 X1 F0', 1, 11, 'never finish'),
    ('G41 D1', 1, 5, 'tool 1 is not in the tool table'),
    ('G0 X1 H1', 1, 7, 'no G43'),
    ('G5.5', 1, 1, 'unknown G code'),
    ('M3 M5', 1, 4, 'same modal group'),
    ('M98 P100', 1, 1, 'not defined'),
    ('  G0 X1 ) ', 1, 9, '")" without'),
    ('G0 X[1', 1, 7, 'without a closing'),
    ('o100 sub', 1, 1, 'endsub'),
    ('G0 X1 Q1', 1, 7, 'no canned cycle'),
    ('G0 X1 ä', 1, 7, 'unexpected character'),
    (' 1 G0 X1', 1, 2, 'number without a letter'),
    ('G90 G90 X1', 1, 5, 'same modal group'),
    ('G4 G9 P1', 1, 4, 'same modal group'),
])
def test_error_places(text, line, column, reason):
    with pytest.raises(GcodeError) as info:
        parse_gcode(text, file='t.nc', strict_tools=True)
    err = info.value
    assert (err.line, err.column) == (line, column), str(err)
    assert reason in err.reason, str(err)
    assert str(err).startswith(f't.nc:{line}:{column}: ')


def test_non_ascii_comment_is_fine_and_error_keeps_columns():
    ms = motion_moves('G1 X1 F100 (Größe ä)\n(ÄÖÜ) G1 X2\n')
    assert_allclose(ms[-1].end, (2 * MM, 0, 0))
    with pytest.raises(GcodeError) as info:
        parse_gcode('(ß) G1 X1 E1 F100\n')
    assert info.value.column == 11


def test_load_errors(tmp_path):
    with pytest.raises(GcodeError) as info:
        load_gcode(tmp_path / 'missing.nc')
    assert (info.value.line, info.value.column) == (0, 0)
    assert 'missing.nc' in str(info.value)
    bad = tmp_path / 'latin1.nc'
    bad.write_bytes(b'G0 X1\n(Gr\xf6\xdfe)\n')
    with pytest.raises(GcodeError, match='not UTF-8') as info:
        load_gcode(bad)
    assert info.value.line == 2 and str(bad) in str(info.value)


def test_garbage_collection_is_resumed_after_parsing_and_after_an_error():
    import gc
    assert gc.isenabled()
    parse_gcode('G1 X1 F100\n', file='t.nc')
    assert gc.isenabled()
    with pytest.raises(GcodeError):
        parse_gcode('G1 X1 Q5 F100\n', file='t.nc')
    assert gc.isenabled()


HOME = (0.0, 0.0, 0.1)


def test_g28_goes_home_through_the_intermediate_point():
    # Fanuc-style program end: incremental Z0 = the current point, then Z to the reference.
    prog = parse_gcode('G21 G90\nG1 X10 Y20 Z5 F600\nG91 G28 Z0\nG90 G28 X30\n',
                       file='t.nc', home=HOME)
    # LinuxCNC issues both rapids of a G28, the first of zero length here
    kinds = [m.kind for m in prog.moves]
    assert kinds == [MoveKind.LINEAR] + [MoveKind.RAPID] * 4
    assert prog.moves[1].length_m == 0.0
    up = prog.moves[2]
    assert up.line == 3 and up.start == pytest.approx((0.01, 0.02, 0.005))
    assert up.end == pytest.approx((0.01, 0.02, 0.1)) and up.exact_stop
    via, home_x = prog.moves[3:]
    assert via.end == pytest.approx((0.03, 0.02, 0.1))     # intermediate X30 (absolute)
    assert home_x.end == pytest.approx((0.0, 0.02, 0.1))   # only X goes home
    assert home_x.length_m == pytest.approx(0.03)


def test_g28_without_axis_words_sends_every_axis_home():
    prog = parse_gcode('G1 X10 Y20 Z5 F600\nG28\n', file='t.nc', home=HOME)
    assert prog.moves[-1].end == pytest.approx(HOME)
    assert prog.moves[-1].kind == MoveKind.RAPID


def test_g28_does_not_change_the_motion_mode():
    prog = parse_gcode('G1 X10 F600\nG28 Y0\nX20\n', file='t.nc', home=HOME)
    assert prog.moves[-1].kind == MoveKind.LINEAR and prog.moves[-1].end[0] == \
        pytest.approx(0.02)
