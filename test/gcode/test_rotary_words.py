"""Rotary axes A, B, C in the interpreter (gcode/interp/rotary.py), derived by hand from
LinuxCNC's rules: degrees in G20 and G21, F in degrees per minute for a pure rotary move,
F on the XYZ length otherwise, G93 as 1/F minutes, offsets and G28 as for X, Y, Z."""
from __future__ import annotations

import math

import pytest

from feed_axis_energy.errors import ConfigError, GcodeError
from feed_axis_energy.gcode import MoveKind, parse_gcode
from feed_axis_energy.gcode.stats import summarize


def _deg(values):
    return None if values is None else tuple(round(math.degrees(v), 9) for v in values)


def _moves(text, axes=('A', 'B', 'C'), **kw):
    return [m for m in parse_gcode(text, rotary_axes=axes, **kw).moves
            if m.kind in (MoveKind.RAPID, MoveKind.LINEAR, MoveKind.ARC_CW, MoveKind.ARC_CCW)]


def test_pure_rotary_g94_feed_is_degrees_per_minute_in_either_unit_system():
    for units in ('G21', 'G20'):
        (m,) = _moves(f'{units} G94 G1 B90 F3600\n')
        assert m.start == m.end
        assert _deg(m.rot_start) == (0.0, 0.0, 0.0)
        assert _deg(m.rot_end) == (0.0, 90.0, 0.0)
        assert m.feed_m_s == pytest.approx(math.radians(60.0), rel=1e-12)   # 60 deg/s


def test_combined_move_keeps_the_xyz_feed():
    (m,) = _moves('G21 G94 G1 X30 Y40 C45 F600\n')
    assert m.feed_m_s == pytest.approx(0.01)            # 600 mm/min on the 50 mm XYZ path
    assert _deg(m.rot_end) == (0.0, 0.0, 45.0)
    assert m.length_m == pytest.approx(0.05)


def test_g93_pure_rotary_and_combined_moves_take_one_over_f_minutes():
    rot, comb = _moves('G21 G93 G1 A180 F2\nG1 X10 A0 F4\n')
    assert math.pi / rot.feed_m_s == pytest.approx(30.0)      # 180 deg in 1/2 minute
    assert 0.01 / comb.feed_m_s == pytest.approx(15.0)        # 10 mm in 1/4 minute
    assert _deg(comb.rot_start) == (180.0, 0.0, 0.0)


def test_incremental_offsets_and_machine_coordinates():
    text = ('G21 G90 G0 C10\nG91 G0 C5\nG90 G92 C0\nG0 C20\nG92.1\nG0 C20\n'
            'G10 L2 P1 C100\nG0 C0\nG53 G0 C7\n')
    ends = [_deg(m.rot_end)[2] for m in _moves(text)]
    # C15 reads as 0 after G92 C0: C20 -> machine 35; G92.1: C20 is 20; G54 C offset 100
    assert ends == [10.0, 15.0, 35.0, 20.0, 100.0, 7.0]


def test_g10_l20_and_g92_with_rotary_words_only():
    text = 'G21 G0 B30\nG10 L20 P1 B0\nG0 B10\nG92 B0\nG0 B5\n'
    ends = [_deg(m.rot_end)[1] for m in _moves(text)]
    assert ends == [30.0, 40.0, 45.0]


def test_g28_without_words_returns_rotary_axes_to_zero_with_words_only_the_named():
    ms = _moves('G21 G0 X5 B30 C40\nG28 C10\nG28\n')
    # G28 C10: C through 10 to 0, X and B stay; then G28: all axes home
    assert [(m.end[0], _deg(m.rot_end)) for m in ms[1:3]] == [
        (0.005, (0.0, 30.0, 10.0)), (0.005, (0.0, 30.0, 0.0))]
    assert _deg(ms[-1].rot_end) == (0.0, 0.0, 0.0)
    assert ms[-1].end == (0.0, 0.0, 0.0)


def test_arc_with_rotary_word_turns_linearly_and_keeps_its_feed():
    (m,) = _moves('G21 G17 G2 X10 Y0 I5 J0 A90 F600\n')
    assert m.kind == MoveKind.ARC_CW
    assert m.feed_m_s == pytest.approx(0.01)
    assert _deg(m.rot_end) == (90.0, 0.0, 0.0)


def test_stats_count_rotary_travel_and_nominal_time():
    text = 'G21 G94 G1 B90 F3600\nG1 X10 B0 F600\nG0 B-45\nG93 G1 B45 F6\n'
    s = summarize(parse_gcode(text, rotary_axes=('B',)).moves)
    assert s.rotary_travel_deg == pytest.approx(90 + 90 + 45 + 90)
    assert s.n_rotary_moves == 4
    # 1.5 s (90 deg at 60 deg/s) + 1 s (10 mm at 10 mm/s) + 10 s (1/6 minute)
    assert s.nominal_feed_time_s == pytest.approx(1.5 + 1.0 + 10.0)


def test_a_machine_without_the_axis_refuses_it_and_ignore_axes_drops_it():
    with pytest.raises(GcodeError, match=r'axis B is not supported.*--ignore-axes B') as info:
        parse_gcode('G21 G0 X1\nG0 B45\n', rotary_axes=('A',))
    assert (info.value.line, info.value.column) == (2, 4)
    program = parse_gcode('G21 G0 X1 B45\n', ignore_axes=('B',))
    assert all(m.rot_end is None for m in program.moves)
    with pytest.raises(ConfigError, match='not a rotary axis'):
        parse_gcode('G0 X1\n', rotary_axes=('W',))


@pytest.mark.parametrize('text, column', [
    ('G21 G81 X1 Y1 Z-1 R1 B10 F100\n', 22),       # a canned cycle
    ('G21 G0 X0 Y0\nG41.1 D2 G1 X10 B10 F100\n', 17),   # cutter radius compensation
])
def test_rotary_words_where_they_cannot_be_simulated_are_refused(text, column):
    with pytest.raises(GcodeError, match='rotary axis word') as info:
        parse_gcode(text, rotary_axes=('B',))
    assert info.value.column == column


def test_live_position_parameters_give_the_rotary_positions():
    text = 'G21 G0 A4\nG92 A1\n#1=#5423\n#2=#<_a>\n#3=#<_abs_a>\nG0 X#1 Y#2 Z#3\n'
    last = parse_gcode(text, rotary_axes=('A',)).moves[-1]
    # program A reads 1 after G92 A1 at machine 4
    assert last.end == pytest.approx((0.001, 0.001, 0.004))
