"""Dialect profiles: each rule against the control it copies (values by hand)."""
from __future__ import annotations

import math

import pytest

from feed_axis_energy.errors import ConfigError, GcodeError
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.gcode.dialect import DIALECTS, dialect_by_name
from feed_axis_energy.gcode.settings import DIALECTS as CONFIG_DIALECTS
from feed_axis_energy.gcode.program import MoveKind

MM = 1e-3


def dwells(text: str, dialect: str) -> list[float]:
    prog = parse_gcode(text, dialect=dialect)
    return [m.dwell_s for m in prog.moves if m.kind == MoveKind.DWELL]


def test_registry_matches_the_machine_config_names():
    assert tuple(DIALECTS) == CONFIG_DIALECTS
    assert dialect_by_name(None).name == 'linuxcnc'
    assert dialect_by_name('FANUC').name == 'fanuc'
    assert dialect_by_name('Sinumerik').siemens
    with pytest.raises(ConfigError, match='known: linuxcnc, fanuc.*sinumerik'):
        dialect_by_name('heidenhain')


@pytest.mark.parametrize('dialect, expected', [
    ('linuxcnc', [2500.0, 2.5]),       # seconds, as LinuxCNC reads P
    ('grbl', [2500.0, 2.5]),
    ('mach3', [2500.0, 2.5]),
    ('fanuc', [2.5, 0.0025]),          # milliseconds
    ('haas', [2.5, 2.5]),              # ms without a decimal point, seconds with one
])
def test_g4_p_unit(dialect, expected):
    assert dwells('G4 P2500\nG4 P2.5\n', dialect) == pytest.approx(expected)


def test_fanuc_g4_x_is_seconds_not_an_axis():
    prog = parse_gcode('G4 X1.5\n', dialect='fanuc')
    assert [(m.kind, m.dwell_s) for m in prog.moves] == [(MoveKind.DWELL, 1.5)]
    assert all(m.end == (0.0, 0.0, 0.0) for m in prog.moves)


def test_k0_on_a_g17_arc():
    text = 'G21 G0 X10 Y0\nG3 X-10 Y0 I-10 J0 K0 F100\nG3 X10 Y0 I10 J0 K0.\n'
    with pytest.raises(GcodeError) as info:
        parse_gcode(text)                                   # LinuxCNC refuses it
    assert (info.value.line, info.value.column) == (2, 20)
    prog = parse_gcode(text, dialect='grbl', file='t.nc')   # ignored, one warning
    arcs = [m for m in prog.moves if m.kind == MoveKind.ARC_CCW]
    assert sum(m.length_m for m in arcs) == pytest.approx(2 * math.pi * 10 * MM)
    assert [w for w in prog.warnings if 'K0' in w] == ['t.nc:2: K0 on a G17 arc is ignored '
                                                       '(grbl dialect; LinuxCNC refuses it)']
    with pytest.raises(GcodeError, match='not an in-plane'):
        parse_gcode('G21 G0 X10\nG3 X-10 Y0 I-10 K1 F100\n', dialect='grbl')


def test_harmless_io_m_codes_and_their_words():
    prog = parse_gcode('M62 P1\nM66 P0 L3 Q2.5\nM68 E0 Q3.3\nG0 X1 M65 P1\n')
    assert [m.end[0] for m in prog.moves] == [1 * MM]
    with pytest.raises(GcodeError, match='M31 is not supported .* linuxcnc dialect'):
        parse_gcode('M31\n')
    assert parse_gcode('M31\nM10\n', dialect='haas').moves == ()


def test_m61_sets_the_tool_for_cutter_compensation():
    text = 'G21 G0 X0 Y0\nM61 Q2\nG41 G1 X10 F100\nG40 X20\n'
    prog = parse_gcode(text, tools={2: 1 * MM})
    feeds = [m for m in prog.moves if m.kind == MoveKind.LINEAR]
    assert [round(m.end[1] / MM, 9) for m in feeds] == [1, 0]
