"""Fanuc / Haas system variables (#4001.., #5001..) in the Macro B dialects.

Expected values are the modes and positions written in each program (hand figures); the
variable numbers are those of the Fanuc and Haas macro manuals.
"""
from __future__ import annotations

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.gcode.dialect import dialect_by_name
from feed_axis_energy.gcode.run import GcodeRun
from feed_axis_energy.gcode.program import MoveKind

MM = 1e-3


def read(text: str, numbers: list[int], *, dialect: str = 'fanuc', tools=None) -> list[float]:
    """Run ``text``, then assign ``#n`` to ``#(100 + i)`` and return those values."""
    reads = ''.join(f'#{100 + i}=#{n}\n' for i, n in enumerate(numbers))
    run = GcodeRun(text + '\n' + reads + 'M30\n', file='f.nc', start=(0.0, 0.0, 0.0),
                   arc_tolerance_m=None, home=None, tools=tools,
                   dialect=dialect_by_name(dialect))
    for _ in run:
        pass
    return [run.params.numbered[100 + i] for i in range(len(numbers))]


@pytest.mark.parametrize('dialect', ['fanuc', 'haas'])
def test_modal_groups_read_the_modes_in_force(dialect):
    text = 'G20 G91 G18 G61 G98 G55 G93\nT7 S1200'
    got = read(text, [4002, 4003, 4005, 4006, 4007, 4008, 4009, 4010, 4011, 4012, 4014,
                      4015, 4016, 4017, 4119, 4120], dialect=dialect)
    assert got == [18, 91, 93, 20, 40, 49, 80, 98, 50, 67, 55, 61, 69, 15, 1200, 7]


def test_modal_defaults_and_extended_work_systems():
    got = read('G21 G59.2 G64', [4002, 4003, 4005, 4006, 4010, 4014, 4015])
    assert got == [17, 90, 94, 21, 99, pytest.approx(59.2), 64]


def test_feed_reads_in_program_units_per_minute():
    assert read('G21 F600', [4109]) == [pytest.approx(600.0)]
    assert read('G20 F20', [4109]) == [pytest.approx(20.0)]
    assert read('G21', [4109]) == [0.0]


def test_motion_group_and_canned_cycle():
    assert read('G21 G1 X1 F100', [4001, 4009]) == [1, 80]
    assert read('G21 G0 X1\nG3 X0 Y1 R1 F100', [4001]) == [3]
    assert read('G21 G0 Z5\nG81 X1 Y1 Z-1 R1 F100', [4009]) == [81]
    with pytest.raises(GcodeError, match=r'#4001 \(modal information\) is not simulated'):
        read('G21 G0 Z5\nG81 X1 Y1 Z-1 R1 F100', [4001])


def test_cutter_compensation_side():
    assert read('G21 G0 X0 Y0\nG41.1 D2 G1 X5 F100', [4007]) == [41]
    assert read('G21 G0 X0 Y0\nG42.1 D2 G1 X5 F100', [4007]) == [42]


def test_positions_with_a_work_offset():
    # G54 at (100, 50, -10) mm; program point (1, 2, 3): machine (101, 52, -7)
    got = read('G21 G10 L2 P1 X100 Y50 Z-10\nG54 G0 X1 Y2 Z3',
               [5001, 5002, 5003, 5021, 5022, 5023, 5041, 5042, 5043, 5081, 5083])
    assert got == pytest.approx([1, 2, 3, 101, 52, -7, 1, 2, 3, 0, 0], abs=1e-9)


def test_positions_with_a_tool_length_offset_in_inches():
    # tool 1: 2 inch long; G43 H1; program Z3: machine Z = 3 + 2 (no work offset)
    tools = {1: (0.0, 2 * 25.4 * MM)}
    got = read('G20 G0 X1 Y2\nT1 M6\nG43 H1 G0 Z3', [5003, 5023, 5043, 5081, 5083, 4008],
               tools=tools)
    assert got == pytest.approx([3, 5, 5, 0, 2, 43], abs=1e-9)


def test_saving_and_restoring_a_mode_runs_as_on_the_control():
    # a macro's "#1=#4003 ... G#1": G90 is restored, so X1 is absolute
    p = parse_gcode('G21 G90 F300\nG1 X10 Y5\n#1=#4003\nG91 G1 X1\nG#1 X1\nM30\n',
                    dialect='fanuc', file='f.nc')
    motion = [m for m in p.moves if m.kind == MoveKind.LINEAR]
    assert motion[-1].end == pytest.approx((1 * MM, 5 * MM, 0.0))


@pytest.mark.parametrize('text, column, message', [
    ('#5001=3', 1, '#5001 is a read-only system variable'),
    ('#4003=90', 1, '#4003 is a read-only system variable'),
    ('#1=#4004', 4, '#4004 (modal information) is not simulated'),
    ('G0 X#4113', 5, '#4113 (modal information) is not simulated'),
])
def test_refused_with_the_place(text, column, message):
    with pytest.raises(GcodeError) as info:
        parse_gcode('G21\n' + text + '\nM30\n', dialect='fanuc', file='f.nc')
    assert message in str(info.value)
    assert (info.value.line, info.value.column) == (2, column)


def test_linuxcnc_keeps_them_ordinary_parameters():
    # in LinuxCNC #5001 and #4003 are plain numbered parameters (0 until set)
    assert read('G21 G0 X7', [5001, 4003], dialect='linuxcnc') == [0.0, 0.0]
    p = parse_gcode('G21\n#5001=3\nG0 X#5001\nM2\n', file='f.nc')
    assert p.moves[0].end == pytest.approx((3 * MM, 0.0, 0.0))
