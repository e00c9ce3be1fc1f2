"""``iter_moves(max_errors=N)``: errors in lines are kept and the run goes on (``check``)."""
from __future__ import annotations

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.load import iter_moves

MM = 1e-3


def _program(tmp_path, text):
    path = tmp_path / 'p.ngc'
    path.write_text(text)
    return path


def test_default_raises_the_first_error(tmp_path):
    path = _program(tmp_path, 'G21\nG1 X1 F100 Q3\nG1 X2.3.4\nG1 X5\n')
    with pytest.raises(GcodeError) as info:
        list(iter_moves(path))
    assert info.value.line == 2


def test_kept_errors_and_the_moves_of_the_lines_after_them(tmp_path):
    # Line 2: the interpreter's error (Q without a cycle), line 3: the reader's (a bad
    # number); line 4 moves from where line 1 left the tool (the failed lines moved nothing).
    path = _program(tmp_path, 'G21 G1 X1 F100\nG1 X7 Q3\nG1 X2.3.4\nG1 X5 Y1\nM2\n')
    stream = iter_moves(path, max_errors=10)
    moves = list(stream)
    assert [(e.line, e.column) for e in stream.errors] == [(2, 7), (3, 5)]
    feeds = [m for m in moves if m.kind.name == 'LINEAR']
    assert [m.line for m in feeds] == [1, 4]
    assert feeds[1].start == pytest.approx((1 * MM, 0.0, 0.0))
    assert feeds[1].end == pytest.approx((5 * MM, 1 * MM, 0.0))


def test_the_max_errors_th_error_is_raised(tmp_path):
    path = _program(tmp_path, 'G21\n' + 'G1 X1 Q3 F100\n' * 5)
    stream = iter_moves(path, max_errors=3)
    with pytest.raises(GcodeError) as info:
        list(stream)
    assert [e.line for e in stream.errors] == [2, 3]
    assert info.value.line == 4


def test_a_line_left_half_done_leaves_nothing_pending(tmp_path):
    # M6 on a line with an error: the tool change is dropped with the rest of the line, so
    # line 4's G41 still finds no tool loaded (radius 0: the path stays as programmed);
    # a tool change left pending would load T2 there (radius 5 mm) and offset the path.
    text = 'G21 G17\nT1 M6 Q3\nT2\nG41 G1 X5 Y5 F100\nG1 X10\nG40 G1 X20\nM2\n'
    stream = iter_moves(_program(tmp_path, text), max_errors=10,
                        tools={1: (0.001, 0.0), 2: (0.005, 0.0)})
    moves = list(stream)
    assert [e.line for e in stream.errors] == [2]
    ends = {m.line: m.end for m in moves if m.kind.name == 'LINEAR'}
    assert ends[4] == pytest.approx((5 * MM, 5 * MM, 0.0))
    assert ends[5] == pytest.approx((10 * MM, 5 * MM, 0.0))
