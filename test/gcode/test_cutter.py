"""Cutter radius compensation: hand geometry, invariants, errors, and the reference."""
from __future__ import annotations

import json
import math
from pathlib import Path
import random
import re
import subprocess

import must_run
import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.expand.cutter import CutterComp, LEFT, RIGHT
from feed_axis_energy.gcode.expand.cutter_corners import arc_sweep, find_turn
from feed_axis_energy.gcode.program import Move, MoveKind

MM = 1e-3
ROOT = Path(__file__).resolve().parents[2]
ARCS = (MoveKind.ARC_CW, MoveKind.ARC_CCW)


def p3(x: float, y: float, z: float = 0.0) -> tuple[float, float, float]:
    return (x * MM, y * MM, z * MM)


class Path2:
    """Builds programmed moves (mm in, metres out) the way the interpreter hands them over."""

    def __init__(self, x: float, y: float, z: float = 0.0, *, plane: int = 17):
        self.pos = p3(x, y, z)
        self.line = 0
        self.plane = plane

    def line_to(self, x=None, y=None, z=None, *, rapid=False) -> Move:
        self.line += 1
        end = tuple(self.pos[i] if v is None else v * MM for i, v in enumerate((x, y, z)))
        m = Move(kind=MoveKind.RAPID if rapid else MoveKind.LINEAR, line=self.line,
                 start=self.pos, end=end, feed_m_s=math.inf if rapid else 0.01,
                 length_m=math.dist(self.pos, end))
        self.pos = end
        return m

    def arc_to(self, x: float, y: float, i: float, j: float, *, ccw: bool) -> Move:
        self.line += 1
        end = (x * MM, y * MM, self.pos[2])
        centre = (self.pos[0] + i * MM, self.pos[1] + j * MM, self.pos[2])
        m = Move(kind=MoveKind.ARC_CCW if ccw else MoveKind.ARC_CW, line=self.line,
                 start=self.pos, end=end, feed_m_s=0.01, center=centre, plane=self.plane,
                 length_m=1.0)
        self.pos = end
        return m


def run(moves, *, side=LEFT, radius=1.0, plane=17, finish=True) -> list[Move]:
    comp = CutterComp()
    comp.start(side, radius * MM, plane)
    out: list[Move] = []
    for m in moves:
        out += comp.feed(m)
    if finish:
        out += comp.finish()
    return out


def assert_chained(moves: list[Move]) -> None:
    for a, b in zip(moves, moves[1:]):
        assert b.start == a.end


def length_mm(moves) -> float:
    return sum(m.length_m for m in moves) / MM


def arc_radius_mm(m: Move) -> float:
    return math.dist(m.start[:2], m.center[:2]) / MM


# -- hand geometry --------------------------------------------------------------------------
def test_entry_move_ends_one_radius_to_the_left_or_right():
    for side, y in ((LEFT, 1.0), (RIGHT, -1.0)):
        path = Path2(0, 0)
        out = run([path.line_to(10, 0)], side=side)
        assert len(out) == 1
        assert out[0].start == p3(0, 0)
        assert out[0].end == pytest.approx(p3(10, y))


def square(path: Path2, *, ccw: bool) -> list[Move]:
    """The 20 mm square from (0, 0), then its first two sides again (lines 2-7)."""
    pts = [(20, 0), (20, 20), (0, 20), (0, 0), (20, 0), (20, 20)] if ccw else \
        [(0, 20), (20, 20), (20, 0), (0, 0), (0, 20), (20, 20)]
    return [path.line_to(x, y) for x, y in pts]


