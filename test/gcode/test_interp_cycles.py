"""Canned cycles and cutter compensation wired into the interpreter: whole programs through
parse_gcode, end positions and path lengths computed by hand."""
from __future__ import annotations

import math

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.gcode.program import MoveKind

MM = 1e-3


def lengths_mm(prog) -> tuple[float, float]:
    """(feed, rapid) path length [mm] of a program's moves."""
    feed = sum(m.length_m for m in prog.moves if m.kind != MoveKind.RAPID) / MM
    rapid = sum(m.length_m for m in prog.moves if m.kind == MoveKind.RAPID) / MM
    return feed, rapid


def moving(prog) -> list:
    """The moves of non-zero length (LinuxCNC also issues zero-length ones)."""
    return [m for m in prog.moves if m.length_m > 0.0]


def end_mm(prog) -> tuple[float, ...]:
    return tuple(round(v / MM, 9) for v in prog.moves[-1].end)


def test_g81_is_the_motion_mode_until_g80():
    # Start above R: across at Z10, down to R1, feed to -2, back to R (G99); the X10 line
    # repeats the cycle from R; after G80 a G0 is an ordinary traverse at R.
    prog = parse_gcode('G21 G90 G0 X0 Y0 Z10\nF120\nG99 G81 X5 Y0 Z-2 R1\nX10\nG80\nG0 X0\n')
    feed, rapid = lengths_mm(prog)
    assert feed == pytest.approx(3 + 3)
    assert rapid == pytest.approx(10 + 5 + 9 + 3 + 5 + 3 + 10)
    assert end_mm(prog) == (0, 0, 1)
    drills = [m for m in prog.moves if m.kind == MoveKind.LINEAR]
    assert [m.line for m in drills] == [3, 4]
    assert all(m.feed_m_s == pytest.approx(120 * MM / 60) for m in drills)


def test_g98_g91_repeats_with_l():
    # G91: R is relative to the initial level (5 - 3 = 2), Z to R (2 - 3 = -1); X10 is added
    # on each of the three repeats; G98 returns to the initial level 5 each time.
    prog = parse_gcode('G21 G0 X0 Y0 Z5\nF100\nG91 G98 G81 X10 Z-3 R-3 L3\n')
    feed, rapid = lengths_mm(prog)
    assert feed == pytest.approx(3 * 3)
    assert rapid == pytest.approx(5 + 3 * (10 + 3 + 6))      # 5: the first G0 to Z5
    assert end_mm(prog) == (30, 0, 5)


def test_other_motion_ends_the_series_and_its_initial_level():
    # After G0 Z5 the second G81 starts a new series: its G98 level is 5, not 10.
    prog = parse_gcode('G21 G0 Z10\nF100\nG98 G81 X0 Z-1 R2\nG0 Z5\nG81 X5 Z-1 R2\n')
    assert end_mm(prog) == (5, 0, 5)
    assert max(m.end[2] for m in prog.moves if m.line == 5) == pytest.approx(5 * MM)


def test_g82_dwell_and_g83_pecks():
    prog = parse_gcode('G21 G0 X0 Y0 Z1\nF60\nG82 X0 Z-2 R1 P0.5\nG80\n')
    dwells = [m.dwell_s for m in prog.moves if m.kind == MoveKind.DWELL]
    assert dwells == [0.5]
    # G83 Q1 from R0 to -3: pecks to -1, -2 then -3; between pecks a rapid out to R and back
    # down to 0.254 mm (0.010 inch) above the depth reached.
    prog = parse_gcode('G21 G0 X0 Y0 Z0\nF60\nG83 X0 Z-3 R0 Q1\n')
    feeds = [round(m.end[2] / MM, 6) for m in prog.moves if m.kind == MoveKind.LINEAR]
    assert feeds == [-1, -2, -3]
    feed, _ = lengths_mm(prog)
    assert feed == pytest.approx(1 + (1 + 0.254) + (1 + 0.254))
    assert end_mm(prog) == (0, 0, 0)


def test_cycle_errors_name_the_line():
    with pytest.raises(GcodeError) as info:
        parse_gcode('G21 G0 Z5\nF100\nG84 X0 Z-2 R1\n')
    assert info.value.line == 3 and 'Spindle not turning' in info.value.reason
    prog = parse_gcode('G21 G0 Z5\nF100 M3 S500\nG84 X0 Z-2 R1\n')
    assert end_mm(prog) == (0, 0, 1)
    with pytest.raises(GcodeError) as info:
        parse_gcode('G21 G0 Z5\nG81 X0 Z-2 R1\n')
    assert (info.value.line, info.value.column) == (2, 1)
    assert 'feed rate' in info.value.reason
    with pytest.raises(GcodeError) as info:
        parse_gcode('G21 G0 Z5\nF100\nG81 X0 Z-2 R1 L0\n')
    assert info.value.column == 15 and 'L0' in info.value.reason
    with pytest.raises(GcodeError) as info:
        parse_gcode('G0 X1 L2\n')
    assert info.value.column == 7 and 'L word' in info.value.reason


