"""The contour lane of the plain-line fast path: ``lexer.CONTOUR_RE`` splits the usual CAM
motion line and ``Interpreter.contour_line`` runs it without a word dictionary.

It must be invisible: CONTOUR_RE reads a subset of LINE_RE's lines into exactly WORD_RE's
words, and whole programs give the same moves (bit for bit), warnings and errors with the
lane as with every line going through ``Interpreter.line``.
"""
from __future__ import annotations

import math
from unittest import mock

from hypothesis import given, HealthCheck, settings, strategies as st
import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.load import iter_moves, parse_gcode
from feed_axis_energy.gcode.interp.interpreter import Interpreter
from feed_axis_energy.gcode.read.lexer import CONTOUR_RE, LINE_RE, WORD_RE
from feed_axis_energy.gcode.program import MoveKind

SETTINGS = settings(max_examples=300, derandomize=True, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow])

_NUMBERS = st.one_of(
    st.integers(-999, 999).map(str),
    st.floats(-200, 200, allow_nan=False).map(lambda v: f'{v:.3f}'),
    st.sampled_from(['0', '.5', '-.5', '+1', '5.', '-0', '123456789012', '1234567890123',
                     '1.2.3', '- 1', '1 .5', '', '.', '+']))
_G_TEXTS = st.sampled_from(['0', '00', '1', '01', '2', '02', '3', '03', '000', '010', '4',
                            '17', '18', '20', '21', '90', '91', '93', '90.1', '81', '80',
                            '1.0', '-1', ' 1'])
_LETTERS = st.sampled_from(list('NGXYZIJKRFMSPTD'))
_SEPARATORS = st.sampled_from(['', ' ', ' ', '  ', '\t'])


@st.composite
def _word(draw) -> str:
    letter = draw(_LETTERS)
    value = draw(_G_TEXTS) if letter == 'G' else draw(_NUMBERS)
    return letter + draw(st.sampled_from(['', '', ' '])) + value


@st.composite
def _line(draw) -> str:
    words = draw(st.lists(_word(), max_size=7))
    if draw(st.booleans()):
        # The usual order, so that the expression has matches to be checked.
        order = 'NGXYZIJKRF'
        words = sorted(words, key=lambda w: order.find(w[0]) if w[0] in order else 99)
    parts = [draw(_SEPARATORS)]
    for w in words:
        parts += [w, draw(_SEPARATORS)]
    return ''.join(parts)


@SETTINGS
@given(_line())
def test_contour_re_reads_a_subset_of_line_re_into_word_re_words(line):
    m = CONTOUR_RE.fullmatch(line)
    if m is None:
        return
    assert LINE_RE.fullmatch(line) is not None
    g, *rest = m.groups()
    expected = [] if g is None else [('G', g)]
    expected += [(letter, v) for letter, v in zip('XYZIJKRF', rest) if v is not None]
    words = WORD_RE.findall(line)
    if words and words[0][0] == 'N':
        words = words[1:]
    assert words == expected


@pytest.mark.parametrize('line, groups', [
    ('N10 G1 X1.5 Y-2 F300', ('1', '1.5', '-2', None, None, None, None, None, '300')),
    ('G2X1Y2I3J-4', ('2', '1', '2', None, '3', '-4', None, None, None)),
    ('  G03 X.5 Z-1. R+2.5 ', ('03', '.5', None, '-1.', None, None, None, '+2.5', None)),
    ('Y2', (None, None, '2', None, None, None, None, None, None)),
])
def test_contour_re_takes_the_usual_cam_lines(line, groups):
    m = CONTOUR_RE.fullmatch(line)
    assert m is not None and m.groups() == groups


@pytest.mark.parametrize('line', [
    'G1 X1 M3',             # an M word
    'G1 F300 X1',           # another order
    'G1 X 1',               # a blank after the letter
    'G1 X1.2.3',            # a bad number
    'G1 X1234567890123',    # more than 12 integer digits (the full reader's)
    'G17 X1', 'G010 X1', 'G1.0 X1', 'X1 X2',
])
def test_contour_re_leaves_other_lines_to_the_word_reader(line):
    assert CONTOUR_RE.fullmatch(line) is None


def _outcome(text: str, dialect: str) -> tuple:
    """Everything a parse gives: each move's repr (exact floats), warnings, line count; or
    the error message."""
    try:
        prog = parse_gcode(text, file='p.nc', dialect=dialect,
                           tools={1: 0.002, 2: (0.003, 0.05)})
    except GcodeError as err:
        return ('error', str(err))
    return (tuple(repr(m) for m in prog.moves), prog.warnings, prog.n_lines)


def _without_lane(text: str, dialect: str) -> tuple:
    with mock.patch.object(Interpreter, 'contour_line', lambda self, *words: False):
        return _outcome(text, dialect)