@pytest.mark.parametrize('ccw, side, loop_mm', [
    # Tool outside the square: each side keeps 20 mm, 4 quarter arcs of r add 2 pi r.
    (True, RIGHT, 80 + 2 * math.pi * 1.0),
    (False, LEFT, 80 + 2 * math.pi * 1.0),
    # Tool inside: every side is shortened by r at both ends, no arcs.
    (True, LEFT, 80 - 8 * 1.0),
    (False, RIGHT, 80 - 8 * 1.0),
])
def test_closed_square_offset_length(ccw, side, loop_mm):
    path = Path2(-10, 0)
    moves = [path.line_to(0, 0)] + square(path, ccw=ccw)
    out = run(moves, side=side)
    assert_chained(out)
    # One full loop: lines 3-6 (second side to first side again; a corner arc belongs to
    # the move after it, and line 7 gives line 6 its far corner).
    loop = [m for m in out if 3 <= m.line <= 6]
    assert length_mm(loop) == pytest.approx(loop_mm)
    arcs = [m for m in loop if m.kind in ARCS]
    outside = loop_mm > 80
    assert len(arcs) == (4 if outside else 0)
    for a in arcs:
        assert arc_radius_mm(a) == pytest.approx(1.0)
        assert abs(a.length_m / MM) == pytest.approx(math.pi / 2)


@pytest.mark.parametrize('side, radius_mm', [(LEFT, 10 - 1.5), (RIGHT, 10 + 1.5)])
def test_full_circle_offset_by_the_tool_radius(side, radius_mm):
    # Tangential lead-in along +Y to (10, 0), then a full CCW circle about the origin.
    path = Path2(10, -10)
    out = run([path.line_to(10, 0), path.arc_to(10, 0, -10, 0, ccw=True)], side=side,
              radius=1.5)
    assert_chained(out)
    circle = out[-1]
    assert circle.kind == MoveKind.ARC_CCW
    assert circle.start == circle.end               # still a full circle, exactly
    assert arc_radius_mm(circle) == pytest.approx(radius_mm)
    assert circle.length_m / MM == pytest.approx(2 * math.pi * radius_mm)


def test_concave_corner_shortens_both_lines_to_their_intersection():
    # Inside an L turning left with the tool on the left: offset lines y = 1 and x = 9.
    path = Path2(0, 0)
    out = run([path.line_to(10, 0), path.line_to(10, 10)], side=LEFT)
    assert [m.end for m in out] == [pytest.approx(p3(9, 1)), pytest.approx(p3(9, 10))]


def test_convex_corner_gets_an_arc_around_the_corner():
    path = Path2(0, 0)
    out = run([path.line_to(10, 0), path.line_to(10, 10)], side=RIGHT)
    kinds = [m.kind for m in out]
    assert kinds == [MoveKind.LINEAR, MoveKind.ARC_CCW, MoveKind.LINEAR]
    corner = out[1]
    assert corner.start == pytest.approx(p3(10, -1))
    assert corner.end == pytest.approx(p3(11, 0))
    assert corner.center == pytest.approx(p3(10, 0))
    assert corner.length_m / MM == pytest.approx(math.pi / 2)
    assert out[2].end == pytest.approx(p3(11, 10))


def test_rapid_convex_corner_is_a_straight_rapid():
    path = Path2(0, 0)
    out = run([path.line_to(10, 0), path.line_to(10, 10, rapid=True)], side=RIGHT)
    assert [m.kind for m in out] == [MoveKind.LINEAR, MoveKind.RAPID, MoveKind.RAPID]
    assert out[1].end == pytest.approx(p3(11, 0))


def test_z_moves_are_held_with_the_corner_and_follow_its_offset():
    path = Path2(0, 0, 5)
    moves = [path.line_to(10, 0), path.line_to(z=-1), path.line_to(10, 10)]
    out = run(moves, side=LEFT)
    assert_chained(out)
    # The plunge happens at the concave corner's intersection point, not at (10, 1).
    assert out[0].end == pytest.approx(p3(9, 1, 5))
    assert out[1].start == pytest.approx(p3(9, 1, 5))
    assert out[1].end == pytest.approx(p3(9, 1, -1))


