"""Program flow: blocks, assignments, O-word control, subroutines and Fanuc subprograms.

Expected values are worked out by hand from the programs (comments say how).
"""
from __future__ import annotations

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.read import control, flow
from feed_axis_energy.gcode.read.block import Block
from feed_axis_energy.gcode.read.flow import read_blocks
from feed_axis_energy.gcode.read.params import Parameters


def blocks(text: str, **kw) -> list[Block]:
    return list(read_blocks(text, file='p.ngc', **kw))


def words(text: str, **kw) -> list[list[tuple[str, float]]]:
    return [b.words for b in blocks(text, **kw)]


def xs(text: str, **kw) -> list[float]:
    """The X value of every block that has one."""
    return [dict(w)['X'] for w in words(text, **kw) if 'X' in dict(w)]


def fails(text: str, **kw) -> GcodeError:
    with pytest.raises(GcodeError) as info:
        blocks(text, **kw)
    return info.value


# -- plain lines ---------------------------------------------------------------------------
def test_plain_lines_become_blocks_with_float_words():
    out = blocks('%\nN10 G1 X1.5 Y-2 F300 (cut)\n\n(only a comment)\ng0 z.5 ; up\n%\n')
    assert [b.words for b in out] == [
        [('N', 10.0), ('G', 1.0), ('X', 1.5), ('Y', -2.0), ('F', 300.0)],
        [('G', 0.0), ('Z', 0.5)]]
    assert [(b.line, b.main_line, b.file) for b in out] == [(2, 2, 'p.ngc'), (5, 5, 'p.ngc')]
    assert out[0].text == 'N10 G1 X1.5 Y-2 F300 (cut)'


def test_blanks_inside_numbers_count_as_in_linuxcnc():
    assert words('G1 X1 0 Y - 2 . 5\n') == [[('G', 1.0), ('X', 10.0), ('Y', -2.5)]]


@pytest.mark.parametrize('ends', ['\n', '\r\n', '\r'])
def test_line_ends(ends):
    out = blocks(ends.join(['G0 X1', 'G1 X2', 'G1 X3', '']))
    assert [b.line for b in out] == [1, 2, 3]


def test_block_delete_and_grbl_dollar_lines():
    rd = read_blocks('$H\n$X\n/G0 X9\nG0 X1\n', file='p.ngc')
    assert [b.words for b in rd] == [[('G', 0.0), ('X', 1.0)]]
    assert rd.warnings == ['p.ngc:1: grbl "$" lines are controller settings/commands and '
                           'are skipped']


def test_percent_with_text_and_closing_percent_ends_the_program():
    rd = read_blocks('%MYPART\nG0 X1\n%\nG0 X2\n', file='p.ngc')
    assert [b.line for b in rd] == [2]
    assert rd.warnings == ['p.ngc:4: lines after the closing "%" (line 3) are ignored']


@pytest.mark.parametrize('line, column, message', [
    ('G1 X1' + '9' * 400, 5, 'too large'),
    ('G1 X1234567890123', 4, 'too large'),       # at the word
    ('G1 X1.2.3', 5, 'bad number'),
    ('G1 X', 5, 'expected a value'),
    ('10 G1', 1, 'number without a letter'),
    ('N', 2, 'expected a number at the end of the line'),
    ('N10 X', 6, 'expected a value'),
    ('G1 X1 !', 7, "unexpected character '!'"),
    ('G1 X1 @', 8, 'expected a value'),
    ('G1 X1 (open', 7, 'unclosed comment'),
    ('G1 X\u00e91', 5, 'unexpected character'),
])
def test_bad_lines_name_line_and_column(line, column, message):
    err = fails('G0 X0\n' + line + '\n')
    assert (err.file, err.line, err.column) == ('p.ngc', 2, column)
    assert message in str(err)
    assert len(str(err)) < 200


def test_polar_words_are_words():
    # LinuxCNC's polar coordinates (nc_files/spiral.ngc): '@' radius, '^' angle.
    assert words('G91 G1 @-.0025 ^4.5\n') == [[('G', 91.0), ('G', 1.0), ('@', -0.0025),
                                               ('^', 4.5)]]


def test_non_ascii_inside_comments_is_fine():
    assert words('G0 X1 (Fräse Ø6)\n') == [[('G', 0.0), ('X', 1.0)]]


# -- parameters ----------------------------------------------------------------------------
def test_assignments_take_effect_after_the_line():
    # Line 2 reads #1 = 5 everywhere on it, also in #2=#1; #1 = 7 only from line 3 on.
    assert xs('#1=5\nG1 X#1 #1=7 #2=#1\nG1 X#1\nG1 X#2\n') == [5.0, 7.0, 5.0]


