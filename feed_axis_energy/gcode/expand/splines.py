"""Splines: G5 (cubic), G5.1 (quadratic) and G5.2/G5.3 (NURBS) as LinuxCNC 2.9 runs them.

LinuxCNC 2.9's interpreter (``convert_spline``, ``convert_nurbs`` in interp_convert.cc) turns
all three into one NURBS in the XY plane and hands it to the canonical call ``NURBS_FEED``:

* ``G5 X Y I J P Q``: a cubic Bezier (order 4) through the control points: the current
  point, the current point + (I, J), the end point + (P, Q), the end point. Without I and
  J the first offset is minus the previous G5's (P, Q) (0 at start-up; LinuxCNC keeps it
  in the same memory as G87's I/J, and so do we: ``CycleMemory.i/j``); I without J or P
  without Q is an error.
* ``G5.1 X Y I J``: a quadratic Bezier (order 3): current point, current point + (I, J),
  end point; both I and J are required.
* ``G5.2 X Y P L`` ... ``G5.3``: a NURBS whose control points are the current point and one
  point (X, Y, weight P) per G5.2 line (a line without G word continues the G5.2 mode);
  ``G5.2 P..`` without X/Y gives the weight of the first point. The order is 3 unless an
  L above 3 is given (the last such L counts). The curve is issued at the G5.3 line, which
  needs at least as many control points as the order, and leaves no motion mode in force.
  Under G91 each point is relative to the curve's start (the position does not move until
  G5.3). The knot vector is clamped and uniform (0 x order, 1, 2, ..., n - order + 2 x order
  for n + 1 points).

Their checks and messages are LinuxCNC's: G5/G5.1 only in G17, without Z, never under
cutter compensation (right after G40 the curve's first feed is the exit move from the offset
point, as in the reference), with a feed rate (F on the line under G93); G5.2 points need
X and Y together and a positive weight P. G5/G5.1 leave the motion mode as it was (LinuxCNC's
``convert_spline`` does not set it: ``G0 ... G5.1 ... X5`` traverses to X5). LinuxCNC keeps
one list of control points for all three: a G5.2 curve left without G5.3 is dropped by
the next G5.2, but a G5/G5.1 before that takes its points as the first of its own; we do
the same and warn in either case.

Discretisation: the reference's preview canon (LinuxCNC's ``gcode`` Python module, which
the oracle drives) issues ``NURBS_FEED`` as straight feeds: with ``n + 1`` control points,
``div = 15 (n + 1)`` steps of ``umax / div`` in the curve parameter, a feed to each point
whose parameter stays below ``umax``, then a feed to the last control point itself. We issue
the same feeds (same parameters, accumulated the same way), so counts and lengths agree.
LinuxCNC's task (the real machine) issues biarcs instead, 4 per control point; the
lengths differ by about the chord error of the polyline (a quarter circle in 45 chords is
5e-5 shorter). The feeds run at the current Z: LinuxCNC's preview uses the Z of the last
straight move there, so after a helix or an arc out of the XY plane its picture differs.

Only where ``Dialect.g5_splines`` (the ``linuxcnc`` dialect): the other controls have no
such codes or, on Fanuc, use G05/G05.1 for high-speed machining modes; they are refused.

Refused beyond LinuxCNC (it runs them with undefined results): a first G5.2 point without
a positive P (LinuxCNC reads a missing P as weight -1 and may divide by zero), G5.2 under
G93 or cutter compensation, axis words on the G5.3 line, more than
:data:`MAX_CONTROL_POINTS` points or an order above :data:`MAX_ORDER` (bounded work: the
curve costs ``15 n order^2`` operations); a Z word on a G5.2 line is ignored as LinuxCNC
ignores it, with a warning.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
import math
from typing import TYPE_CHECKING

from ..program import make_move, MoveKind
from .nurbs import ControlPoint

if TYPE_CHECKING:
    from ..interp.state import InterpreterState
else:
    InterpreterState = object     # the declarations are for the type checker only

__all__ = ['SplineMixin', 'knot_vector', 'nurbs_point',
           'nurbs_polyline',
           'SAMPLES_PER_POINT', 'MAX_CONTROL_POINTS', 'MAX_ORDER', 'SPLINE_WORDS']

SAMPLES_PER_POINT = 15
"""Straight feeds per control point of LinuxCNC's preview canon (gcodemodule.cc)."""
MAX_CONTROL_POINTS = 2_000
"""Control points of one curve: at most 30 000 feeds, issued at once (about 25 MB). LinuxCNC
itself evaluates a curve in time growing at least with the cube of its points: a curve
this long would take it hours."""
MAX_ORDER = 16
"""Highest NURBS order L (LinuxCNC's own evaluation time doubles with each order)."""