_SMALL = st.one_of(st.integers(-30, 30).map(str),
                   st.floats(-30, 30, allow_nan=False).map(lambda v: f'{v:.3f}'),
                   st.sampled_from(['0', '-0', '.5', '5.', '+2', '0.0001']))
_MODE_LINES = st.sampled_from([
    'G20', 'G21', 'G90', 'G91', 'G17', 'G18', 'G19', 'G93', 'G94', 'G90.1', 'G91.1', 'G61',
    'G64', 'G64 P0.01', 'G80', 'G81 X1 Y1 Z-1 R2 F100', 'G83 Z-2 R1 Q0.5 F50', 'G98', 'G99',
    'G41.1 D2 G1 X0 Y0', 'G42 D1 G1 X1 Y1', 'G40', 'G92 X0 Y0', 'G92.1', 'G10 L2 P1 X5 Y3',
    'G10 L2 P1 R30', 'G10 L2 P1 R0', 'G55', 'G54', 'G43 H2', 'G49', 'T1 M6', 'F0', 'F100',
    'F-5', 'G0', 'G1', 'M3 S1000', 'G4 P0.1', 'M62 P1', 'G53 G0 X0', 'G28', '(comment)',
    '', '%', '/G1 X3', 'N5', 'G2 I5 J0', 'G1 X1 (comment) Y2', 'G1 X1 ; note'])


@st.composite
def _contour(draw) -> str:
    """A motion line in the usual order: mostly moves that run (lines, full circles under
    G91, R arcs of 100 units, which reach any end point drawn here), some of random words."""
    kind = draw(st.sampled_from(['line', 'line', 'circle', 'radius', 'any']))
    words = [draw(st.sampled_from(['', '', 'N7', 'N0010']))]
    if kind == 'line':
        words.append(draw(st.sampled_from(['', 'G0', 'G1', 'G01', 'G00'])))
        words += [f'{a}{draw(_SMALL)}' for a in 'XYZ' if draw(st.booleans())]
    elif kind == 'circle':
        words += [draw(st.sampled_from(['G2', 'G3', 'G02', 'G03'])), 'X0', 'Y0']
        words += [f'{c}{draw(_SMALL)}' for c in draw(st.sampled_from(['I', 'J', 'IJ']))]
    elif kind == 'radius':
        words += [draw(st.sampled_from(['G2', 'G3'])), f'X{draw(_SMALL)}',
                  f'Y{draw(_SMALL)}', draw(st.sampled_from(['R100', 'R-100', 'R100.0']))]
    else:
        words.append(draw(st.sampled_from(['', 'G0', 'G1', 'G2', 'G3'])))
        words += [f'{a}{draw(_SMALL)}' for a in 'XYZIJKR' if draw(st.integers(0, 3)) == 0]
    if draw(st.integers(0, 3)) == 0:
        words.append(f'F{draw(st.sampled_from(["60", "1200", "30000", "60", "0", "-1"]))}')
    return draw(st.sampled_from([' ', ''])).join(w for w in words if w)


@st.composite
def _program(draw) -> str:
    lines = draw(st.lists(st.one_of(_contour(), _contour(), _contour(), _contour(),
                                    _contour(), _MODE_LINES), min_size=1, max_size=30))
    head = draw(st.sampled_from(['G21 G91 G17 G1 F600', 'G91 G0', 'G20 G90 G1 F10',
                                 'G21 G90 G0 F1000', 'G18 G91 G1 F100', '']))
    return '\n'.join([head] + lines + [draw(st.sampled_from(['M30', '', 'M2\nG1 X1']))])


@SETTINGS
@given(_program(), st.sampled_from(['linuxcnc', 'fanuc', 'grbl', 'haas']))
def test_programs_give_the_same_result_with_and_without_the_lane(text, dialect):
    assert _outcome(text, dialect) == _without_lane(text, dialect)


_NONZERO = st.one_of(st.integers(1, 30), st.integers(-30, -1)).map(str) | st.sampled_from(
    ['2.5', '-.75', '12.125', '+3'])
_SAFE_MODE_LINES = st.sampled_from([
    'G20', 'G21', 'G61', 'G64', 'G0', 'G1', 'F100', 'F2500', 'G92 X0 Y0', 'G92.1',
    'G10 L2 P2 X5 Y3 Z1', 'G55', 'G54', 'G41.1 D0.1', 'G42.1 D0.2', 'G40', 'G9 G1 X1', 'S100',
    'G17', '(comment)', 'G1 X1 ; note'])