def test_named_and_indirect_parameters():
    text = ('#<depth> = 2\n#<_Safe Z> = [#<depth> * 3]\n#5 = 10\n#6 = 5\n'
            'G1 X#<_safez> Y##6 Z-#<DEPTH>\n')
    assert words(text) == [[('G', 1.0), ('X', 6.0), ('Y', 10.0), ('Z', -2.0)]]


def test_unset_named_parameter_is_an_error_at_its_column():
    err = fails('G1 X#<nothing>\n')
    assert (err.line, err.column) == (1, 5)
    assert '#<nothing> is not defined' in str(err)


def test_read_only_parameter_cannot_be_assigned():
    err = fails('G0 X0\n#5420 = 1\n')
    assert (err.line, err.column) == (2, 1)
    assert 'read-only' in str(err)


def test_predefined_named_parameter_cannot_be_assigned():
    err = fails('G0 X0\n#<_value> = 1\n')
    assert (err.line, err.column) == (2, 1)
    assert 'read-only' in str(err)


def test_call_level_inside_a_subroutine():
    assert xs('o<f> sub\nG0 X#<_call_level>\no<f> endsub\no<f> call\nG0 X#<_call_level>\n') \
        == [1.0, 0.0]


def test_provider_supplies_live_values():
    pos = {'x': 0.0}
    params = Parameters(provider=lambda key: pos['x'] if key in (5420, '_x') else None)
    rd = read_blocks('G0 X5\nG0 X[#5420 + 1]\nG0 X[#<_x> + 1]\n', file='p', params=params)
    out = []
    for b in rd:             # the interpreter moves, then asks for the next block
        out.append(dict(b.words)['X'])
        pos['x'] = out[-1]
    assert out == [5.0, 6.0, 7.0]


# -- control flow --------------------------------------------------------------------------
def test_while_loop_adds_up():
    # 1 + 2 + ... + 10 = 55
    text = ('#1 = 1\n#2 = 0\no100 while [#1 LE 10]\n  #2 = [#2 + #1]\n  #1 = [#1 + 1]\n'
            'o100 endwhile\nG1 X#2\n')
    assert xs(text) == [55.0]


def test_while_false_at_start_skips_the_body():
    assert xs('o1 while [0]\nG1 X1\no1 endwhile\nG1 X2\n') == [2.0]


def test_do_while_runs_at_least_once_and_continue_goes_to_the_test():
    text = ('#1 = 0\no7 do\n  #1 = [#1 + 1]\n  o8 if [#1 EQ 2]\n    o7 continue\n  o8 endif\n'
            '  G0 X#1\no7 while [#1 LT 4]\no9 do\n  G0 X100\no9 while [0]\n')
    assert xs(text) == [1.0, 3.0, 4.0, 100.0]


def test_repeat_and_break():
    text = ('#1 = 0\no5 repeat [3]\n  #1 = [#1 + 1]\n  G0 X#1\no5 endrepeat\n'
            'o6 repeat [0]\n  G0 X99\no6 endrepeat\n'
            'o4 while [1]\n  #1 = [#1 + 1]\n  o3 if [#1 GT 5]\n    o4 break\n  o3 endif\n'
            '  G0 X#1\no4 endwhile\nG0 X-1\n')
    assert xs(text) == [1.0, 2.0, 3.0, 4.0, 5.0, -1.0]


@pytest.mark.parametrize('n, expected', [(1, 10.0), (2, 20.0), (3, 30.0), (7, 40.0)])
def test_if_elseif_else(n, expected):
    text = (f'#1 = {n}\no1 if [#1 EQ 1]\n  G0 X10\no1 elseif [#1 EQ 2]\n  G0 X20\n'
            'o1 elseif [#1 EQ 3]\n  G0 X30\no1 else\n  G0 X40\no1 endif\nG0 Y1\n')
    assert xs(text) == [expected]


def test_nested_if_inside_while():
    # Even numbers below 6 give X = n, odd ones X = -n.
    text = ('#1 = 0\no1 while [#1 LT 6]\n  o2 if [[#1 MOD 2] EQ 0]\n    G0 X#1\n'
            '  o2 else\n    G0 X-#1\n  o2 endif\n  #1 = [#1 + 1]\no1 endwhile\n')
    assert xs(text) == [0.0, -1.0, 2.0, -3.0, 4.0, -5.0]


def test_runaway_loop_stops_with_a_clear_error(monkeypatch):
    monkeypatch.setattr(control, 'MAX_LOOP_ITERATIONS', 50)
    err = fails('G0 X0\no10 while [1]\n  G0 X1\no10 endwhile\n')
    assert err.line == 2
    assert 'ran 50 times' in str(err)


def test_total_line_budget(monkeypatch):
    monkeypatch.setattr(flow, 'MAX_EXECUTED_LINES', 200)
    err = fails('#1 = 0\no10 repeat [1000]\n  #1 = [#1 + 1]\no10 endrepeat\n')
    assert 'more than 200 lines executed' in str(err)


