"""gcode/check: sanity warnings from the moves, checked on hand-made programs."""
from __future__ import annotations

import math

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.gcode.check import (check_moves, CheckLimits, MAX_LISTED_DWELLS,
                                          problem_from_error, problems_from_warnings)

LIMITS = CheckLimits(travel_m={'X': (-0.1, 0.1), 'Y': (-0.1, 0.1), 'Z': (-0.05, 0.05)},
                     velocity_m_s={'X': 0.5, 'Y': 0.5, 'Z': 0.1}, max_dwell_s=10.0)


def _check(text: str, limits: CheckLimits = LIMITS):
    program = parse_gcode(text, file='p.nc')
    lines = text.split('\n')
    return check_moves(program.moves, file='p.nc', limits=limits,
                       line_text=lambda n: lines[n - 1])


def _kinds(problems):
    return [(p.kind, p.line) for p in problems]


def test_program_within_every_limit_has_no_warning():
    # 30 m/min = 0.5 m/s: exactly the X limit is not above it.
    problems, stats = _check('G21 G90\nG0 X50 Y50\nG1 X-50 F30000\nG4 P10\nM2')
    assert problems == []
    assert stats.n_feed_moves == 1 and stats.n_dwells == 1


def test_travel_beyond_max_names_the_first_line_count_and_farthest_point():
    problems, _ = _check('G21 G90\nG0 X50\nG1 X120 F1000\nG1 X150\nG1 X0\nM2')
    assert _kinds(problems) == [('travel', 3)]
    p = problems[0]
    assert p.severity == 'warning' and p.text == 'G1 X120 F1000'
    # X120, X150 and the move back from 150 to 0 (it starts beyond the travel).
    assert '3 moves go beyond the X travel (max 100.000 mm)' in p.message
    assert 'X reaches 150.000 mm' in p.message


def test_travel_below_min_is_its_own_warning():
    problems, _ = _check('G21 G90\nG1 X150 F1000\nG1 X-150\nM2')
    sides = sorted(p.message.split('(')[1].split(' ')[0] for p in problems)
    assert sides == ['max', 'min']


def test_arc_inside_its_end_points_but_beyond_travel_at_its_extreme():
    # Half circle G3 from (90, 0) to (-90, 0) mm about the origin, radius 90: it passes
    # Y = +90 mm; with a Y travel of +-50 mm only the arc's top is beyond, not its ends.
    limits = CheckLimits(travel_m={'Y': (-0.05, 0.05)}, velocity_m_s={}, max_dwell_s=10.0)
    problems, _ = _check('G21 G90\nG0 X90 Y0\nG3 X-90 Y0 I-90 J0 F1000\nM2', limits)
    assert _kinds(problems) == [('travel', 3)]
    assert 'Y reaches 90.000 mm' in problems[0].message
    # The same arc clockwise passes Y = -90 mm: the min side.
    problems, _ = _check('G21 G90\nG0 X90 Y0\nG2 X-90 Y0 I-90 J0 F1000\nM2', limits)
    assert '(min -50.000 mm)' in problems[0].message


def test_feed_component_along_an_axis():
    # 60 m/min along a 3-4-5 diagonal: X gets 3/5 of 1 m/s = 0.6 m/s > 0.5 m/s,
    # Y 4/5 = 0.8 m/s > 0.5; a move along Z alone at 0.2 m/s > 0.1 m/s.
    problems, _ = _check('G21 G91\nG1 X3 Y4 F60000\nG1 Z-1 F12000\nM2')
    msgs = {p.message.split(' axis limit')[0].split('above the ')[1]: p for p in problems}
    assert set(msgs) == {'X', 'Y', 'Z'}
    assert '36000.0 mm/min along X' in msgs['X'].message
    assert '48000.0 mm/min along Y' in msgs['Y'].message
    assert '12000.0 mm/min along Z' in msgs['Z'].message


def test_feed_on_an_arc_whose_tangent_never_lines_up_with_x():
    # Quarter arc G3 from angle 45 to 135 degrees: the tangent (-sin t, cos t) has an X
    # component of at most |sin 90 deg| = 1 (the sweep passes 90 deg) and a Y component of
    # at most |cos 45 deg| = 0.7071. At 0.6 m/s: X 0.6 > 0.5, Y 0.4243 < 0.5.
    c = 10 * math.sqrt(0.5)
    text = f'G21 G90\nG0 X{c:.6f} Y{c:.6f}\nG3 X{-c:.6f} Y{c:.6f} I{-c:.6f} J{-c:.6f} F36000\nM2'
    problems, _ = _check(text)
    assert [p.message.split(' axis')[0][-1] for p in problems] == ['X']


def test_rapids_are_not_feed_checked():
    problems, _ = _check('G21 G90\nG0 X90 Y90\nM2')
    assert problems == []