# Words each spline code uses besides X/Y/F (others are errors, as in LinuxCNC).
SPLINE_WORDS = {50: 'IJPQ', 51: 'IJ', 52: 'PL'}
_NAMES = {50: 'G5', 51: 'G5.1', 52: 'G5.2', 53: 'G5.3'}


def knot_vector(n_points: int, order: int) -> list[float]:
    """LinuxCNC's clamped uniform knot vector for ``n_points`` points of ``order``.

    ``order`` zeros, then 1, 2, ..., and ``order`` times ``n_points - order + 1`` at the end
    (``n_points + order`` knots); valid for ``n_points >= order >= 1``.
    """
    n = n_points - 1
    top = float(n - order + 2)
    return [0.0 if i < order else (float(i - order + 1) if i <= n else top)
            for i in range(n_points + order)]


def _basis(u: float, span: int, order: int, knots: Sequence[float]) -> list[float]:
    """The ``order`` B-spline basis values that are non-zero at ``u`` in the knot ``span``
    (``knots[span] <= u < knots[span + 1]``): those of points ``span - order + 1 .. span``.

    The triangular Cox-de Boor recurrence, one degree at a time.
    """
    values = [1.0]
    left = [0.0] * order
    right = [0.0] * order
    for r in range(1, order):
        left[r] = u - knots[span + 1 - r]
        right[r] = knots[span + r] - u
        carry = 0.0
        nxt = []
        for s in range(r):
            share = values[s] / (right[s + 1] + left[r - s])
            nxt.append(carry + right[s + 1] * share)
            carry = left[r - s] * share
        nxt.append(carry)
        values = nxt
    return values


def nurbs_point(points: Sequence[ControlPoint], order: int, u: float) -> tuple[float, float]:
    """The point of a NURBS at parameter ``u`` (``0 <= u < len(points) - order + 1``).

    ``sum(N_i(u) w_i P_i) / sum(N_i(u) w_i)`` with the B-spline basis ``N_i`` of
    :func:`knot_vector`.
    """
    return _Curve(points, order).at(u)


def nurbs_polyline(points: Sequence[ControlPoint], order: int) -> list[tuple[float, float]]:
    """The points LinuxCNC's preview canon feeds to for a NURBS (the start excluded).

    Parameters
    ----------
    points
        Control points (the first is the curve's start), all weights positive.
    order
        NURBS order, ``2 <= order <= len(points)``.

    Returns
    -------
    list of (x, y)
        One point per parameter ``u = h, 2h, ...`` below ``umax = n - order + 2`` with
        ``h = umax / (15 (n + 1))`` (``n + 1`` points; accumulated as LinuxCNC does), then
        the last control point exactly.
    """
    curve = _Curve(points, order)
    count = len(points)
    umax = float(count - order + 1)
    div = count * SAMPLES_PER_POINT
    out: list[tuple[float, float]] = []
    u = 0.0
    while u + umax / div < umax:
        u = u + umax / div
        out.append(curve.at(u))
    out.append((points[-1].x, points[-1].y))
    return out


class _Curve:
    """A NURBS ready for evaluation: knots and the weighted coordinates."""

    __slots__ = ('order', 'last', 'knots', 'wx', 'wy', 'w')

    def __init__(self, points: Sequence[ControlPoint], order: int) -> None:
        self.order = order
        self.last = len(points) - 1
        self.knots = knot_vector(len(points), order)
        self.wx = [p.w * p.x for p in points]
        self.wy = [p.w * p.y for p in points]
        self.w = [p.w for p in points]

    def at(self, u: float) -> tuple[float, float]:
        """The point at ``u``."""
        order = self.order
        # Interior knots are the integers 1 .. n - order + 1: the span is found directly.
        span = min(order - 1 + int(u), self.last)
        first = span - order + 1
        wx, wy, w = self.wx, self.wy, self.w
        sx = sy = sw = 0.0
        for s, v in enumerate(_basis(u, span, order, self.knots)):
            i = first + s
            sx += v * wx[i]
            sy += v * wy[i]
            sw += v * w[i]
        return (sx / sw, sy / sw)


