"""Property tests of the front end: random programs end in blocks or a clear error.

Whatever the text, reading it either yields blocks whose values are finite and at most
``MAX_MAGNITUDE`` or raises :class:`GcodeError` naming a line that exists; never another
exception, NaN or infinity.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

from hypothesis import given, HealthCheck, settings, strategies as st

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.read import control, flow
from feed_axis_energy.gcode.read.expr import MAX_MAGNITUDE
from feed_axis_energy.gcode.read.flow import read_blocks
from feed_axis_energy.gcode.read.source import decode_program, split_lines

_NUMBERS = st.one_of(
    st.integers(-10 ** 6, 10 ** 6).map(str),
    st.floats(-1e6, 1e6, allow_nan=False).map(lambda v: f'{v:.4f}'),
    st.integers(1, 500).map(lambda n: '9' * n),
    st.sampled_from(['.', '-.', '1.2.3', '+', '--1', '0', '1e5']))
_PARAMS = st.one_of(st.integers(-2, 5610).map(lambda n: f'#{n}'),
                    st.sampled_from(['#<a>', '#<_b>', '##1', '#[#1+1]', '#<_x>']))
_ATOMS = st.one_of(_NUMBERS, _PARAMS)
_OPS = st.sampled_from(['+', '-', '*', '/', '**', 'MOD', 'EQ', 'NE', 'GT', 'LT', 'AND', 'OR',
                        'XOR'])
_FUNCS = st.sampled_from(['SIN', 'COS', 'TAN', 'ASIN', 'ACOS', 'SQRT', 'LN', 'EXP', 'ABS',
                          'FIX', 'FUP', 'ROUND'])


@st.composite
def _expr(draw, depth: int = 0) -> str:
    if depth > 2 or draw(st.booleans()):
        return draw(_ATOMS)
    kind = draw(st.integers(0, 2))
    if kind == 0:
        return f'[{draw(_expr(depth + 1))} {draw(_OPS)} {draw(_expr(depth + 1))}]'
    if kind == 1:
        return f'{draw(_FUNCS)}[{draw(_expr(depth + 1))}]'
    return f'ATAN[{draw(_expr(depth + 1))}]/[{draw(_expr(depth + 1))}]'


_LABELS = st.sampled_from(['o1', 'o2', 'o<s>', 'O100', 'o[#1]'])
_KEYWORDS = st.sampled_from(['sub', 'endsub', 'call', 'return', 'if', 'elseif', 'else', 'endif',
                             'while', 'endwhile', 'do', 'repeat', 'endrepeat', 'break',
                             'continue', ''])


@st.composite
def _line(draw) -> str:
    kind = draw(st.integers(0, 6))
    if kind == 0:
        letters = draw(st.lists(st.sampled_from('GXYZFMPLIJKRN@^'), min_size=1, max_size=4))
        return ' '.join(f'{a}{draw(_expr())}' for a in letters)
    if kind == 1:
        return f'{draw(_PARAMS)} = {draw(_expr())}'
    if kind == 2:
        cond = f' [{draw(_expr())}]' if draw(st.booleans()) else ''
        return f'{draw(_LABELS)} {draw(_KEYWORDS)}{cond}'
    if kind == 3:
        return draw(st.sampled_from(['M98 P100 L2', 'M99', 'O100', '%', '$H', '/G0 X1',
                                     '(comment', 'M30', ';x', 'G0 X1 (a) Y2', 'N10 G0 X1',
                                     'WHILE [#1 LT 3] DO1', 'END1', 'GOTO 10', 'END2',
                                     'IF [#1 GT 2] GOTO 10', 'IF [1] THEN #1 = #1 + 1',
                                     'G65 P100 A1 X2', 'M97 P10 L2', '#1 = #1 + 1 * 2']))
    if kind == 4:
        return draw(st.text(max_size=20))
    return draw(st.sampled_from(['G0 X1', 'G1 X2 Y3 F100', 'G2 X1 Y1 I1 J0']))


_DIALECTS = [None, SimpleNamespace(name='fanuc', fanuc_subprograms=True),
             SimpleNamespace(name='grbl', fanuc_subprograms=False)]


def _read_all(text: str, dialect: object = None) -> list:
    saved = control.MAX_LOOP_ITERATIONS, flow.MAX_EXECUTED_LINES
    control.MAX_LOOP_ITERATIONS, flow.MAX_EXECUTED_LINES = 50, 2000
    try:
        return list(read_blocks(text, file='prop.ngc', dialect=dialect))
    finally:
        control.MAX_LOOP_ITERATIONS, flow.MAX_EXECUTED_LINES = saved


def _check(text: str, dialect: object = None) -> None:
    n_lines = len(split_lines(text)) if text else 0
    try:
        blocks = _read_all(text, dialect)
    except GcodeError as err:
        assert err.file == 'prop.ngc'
        assert 1 <= err.line <= max(n_lines, 1)
        assert err.column >= 1
        assert len(str(err)) < 400
        return
    for b in blocks:
        assert 1 <= b.line <= n_lines
        for letter, v in b.words:
            assert isinstance(v, float) and math.isfinite(v) and abs(v) <= MAX_MAGNITUDE


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(_line(), max_size=12), st.sampled_from(['\n', '\r\n', '\r']),
       st.sampled_from(_DIALECTS))
def test_random_programs_give_blocks_or_a_clear_error(lines, end, dialect):
    _check(end.join(lines), dialect)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200))
def test_random_bytes_give_text_or_a_clear_error(data):
    try:
        text = decode_program(data, file='prop.ngc')
    except GcodeError as err:
        assert err.line >= 1 and err.column >= 1
        return
    _check(text)
