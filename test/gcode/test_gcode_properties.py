"""Property tests of the G-code front end: random programs never escape as anything but
:class:`GcodeError`, never give NaN/inf or negative lengths and durations, and the accepted
ones plan into finite motion.

Programs are built from a grammar of real words (motion, planes, units, distance modes,
canned cycles, cutter compensation, offsets, dwells, parameters, expressions, O-words) with
numbers from plain to absurd (400 digits, 1e300, ``nan``), plus garbage bytes, CR / LF / CRLF
mixes and unbalanced comments and brackets. Derandomized with a bounded number of examples,
so CI sees the same cases every time.
"""
from __future__ import annotations

import math
from pathlib import Path

from hypothesis import given, HealthCheck, settings, strategies as st

from feed_axis_energy.errors import FeedAxisError, GcodeError
from feed_axis_energy.gcode.load import iter_moves, load_gcode, parse_gcode
from feed_axis_energy.gcode.check import check_moves, CheckLimits
from feed_axis_energy.gcode.stats import summarize
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.plan.stream import estimate_plan, iter_motion
from feed_axis_energy.gcode.program import MoveKind
from feed_axis_energy.machine.limits import PlannerOptions

ROOT = Path(__file__).resolve().parents[2]
MILL = load_machine(ROOT / 'config' / 'three_axis_mill.yaml')
LIMITS = MILL.limits()
OPTIONS = PlannerOptions(rate_hz=50.0)
MAX_SAMPLED = 200_000    # plan and sample only programs up to this many samples at 50 Hz

