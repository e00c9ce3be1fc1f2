"""User M codes M100-M199: LinuxCNC runs the program ``M1nn`` of its USER_M_PATH; here no
motion with one warning per code in the ``linuxcnc`` dialect, an error in the others
(gcode/dialect.py's table)."""
from __future__ import annotations

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode import DIALECTS, MoveKind, parse_gcode


def _user_warnings(program):
    return [w for w in program.warnings if 'user M code' in w]


def test_user_m_codes_are_no_motion_with_one_warning_per_code():
    text = ('G21 G90\nG0 X1\nM100 P2 Q3.5\nG1 X2 F600\nM100\nM199 P1\nM101 G0 X5\nM30\n')
    prog = parse_gcode(text, file='u.nc')
    plain = parse_gcode(text.replace('M100 P2 Q3.5', '').replace('M100', '')
                        .replace('M199 P1', '').replace('M101 ', ''), file='u.nc')
    # the same moves as without the user codes: no motion, no dwell, no stop
    assert [(m.kind, m.end) for m in prog.moves] == [(m.kind, m.end) for m in plain.moves]
    assert MoveKind.STOP not in [m.kind for m in prog.moves[:-1]]
    warned = _user_warnings(prog)
    assert [w.split(':')[1] for w in warned] == ['3', '6', '7']     # M100, M199, M101
    assert 'M100' in warned[0] and 'USER_M_PATH' in warned[0]


@pytest.mark.parametrize('dialect', sorted(set(DIALECTS) - {'linuxcnc'}))
def test_other_dialects_refuse_user_m_codes_naming_the_dialect(dialect):
    head = 'G710' if dialect == 'sinumerik' else 'G21'    # G21 is not a Siemens code
    with pytest.raises(GcodeError) as err:
        parse_gcode(f'{head}\nG0 X1\nM120\n', file='u.nc', dialect=dialect)
    assert (err.value.line, err.value.column) == (3, 1)
    assert dialect in err.value.reason


@pytest.mark.parametrize('text, column', [
    ('M200', 1),             # beyond the user range
    ('M99.5', 1),
    ('M100.5', 1),           # not a whole number
    ('G0 X1 M100 L2', 12),   # an L word has no use with a user M code (P and Q have)
])
def test_outside_the_user_range_or_with_foreign_words_is_an_error(text, column):
    with pytest.raises(GcodeError) as err:
        parse_gcode('G21\n' + text + '\n', file='u.nc')
    assert (err.value.line, err.value.column) == (2, column)
