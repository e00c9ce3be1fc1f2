"""The whole package end to end: plain lines, the hand-over to the front's reader, streams."""
from __future__ import annotations

import math

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.load import iter_moves, load_gcode, parse_gcode
from feed_axis_energy.gcode.program import MoveKind

MM = 1e-3

# Plain lines first (the fast path), then parameters and a subroutine (the front's reader).
MIXED = """G21 G90 G0 X0 Y0 Z5
G1 Z0 F600
X10
#<_d> = 20
o100 sub
  G91 G1 Y#<_d>
  G90
o100 endsub
o100 call
X#<_d> Y[#<_d> + 5]
G2 X[#<_d> + 10] Y25 I5 J0
M2
"""


def test_plain_lines_then_the_reader():
    prog = parse_gcode(MIXED, file='m.nc')
    feeds = [m for m in prog.moves if m.kind in (MoveKind.LINEAR, MoveKind.ARC_CW)]
    ends = [tuple(round(v / MM, 9) for v in m.end) for m in feeds]
    assert ends == [(0, 0, 0), (10, 0, 0), (10, 20, 0), (20, 25, 0), (30, 25, 0)]
    # The line of each move is its line in the program file (the sub is in it).
    assert [m.line for m in feeds] == [2, 3, 6, 10, 11]
    length = 5 + 10 + 20 + math.hypot(10, 5) + math.pi * 5
    assert sum(m.length_m for m in prog.moves if m.kind != MoveKind.RAPID) == pytest.approx(
        length * MM)
    assert prog.n_lines == 12


def test_errors_after_the_hand_over_keep_their_line():
    text = 'G21 G0 X1\nG1 X2 F100\n#2 = 3\nG1 X[#2 / 0]\n'
    with pytest.raises(GcodeError) as info:
        parse_gcode(text, file='e.nc')
    assert (info.value.file, info.value.line) == ('e.nc', 4)


def test_stream_equals_whole_program(tmp_path):
    path = tmp_path / 'm.nc'
    path.write_text(MIXED.replace('M2\n', '') * 1 + 'G0 Z5\nM30\n')
    whole = load_gcode(path)
    stream = iter_moves(path, batch=1)
    assert list(stream) == list(whole.moves)
    assert stream.warnings == list(whole.warnings)


def test_stream_raises_at_the_bad_line(tmp_path):
    path = tmp_path / 'bad.nc'
    path.write_text('G21 G0 X1\n' * 50 + 'G1 X2 F0\n')     # zero feed rate on line 51
    stream = iter(iter_moves(path, batch=10))
    first = [next(stream) for _ in range(10)]
    assert [m.line for m in first] == list(range(1, 11))
    with pytest.raises(GcodeError) as info:
        list(stream)
    assert info.value.line == 51


@pytest.mark.parametrize('ends', ['\n', '\r\n', '\r'])
def test_line_ends(ends):
    prog = parse_gcode(ends.join(['G21 G0 X1', 'Y2', '(c)', 'Z3']) + ends, file='t.nc')
    assert [m.line for m in prog.moves] == [1, 2, 4]
    assert prog.moves[-1].end == pytest.approx((1 * MM, 2 * MM, 3 * MM))


def test_fanuc_subprogram_after_plain_lines():
    # The fast path hands the M98 line (and everything after it) to the front's reader.
    text = 'G21 G0 X1\nM98 P100 L2\nM30\nO100\nG91 G1 X5 F100\nG90\nM99\n'
    prog = parse_gcode(text, file='f.nc', dialect='fanuc')
    feeds = [m for m in prog.moves if m.kind == MoveKind.LINEAR]
    assert [round(m.end[0] / MM, 9) for m in feeds] == [6, 11]


@pytest.mark.parametrize('ends', ['\n', '\r\n', '\r'])
def test_stream_reads_every_line_end_and_counts_lines(tmp_path, ends):
    path = tmp_path / 'p.nc'
    path.write_bytes(ends.join(['G21 G0 X1', 'G1 Y2 F100', 'M2', 'G0 X9', '']).encode())
    stream = iter_moves(path)
    moves = list(stream)
    assert [m.line for m in moves] == [1, 2, 3]
    assert stream.n_lines == 4
    assert stream.warnings == [f'{path}:4: lines after the end of the program (line 3) are '
                               'ignored']
    assert moves == list(load_gcode(path).moves)


def test_stream_file_errors(tmp_path):
    with pytest.raises(GcodeError) as info:
        list(iter_moves(tmp_path / 'missing.nc'))
    assert (info.value.line, info.value.column) == (0, 0)
    bad = tmp_path / 'latin1.nc'
    bad.write_bytes(b'G0 X1\n' * 3 + b'(Gr\xf6\xdfe)\n')
    with pytest.raises(GcodeError, match='not UTF-8') as info:
        list(iter_moves(bad))
    assert (info.value.line, info.value.column) == (4, 4)