SETTINGS = settings(max_examples=250, derandomize=True, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

_SMALL = st.one_of(st.integers(-200, 200).map(str),
                   st.floats(-500, 500, allow_nan=False).map(lambda v: f'{v:.4f}'),
                   st.sampled_from(['0', '.5', '-1.', '+2', '0.0001', '1e3']))
_ABSURD = st.sampled_from(['9' * 400, '-' + '9' * 400, '1e300', '1e-300', 'nan', 'inf',
                           '1.2.3', '', '-', '.', '0' * 50 + '1', '3' * 20 + '.5'])
NUMBER = st.one_of(_SMALL, _SMALL, _SMALL, _ABSURD)
LETTER = st.sampled_from(list('XYZIJKRFPQLDHSTNABCUVW'))
G_CODE = st.sampled_from(['0', '1', '2', '3', '4', '17', '18', '19', '20', '21', '90', '91',
                          '90.1', '91.1', '93', '94', '80', '81', '82', '83', '73', '85', '89',
                          '98', '99', '40', '41', '42', '41.1', '42.1', '43', '49', '54', '55',
                          '59.3', '92', '92.1', '28', '30', '53', '52', '10 L2 P1', '10 L20 P2',
                          '61', '64', '9', '5', '5.1', '5.2', '5.3', '33', '38.2', '95',
                          '999'])
M_CODE = st.sampled_from(['0', '1', '2', '30', '3', '5', '6', '8', '9', '62 P1', '98 P1',
                          '99', '100'])


def _word(draw) -> str:
    kind = draw(st.integers(0, 9))
    if kind <= 2:
        return 'G' + draw(G_CODE)
    if kind == 3:
        return 'M' + draw(M_CODE)
    if kind == 4:
        return 'F' + draw(NUMBER)
    if kind == 5:
        expr = draw(st.sampled_from(['[1+2]', '[#1*2]', '[SIN[30]]', '[1/0]', '[SQRT[-1]]',
                                     '[2**2000]', '[#<x>]', '[[1]', '[1]]', '#5420']))
        return draw(LETTER) + expr
    return draw(LETTER) + draw(NUMBER)


@st.composite
def lines(draw) -> str:
    kind = draw(st.integers(0, 14))
    if kind == 0:
        return draw(st.sampled_from(['%', '% header text', '/G1 X1', '$H', '$$', ';comment',
                                     '(comment', 'comment)', '((nested))', '(a)(b) G0 X1',
                                     '#1 = 5', '#<len> = [3 * 4]', '#1=#1+1', '#2=[1/0]',
                                     'o100 sub', 'o100 endsub', 'o100 call [1]', 'o101 if [1]',
                                     'o101 endif', 'o102 while [1]', 'o102 endwhile',
                                     'o103 repeat [3]', 'o103 endrepeat', 'O1234', 'M99',
                                     'N10 G0 X0', '@10 ^45', 'G0 @5 ^90']))
    if kind == 1:
        return draw(st.binary(max_size=20)).decode('latin-1')
    n = draw(st.integers(1, 5))
    out = [_word(draw) for _ in range(n)]
    sep = draw(st.sampled_from([' ', '', '  ', '\t']))
    return sep.join(out)


_STEP = st.one_of(st.integers(-30, 30).map(str),
                  st.floats(-30, 30, allow_nan=False).map(lambda v: f'{v:.3f}'))


@st.composite
def clean_lines(draw) -> str:
    """Lines a CAM system writes, relative (G91): most are accepted."""
    kind = draw(st.integers(0, 9))
    x, y, z = draw(_STEP), draw(_STEP), draw(_STEP)
    r = draw(st.integers(1, 20))
    feed = draw(st.sampled_from(['', '', ' F300', ' F6000', ' F0.5']))
    if kind <= 3:
        return f'G{kind % 2} X{x} Y{y}' + (f' Z{z}' if kind >= 2 else '') + feed
    if kind == 4:    # full circle (and a helix) about a centre r to the side
        return f'G{draw(st.sampled_from(["2", "3"]))} X0 Y0 Z{z} I{r} J0' + feed
    if kind == 5:    # half circle by R: the chord is 2r
        return f'G{draw(st.sampled_from(["2", "3"]))} X{2 * r} Y0 R{r}' + feed
    if kind == 6:    # G18/G19 full circles, then back to G17
        plane, word = draw(st.sampled_from([('18', 'K'), ('19', 'J')]))
        return f'G{plane} G2 X0 Y0 Z0 {word}{r} P{draw(st.integers(1, 3))}' + feed + '\nG17'
    if kind == 7:
        return f'G4 P{draw(st.sampled_from(["0", "0.25", "2"]))}'
    if kind == 8:    # a drilling cycle, relative: R above, Z below the initial level
        return f'G99 G81 X{x} Y{y} Z-{r} R2 L{draw(st.integers(1, 3))} F300\nG80'
    return draw(st.sampled_from(['G64', 'G61', 'G20', 'G21', 'G94', 'M3 S1000', 'M5',
                                 'G54', 'G40', 'G49', 'T1 M6', 'G43 H1']))


@st.composite
def programs(draw) -> str:
    wild = draw(st.sampled_from([0.0, 0.1, 0.5, 1.0]))
    n = draw(st.integers(0, 25))
    body = [draw(lines()) if draw(st.floats(0, 1)) < wild else draw(clean_lines())
            for _ in range(n)]
    head = draw(st.sampled_from(['', 'G21 G91 G17 F500\n', 'G20 G91 F20\n',
                                 'G21 G90 G0 X0 Y0 Z5\nG91 F500\n']))
    eol = draw(st.sampled_from(['\n', '\r\n', '\r', 'mixed']))
    if eol == 'mixed':
        text = ''.join(line + draw(st.sampled_from(['\n', '\r\n', '\r'])) for line in body)
    else:
        text = eol.join(body)
    tail = draw(st.sampled_from(['', '\nM2\n', '\nM30', '\n%\n']))
    return head + text + tail


def _assert_sane(program) -> None:
    for m in program.moves:
        for v in m.start + m.end:
            assert math.isfinite(v), m
        assert math.isfinite(m.length_m) and m.length_m >= 0.0, m
        assert math.isfinite(m.dwell_s) and m.dwell_s >= 0.0, m
        if m.kind in (MoveKind.LINEAR, MoveKind.ARC_CW, MoveKind.ARC_CCW):
            assert m.feed_m_s > 0.0 and not math.isnan(m.feed_m_s), m
        if m.kind in (MoveKind.ARC_CW, MoveKind.ARC_CCW):
            assert m.center is not None and all(math.isfinite(v) for v in m.center), m
            sweep = getattr(m, 'sweep_rad', None)
            assert sweep is None or math.isfinite(sweep), m
    s = summarize(program.moves)
    assert math.isfinite(s.feed_length_m) and s.feed_length_m >= 0.0
    assert math.isfinite(s.traverse_length_m) and s.traverse_length_m >= 0.0
    assert math.isfinite(s.dwell_s) and s.dwell_s >= 0.0


def _parse(text: str):
    """Parse; only GcodeError may come out (anything else fails the test with its trace)."""
    try:
        return parse_gcode(text, file='random.nc', **MILL.gcode_keywords())
    except GcodeError as err:
        assert str(err).startswith('random.nc:'), err
        assert len(str(err)) < 1000, 'unbounded error message'
        return None


@SETTINGS
@given(programs())
def test_random_programs_never_escape_and_never_give_nan(text):
    program = _parse(text)
    if program is not None:
        _assert_sane(program)


@SETTINGS
@given(programs())
def test_accepted_random_programs_plan_into_finite_motion(text):
    program = _parse(text)
    if program is None:
        return
    try:
        est = estimate_plan(program.moves, LIMITS, options=OPTIONS, file='random.nc')
    except FeedAxisError:
        return      # a clear refusal by the planner (e.g. beyond its own bounds) is fine
    assert math.isfinite(est.duration_s) and est.duration_s >= 0.0
    if est.samples > MAX_SAMPLED:
        return
    n = 0
    for chunk in iter_motion(program.moves, LIMITS, options=OPTIONS, file='random.nc'):
        for arr in (chunk.t, chunk.pos, chunk.vel, chunk.acc):
            assert all(math.isfinite(v) for v in arr.ravel()), 'non-finite sample'
        n += len(chunk.t)
    assert n == est.samples


@settings(max_examples=150, derandomize=True, deadline=None, database=None)
@given(st.binary(max_size=300))
def test_random_bytes_from_a_file_are_read_or_refused_with_a_place(tmp_path_factory, data):
    path = tmp_path_factory.mktemp('bytes') / 'b.nc'
    path.write_bytes(data)
    try:
        program = load_gcode(path, **MILL.gcode_keywords())
    except GcodeError as err:
        assert str(err).startswith(f'{path}:'), err
        return
    _assert_sane(program)


_BODIES = st.lists(st.sampled_from(['G0 X1', 'G1 Y2 F100', 'G0 X0 Y0', '(c)', '']),
                   min_size=1, max_size=12)


@settings(max_examples=100, derandomize=True, deadline=None, database=None)
@given(_BODIES)
def test_crlf_line_ends_give_the_same_moves_as_lf(body):
    ref = parse_gcode('\n'.join(body), file='p.nc')
    assert parse_gcode('\r\n'.join(body), file='p.nc').moves == ref.moves


@settings(max_examples=100, derandomize=True, deadline=None, database=None)
@given(_BODIES)
def test_cr_line_ends_give_the_same_moves_as_lf(body):
    """A file with CR-only line ends (old Mac editors) is read line by line (issue 8)."""
    ref = parse_gcode('\n'.join(body), file='p.nc')
    assert parse_gcode('\r'.join(body), file='p.nc').moves == ref.moves


CHECK_LIMITS = CheckLimits(travel_m={'X': (-0.6, 0.6), 'Y': (-0.4, 0.4), 'Z': (-0.4, 0.15)},
                           velocity_m_s={'X': 0.5, 'Y': 0.5, 'Z': 0.2}, max_dwell_s=1.0)


@settings(max_examples=150, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                 HealthCheck.function_scoped_fixture])
@given(programs())
def test_streamed_moves_equal_the_whole_program_and_check_never_fails(tmp_path, text):
    """iter_moves (bounded memory, batch of 3) gives the moves parse_gcode gives, or the
    same refusal; `check`'s sanity pass over them only ever returns problems."""
    path = tmp_path / 'r.nc'
    path.write_text(text, encoding='utf-8', newline='')
    kw = MILL.gcode_keywords()
    try:
        whole = load_gcode(path, **kw)
    except GcodeError as err:
        try:
            list(iter_moves(path, batch=3, **kw))
        except GcodeError as err2:
            assert (err2.line, err2.column) == (err.line, err.column)
            return
        raise AssertionError(f'iter_moves accepted what load_gcode refused: {err}')
    assert list(iter_moves(path, batch=3, **kw)) == list(whole.moves)
    problems, stats = check_moves(whole.moves, file=str(path), limits=CHECK_LIMITS)
    for p in problems:
        assert p.severity == 'warning' and p.line >= 0 and len(p.message) < 500
        assert str(p).startswith(f'{path}:')
    assert stats == summarize(whole.moves)
