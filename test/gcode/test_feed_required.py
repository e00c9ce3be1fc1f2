"""A feed move with no feed rate: refused as on the control (LinuxCNC "Cannot do G1 with zero
feed rate", Fanuc alarm PS0011, grbl error 22), or previewed at the axis limits with
``allow_no_feed`` (LinuxCNC's preview starts with a feed rate of 1)."""
from __future__ import annotations

import math

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode import DIALECTS, iter_moves, parse_gcode


@pytest.mark.parametrize('text, line, column', [
    ('G21 G90\nG1 X10\n', 2, 1),                  # at the G word of the line
    ('G21 G90\nG1\nX10 Y5\n', 2, 1),              # G1 alone: the control checks it too
    ('G21 G90\nG0 X1\nG1 Z-1\n', 3, 1),
    ('G21 G90\nG0 X1\nG1\nZ-1\n', 3, 1),
    ('G21 G90\nG0 X10\nG2 X0 Y10 I-10 J0\n', 3, 1),
    ('G21 G90\nG0 X10\nG3 X0 Y10 R10\n', 3, 1),
    ('G21 G90\nG0 X1\nG1 X2 F0\n', 3, 7),          # F0 on the line: at the F word
    ('G21 G90\nF0\nG1 X2\n', 3, 1),                # an F0 in force
    ('G21 G90\nG1 X1 F100\nG93 G1 X2 F1\nG94 G1 X3\n', 4, 5),   # F cleared by the switch
    ('G21 G90\nG93 G1 X2\n', 2, 5),                # G93: F on every feed line
    ('G21 G90\nG0 X0 Y0\nG5 I1 J0 P-1 Q0 X2 Y0\n', 3, 1),        # spline, LinuxCNC dialect
])
def test_feed_move_without_a_feed_rate_is_refused_at_its_place(text, line, column):
    with pytest.raises(GcodeError) as err:
        parse_gcode(text, file='p.nc')
    assert (err.value.file, err.value.line, err.value.column) == ('p.nc', line, column)
    assert 'feed' in err.value.reason.lower() or 'F' in err.value.reason
    assert str(err.value).startswith(f'p.nc:{line}:{column}: ')


@pytest.mark.parametrize('dialect', sorted(DIALECTS))
def test_every_dialect_refuses_g1_before_any_f(dialect):
    # Sinumerik: metric is G710 (G21 is not a Siemens code); its control refuses the move
    # too (alarm 10860, no feed rate programmed)
    head = 'G710 G90' if dialect == 'sinumerik' else 'G21 G90'
    with pytest.raises(GcodeError) as err:
        parse_gcode(f'{head}\nG0 X1\nG1 X2\n', file='p.nc', dialect=dialect)
    assert (err.value.line, err.value.column) == (3, 1)
    assert '--allow-no-feed' in err.value.reason


def test_allow_no_feed_runs_at_the_axis_limits_with_one_warning():
    text = 'G21 G90\nG0 X1\nG1 X2\nG1 Y3\nG2 X3 Y4 I1 J0\nG1 X10 F600\n'
    prog = parse_gcode(text, file='p.nc', allow_no_feed=True)
    feeds = [m.feed_m_s for m in prog.moves[1:]]
    assert feeds[:3] == [math.inf] * 3
    assert feeds[3] == pytest.approx(600e-3 / 60.0)
    warned = [w for w in prog.warnings if 'no feed rate' in w]
    assert len(warned) == 1 and warned[0].startswith('p.nc:3: ')


def test_allow_no_feed_still_refuses_f0_and_g93_without_f():
    # LinuxCNC's preview refuses these too: an F0 in force, a G93 line without F
    for text, line in (('G21\nF0\nG1 X2\n', 3), ('G21\nG93 G1 X2\n', 2)):
        with pytest.raises(GcodeError) as err:
            parse_gcode(text, file='p.nc', allow_no_feed=True)
        assert err.value.line == line


def test_a_feed_rate_set_anywhere_before_is_enough():
    # F on a line of its own, on a G0 line, or on the move itself
    for text in ('G21\nF300\nG1 X1\n', 'G21\nG0 X1 F300\nG1 X2\n', 'G21\nG1 X1 F300\n',
                 'G21\nG94 F300\nG2 X2 I1 J0\n'):
        prog = parse_gcode(text, file='p.nc')
        assert prog.warnings == ()
        assert prog.moves[-1].feed_m_s == pytest.approx(0.3 / 60.0)


def test_the_streaming_reader_refuses_the_same_line(tmp_path):
    path = tmp_path / 'p.nc'
    path.write_text('G21 G90\nG0 X1 Y1\nG1 X2 Y3\nM30\n')
    with pytest.raises(GcodeError) as err:
        list(iter_moves(path))
    assert (err.value.line, err.value.column) == (3, 1)
    stream = iter_moves(path, allow_no_feed=True)
    assert [m.feed_m_s for m in stream][1] == math.inf
    assert len([w for w in stream.warnings if 'no feed rate' in w]) == 1