def test_long_dwells_each_listed_then_summed():
    text = 'G21\nG1 X1 F100\n' + '\n'.join(['G4 P11'] * (MAX_LISTED_DWELLS + 2)) + '\nM2'
    problems, stats = _check(text)
    dwell = [p for p in problems if p.kind == 'dwell']
    assert len(dwell) == MAX_LISTED_DWELLS + 1
    assert dwell[0].line == 3 and dwell[0].text == 'G4 P11'
    assert dwell[-1].line == 0 and dwell[-1].message.startswith('2 more dwells')
    assert f'({11 * (MAX_LISTED_DWELLS + 2)} s in all' in dwell[-1].message
    assert stats.dwell_s == 11 * (MAX_LISTED_DWELLS + 2)


def test_program_that_never_moves():
    problems, _ = _check('G21\nG4 P1\nM2')
    assert _kinds(problems) == [('no-motion', 0)]


def test_parse_error_becomes_an_error_problem_with_its_place():
    with pytest.raises(GcodeError) as info:
        parse_gcode('G21\nG1 X1 F100\nG1 X1.2.3\n', file='bad.nc')
    p = problem_from_error(info.value)
    assert (p.severity, p.file, p.line) == ('error', 'bad.nc', 3)
    assert p.column >= 1
    assert str(p).startswith(f'bad.nc:3:{p.column}: error: ')


def test_parser_warnings_keep_file_and_line():
    ps = problems_from_warnings(['a.nc:12: G43 without a tool', 'odd text'], file='a.nc')
    assert [(p.file, p.line, p.message) for p in ps] == [('a.nc', 12, 'G43 without a tool'),
                                                         ('a.nc', 0, 'odd text')]


def _batch_program() -> str:
    """Runs of straight moves (some beyond X travel or the Y feed limit) between arcs,
    dwells and a subroutine-like jump back to smaller line numbers."""
    out = ['G21 G90 G94 G17', 'G0 X0 Y0 Z0', 'G1 F3000']
    for row in range(6):
        for j in range(40):
            x = -90.0 + 5.0 * j + (30.0 if row == 3 else 0.0)
            y = 2.0 * row + (0.5 if j % 2 else 0.0)
            out.append(f'G1 X{x:.3f} Y{y:.3f} F{40000 if row == 4 else 3000}')
        out.append(f'G2 X{x:.3f} Y{y + 4.0:.3f} I0 J2')
        out.append('G4 P0.1')
    out.append('G0 Z-70')
    out.append('M2')
    return '\n'.join(out) + '\n'


@pytest.mark.parametrize('batch', [1, 7, 40, 4096])
def test_batches_of_moves_give_the_warnings_of_one_by_one(batch):
    from feed_axis_energy.gcode.check import MoveChecker
    moves = parse_gcode(_batch_program(), file='b.nc').moves
    one = MoveChecker(file='b.nc', limits=LIMITS)
    for mv in moves:
        one.add(mv)
    many = MoveChecker(file='b.nc', limits=LIMITS)
    for lo in range(0, len(moves), batch):
        many.add_many(moves[lo:lo + batch])
    ref, got = one.problems(), many.problems()
    assert {p.kind for p in ref} >= {'travel', 'feed'}
    assert [str(p) for p in got] == [str(p) for p in ref]
    a, b = one.result(), many.result()
    assert (b.n_feed_moves, b.n_traverses, b.n_arcs, b.n_dwells, b.final_position,
            b.bbox_min, b.bbox_max) == (a.n_feed_moves, a.n_traverses, a.n_arcs, a.n_dwells,
                                        a.final_position, a.bbox_min, a.bbox_max)
    assert b.feed_length_m == pytest.approx(a.feed_length_m, rel=1e-14)
    assert b.traverse_length_m == pytest.approx(a.traverse_length_m, rel=1e-14)


def test_add_all_checks_the_moves_taken_before_the_stream_fails():
    from feed_axis_energy.gcode.check import MoveChecker
    moves = parse_gcode(_batch_program(), file='b.nc').moves
    cut = len(moves) - 5                    # the travel and feed warnings come before
    ref = MoveChecker(file='b.nc', limits=LIMITS)
    for mv in moves[:cut]:
        ref.add(mv)

    def failing():
        yield from moves[:cut]
        raise GcodeError('bad line', file='b.nc', line=999, column=1)
    got = MoveChecker(file='b.nc', limits=LIMITS)
    with pytest.raises(GcodeError, match='bad line'):
        got.add_all(failing(), batch=50)
    assert {p.kind for p in ref.problems()} >= {'travel', 'feed'}
    assert [str(p) for p in got.problems()] == [str(p) for p in ref.problems()]
    assert got.result().n_feed_moves == ref.result().n_feed_moves
