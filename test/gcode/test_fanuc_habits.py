"""Habits of Fanuc/Haas programs: feed per revolution (G95), a D word on its own line."""
from __future__ import annotations

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.load import parse_gcode

MM = 1e-3


def _feeds_mm_min(prog):
    return [round(m.feed_m_s * 60 / MM, 9) for m in prog.moves if m.kind.name == 'LINEAR']


def test_g95_feed_is_f_per_revolution_times_the_spindle_speed():
    # 0.2 mm/rev at 600 rev/min = 120 mm/min; S1200 doubles it; G94 needs a new F.
    prog = parse_gcode('G21 G95 S600 M3\nG1 X10 F0.2\nS1200\nG1 X20\nG94 F60\nG1 X30\n')
    assert _feeds_mm_min(prog) == [120.0, 240.0, 60.0]


def test_g95_in_inches():
    prog = parse_gcode('G20 G95 S1000 M3\nG1 X1 F0.004\n')     # 4 in/min = 101.6 mm/min
    assert _feeds_mm_min(prog) == [pytest.approx(101.6)]


@pytest.mark.parametrize('text, what', [
    ('G21 G95\nG1 X10 F0.2\n', 'needs a spindle speed S'),
    ('G21 G95 S100 M3\nG1 X10\n', r'needs an F \(per revolution\)'),
    ('G21 F100 S100 M3\nG95\nG1 X10\n', r'needs an F \(per revolution\)'),   # new mode, new F
])
def test_g95_without_f_or_s_is_an_error_at_the_move(text, what):
    with pytest.raises(GcodeError, match=f'G95 feed per revolution: a feed move {what}') as info:
        parse_gcode(text)
    assert info.value.line == text.count('\n')


@pytest.mark.parametrize('dialect', ['fanuc', 'haas'])
def test_d_on_its_own_line_selects_the_radius_for_a_later_g41(dialect):
    # T2's radius is 5 mm; compensation left of a +X line offsets the path by +5 mm in Y.
    text = 'G21 G17 G90\nT1 D2 M6\nG0 X0 Y0\nG41 G1 X20 Y0 F100\nG1 X40\nG40 G1 X60 Y-20\nM30\n'
    prog = parse_gcode(text, dialect=dialect, tools={1: (0.001, 0.0), 2: (0.005, 0.0)})
    ends = {m.line: m.end for m in prog.moves if m.kind.name == 'LINEAR'}
    assert ends[5] == pytest.approx((40 * MM, 5 * MM, 0.0))


def test_linuxcnc_refuses_d_without_g41():
    with pytest.raises(GcodeError, match='D word with no G41/G42') as info:
        parse_gcode('G21\nT1 D2 M6\n', tools={1: (0.001, 0.0), 2: (0.005, 0.0)})
    assert (info.value.line, info.value.column) == (2, 4)
