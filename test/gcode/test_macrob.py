"""Fanuc Custom Macro B statements (fanuc/haas dialects), hand-checked."""
from __future__ import annotations

from types import SimpleNamespace

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.read import control
from feed_axis_energy.gcode.read.flow import read_blocks

FANUC = SimpleNamespace(name='fanuc', fanuc_subprograms=True)
LINUXCNC = SimpleNamespace(name='linuxcnc', fanuc_subprograms=True)


def words(text: str, dialect=FANUC) -> list[list[tuple[str, float]]]:
    out = []
    for b in read_blocks(text, file='m.nc', dialect=dialect):
        out.append(b.words)
        if ('M', 30.0) in b.words:
            break
    return out


def xs(text: str) -> list[float]:
    return [dict(w)['X'] for w in words(text) if 'X' in dict(w)]


def test_assignment_without_brackets():
    # -120 / 2 - 25.2 - 5 = -90.2 (Fanuc: * and / before + and -)
    text = '#4= 50.4 / 2\n#7= -120. / 2. - #4 - 5.\n#6= - #4 + 2.\nG0 X#7 Y#6\n'
    assert words(text) == [[('G', 0.0), ('X', pytest.approx(-90.2)), ('Y', -23.2)]]


def test_while_do_end_like_the_corpus_program():
    # RomanBoreyko r_cod2 WHILE.nc pattern: step down by 1 from 3 to 0 -> Z 2, 1, 0.
    text = ('#1= 3.\n#2= 0.\n#3= 1.\nWHILE [ #1 GT #2 ] DO1\n#1= #1 - #3\n'
            'IF [ #1 LT #2 ] THEN #1= #2\nG00 Z [ #1 ]\nEND1\nG0 X9\nM30\n')
    zs = [dict(w)['Z'] for w in words(text) if 'Z' in dict(w)]
    assert zs == [2.0, 1.0, 0.0]
    assert xs(text) == [9.0]


def test_nested_while_loops_with_different_ids():
    # 2 outer x 3 inner passes; X = 10 * outer + inner
    text = ('#1=0\nWHILE [#1 LT 2] DO1\n#2=0\nWHILE [#2 LT 3] DO2\nG0 X[10*#1+#2]\n#2=#2+1\n'
            'END2\n#1=#1+1\nEND1\n')
    assert xs(text) == [0.0, 1.0, 2.0, 10.0, 11.0, 12.0]


def test_while_false_skips_to_its_end_past_an_inner_loop_with_the_same_id():
    text = ('WHILE [0] DO1\nWHILE [1] DO1\nG0 X1\nEND1\nEND1\nG0 X2\n')
    assert xs(text) == [2.0]


def test_if_goto_counts_down():
    text = '#1=3\nN10 G0 X#1\n#1=#1-1\nIF [#1 GT 0] GOTO10\nGOTO 20\nG0 X99\nN20 G0 X-1\n'
    assert xs(text) == [3.0, 2.0, 1.0, -1.0]


def test_g65_macro_call_with_arguments_local_to_the_call():
    # A -> #1, X -> #24; #1 is restored after the call (local).
    text = ('#1=7\nG65 P9001 A2. X5.\nG0 Y#1\nM30\nO9001\nG0 X[#24*#1]\nM99\n')
    assert words(text) == [[('G', 0.0), ('X', 10.0)], [('G', 0.0), ('Y', 7.0)],
                           [('M', 30.0)]]


def test_haas_m97_local_subprogram():
    # M97 P100 L2 runs N100..M99 twice: X1, X1; then the main goes on to Y5.
    text = 'G0 X0\nM97 P100 L2\nG0 Y5\nM30\nN100 G91 G0 X1\nM99\n'
    assert words(text, SimpleNamespace(name='haas', fanuc_subprograms=True)) == [
        [('G', 0.0), ('X', 0.0)], [('N', 100.0), ('G', 91.0), ('G', 0.0), ('X', 1.0)],
        [('N', 100.0), ('G', 91.0), ('G', 0.0), ('X', 1.0)], [('G', 0.0), ('Y', 5.0)],
        [('M', 30.0)]]


def test_m97_goes_to_the_interpreter_without_macros():
    assert words('M97 P100\n', LINUXCNC) == [[('M', 97.0), ('P', 100.0)]]


@pytest.mark.parametrize('text, line, message', [
    ('END1\n', 1, 'END1 without a WHILE'),
    ('WHILE [0] DO1\nG0 X1\n', 1, 'no END1'),
    ('GOTO 50\n', 1, 'no block N50'),
    ('IF [1] G0 X1\n', 1, 'expected GOTO n or THEN'),
    ('WHILE [1] D1\nEND1\n', 1, 'expected DOm'),
    ('G65 P1 O2\nM30\nO1\nM99\n', 1, 'not a G65 argument'),
])
def test_macro_errors(text, line, message):
    with pytest.raises(GcodeError) as info:
        words(text)
    assert info.value.line == line
    assert message in str(info.value)


def test_endless_goto_loop_stops(monkeypatch):
    monkeypatch.setattr(control, 'MAX_LOOP_ITERATIONS', 20)
    with pytest.raises(GcodeError, match='GOTO 1 ran 20 times'):
        words('N1 G0 X1\nGOTO 1\n')


def test_linuxcnc_dialect_does_not_read_macro_statements():
    with pytest.raises(GcodeError):
        words('#1=1\nWHILE [#1 GT 0] DO1\n#1=#1-1\nEND1\n', LINUXCNC)
    with pytest.raises(GcodeError, match="unexpected character '/'"):
        words('#1= 2 / 2\n', LINUXCNC)
