"""Canned cycles: hand-computed moves, LinuxCNC's errors, and (where installed) the reference."""
from __future__ import annotations

import json
import math
from pathlib import Path
import re
import subprocess

import must_run
import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.expand.cycles import (CYCLE_CODES, CycleMemory, CycleSpec,
                                                  expand_cycle, PECK_BACKOFF_M, word_failer)

MM = 1e-3
ROOT = Path(__file__).resolve().parents[2]


def mm(*v: float) -> tuple[float, ...]:
    return tuple(x * MM for x in v)


def spec(code: int, pos: tuple[float, float, float], words: dict[str, float], **kw) -> CycleSpec:
    """A spec with mm positions/words (P, L as given) and a feed of 100 mm/min."""
    w = {k: (v if k in 'PL' else v * MM) for k, v in words.items()}
    kw.setdefault('feed_m_s', 100 * MM / 60)
    return CycleSpec(code, kw.pop('plane', 17), mm(*pos), w, **kw)


def as_mm(prims) -> list[tuple]:
    out = []
    for p in prims:
        if p[0] in ('rapid', 'feed'):
            out.append((p[0], tuple(round(v / MM, 9) for v in p[1])))
        else:
            out.append(p)
    return out


def lengths(start, prims) -> dict[str, float]:
    """Rapid and feed path length [mm] of primitives starting at ``start`` [m]."""
    tot = {'rapid': 0.0, 'feed': 0.0}
    pos = start
    for p in prims:
        if p[0] in tot:
            tot[p[0]] += math.dist(pos, p[1]) / MM
            pos = p[1]
    return tot


# -- hand-computed geometry ---------------------------------------------------------------
def test_g81_g98_returns_to_the_start_level():
    res = expand_cycle(spec(81, (0, 0, 10), dict(X=5, Y=5, Z=-3, R=2), retract=98))
    assert as_mm(res.primitives) == [('rapid', (5, 5, 10)), ('rapid', (5, 5, 2)),
                                     ('feed', (5, 5, -3)), ('rapid', (5, 5, 10))]
    tot = lengths(mm(0, 0, 10), res.primitives)
    assert tot['feed'] == pytest.approx(5.0)                 # R 2 -> Z -3
    assert tot['rapid'] == pytest.approx(math.hypot(5, 5) + 8 + 13)
    assert res.end == pytest.approx(mm(5, 5, 10))


def test_g81_g99_returns_to_r():
    res = expand_cycle(spec(81, (0, 0, 10), dict(X=5, Y=5, Z=-3, R=2), retract=99))
    tot = lengths(mm(0, 0, 10), res.primitives)
    assert tot['rapid'] == pytest.approx(math.hypot(5, 5) + 8 + 5)
    assert res.end == pytest.approx(mm(5, 5, 2))


def test_start_below_r_rises_to_r_first():
    res = expand_cycle(spec(81, (0, 0, -1), dict(X=5, Z=-4, R=2), retract=98))
    # Below R: straight up to R, then across at R (the initial level is taken as R).
    assert as_mm(res.primitives) == [('rapid', (0, 0, 2)), ('rapid', (5, 0, 2)),
                                     ('feed', (5, 0, -4)), ('rapid', (5, 0, 2))]


def test_g83_pecks_counted_by_hand():
    # R 1, Q 1, bottom -2.5: pecks to 0, -1, -2, then the bottom.
    res = expand_cycle(spec(83, (0, 0, 1), dict(Z=-2.5, R=1, Q=1)))
    feeds = [p[1][2] / MM for p in res.primitives if p[0] == 'feed']
    assert feeds == pytest.approx([0, -1, -2, -2.5])
    b = PECK_BACKOFF_M / MM
    assert b == pytest.approx(0.254)
    rapids = [p[1][2] / MM for p in res.primitives if p[0] == 'rapid']
    # Out to R and back to 0.254 mm above the depth reached, after each of the 3 pecks.
    assert rapids == pytest.approx([1, 1, 0 + b, 1, -1 + b, 1, -2 + b, 1])
    tot = lengths(mm(0, 0, 1), res.primitives)
    assert tot['feed'] == pytest.approx(3.5 + 3 * b)          # depth + the re-cut back-offs
    # Out: 1 + 2 + 3 mm; back in: the same less 3 back-offs; final retract 3.5 mm.
    assert tot['rapid'] == pytest.approx((1 + 2 + 3) + (1 + 2 + 3 - 3 * b) + 3.5)