# -- subroutines ---------------------------------------------------------------------------
def test_subroutine_with_arguments_and_return_value_defined_after_the_call():
    text = ('#1 = 100\no<hyp> call [3] [4]\nG1 X#<_value> Y#1\nM2\n'
            'o<hyp> sub\n  G0 Z#2\n  o<hyp> return [SQRT[#1 * #1 + #2 * #2]]\n  G0 Z99\n'
            'o<hyp> endsub\n')
    out = blocks(text)
    # Z4 inside the sub, then X5 (returned), Y100 (#1 restored after the call), M2.
    assert [b.words for b in out] == [[('G', 0.0), ('Z', 4.0)],
                                      [('G', 1.0), ('X', 5.0), ('Y', 100.0)], [('M', 2.0)]]
    assert out[0].line == 6


def test_linuxcnc_return_value_test():
    # LinuxCNC tests/interp/return-value: 'return' under an if label leaves the sub;
    # 123 * 2 = 246; a plain return gives 0; endsub [4712] when no return ran.
    text = ('o1000 sub\no1010 if [#1 GT 0]\no1010    return [123*[#1]]\no1010 endif\n'
            'o1020 if [#1 LT 0]\no1020    return\no1020 endif\no1000 endsub [4712]\n'
            'o1000 call [2]\nG0 X#<_value> Y#<_value_returned>\n'
            'o1000 call [-1]\nG0 X#<_value> Y#<_value_returned>\n'
            'o1000 call [0]\nG0 X#<_value> Y#<_value_returned>\n')
    assert words(text) == [[('G', 0.0), ('X', 246.0), ('Y', 1.0)],
                           [('G', 0.0), ('X', 0.0), ('Y', 0.0)],
                           [('G', 0.0), ('X', 4712.0), ('Y', 1.0)]]


def test_arguments_not_given_are_zero_in_the_call():
    # LinuxCNC 2.9 interp_o_word.cc copies all 30 block parameters, unused ones 0.
    assert xs('#2 = 5\no<f> sub\nG0 X#2\no<f> endsub\no<f> call [1]\nG0 X#2\n') == [0.0, 5.0]


def test_computed_label_inside_a_skipped_definition():
    # LinuxCNC tests/interp/oword-bug315-p2: o#<sub> call inside a sub definition.
    text = ('o2 sub\ng0 x2\no2 endsub\no<multipass> sub\n#<sub> = 2\no#<sub> call\n'
            'o<multipass> endsub\no<multipass> call\nm2\n')
    assert xs(text) == [2.0]


def test_subroutine_defined_before_is_skipped_where_it_stands():
    text = 'o100 sub\n  G0 X#1\no100 endsub\nG0 X1\no100 call [2]\no100 call [3]\n'
    assert xs(text) == [1.0, 2.0, 3.0]


def test_locals_are_local_to_the_call():
    text = ('#<n> = 1\no<f> sub\n  #<n> = 5\n  #<_g> = 6\n  G0 X#<n>\no<f> endsub\n'
            'o<f> call\nG0 X#<n> Y#<_g>\n')
    assert words(text) == [[('G', 0.0), ('X', 5.0)], [('G', 0.0), ('X', 1.0), ('Y', 6.0)]]


def test_recursion_depth_limit():
    text = 'o<r> sub\n  o<r> call\no<r> endsub\no<r> call\n'
    err = fails(text)
    assert 'nested more than 10 deep' in str(err)


def test_recursion_that_ends_is_fine():
    # countdown: X3 X2 X1
    text = ('o<c> sub\n  o1 if [#1 GT 0]\n    G0 X#1\n    o<c> call [#1 - 1]\n  o1 endif\n'
            'o<c> endsub\no<c> call [3]\n')
    assert xs(text) == [3.0, 2.0, 1.0]


def test_subroutine_file_on_the_search_path(tmp_path):
    lib = tmp_path / 'lib'
    lib.mkdir()
    (lib / 'square.ngc').write_text('(square of side #1)\no<square> sub\n  G1 X#1\n'
                                    '  G1 Y#1\no<square> endsub\nM2\n')
    prog = tmp_path / 'main.ngc'
    text = 'G0 X0\no<Square> call [7]\nG0 Z5\n'
    out = list(read_blocks(text, file=str(prog), search_path=(lib,)))
    assert [b.words for b in out] == [[('G', 0.0), ('X', 0.0)], [('G', 1.0), ('X', 7.0)],
                                      [('G', 1.0), ('Y', 7.0)], [('G', 0.0), ('Z', 5.0)]]
    assert [(b.file, b.line, b.main_line) for b in out[1:3]] == [
        (str(lib / 'square.ngc'), 3, 2), (str(lib / 'square.ngc'), 4, 2)]


