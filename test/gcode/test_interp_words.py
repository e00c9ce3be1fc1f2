"""Less common words: polar coordinates, ignored rotary axes (hand-computed positions)."""
from __future__ import annotations

import math

import pytest

from feed_axis_energy.errors import ConfigError, GcodeError
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.gcode.stats import summarize

MM = 1e-3


def ends_mm(prog) -> list[tuple[float, ...]]:
    return [tuple(round(v / MM, 6) for v in m.end) for m in prog.moves if m.length_m > 0]


def test_polar_coordinates_absolute_and_incremental():
    # From (10, 0): @5 ^90 is (0, 5); G91 ^90 turns by another 90 degrees at radius 5
    # (-5, 0); G91 @2 lengthens the radius to 7 (-7, 0); G90 ^45 keeps radius 7.
    text = 'G21 G0 X10 Y0\nG1 @5 ^90 F100\nG91 ^90\n@2\nG90 ^45\n'
    r = 7 / math.sqrt(2)
    assert ends_mm(parse_gcode(text)) == [(10, 0, 0), (0, 5, 0), (-5, 0, 0), (-7, 0, 0),
                                          (round(r, 6), round(r, 6), 0)]


def test_polar_with_x_is_an_error():
    with pytest.raises(GcodeError) as info:
        parse_gcode('G1 X1 @5 F100\n')
    assert (info.value.line, info.value.column) == (1, 7)


def test_rotary_axis_is_an_error_naming_the_line_or_ignored():
    text = 'G21 G0 X1\nG1 X2 A90 F100\nG1 X3 A180 B5\n'
    with pytest.raises(GcodeError) as info:
        parse_gcode(text, file='r.nc')
    assert (info.value.line, info.value.column) == (2, 7)
    assert '--ignore-axes A' in info.value.reason
    prog = parse_gcode(text, file='r.nc', ignore_axes=('a', 'B'))
    assert ends_mm(prog) == [(1, 0, 0), (2, 0, 0), (3, 0, 0)]
    assert prog.warnings == (
        'r.nc:2: axis A words are ignored (--ignore-axes): its motion is not simulated',
        'r.nc:3: axis B words are ignored (--ignore-axes): its motion is not simulated')
    with pytest.raises(ConfigError, match="cannot ignore axis 'X'"):
        parse_gcode(text, ignore_axes=('X',))


def test_rigid_tap_goes_in_and_back_at_k_times_s():
    # K1.5 mm/rev at S600 rev/min: 900 mm/min; 15 mm in and 15 mm out; back at Z5.
    prog = parse_gcode('G21 G0 X0 Y0 Z5\nS600 M3\nG33.1 Z-10 K1.5\nG0 X5\n')
    taps = [m for m in prog.moves if m.line == 3]
    assert [round(m.end[2] / MM, 9) for m in taps] == [-10, 5]
    assert [m.length_m for m in taps] == pytest.approx([15 * MM, 15 * MM])
    assert all(m.feed_m_s == pytest.approx(900 * MM / 60) for m in taps)
    assert [m.tap_return for m in taps] == [False, True]
    # One canonical RIGID_TAP call, as the reference counts it: one feed move, in and back.
    stats = summarize(prog.moves)
    assert stats.n_feed_moves == 1
    assert stats.feed_length_m == pytest.approx(30 * MM)
    with pytest.raises(GcodeError, match='spindle speed S'):
        parse_gcode('G21 G33.1 Z-10 K1.5\n')


def test_probe_runs_to_its_end_point_and_stays_the_motion_mode():
    prog = parse_gcode('G21 G0 X5 Z5\nF100\nG38.2 Z-3\nX8\n', file='p.nc')
    assert ends_mm(prog)[-2:] == [(5, 0, -3), (8, 0, -3)]
    assert [w for w in prog.warnings if 'probing' in w] == [
        'p.nc:3: G38.2 probing runs to its end point (no contact is simulated)']
    with pytest.raises(GcodeError, match='needs a feed rate'):
        parse_gcode('G21 G38.2 Z-3\n')


def test_polar_increments_repeat_in_a_g91_cycle():
    # Six holes on a circle of radius 1.5 inch, 60 degrees apart (LinuxCNC's hole-circle.ngc):
    # each repeat turns the hole position about the origin; the last is back at the start.
    prog = parse_gcode('G20 G17 G90\nG0 X1.5 Y0 Z0\nG91 G81 R.1 Z-.5 ^60 L6 F10\n')
    inch = 0.0254
    holes = [m.end for m in prog.moves if m.kind.name == 'LINEAR']
    assert len(holes) == 6
    for k, (x, y, z) in enumerate(holes, 1):
        angle = math.radians(60 * k)
        assert (x, y, z) == pytest.approx((1.5 * inch * math.cos(angle),
                                           1.5 * inch * math.sin(angle), -0.4 * inch))
    assert prog.moves[-1].end == pytest.approx((1.5 * inch, 0.0, 0.1 * inch))


@pytest.mark.parametrize('text, column', [('G17 F100\nG2 K0\n', 1), ('G18 F100\nG3 J0\n', 1)])
def test_ignored_normal_centre_word_alone_is_an_error_at_the_g_word(text, column):
    # Dialects that ignore K0 on a G17 arc (FreeCAD writes it) leave no centre and no end
    # point: an error at the arc's G word, not a StopIteration from the error locator.
    with pytest.raises(GcodeError) as info:
        parse_gcode(text, dialect='fanuc')
    assert (info.value.line, info.value.column) == (2, column)
    assert 'arc needs' in info.value.reason
