"""A tool the tool table lacks: length and radius 0 with one warning per tool, or an error
at the word naming it with ``strict_tools`` (gcode/interp/tools.py)."""
from __future__ import annotations

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode import parse_gcode, ToolSpec

MM = 1e-3
TABLE = {1: ToolSpec(radius_m=2 * MM, length_m=40 * MM)}


def _tool_warnings(program, number):
    return [w for w in program.warnings if f'tool {number} is not in the tool table' in w]


def test_t5_m6_g43_h5_runs_with_zero_length_and_one_warning():
    # the case: T5 M6 G43 H5 on a table without tool 5, tool 5 used twice more
    text = ('G21 G90\nT5 M6\nG43 H5 G0 Z50\nG1 Z10 F600\nG43 H5\nG0 Z20\nG49\n'
            'T1 M6\nG43 H1 G0 Z50\nM30\n')
    prog = parse_gcode(text, file='t.nc', tools=TABLE)
    z = [m.end[2] for m in prog.moves if m.length_m > 0]
    # tool 5: Z as programmed (length 0); tool 1: its 40 mm added
    assert z == pytest.approx([0.05, 0.01, 0.02, 0.09])
    warned = _tool_warnings(prog, 5)
    assert len(warned) == 1 and warned[0].startswith('t.nc:3: ')
    assert 'length and radius 0' in warned[0] and '--strict-tools' in warned[0]
    assert not _tool_warnings(prog, 1)


def test_one_warning_per_tool_number_without_any_table():
    prog = parse_gcode('G21\nG43 H3 G0 Z5\nG43 H4 G0 Z5\nG43 H3\nG49\nM30\n', file='t.nc')
    assert [len(_tool_warnings(prog, n)) for n in (3, 4)] == [1, 1]
    assert _tool_warnings(prog, 4)[0].startswith('t.nc:3: ')


@pytest.mark.parametrize('text', [
    'G21 G90\nG0 X0 Y0\nG41 D7 G1 X10 F100\nY10\nG40 G1 X0\nM30\n',
    'G21 G90\nG0 X0 Y0\nG42 D7 G1 X10 F100\nY10\nG40 G1 X0\nM30\n',
    'G21 G90\nT7 M6\nG0 X0 Y0\nG41 G1 X10 F100\nY10\nG40 G1 X0\nM30\n',   # loaded tool
])
def test_cutter_compensation_with_a_missing_tool_leaves_the_path(text):
    # radius 0: the compensated path is the programmed one
    prog = parse_gcode(text, file='t.nc', tools=TABLE)
    plain = parse_gcode(text.replace(' D7', '').replace('G41 ', '').replace('G42 ', ''),
                        file='t.nc', tools=TABLE)
    assert [m.end for m in prog.moves if m.length_m > 0] == \
        [m.end for m in plain.moves if m.length_m > 0]
    assert len(_tool_warnings(prog, 7)) == 1


def test_g43_without_h_uses_the_loaded_missing_tool():
    prog = parse_gcode('G21\nT9 M6\nG43 G0 Z5\nM30\n', file='t.nc', tools=TABLE)
    assert prog.moves[0].end[2] == pytest.approx(0.005)
    assert _tool_warnings(prog, 9)[0].startswith('t.nc:3: ')


def test_t_and_m6_alone_use_no_tool_data_and_do_not_warn():
    prog = parse_gcode('G21\nT8 M6\nM61 Q9\nG0 X1\nM30\n', file='t.nc', tools=TABLE)
    assert prog.warnings == ()


def test_g10_l1_adds_a_missing_tool_that_g43_then_uses():
    # G10 L1 P6 Z30 sets tool 6's length; a warning (the tool was not in the table), then
    # G43 H6 applies 30 mm without another warning
    prog = parse_gcode('G21 G90\nG10 L1 P6 Z30 R1\nG43 H6 G0 Z10\nM30\n', file='t.nc',
                       tools=TABLE)
    assert prog.moves[0].end[2] == pytest.approx(0.04)
    warned = _tool_warnings(prog, 6)
    assert len(warned) == 1 and warned[0].startswith('t.nc:2: ')


@pytest.mark.parametrize('text, line, column', [
    ('G21\nT5 M6\n', 2, 1),                          # LinuxCNC: tool not in the table at T
    ('G21\nM61 Q5\n', 2, 5),
    ('G21\nG43 H5 G0 Z5\n', 2, 5),
    ('G21\nT1 M6\nG43 H5\n', 3, 5),
    ('G21\nM61 Q0\nG43 G0 Z5\n', None, None),        # tool 0: no tool, never an error
    ('G21\nG0 X0 Y0\nG41 D5 G1 X10 F100\n', 3, 5),
    ('G21\nG0 X0 Y0\nG42 D5 G1 X10 F100\n', 3, 5),
    ('G21\nG10 L1 P5 Z30\n', 2, 8),
    ('G21\nG10 L10 P5 Z0\n', 2, 9),
])
def test_strict_tools_refuses_at_the_word_naming_the_tool(text, line, column):
    if line is None:
        parse_gcode(text, file='t.nc', tools=TABLE, strict_tools=True)
        return
    with pytest.raises(GcodeError) as err:
        parse_gcode(text, file='t.nc', tools=TABLE, strict_tools=True)
    assert (err.value.file, err.value.line, err.value.column) == ('t.nc', line, column)
    assert 'tool 5 is not in the tool table' in err.value.reason


def test_strict_tools_accepts_every_tool_of_the_table():
    prog = parse_gcode('G21 G90\nT1 M6\nG43 H1 G0 Z10\nG41 D1 G1 X10 F100\nG40 G1 X20\n'
                       'M30\n', file='t.nc', tools=TABLE, strict_tools=True)
    assert prog.moves[0].end[2] == pytest.approx(0.05) and prog.warnings == ()


def test_iter_moves_takes_the_same_options(tmp_path):
    from feed_axis_energy.gcode import iter_moves
    path = tmp_path / 'p.nc'
    path.write_text('G21\nG43 H5 G0 Z5\nM30\n')
    stream = iter_moves(path)
    assert [m.end[2] for m in stream if m.length_m > 0] == pytest.approx([0.005])
    assert len(_tool_warnings(stream, 5)) == 1
    with pytest.raises(GcodeError) as err:
        list(iter_moves(path, strict_tools=True))
    assert (err.value.line, err.value.column) == (2, 5)