def test_g73_backs_off_without_leaving_the_hole():
    res = expand_cycle(spec(73, (0, 0, 1), dict(Z=-2.5, R=1, Q=1)))
    b = PECK_BACKOFF_M / MM
    kinds = [p[0] for p in res.primitives]
    # Starting at R: one (zero-length) positioning rapid, as LinuxCNC issues it.
    assert kinds == ['rapid'] + ['feed', 'rapid'] * 4
    levels = [p[1][2] / MM for p in res.primitives]
    assert levels == pytest.approx([1, 0, b, -1, -1 + b, -2, -2 + b, -2.5, 1])


def test_peck_that_divides_the_depth_makes_no_empty_peck():
    res = expand_cycle(spec(83, (0, 0, 1), dict(Z=-2, R=1, Q=1)))
    feeds = [p[1][2] / MM for p in res.primitives if p[0] == 'feed']
    assert feeds == pytest.approx([0, -1, -2])


def test_l_repeats_in_g91_move_by_the_increment():
    # G91: R relative to the initial level 10 -> 8; Z relative to R -> 3; holes at X 10, 20, 30.
    res = expand_cycle(spec(81, (0, 0, 10), dict(X=10, Z=-5, R=-2, L=3), incremental=True))
    assert as_mm(res.primitives) == [
        ('rapid', (10, 0, 10)), ('rapid', (10, 0, 8)), ('feed', (10, 0, 3)), ('rapid', (10, 0, 8)),
        ('rapid', (20, 0, 8)), ('feed', (20, 0, 3)), ('rapid', (20, 0, 8)),
        ('rapid', (30, 0, 8)), ('feed', (30, 0, 3)), ('rapid', (30, 0, 8))]
    assert lengths(mm(0, 0, 10), res.primitives)['feed'] == pytest.approx(15.0)


def test_l_repeats_in_g90_drill_the_same_hole():
    res = expand_cycle(spec(81, (0, 0, 5), dict(X=1, Z=-1, R=2, L=2), retract=98))
    assert [p[0] for p in res.primitives].count('feed') == 2
    assert lengths(mm(0, 0, 5), res.primitives)['feed'] == pytest.approx(6.0)


def test_sticky_words_and_initial_level_carry_over_lines():
    first = expand_cycle(spec(82, (0, 0, 10), dict(X=1, Z=-2, R=1, P=0.5), retract=98))
    second = expand_cycle(spec(82, tuple(v / MM for v in first.end), dict(X=4), retract=99),
                          first.memory)
    # Same cycle: R, Z, P reused; G99 now retracts to R although the series began at 10.
    assert as_mm(second.primitives) == [('rapid', (4, 0, 10)), ('rapid', (4, 0, 1)),
                                        ('feed', (4, 0, -2)), ('dwell', 0.5),
                                        ('rapid', (4, 0, 1))]
    third = expand_cycle(spec(82, (4, 0, 1), dict(X=8), retract=98), second.memory)
    # Back to G98 from R: LinuxCNC goes up to the initial level on the way to the hole.
    assert as_mm(third.primitives)[:2] == [('rapid', (8, 0, 10)), ('rapid', (8, 0, 1))]


def test_a_new_cycle_code_needs_r_and_z_again():
    first = expand_cycle(spec(81, (0, 0, 10), dict(X=1, Z=-2, R=1)))
    with pytest.raises(GcodeError, match='R clearance plane unspecified'):
        expand_cycle(spec(85, (1, 0, 1), dict(X=4, Z=-2)), first.memory)
    with pytest.raises(GcodeError, match='Z value unspecified'):
        expand_cycle(spec(85, (1, 0, 1), dict(X=4, R=1)), first.memory)
    # After a non-cycle motion the same code starts a new series too.
    with pytest.raises(GcodeError, match='R clearance plane unspecified'):
        expand_cycle(spec(81, (1, 0, 1), dict(X=4)), first.memory.end_series())