def test_exit_move_after_g40_starts_at_the_offset_point():
    comp = CutterComp()
    path = Path2(0, 0)
    comp.start(LEFT, 1 * MM, 17)
    out = comp.feed(path.line_to(10, 0))
    out += comp.finish()
    assert comp.engaged and not comp.active
    out += comp.feed(path.line_to(20, 0))
    assert not comp.engaged
    assert out[-1].start == pytest.approx(p3(10, 1))
    assert out[-1].end == p3(20, 0)
    assert out[-1].length_m == pytest.approx(math.hypot(10, 1) * MM)


def test_dwell_waits_with_a_held_move_and_sits_at_the_corner_point():
    comp = CutterComp()
    path = Path2(0, 0)
    comp.start(LEFT, 1 * MM, 17)
    dwell_first = Move(kind=MoveKind.DWELL, line=9, start=p3(0, 0), end=p3(0, 0), dwell_s=2)
    assert comp.feed(dwell_first) == [dwell_first]        # nothing held: issued at once
    assert comp.feed(path.line_to(10, 0)) == []
    held = Move(kind=MoveKind.DWELL, line=10, start=p3(10, 0), end=p3(10, 0), dwell_s=1)
    assert comp.feed(held) == []
    out = comp.feed(path.line_to(10, 10))
    # The concave corner moved the line's end to (9, 1): the dwell happens there.
    assert [m.kind for m in out] == [MoveKind.LINEAR, MoveKind.DWELL]
    assert out[1].start == out[1].end == out[0].end == pytest.approx(p3(9, 1))


def test_arc_is_refused_after_g40_even_when_comp_is_restarted():
    comp = CutterComp()
    path = Path2(0, 0)
    comp.start(LEFT, 1 * MM, 17)
    comp.feed(path.line_to(10, 0))
    comp.finish()
    comp.start(RIGHT, 1 * MM, 17)                          # LinuxCNC keeps the rule
    with pytest.raises(GcodeError, match='must be straight'):
        comp.feed(path.arc_to(20, 0, 5, 0, ccw=True))


def test_random_contours_give_chained_finite_moves_or_a_gcode_error():
    rng = random.Random(8)
    for _ in range(400):
        path = Path2(0, 0)
        moves = []
        for _ in range(rng.randint(1, 8)):
            if rng.random() < 0.6:
                moves.append(path.line_to(rng.uniform(-30, 30), rng.uniform(-30, 30),
                                          rng.choice([None, rng.uniform(-5, 5)])))
            else:
                r, a0 = rng.uniform(0.01, 20), rng.uniform(0, 2 * math.pi)
                cx, cy = path.pos[0] / MM - r * math.cos(a0), path.pos[1] / MM - r * math.sin(a0)
                a1 = a0 + rng.uniform(-3, 3)
                moves.append(path.arc_to(cx + r * math.cos(a1), cy + r * math.sin(a1),
                                         cx - path.pos[0] / MM, cy - path.pos[1] / MM,
                                         ccw=rng.random() < 0.5))
        try:
            out = run(moves, side=rng.choice([LEFT, RIGHT]), radius=rng.choice([0.5, 2, 6]))
        except GcodeError as err:
            assert 1 <= err.line <= len(moves)
            continue
        assert_chained(out)
        assert out[0].start == p3(0, 0)
        for m in out:
            values = [*m.start, *m.end, m.length_m, *(m.center or ())]
            assert all(math.isfinite(v) for v in values) and m.length_m > 0.0


def test_zero_radius_changes_nothing_and_negative_radius_swaps_the_side():
    path = Path2(0, 0)
    moves = [path.line_to(10, 0), path.line_to(10, 10)]
    assert run(moves, radius=0.0) == moves
    assert [m.end for m in run(moves, side=LEFT, radius=-1.0)] == \
        [m.end for m in run(moves, side=RIGHT, radius=1.0)]


def test_g18_offsets_in_the_zx_plane():
    # In G18 LinuxCNC takes Z as the first and X as the second axis: a move along +Z with
    # G41 ends one radius towards +X.
    path = Path2(0, 0, 0, plane=18)
    out = run([path.line_to(z=10)], side=LEFT, plane=18)
    assert out[0].end == pytest.approx(p3(1, 0, 10))