def test_g80_beside_another_motion_code_is_accepted():
    # Fanuc safety block; LinuxCNC 2.9 lets the other motion code win.
    prog = parse_gcode('G0 G17 G40 G49 G80 G90\nX5\nG80 G1 X6 F60\n')
    # The first line is a G0 without axis words: a zero-length traverse, as in LinuxCNC.
    assert [m.kind for m in prog.moves] == [MoveKind.RAPID] * 2 + [MoveKind.LINEAR]
    assert prog.moves[0].length_m == 0.0
    assert end_mm(prog) == (6, 0, 0)
    with pytest.raises(GcodeError):
        parse_gcode('G0 G1 X1 F60\n')


# -- cutter compensation -------------------------------------------------------------------
COMP_PROGRAM = 'G21 G0 X0 Y0 Z0\n{on} G1 X10 F100\nX20\nG40 X30\n'


@pytest.mark.parametrize('on, tools', [('G41 D1', {1: 1 * MM}),
                                       ('G41 D1', {1: {'radius_m': 1 * MM}}),
                                       ('G41 D1', {1: (1 * MM, 0.0)}),
                                       ('T1 M6 G41', {1: 1 * MM}),
                                       ('G41.1 D2', None)])
def test_g41_offsets_left_by_the_tool_radius(on, tools):
    # Entry ends one radius left of (10, 0); the straight X20 stays 1 mm to the left; the
    # exit after G40 runs from (20, 1) back to the programmed (30, 0).
    prog = parse_gcode(COMP_PROGRAM.format(on=on), tools=tools)
    ends = [tuple(round(v / MM, 9) for v in m.end) for m in moving(prog)]
    assert ends == [(10, 1, 0), (20, 1, 0), (30, 0, 0)]
    feed, _ = lengths_mm(prog)
    assert feed == pytest.approx(2 * math.hypot(10, 1) + 10)


def test_g42_and_zero_radius():
    prog = parse_gcode(COMP_PROGRAM.format(on='G42 D1'), tools={1: 1 * MM})
    assert [round(m.end[1] / MM, 9) for m in moving(prog)] == [-1, -1, 0]
    prog = parse_gcode(COMP_PROGRAM.format(on='G42 D1'), tools={1: 0.0})
    assert [round(m.end[0] / MM, 9) for m in moving(prog)] == [10, 20, 30]
    assert all(m.end[1] == 0.0 for m in prog.moves)


def test_program_end_flushes_held_moves():
    prog = parse_gcode('G21 G0 X0 Y0\nG41 D1 G1 X10 F100\nX20\n', tools={1: 1 * MM})
    assert end_mm(prog) == (20, 1, 0)
    prog = parse_gcode('G21 G0 X0 Y0\nG41 D1 G1 X10 F100\nX20\nM2\n', tools={1: 1 * MM})
    assert prog.moves[-1].kind == MoveKind.STOP
    assert tuple(round(v / MM, 9) for v in prog.moves[-2].end) == (20, 1, 0)


@pytest.mark.parametrize('text, tools, line, column, reason', [
    ('G41 D1 G1 X10 F100\n', None, 1, 5, 'tool 1 is not in the tool table'),
    ('G41 D3 G1 X10 F100\n', {1: 0.001}, 1, 5, 'tool 3 is not in the tool table'),
    ('G41.1 G1 X10 F100\n', None, 1, 1, 'needs a D word'),
    ('G1 X1 D1 F100\n', None, 1, 7, 'D word with no G41'),
    ('G41 D1 G1 X10 F100\nG18\n', {1: 0.001}, 2, 1, 'Cannot change planes'),
    ('G41 D1 G1 X10 F100\nG64\n', {1: 0.001}, 2, 1, 'Cannot change control mode'),
    ('G41 D1 G1 X10 F100\nG81 X0 Z-1 R1\n', {1: 0.001}, 2, 1, 'cutter compensation'),
    ('G41 D1 G1 X0.5 F100\n', {1: 0.001}, 1, 1, 'entry move'),
])
def test_cutter_errors(text, tools, line, column, reason):
    with pytest.raises(GcodeError) as info:
        parse_gcode('G21\n' + text, tools=tools, strict_tools=True)
    err = info.value
    assert (err.line, err.column) == (line + 1, column), str(err)
    assert reason.lower() in err.reason.lower()