@pytest.mark.parametrize('plane, words, expected', [
    # G18 drills along Y; G19 along X (LinuxCNC's convert_cycle_zx / _yz).
    (18, dict(X=1, Z=1, Y=-3, R=2),
     [('rapid', (1, 5, 1)), ('rapid', (1, 2, 1)), ('feed', (1, -3, 1)), ('rapid', (1, 5, 1))]),
    (19, dict(Y=1, Z=2, X=-3, R=2),
     [('rapid', (5, 1, 2)), ('rapid', (2, 1, 2)), ('feed', (-3, 1, 2)), ('rapid', (5, 1, 2))]),
])
def test_other_planes_permute_the_axes(plane, words, expected):
    start = (5, 5, 5)
    res = expand_cycle(spec(81, start, words, plane=plane, retract=98))
    assert as_mm(res.primitives) == expected


@pytest.mark.parametrize('code, tail', [
    (82, [('feed', (0, 0, -2)), ('dwell', 0.25), ('rapid', (0, 0, 1))]),
    (84, [('feed', (0, 0, -2)), ('dwell', 0.25), ('feed', (0, 0, 1))]),
    (85, [('feed', (0, 0, -2)), ('feed', (0, 0, 1)), ('rapid', (0, 0, 1))]),
    (86, [('feed', (0, 0, -2)), ('dwell', 0.25), ('rapid', (0, 0, 1))]),
    (88, [('feed', (0, 0, -2)), ('dwell', 0.25), ('stop',), ('rapid', (0, 0, 1))]),
    (89, [('feed', (0, 0, -2)), ('dwell', 0.25), ('feed', (0, 0, 1))]),
])
def test_bottom_and_retract_of_each_cycle(code, tail):
    res = expand_cycle(spec(code, (0, 0, 1), dict(Z=-2, R=1, P=0.25), spindle=1))
    assert as_mm(res.primitives) == [('rapid', (0, 0, 1))] + tail


def test_g84_dwell_defaults_to_zero_and_remembers_p():
    res = expand_cycle(spec(84, (0, 0, 1), dict(Z=-2, R=1), spindle=1))
    assert ('dwell', 0.0) in res.primitives
    g82 = expand_cycle(spec(82, (0, 0, 1), dict(Z=-2, R=1, P=0.7)))
    res = expand_cycle(spec(84, (0, 0, 1), dict(Z=-2, R=1), spindle=1), g82.memory)
    assert ('dwell', 0.7) in res.primitives


def test_g87_back_boring_by_hand():
    res = expand_cycle(spec(87, (10, 10, 5), dict(Z=-5, R=2, I=-1, J=0, K=-3), retract=98,
                            spindle=1))
    assert as_mm(res.primitives) == [
        ('rapid', (10, 10, 5)), ('rapid', (10, 10, 2)),
        ('rapid', (9, 10, 2)), ('rapid', (9, 10, -5)), ('rapid', (10, 10, -5)),
        ('feed', (10, 10, -3)), ('feed', (10, 10, -5)),
        ('rapid', (9, 10, -5)), ('rapid', (9, 10, 5)), ('rapid', (10, 10, 5))]


def test_offsets_translate_every_point_and_keep_the_level_in_program_frame():
    off = mm(100, -50, 7)
    plain = expand_cycle(spec(83, (0, 0, 10), dict(X=3, Z=-4, R=1, Q=1.5), retract=98))
    start = tuple(p + o for p, o in zip(mm(0, 0, 10), off))
    words = {k: v * MM for k, v in dict(X=3, Z=-4, R=1, Q=1.5).items()}
    moved = expand_cycle(CycleSpec(83, 17, start, words, offset=off, retract=98, feed_m_s=1.0))
    assert len(moved.primitives) == len(plain.primitives)
    for p, q in zip(plain.primitives, moved.primitives):
        assert p[0] == q[0]
        if p[0] in ('rapid', 'feed'):
            assert q[1] == pytest.approx(tuple(a + o for a, o in zip(p[1], off)), abs=1e-15)
    assert moved.memory.level == pytest.approx(plain.memory.level)