def test_sweep_helpers_follow_the_reference_conventions():
    assert find_turn(1, 0, 0, 0, 1, 0, 1) == pytest.approx(math.pi / 2)
    assert find_turn(1, 0, 0, 0, -1, 0, 1) == pytest.approx(-3 * math.pi / 2)
    assert arc_sweep((1, 0), (1, 0), (0, 0), 1) == 2 * math.pi
    assert arc_sweep((1, 0), (1, 1e-15), (0, 0), -2) == -4 * math.pi


# -- errors ---------------------------------------------------------------------------------
def placed(text: str, line: int):
    def fail(message: str, letter: str):
        col = text.upper().find(letter) + 1
        raise GcodeError(message, file='part.ngc', line=line, column=col, text=letter)
    return fail


def test_tool_too_big_for_an_inside_arc_names_the_line():
    comp = CutterComp()
    path = Path2(0, 0)
    comp.start(LEFT, 2 * MM, 17)
    comp.feed(path.line_to(10, 0))
    arc = path.arc_to(12, 0, 1, 0, ccw=True)          # radius 1 mm, tool inside
    with pytest.raises(GcodeError, match='tool too big for the arc') as info:
        comp.feed(arc, fail=placed('G3 X12 Y0 I1 J0', arc.line))
    assert (info.value.file, info.value.line, info.value.column) == ('part.ngc', 2, 1)


@pytest.mark.parametrize('build, message', [
    # Entry move not longer than the radius (a Z-only first move included).
    (lambda p: [p.line_to(z=-1)], 'entry move is not greater than the tool radius'),
    (lambda p: [p.line_to(0.5, 0)], 'entry move is not greater than the tool radius'),
    # Concave corner whose next line is shorter than the tool needs: gouge.
    (lambda p: [p.line_to(10, 0), p.line_to(10, 10), p.line_to(9, 10), p.line_to(9, 0)],
     'without gouging'),
])
def test_moves_the_tool_cannot_make(build, message):
    with pytest.raises(GcodeError, match=message):
        run(build(Path2(0, 0)), side=LEFT, radius=1.5)


def test_mode_errors_as_linuxcnc():
    comp = CutterComp()
    with pytest.raises(GcodeError, match='only allowed in XY or XZ'):
        comp.start(LEFT, MM, 19)
    comp.start(LEFT, MM, 17)
    with pytest.raises(GcodeError, match='already on'):
        comp.start(RIGHT, MM, 17)
    path = Path2(0, 0)
    comp.feed(path.line_to(10, 0))
    comp.finish()
    with pytest.raises(GcodeError, match='must be straight, not an arc'):
        comp.feed(path.arc_to(20, 0, 5, 0, ccw=False))


# -- agreement with LinuxCNC's interpreter, where it is installed ---------------------------
# Runs under /usr/bin/python3 with LinuxCNC's `gcode` module: the oracle's canon, with the
# tool diameters given on the command line, printing every canon move as JSON (mm).
_TRACE = r'''
import json, os, sys, tempfile
sys.path.insert(0, sys.argv[1])
import run_oracle as ro
IN = 25.4
diam = json.loads(sys.argv[3])
tmp = tempfile.mkdtemp()
ro._setup_tools(tmp)
import gcode
class C(ro.Canon):
    def __init__(self, *a):
        super().__init__(*a)
        self.log, self.line = [], 0
    def next_line(self, lc):
        super().next_line(lc)
        self.line = lc.sequence_number
    def get_tool(self, pocket):
        d = diam.get(str(pocket), 0.0) / IN
        return (pocket if pocket > 0 else -1,) + (0.0,) * 9 + (d, 0.0, 0.0, 0)
    def straight_traverse(self, *a):
        self.log.append([self.line, 'rapid', [v * IN for v in a[:3]]])
        super().straight_traverse(*a)
    def straight_feed(self, *a):
        self.log.append([self.line, 'feed', [v * IN for v in a[:3]]])
        super().straight_feed(*a)
    def arc_feed(self, fe, se, fa, sa, rot, ae, *r):
        self.log.append([self.line, 'arc', [fe * IN, se * IN, fa * IN, sa * IN, ae * IN], rot])
        super().arc_feed(fe, se, fa, sa, rot, ae, *r)
ini, var = os.path.join(tmp, 'o.ini'), os.path.join(tmp, 'o.var')
open(var, 'w').close()
open(ini, 'w').write('[RS274NGC]\nPARAMETER_FILE = %s\n' % var)
os.environ['INI_FILE_NAME'] = ini
c = C(var, 1e18)
res, seq = gcode.parse(sys.argv[2], c, 'G21', '')
print(json.dumps({'log': c.log, 'error': gcode.strerror(res) if res > gcode.MIN_ERROR else None,
                  'error_line': seq if res > gcode.MIN_ERROR else None}))
'''