class SplineMixin(InterpreterState):
    """G5, G5.1, G5.2 and G5.3 for :class:`~.interp.Interpreter` (uses its ``pos``,
    ``target``, ``feed``, ``fail``, ``emit``, ``nurbs`` state)."""

    __slots__ = ()

    # -- words --------------------------------------------------------------------------
    def spline_words(self, d: dict[str, str | float], mode: int, dwell: bool) -> None:
        """Refuse the words a spline line does not use (LinuxCNC's word checks)."""
        if dwell:
            self.fail(f'G4 and {_NAMES[mode]} on one line would share the P word', 'G',
                      value=4.0)
        used = SPLINE_WORDS[mode]
        for letter in 'IJKRPQL':
            if letter in d and letter not in used:
                self.fail(f'{letter} word is not used by {_NAMES[mode]}', letter)

    def spline_g_codes(self, motion: int | None, end: bool) -> None:
        """Note the spline G codes of a line (called from ``g_words`` before the line's
        motion mode is set): the mode before it, and a G5.3 to run before the motion."""
        if not self.dialect.g5_splines:
            self.foreign_spline(motion if motion is not None and 50 <= motion <= 52 else 53)
        state = self.nurbs
        if motion is not None and 50 <= motion <= 52:
            state.before = self.motion
            state.motion_line = self.lineno
        if end:
            if motion is not None and motion != 52:
                self.fail('Between G5.2 and G5.3 codes, only additional G5.2 codes are '
                          'allowed (LinuxCNC)', 'G', value=53 / 10)
            state.end_line = self.lineno
            self.pending_lineno = self.lineno

    def foreign_spline(self, code: int):
        """Refuse a G5.x code in a dialect whose control does not have LinuxCNC's splines."""
        name = self.dialect.name
        if name == 'fanuc':
            why = ('there G05/G05.1 select high-speed machining modes (G05.1 Q1: AI contour '
                   'control), not splines')
        else:
            why = f'{self.dialect.control} has no such spline code'
        self.fail(f'{_NAMES[code]} is not simulated in the {name} dialect: {why}; LinuxCNC '
                  'programs with G5.x splines are read with --dialect linuxcnc', 'G',
                  value=code / 10)

    # -- G5 / G5.1 ----------------------------------------------------------------------
    def spline(self, d: dict[str, str | float], mode: int, g9: bool) -> None:
        """A line in a spline motion mode: G5/G5.1 (issued now) or a G5.2 point."""
        if mode == 52:
            self.nurbs_point(d)
            return
        name = _NAMES[mode]
        code = mode / 10
        state = self.nurbs
        if not ('X' in d or 'Y' in d or 'Z' in d):
            self.fail(f'{name} needs an end point (X and/or Y; LinuxCNC: All axes missing '
                      'with motion code)', 'G', value=code)
        self.spline_checks(d, name, code)
        if 'Z' in d:
            self.fail('Splines may not have motion in Z (LinuxCNC)', 'Z')
        start = self.pos
        end = self.target(d)
        if mode == 51:
            if 'I' not in d or 'J' not in d:
                self.fail('Must specify both I and J with G5.1 (LinuxCNC)',
                          'I' if 'I' in d else ('J' if 'J' in d else 'G'), value=(
                              None if 'I' in d or 'J' in d else code))
            i, j = self.spline_offset(d, 'I', 'J')
            inner = [ControlPoint(start[0] + i, start[1] + j, 1.0)]
        else:
            if ('I' in d) != ('J' in d):
                self.fail('Must specify both I and J, or neither (LinuxCNC)',
                          'I' if 'I' in d else 'J')
            if 'I' in d:
                i, j = self.spline_offset(d, 'I', 'J')
            else:       # minus the previous G5's P, Q (LinuxCNC's cycle_i/cycle_j)
                i, j = self.rotated_offset(self.cycle_memory.i, self.cycle_memory.j)
            if 'P' not in d or 'Q' not in d:
                self.fail('Must specify both P and Q with G5 (LinuxCNC)',
                          'P' if 'P' in d else ('Q' if 'Q' in d else 'G'),
                          value=None if 'P' in d or 'Q' in d else code)
            p = self.num('P', d['P']) * self.scale
            q = self.num('Q', d['Q']) * self.scale
            rp, rq = self.rotated_offset(p, q)
            inner = [ControlPoint(start[0] + i, start[1] + j, 1.0),
                     ControlPoint(end[0] + rp, end[1] + rq, 1.0)]
            self.cycle_memory = replace(self.cycle_memory, i=-p, j=-q)
        points = state.points
        if points:
            self.warnings.append(
                f'{self.file}:{self.lineno}: {name} also takes the {len(points)} control '
                f'points of the G5.2 of line {state.first_line} that no G5.3 ended (as '
                'LinuxCNC does)')
        points = points + [ControlPoint(start[0], start[1], 1.0), *inner,
                           ControlPoint(end[0], end[1], 1.0)]
        state.points = []
        self.spline_feeds(points, 4 if mode == 50 else 3, d, g9)
        # LinuxCNC's convert_spline leaves the motion mode as it was.
        self.motion = state.before

    def spline_checks(self, d: dict[str, str | float], name: str, code: float) -> None:
        """LinuxCNC's checks of G5/G5.1 before their geometry: no cutter compensation, a
        feed rate, the XY plane."""
        # Right after G40 (the exit still pending) the first feed is the exit move, as the
        # reference runs it: from the offset point to the curve's first point.
        if self.comp.active:
            self.fail('Cannot convert spline with cutter radius compensation (LinuxCNC)', 'G',
                      value=code)
        if self.inverse_time:
            if 'F' not in d:
                self.fail(f'{name} in inverse time (G93) needs F on its line (LinuxCNC: F '
                          'word missing with inverse time arc move)', 'G', value=code)
        if self.plane != 17:
            self.fail(f'Splines must be in the XY plane (LinuxCNC): G{self.plane} is in '
                      'force', 'G', value=code)
        if self.series:
            self.end_series()

    def spline_offset(self, d: dict[str, str | float], la: str, lb: str) -> tuple[float, float]:
        """A control-point offset [m] from two words (turned with a rotated system)."""
        a = self.num(la, d[la]) * self.scale
        b = self.num(lb, d[lb]) * self.scale
        return self.rotated_offset(a, b)

    def rotated_offset(self, a: float, b: float) -> tuple[float, float]:
        """An XY offset [m] of the program frame in machine axes (G10 L2 R rotation)."""
        if self.rotated:
            return self.coords.rotate(a, b)
        return a, b

    # -- G5.2 / G5.3 --------------------------------------------------------------------
    def nurbs_point(self, d: dict[str, str | float]) -> None:
        """A G5.2 line: collect its control point (or the first point's weight, the
        order); nothing moves until G5.3."""
        state = self.nurbs
        points = state.points
        has_x = 'X' in d
        if has_x != ('Y' in d):
            self.fail('You must specify both X and Y coordinates for Control Points '
                      '(LinuxCNC)', 'X' if has_x else 'Y')
        weight = self.num('P', d['P']) if 'P' in d else -1.0
        if not has_x and weight > 0.0 and points:
            self.fail('Can specify P without X and Y only for the first control point '
                      '(LinuxCNC)', 'P')
        if weight <= 0.0 and points:
            if 'P' in d:
                self.fail('Must specify positive weight P for every Control Point '
                          '(LinuxCNC)', 'P')
            self.nurbs_fail('Must specify positive weight P for every Control Point '
                            '(LinuxCNC)', d)
        if self.inverse_time:
            self.nurbs_fail('G5.2 NURBS in inverse time (G93) is not supported: use G94', d)
        if self.comp.active:
            self.nurbs_fail('G5.2 NURBS with cutter radius compensation is not supported '
                            '(LinuxCNC issues it uncompensated)', d)
        if self.series:
            self.end_series()
        fresh = state.motion_line == self.lineno and state.before != 52
        if fresh and points:
            self.warnings.append(
                f'{self.file}:{self.lineno}: the {len(points)} control points of the G5.2 '
                f'of line {state.first_line} were never ended by G5.3: dropped (as LinuxCNC '
                'does)')
            points = state.points = []
        if not points:
            if has_x and weight <= 0.0:
                self.fail('the first G5.2 control point needs a positive weight P (LinuxCNC '
                          'reads a missing P as weight -1 here)', 'P' if 'P' in d else 'X')
            x, y, _ = self.pos
            points.append(ControlPoint(x, y, 1.0 if has_x or weight <= 0.0 else weight))
            state.order = 3
            state.first_line = self.lineno
        if 'L' in d:
            order = self.num('L', d['L'])
            if order != int(order) or order < 0:
                self.fail('L (the NURBS order) must be a whole number', 'L')
            if order > MAX_ORDER:
                self.fail(f'NURBS order L{order:g} is above {MAX_ORDER}, the highest '
                          'supported', 'L')
            if order > 3:
                state.order = int(order)
        if has_x:
            if len(points) >= MAX_CONTROL_POINTS:
                self.fail(f'more than {MAX_CONTROL_POINTS} control points in one NURBS '
                          f'(G5.2 of line {state.first_line})', 'X')
            x, y, _ = self.target(d)
            points.append(ControlPoint(x, y, weight))
        if 'Z' in d and 'G5.2 Z' not in self.warned:
            self.warned.add('G5.2 Z')
            self.warnings.append(f'{self.file}:{self.lineno}: Z words on G5.2 control points '
                                 'are ignored (as LinuxCNC ignores them)')

    def nurbs_fail(self, msg: str, d: dict[str, str | float]):
        """Fail at the G5.2 word of the line, else at its first axis word, else at P/L."""
        if self.nurbs.motion_line == self.lineno:
            self.fail(msg, 'G', value=5.2)
        letter = next(c for c in 'XYZPL' if c in d)
        self.fail(msg, letter)

    def nurbs_end(self, d: dict[str, str | float]) -> None:
        """G5.3: issue the NURBS collected since G5.2; no motion mode is left in force."""
        state = self.nurbs
        before = state.before if state.motion_line == self.lineno else self.motion
        if before != 52:
            self.fail('Cannot use G5.3 without G5.2 first (LinuxCNC)', 'G', value=5.3)
        if self.inverse_time:
            self.fail('G5.2 NURBS in inverse time (G93) is not supported: use G94', 'G',
                      value=5.3)
        if 'X' in d or 'Y' in d or 'Z' in d:
            self.fail('G5.3 ends a NURBS: give its control points on the G5.2 lines before '
                      'it, not on the G5.3 line', self.first_axis(d))
        points = state.points
        if len(points) < state.order:
            self.fail('You must specify a number of control points at least equal to the '
                      f'order L = {state.order} (LinuxCNC; {len(points)} given)', 'G',
                      value=5.3)
        state.points = []
        self.spline_feeds(points, state.order, d, False)
        self.motion = None
        state.before = None

    # -- output -------------------------------------------------------------------------
    def spline_feeds(self, points: list[ControlPoint], order: int, d: dict[str, str | float],
                     g9: bool) -> None:
        """Emit the straight feeds of a NURBS (at the current Z) and move there."""
        path = nurbs_polyline(points, order)
        start = self.pos
        z = start[2]
        ends = [(x, y, z) for x, y in path]
        lengths = []
        prev = start
        for end in ends:
            lengths.append(math.dist(prev, end))
            prev = end
        feed = self.feed
        if not feed or self.inverse_time:
            # G93 (G5/G5.1 only): the whole curve takes 1/F minutes; G94 without a feed
            # rate: refused as G1, or at the machine's limits with a warning under
            # allow_no_feed (LinuxCNC's preview accepts it)
            feed = self.feed_for(d, math.fsum(lengths), True)
        exact = self.exact or g9
        line = self.lineno
        prev = start
        for end, length in zip(ends, lengths):
            self.emit(make_move(MoveKind.LINEAR, line, prev, end, feed_m_s=feed,
                                exact_stop=exact, length_m=length))
            prev = end
        self.pos = prev

    def nurbs_close(self) -> None:
        """End of the program: a G5.2 curve that no G5.3 ended is dropped (warned)."""
        state = self.nurbs
        if state.points:
            self.warnings.append(
                f'{self.file}:{state.first_line}: the {len(state.points)} control points of '
                'this G5.2 were never ended by G5.3: dropped (as LinuxCNC does)')
            state.points = []