@st.composite
def _running_line(draw) -> str:
    """A motion line that runs under G91 G17 with a feed rate in force."""
    kind = draw(st.sampled_from(['line', 'circle', 'radius']))
    words = [draw(st.sampled_from(['', 'N12']))]
    if kind == 'line':
        words.append(draw(st.sampled_from(['', 'G0', 'G1', 'G01'])))
        words += [f'X{draw(_NONZERO)}', f'Y{draw(_NONZERO)}']
    elif kind == 'circle':
        words += [draw(st.sampled_from(['G2', 'G3', 'G02', 'G03'])), 'X0', 'Y0',
                  f'I{draw(_NONZERO)}', f'J{draw(_NONZERO)}']
    else:
        words += [draw(st.sampled_from(['G2', 'G3'])), f'X{draw(_NONZERO)}',
                  f'Y{draw(_NONZERO)}', draw(st.sampled_from(['R100', 'R-100']))]
    if draw(st.booleans()):
        words.append(f'Z{draw(_NONZERO)}')
    if draw(st.integers(0, 3)) == 0:
        words.append(f'F{draw(st.integers(1, 30000))}')
    return draw(st.sampled_from([' ', ''])).join(w for w in words if w)


@SETTINGS
@given(st.lists(st.one_of(_running_line(), _running_line(), _running_line(),
                          _SAFE_MODE_LINES), min_size=1, max_size=40),
       st.sampled_from(['linuxcnc', 'grbl']))
def test_running_programs_give_the_same_moves_with_and_without_the_lane(lines, dialect):
    text = '\n'.join(['G21 G91 G17 G1 F600'] + lines + ['M30'])
    assert _outcome(text, dialect) == _without_lane(text, dialect)


@pytest.mark.parametrize('text', [
    # Full circles in G91: the end is the start, so every arc passes LinuxCNC's checks.
    'G91 G17 F600\n' + '\n'.join(f'G{2 + k % 2} X0 Y0 I{k % 7 - 3}.5 J{k % 5}' for k in range(40)),
    'G91 G18 F600\nG2 X0 Z0 I1 K2\nG3 Z0 X0 K-1.5\nG19\nG2 Y0 Z0 J1 K1 F300\nM30',
    'G90 G17 F100\nG2 X10 Y0 R5\nG3 X0 Y0 R-5.0001\nG2 X10 Y0 R4\nM30',   # R too small
    'G90 G17\nG1 X1 Y1\nM30',                                           # no feed rate
    'G90 G17 F100\nG1 X1 F-3\nM30',                                     # negative F
    'G90 G17 F100\nG2 X10 Y0 I5.1 J0\nM30',                             # end off the circle
])
def test_chosen_programs_give_the_same_result_with_and_without_the_lane(text):
    assert _outcome(text, 'linuxcnc') == _without_lane(text, 'linuxcnc')


@pytest.mark.parametrize('batch', [1, 3, 4096])
def test_streamed_moves_equal_the_parsed_ones(tmp_path, batch):
    # iter_moves hands on the lane's moves in batches as they gather.
    pairs = (f'G{2 + k % 2} X0 Y0 I{k % 7 - 3}.5 J{k % 5}\nG1 X{k % 3}.25 Y-{k % 4}'
             for k in range(30))
    text = 'G91 G17 F600\n' + '\n'.join(pairs)
    path = tmp_path / 'p.nc'
    path.write_text(text + '\nM30\n')
    parsed = parse_gcode(path.read_text(), file=str(path))
    stream = iter_moves(path, batch=batch)
    assert list(stream) == list(parsed.moves) and len(parsed.moves) == 61
    assert stream.n_lines == parsed.n_lines == 62


def test_lane_moves_by_hand():
    """The lane's moves checked by hand: a 3-4-5 line, a half circle of radius 5 mm and an
    R-form quarter circle of radius 10 mm, at F600 (10 mm/s)."""
    calls = []
    original = Interpreter.contour_line

    def counting(self, *words):
        taken = original(self, *words)
        calls.append(taken)
        return taken

    text = 'G21 G90 G17\nG1 X3 Y4 F600\nG0 X0 Y0\nG2 X10 Y0 I5 J0\nG3 X0 Y10 R10\nM30\n'
    with mock.patch.object(Interpreter, 'contour_line', counting):
        prog = parse_gcode(text, file='hand.nc')
    assert calls == [True, True, True, True]
    line, rapid, half, quarter, stop = prog.moves
    assert line.kind == MoveKind.LINEAR and math.isclose(line.length_m, 0.005)
    assert math.isclose(line.feed_m_s, 0.01)
    assert rapid.kind == MoveKind.RAPID and rapid.feed_m_s == math.inf
    assert half.kind == MoveKind.ARC_CW and half.center == pytest.approx((0.005, 0.0, 0.0))
    assert math.isclose(half.sweep_rad, -math.pi)
    assert math.isclose(half.length_m, math.pi * 0.005)
    assert quarter.kind == MoveKind.ARC_CCW
    assert quarter.center == pytest.approx((0.0, 0.0, 0.0), abs=1e-15)
    assert math.isclose(quarter.sweep_rad, math.pi / 2)
    assert math.isclose(quarter.length_m, math.pi / 2 * 0.010)
    assert stop.kind == MoveKind.STOP and stop.end == pytest.approx((0.0, 0.010, 0.0))