# -- errors as LinuxCNC reports them, with the place --------------------------------------
@pytest.mark.parametrize('code, words, kw, message, letter', [
    (81, dict(X=1, Z=3, R=2), {}, 'R less than Z', 'R'),
    (83, dict(X=1, Z=-3, R=2), {}, 'Q word missing with G83', 'G'),
    (73, dict(X=1, Z=-3, R=2, Q=-1), {}, 'Negative or zero Q', 'Q'),
    (82, dict(X=1, Z=-3, R=2), {}, 'P word missing with G82', 'G'),
    (82, dict(X=1, Z=-3, R=2, P=-1), {}, 'Negative P word', 'P'),
    (81, dict(X=1, Z=-3, R=2, L=0), {}, 'zero repeats', 'L'),
    (81, dict(X=1, Z=-3, R=2, L=2.5), {}, 'whole number', 'L'),
    (81, dict(X=1, Z=-3, R=2, L=-2), {}, 'Negative L', 'L'),
    (81, dict(X=1, Z=-3, R=2), dict(feed_m_s=0.0), 'zero feed rate', 'G'),
    (81, dict(X=1, Z=-3, R=2), dict(inverse_time=True), 'inverse time', 'G'),
    (81, dict(X=1, Z=-3, R=2), dict(cutter_comp=True), 'cutter compensation', 'G'),
    (86, dict(X=1, Z=-3, R=2, P=1), dict(spindle=0), 'Spindle not turning in G86', 'G'),
    (84, dict(X=1, Z=-3, R=2), dict(spindle=-1), 'counterclockwise in G84', 'G'),
    (87, dict(X=1, Z=-3, R=2, I=1, J=1), dict(spindle=1), 'K word missing', 'G'),
])
def test_errors_name_the_word(code, words, kw, message, letter):
    text = f'G{code} ' + ' '.join(f'{k}{v:g}' for k, v in words.items())
    fail = word_failer('part.ngc', 12, text)
    with pytest.raises(GcodeError, match=message) as info:
        expand_cycle(spec(code, (0, 0, 5), words, **kw), fail=fail)
    column = text.index(letter) + 1
    assert (info.value.file, info.value.line, info.value.column) == ('part.ngc', 12, column)
    assert text[column - 1:].startswith(info.value.text)


def test_a_runaway_peck_count_is_refused_not_expanded():
    with pytest.raises(GcodeError, match='Q is too small'):
        expand_cycle(spec(83, (0, 0, 1), dict(Z=-1000, R=1, Q=1e-9)))
    with pytest.raises(GcodeError, match='not a finite number'):
        expand_cycle(spec(81, (0, 0, 1), dict(Z=float('-inf'), R=1)))


# -- agreement with LinuxCNC's interpreter, where it is installed -------------------------
def _drive(text: str) -> dict:
    """Run a cycle-only fixture (G0/G1, G17-19, G90/91, G98/99, cycles, F, M3-5) through
    expand_cycle, summarised as run_oracle.py does (mm)."""
    pos, plane, inc, ret, motion, feed = (0.0, 0.0, 0.0), 17, False, 99, None, None
    memory, spindle = CycleMemory(), 0
    s = dict(n_feed_moves=0, n_traverses=0, n_dwells=0, feed=0.0, traverse=0.0, dwell=0.0)
    lo, hi = list(pos), list(pos)

    def go(kind: str, end) -> None:
        nonlocal pos
        key = 'feed' if kind == 'feed' else 'traverse'
        s['n_feed_moves' if kind == 'feed' else 'n_traverses'] += 1
        s[key] += math.dist(pos, end) / MM
        pos = tuple(end)
        for i in range(3):
            lo[i], hi[i] = min(lo[i], pos[i]), max(hi[i], pos[i])

    for line in text.upper().splitlines():
        words = [(m[1], float(m[2])) for m in re.finditer(r'([A-Z])([-+.\d]+)', line)]
        d, new = {}, None
        for letter, v in words:
            if letter == 'G':
                g = round(v)
                plane = g if g in (17, 18, 19) else plane
                inc = {90: False, 91: True}.get(g, inc)
                ret = g if g in (98, 99) else ret
                new = g if g in (0, 1, 80) or g in CYCLE_CODES else new
            elif letter == 'M':
                spindle = {3: 1, 4: -1, 5: 0}.get(int(v), spindle)
            elif letter == 'F':
                feed = v * MM / 60
            else:
                d[letter] = v if letter in 'PL' else v * MM
        if new is not None:
            memory = memory if new in CYCLE_CODES else memory.end_series()
            motion = new
        has_axes = any(a in d for a in 'XYZ')
        if motion in CYCLE_CODES and (has_axes or new in CYCLE_CODES):
            res = expand_cycle(CycleSpec(motion, plane, pos, d, incremental=inc, retract=ret,
                                         feed_m_s=feed, spindle=spindle), memory)
            for p in res.primitives:
                if p[0] in ('rapid', 'feed'):
                    go(p[0], p[1])
                elif p[0] == 'dwell':
                    s['n_dwells'] += 1
                    s['dwell'] += p[1]
            memory = res.memory
        elif motion in (0, 1) and has_axes:
            base = pos if inc else (0.0, 0.0, 0.0)
            go('rapid' if motion == 0 else 'feed',
               [base[i] + d[a] if a in d else pos[i] for i, a in enumerate('XYZ')])
    s['final'] = [v / MM for v in pos]
    s['bbox'] = ([v / MM for v in lo], [v / MM for v in hi])
    return s