def test_subroutine_file_in_the_program_directory(tmp_path):
    (tmp_path / 'up.ngc').write_text('o<up> sub\nG0 Z#1\no<up> endsub\n')
    prog = tmp_path / 'main.ngc'
    assert [b.words for b in read_blocks('o<up> call [9]\n', file=str(prog))] == [
        [('G', 0.0), ('Z', 9.0)]]


def test_missing_subroutine_is_an_error_naming_the_file_looked_for():
    err = fails('G0 X0\no<pocket> call\n')
    assert err.line == 2
    assert 'no file pocket.ngc' in str(err)


@pytest.mark.parametrize('text, line, message', [
    ('o1 endwhile\n', 1, 'endwhile without a matching while'),
    ('o1 endsub\n', 1, 'not in a subroutine'),
    ('o1 sub\nG0 X1\n', 1, 'no matching o1 endsub'),
    ('o1 if [1]\nG0 X1\no1 else\nG0 X2\n', 3, 'no matching o1 endif'),
    ('o1 if [0]\nG0 X1\n', 1, 'no matching o1 elseif or else or endif'),
    ('o1 frobnicate\n', 1, 'unknown O-word keyword'),
    ('o1 if [1] G0 X1\no1 endif\n', 1, 'unexpected text after the O-word'),
    ('o1 if 1\no1 endif\n', 1, 'expected [condition]'),
    ('o1 break\n', 1, 'outside a loop'),
    ('o<a> sub\no<b> sub\no<b> endsub\no<a> endsub\no<a> call\n', 2, 'cannot be nested'),
    ('o<a> call\nM2\no<a> sub\nG0 X1\n', 4, 'o<a> endsub missing'),
])
def test_control_errors_name_the_line(text, line, message):
    err = fails(text)
    assert err.line == line
    assert message in str(err)


# -- Fanuc subprograms ---------------------------------------------------------------------
def test_fanuc_example_of_the_linuxcnc_manual():
    # LinuxCNC manual, "Fanuc-Style Numbered Programs": #1 ends at 5 + 25 * 0.01 = 5.25.
    text = ('o1\n#1 = 0\nM98 P100 L5\nG0 X#1\nM30\no100\n#1 = [#1 + 1]\nM98 P200 L5\nM99\n'
            'o200\n#1 = [#1 + 0.01]\nM99\n')
    assert xs(text)[0] == pytest.approx(5.25, abs=1e-12)


def test_m98_repeats_and_attribution():
    text = 'O1000\nG0 X0\nM98 P2000 L3\nM98 P2000 L0\nM30\nO2000\nG91 G0 X1\nM99\n'
    out = []
    for b in read_blocks(text, file='p.ngc'):   # as the interpreter: stop at M30
        out.append(b)
        if b.words == [('M', 30.0)]:
            break
    assert [b.words for b in out] == [[('G', 0.0), ('X', 0.0)]] + \
        [[('G', 91.0), ('G', 0.0), ('X', 1.0)]] * 3 + [[('M', 30.0)]]
    assert [b.main_line for b in out] == [2, 7, 7, 7, 5]   # the sub is in the main file


def test_m99_in_the_main_program_ends_it_with_a_warning():
    rd = read_blocks('G0 X1\nM99\nG0 X2\n', file='p.ngc')
    assert [b.words for b in rd] == [[('G', 0.0), ('X', 1.0)]]
    assert 'endless program' in rd.warnings[0] and rd.warnings[0].startswith('p.ngc:2:')


@pytest.mark.parametrize('text, line, message', [
    ('M98\n', 1, 'no P word'),
    ('M98 P1.5\n', 1, 'must be an integer'),
    ('M98 P7\nM30\n', 1, "'7' is not defined"),
    ('M98 P7 L-1\nM30\nO7\nM99\n', 1, 'repeat count'),
    ('o7 call\nM30\nO7\nM99\n', 1, 'call it with M98'),
    ('M98 P7\nM30\no7 sub\no7 endsub\n', 1, 'not M98'),
    ('o<s> call\nM2\no<s> sub\nM99\no<s> endsub\n', 4, 'cannot end subroutine'),
])
def test_fanuc_errors(text, line, message):
    err = fails(text)
    assert err.line == line
    assert message in str(err)


def test_a_program_with_a_million_lines_streams_without_copies():
    # Blocks are produced lazily: taking the first few reads only the first few lines.
    text = 'G1 X1\n' * 1_000_000
    rd = iter(read_blocks(text, file='big'))
    first = [next(rd) for _ in range(3)]
    assert [b.line for b in first] == [1, 2, 3]


def test_locate_word_text_is_bounded():
    from feed_axis_energy.gcode.read.lexer import locate_word
    column, text = locate_word('G10 L2 P1 X1' + '0' * 400, 'X')
    assert column == 11 and text.startswith('X10') and len(text) <= 63