def _reference(program: Path, diameters: dict[int, float]) -> dict:
    """The reference's canon log of ``program`` (skips without LinuxCNC or the oracle)."""
    tools = must_run.oracle_script().parent
    script = program.with_suffix('.trace.py')
    script.write_text(_TRACE)
    run_ = subprocess.run(['/usr/bin/python3', str(script), str(tools), str(program),
                           json.dumps({str(k): v for k, v in diameters.items()})],
                          capture_output=True, text=True, timeout=120, cwd=program.parent)
    assert run_.returncode == 0 and run_.stdout.strip(), run_.stderr[-2000:]
    return json.loads(run_.stdout.strip().splitlines()[-1])


_PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1)}


def _ours(text: str, diameters: dict[int, float]) -> tuple[list, GcodeError | None]:
    """A restricted reader (G0-G3 with I/J/K, G17/G18, G20/G21, G40-G42.1 D, T, F) feeding
    programmed moves through CutterComp, logged like the reference's canon (mm)."""
    pos, motion, plane, scale, tool = (0.0, 0.0, 0.0), None, 17, MM, 0
    comp, out, log = CutterComp(), [], []
    try:
        for ln, raw in enumerate(text.splitlines(), 1):
            words = re.findall(r'([A-Z])\s*([-+.\d]+)', raw.upper())
            d = {k: float(v) for k, v in words if k != 'G'}
            gs = [float(v) for k, v in words if k == 'G']
            tool = int(d.get('T', tool))
            plane = next((int(g) for g in gs if g in (17, 18)), plane)
            if 20 in gs:
                scale = comp.units_m = 0.0254
            fail = placed(raw, ln)
            for g in gs:
                if g == 40:
                    out += comp.finish(fail=fail)
                elif g in (41, 42, 41.1, 42.1):
                    r = d['D'] * scale / 2 if g % 1 else \
                        diameters.get(int(d.get('D', tool)), 0.0) * MM / 2
                    comp.start(LEFT if int(g) == 41 else RIGHT, r, plane, fail=fail)
            motion = next((int(g) for g in gs if g in (0, 1, 2, 3)), motion)
            if d.get('M') in (2.0, 30.0):
                out += comp.finish(fail=fail)
            if motion is None or not any(a in d for a in 'XYZ'):
                continue
            end = tuple(d[a] * scale if a in d else pos[i] for i, a in enumerate('XYZ'))
            if motion < 2:
                m = Move(kind=MoveKind(motion), line=ln, start=pos, end=end, feed_m_s=0.01,
                         length_m=math.dist(pos, end))
            else:
                a, b, _ = _PLANE_AXES[plane]
                c = list(pos)
                c[a] += d.get('IJK'[a], 0.0) * scale
                c[b] += d.get('IJK'[b], 0.0) * scale
                m = Move(kind=MoveKind(motion), line=ln, start=pos, end=end, feed_m_s=0.01,
                         center=tuple(c), plane=plane, length_m=1.0)
            out += comp.feed(m, fail=fail) if comp.engaged else ([m] if m.length_m else [])
            pos = end
        err = None
    except GcodeError as e:
        err = e
    for m in out:
        e = [v / MM for v in m.end]
        if m.kind in ARCS:
            a, b, n = _PLANE_AXES[m.plane]
            turn = (m.turns + 1) * (1 if m.kind == MoveKind.ARC_CCW else -1)
            log.append([m.line, 'arc', [e[a], e[b], m.center[a] / MM, m.center[b] / MM, e[n]],
                        turn])
        else:
            log.append([m.line, 'rapid' if m.kind == MoveKind.RAPID else 'feed', e])
    return log, err