FIXTURES = {
    'drill_g98_g99.ngc': """G21 G17 G90 F120 M3
G0 X0 Y0 Z10
G98 G81 X5 Y5 Z-3 R2
X10
G99 X15
G91 G81 X5 Z-4 R1 L3
G90 G80
G0 Z5
G73 X0 Y0 Z-2.5 R1 Q1
G83 X1 Z-2.5 R1 Q0.7
G82 X2 P0.5 Z-2 R1
G85 X3 Z-2 R1
G86 X4 P1 Z-2 R1
G89 X6 P1 Z-2 R1
G84 X7 Z-2 R1
M2
""",
    'planes_incremental.ngc': """G21 G17 G90 F100 M3
G0 X0 Y0 Z-5
G98 G81 X5 Y5 Z-8 R2 L2
G91 X2 Y1 L3
G99 X-1 Z-3 R-1 L2
G90 G83 X1 Y1 Z-3.3 R1.5 Q0.7
G91 G73 X1 Z-2 R1 Q0.6 L2
G90 G82 X0 Y0 Z-1 R3 P0.2
X3
G0 X0 Y0 Z20
G19 G98 G85 X-4 Y2 Z3 R5
G18 G99 G89 Y-1 Z1 X2 R2 P0.1 L2
G17 G91 G87 X1 Y1 Z-5 R3 I1 J-1 K2
G90 G86 X10 Y10 Z-2 R4 P0
M2
""",
}


@pytest.mark.parametrize('name', sorted(FIXTURES))
def test_agrees_with_the_reference_interpreter(name, tmp_path):
    tool = must_run.oracle_script()
    prog = tmp_path / name
    prog.write_text(FIXTURES[name])
    run = subprocess.run(['/usr/bin/python3', str(tool), '--one', str(prog)],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    ref = json.loads(run.stdout.strip().splitlines()[-1])
    assert ref['status'] == 'ok', ref['error']
    ours = _drive(FIXTURES[name])
    assert ours['n_feed_moves'] == ref['n_feed_moves']
    assert ours['n_traverses'] == ref['n_traverses']
    assert ours['n_dwells'] == ref['n_dwells']
    assert ours['dwell'] == pytest.approx(ref['dwell_s_total'], abs=1e-4)
    assert ours['feed'] == pytest.approx(ref['feed_path_length_mm'], abs=2e-4)
    assert ours['traverse'] == pytest.approx(ref['traverse_path_length_mm'], abs=2e-4)
    assert ours['final'] == pytest.approx(ref['final_position'], abs=1e-4)
    assert ours['bbox'][0] == pytest.approx(ref['bbox_mm']['min'], abs=1e-4)
    assert ours['bbox'][1] == pytest.approx(ref['bbox_mm']['max'], abs=1e-4)