FIXTURES = {
    # Outside contour with G42: convex corners, line/arc tangencies, concave arc corners.
    'outside.ngc': ({1: 2.0}, """G21 G17 G90 F100
T1 M6
G0 X-10 Y-10 Z1
G42 D1
G1 X0 Y0
Z-1
X20
G3 X30 Y10 I0 J10
G1 Y20
G2 X20 Y30 I-10 J0
G1 X5
G3 X0 Y25 I0 J-5
G1 Y0
G40 G0 X-10 Y-10
M2
"""),
    # Full circle, arc/arc corners both ways, G0 corner, G41.1 / G42.1 with D, G18.
    'mixed.ngc': ({2: 3.0}, """G21 G17 G90 F100
T2 M6
G0 X10 Y0 Z1
G41 D2
G1 X20 Y0
G3 X20 Y0 I-10 J0
G1 X30 Y0
G2 X50 Y0 I10 J0
G2 X70 Y0 I10 J0
G3 X80 Y10 I0 J10
G3 X70 Y20 I-10 J0
G1 X10 Y20
G0 X10 Y5
G1 X5 Y5
G40 X0 Y0
G42.1 D4 G1 X0 Y-10
G1 X10 Y-10
G1 X10 Y0
G40 G1 X0 Y0
G18
G41 D2 G1 X10 Z-10
G1 X20 Z-10
G2 X30 Z-20 I0 K-10
G1 X30 Z-30
G40 G1 X0 Z0
M2
"""),
    # A concave corner whose next line is too short: the reference refuses it (line 7).
    'gouge.ngc': ({3: 4.0}, """G21 G17 G90 F100
G0 X0 Y0 Z1
G41 D3
G1 X10 Y0
G1 X10 Y10
G1 X9 Y10
G1 X9 Y0
M2
"""),
    # Inch program, a near reversal and small corners.
    'inch_reversal.ngc': ({3: 4.0}, """G20 G17 G90 F10
G0 X0 Y0 Z0.1
G42 D3
G1 X1 Y0
G2 X2 Y0 I0.5 J0
G1 X2 Y-1
G1 X1.5 Y-1
G3 X1.2 Y-0.7 I0 J0.3
G1 X1.2 Y1
G1 X1.21 Y-1
G1 X1.21 Y-0.9
G1 X1.3 Y-0.9
M2
"""),
}


@pytest.mark.parametrize('name', sorted(FIXTURES))
def test_agrees_with_the_reference_interpreter(name, tmp_path):
    diameters, text = FIXTURES[name]
    prog = tmp_path / name
    prog.write_text(text)
    ref = _reference(prog, diameters)
    ours, err = _ours(text, diameters)
    assert (err is None) == (ref['error'] is None), (err, ref['error'])
    if err is not None:
        assert err.line == ref['error_line']
    assert len(ours) == len(ref['log'])
    for mine, theirs in zip(ours, ref['log']):
        assert mine[0] == theirs[0] and mine[1] == theirs[1], (mine, theirs)
        assert mine[2] == pytest.approx(theirs[2], abs=1e-7), (mine, theirs)
        if mine[1] == 'arc':
            assert mine[3] == theirs[3]
