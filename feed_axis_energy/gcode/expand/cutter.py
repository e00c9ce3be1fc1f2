"""Cutter radius compensation (G41/G42/G40, G41.1/G42.1) as a filter over programmed moves.

A port of the method of LinuxCNC 2.9's interpreter (``convert_straight_comp1/2``,
``convert_arc_comp1/2``, ``convert_cutter_compensation_on/off`` in ``interp_convert.cc``
and the move queue of ``interp_queue.cc``), so that compensated paths agree with the
reference move for move:

* **Entry** (the first move after G41/G42): a straight move ends one tool radius to the
  left (G41) / right (G42) of its programmed end, perpendicular to the move; it must be
  longer than the tool radius (so a Z-only first move is an error, as in LinuxCNC). An arc
  as first move keeps its start (the tool is not yet offset) and is re-centred so it ends
  one radius off the programmed end.
* **Corners** need the next move, so one move (plus any Z-only moves, dwells after it) is
  held back. Concave corner (the tool is inside the turn): the held move is shortened to
  the intersection of the two offset paths (line/line, line/arc, arc/line, arc/arc). Convex
  corner: an arc of the tool radius around the programmed corner is inserted (a straight
  rapid to the new offset point for G0, as LinuxCNC does). Corners within 0.05 rad of
  straight (LinuxCNC's ``TOLERANCE_CONCAVE_CORNER``) need neither.
* **Arcs**: offset by the radius towards or away from the centre; an arc the tool cannot
  fit inside (radius not larger than the tool radius on the concave side) is an error
  ("tool too big for the arc"), as are corners the tool cannot reach without gouging.
* **Exit**: G40 flushes the held moves unchanged; the next move (it must be straight)
  starts from the compensated point and ends at the programmed point.
* G17 (XY) and G18 (ZX, with Z as the first axis as in LinuxCNC); G19 is refused as in
  LinuxCNC. A radius of zero leaves the path unchanged; a negative radius (tool table)
  swaps the side. Moves along the plane normal only pass through at the offset position.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import fields
import math
from typing import Any, cast, NoReturn

from .cutter_corners import arc_sweep, find_turn
from .cutter_moves import CompMoves, QueuedArc, QueuedLine
from ...errors import GcodeError
from ..program import Move, MoveKind

__all__ = ['CutterComp', 'LEFT', 'RIGHT']

Vec3 = tuple[float, float, float]
Fail = Callable[[str, str], NoReturn]

LEFT = 41
RIGHT = 42
_TWO_PI = 2.0 * math.pi
_PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1)}
_ARC_KINDS = (MoveKind.ARC_CW, MoveKind.ARC_CCW)
_HAS_SWEEP = 'sweep_rad' in {f.name for f in fields(Move)}
_GOUGE = 'cannot be reached by the tool without gouging'


class CutterComp(CompMoves):
    """Cutter radius compensation over a stream of programmed moves (machine coords).

    Route every move through :meth:`feed` while :attr:`engaged` is true (also after G40,
    until the exit move has passed); call :meth:`start` for G41/G42 (before the line's
    motion) and :meth:`finish` for G40, M2/M30 or the end of the program.

    Parameters
    ----------
    file
        Program name for errors raised without a ``fail`` callback.
    units_m
        The program's length unit (0.001 for G21, 0.0254 for G20): LinuxCNC's tolerances
        are given per unit system.
    """

    def __init__(self, *, file: str = '<program>', units_m: float = 0.001):
        self.file = file
        self.units_m = units_m
        self.left = True
        self.radius = 0.0
        self.on = False            # G41/G42 in force (even with radius 0)
        self.first = True          # the next move is the entry move
        self.exit_pending = False  # G40 done, the exit move has not come yet
        self.carry = False         # restarted while the tool was still offset
        self.arc_not_allowed = False   # LinuxCNC: the move after G40 must be straight
        self.axes = _PLANE_AXES[17]
        self.plane = 17
        self.prog: list[float] = [0.0, 0.0, 0.0]    # last programmed point (u, v, w)
        self.cur: list[float] = [0.0, 0.0, 0.0]     # compensated tool point (u, v, w)
        self.queue: list[QueuedLine | QueuedArc | Move] = []
        self.endpoint = (0.0, 0.0)
        self.endpoint_valid = False
        self.tool: Vec3 | None = None               # where the emitted moves have got to
        self._out: list[Move] = []
        self._fail: Fail | None = None
        self._line = 0

    # -- public ----------------------------------------------------------------------------
    @property
    def active(self) -> bool:
        """True while G41/G42 is in force (canned cycles and offset changes are refused)."""
        return self.on

    @property
    def engaged(self) -> bool:
        """True while moves must go through :meth:`feed` (comp on, or the exit pending)."""
        return (self.on and self.radius > 0.0) or self.exit_pending or self.arc_not_allowed

    def start(self, side: int, radius_m: float, plane: int, *, fail: Fail | None = None,
              line: int = 0) -> None:
        """Turn compensation on (G41 = ``LEFT`` / G42 = ``RIGHT``).

        Parameters
        ----------
        side
            ``LEFT`` (41) or ``RIGHT`` (42).
        radius_m
            Tool radius [m] (the tool table's diameter / 2, or G41.1/G42.1's D / 2); a
            negative radius swaps the side, zero leaves the path unchanged.
        plane
            17 or 18 (19 is refused as in LinuxCNC).
        fail, line
            Error callback ``fail(message, letter)`` and line for the default one.
        """
        self._begin(fail, line)
        if plane not in _PLANE_AXES:
            self._raise('Radius compensation only allowed in XY or XZ planes (G17, G18), '
                        f'not G{plane}', 'G')
        if self.on:
            self._raise('Cannot turn cutter radius comp on when already on (G40 first)', 'G')
        if side not in (LEFT, RIGHT):
            self._raise(f'cutter compensation side must be G41 or G42, not {side}', 'G')
        if not math.isfinite(radius_m):
            self._raise('tool radius is not a finite number', 'D')
        # After G40 with the exit still to come the tool stays offset (``carry``); otherwise
        # moves bypassed the filter since it was last engaged and the tool is unknown here.
        self.carry = self.exit_pending
        if not self.carry:
            self.tool = None
        self.left = (side == LEFT) != (radius_m < 0.0)
        self.radius = abs(float(radius_m))
        self.plane = plane
        self.axes = _PLANE_AXES[plane]
        self.on = True
        self.first = True
        self.exit_pending = False

    def feed(self, move: Move, *, fail: Fail | None = None) -> list[Move]:
        """Take the next programmed move; return the compensated moves now final.

        Parameters
        ----------
        move
            A programmed move (start = programmed start), any kind.
        fail
            ``fail(message, letter)`` raising the caller's error at the current line.

        Returns
        -------
        list[Move]
            Moves ready for the planner, in order (possibly none: one is held back).
        """
        self._begin(fail, move.line)
        if self.tool is None:
            self.tool = move.start
        moving = move.kind in (MoveKind.RAPID, MoveKind.LINEAR) or move.kind in _ARC_KINDS
        if self.arc_not_allowed and moving:
            if move.kind in _ARC_KINDS:
                self._raise('The move just after exiting cutter compensation mode must be '
                            'straight, not an arc', 'G')
            self.arc_not_allowed = False
        if not (self.on and self.radius > 0.0):
            if self.exit_pending and moving:
                self._exit(move)
            else:
                self._pass(move)
            return self._take()
        if not moving:
            if move.kind == MoveKind.STOP:
                self._flush_at(self.cur[0], self.cur[1])
                self._pass(move)
            elif self.queue:
                self.queue.append(move)
            else:
                self._pass(move)       # nothing held back: no reason to wait (enqueue_DWELL)
            return self._take()
        if move.kind in _ARC_KINDS and move.plane != self.plane:
            self._raise(f'arc in plane G{move.plane} while cutter compensation works in '
                        f'G{self.plane}', 'G')
        if self.first:
            self.cur = self._uvw(move.start)
            self.prog = list(self.cur)
            if move.kind in _ARC_KINDS:
                self._arc_first(move)
            else:
                self._straight_first(move)
        elif move.kind in _ARC_KINDS:
            self._arc_next(move)
        else:
            self._straight_next(move)
        return self._take()

    def finish(self, *, fail: Fail | None = None, line: int = 0) -> list[Move]:
        """G40 (or program end): flush the held moves; the next move is the exit move.

        ``line`` (for errors without ``fail``) defaults to the line of the last move fed.
        """
        self._begin(fail, line or self._line)
        if self.on and self.radius > 0.0 and not self.first:
            self._flush_at(self.cur[0], self.cur[1])
            self.exit_pending = True
            self.arc_not_allowed = True
        elif self.carry:
            self.exit_pending = True   # G40 G41 G40 without motion: still offset
        self._dequeue()
        self.carry = False
        self.on = False
        self.first = True
        return self._take()

    # -- plumbing ------------------------------------------------------------------------
    def _begin(self, fail: Fail | None, line: int) -> None:
        self._fail = fail
        self._line = line

    def _raise(self, message: str, letter: str) -> NoReturn:
        if self._fail is not None:
            self._fail(message, letter)
        raise GcodeError(message, file=self.file, line=self._line, column=1)

    def _take(self) -> list[Move]:
        out, self._out = self._out, []
        return out

    def _uvw(self, p: Vec3) -> list[float]:
        a, b, n = self.axes
        return [p[a], p[b], p[n]]

    def _xyz(self, u: float, v: float, w: float) -> Vec3:
        a, b, n = self.axes
        p = [0.0, 0.0, 0.0]
        p[a], p[b], p[n] = u, v, w
        return (p[0], p[1], p[2])

    def _pass(self, move: Move) -> None:
        """Emit a move unchanged, except that it starts where the tool really is."""
        if move.kind in (MoveKind.DWELL, MoveKind.STOP):
            move = _replace(move, start=self.tool, end=self.tool)
        elif move.start != self.tool:
            move = _replace(move, start=self.tool)
        self._out.append(move)
        self.tool = move.end

    def _exit(self, move: Move) -> None:
        """The first motion after G40: straight from the compensated to the programmed point."""
        length = math.dist(cast(Vec3, self.tool), move.end)    # feed() has set it
        self.exit_pending = False
        if length > 0.0:
            self._out.append(_replace(move, start=self.tool, length_m=length))
            self.tool = move.end

    def _emit_line(self, kind: MoveKind, src: Move, end: Vec3) -> None:
        length = math.dist(cast(Vec3, self.tool), end)         # feed() has set it
        if length == 0.0:
            return
        self._out.append(Move(kind=kind, line=src.line, start=cast(Vec3, self.tool), end=end,
                              feed_m_s=src.feed_m_s, exact_stop=src.exact_stop,
                              length_m=length))
        self.tool = end

    def _emit_arc(self, src: Move, end_uvw: list[float], centre: tuple[float, float],
                  turn: int) -> None:
        start = cast(Vec3, self.tool)                           # feed() has set it
        su, sv, sw = self._uvw(start)
        eu, ev, ew = end_uvw
        cu, cv = centre
        sweep = arc_sweep((su, sv), (eu, ev), centre, turn)
        if (abs(sweep) / _TWO_PI).is_integer():
            eu, ev = su, sv          # full circles start and end at the same point exactly
        r0 = math.hypot(su - cu, sv - cv)
        r1 = math.hypot(eu - cu, ev - cv)
        length = math.hypot(abs(sweep) * 0.5 * (r0 + r1), ew - sw)
        if length == 0.0:
            return
        end = self._xyz(eu, ev, ew)
        extra: dict[str, Any] = {'sweep_rad': sweep} if _HAS_SWEEP else {}
        self._out.append(Move(
            kind=MoveKind.ARC_CCW if turn > 0 else MoveKind.ARC_CW, line=src.line,
            start=start, end=end, feed_m_s=src.feed_m_s,
            exact_stop=src.exact_stop, center=self._xyz(cu, cv, sw), plane=self.plane,
            turns=abs(turn) - 1, length_m=length, **extra))
        self.tool = end

    def _set_endpoint(self, u: float, v: float) -> None:
        self.endpoint = (u, v)
        self.endpoint_valid = True

    def _dequeue(self) -> None:
        """Emit the held moves as they stand (LinuxCNC dequeue_canons)."""
        self.endpoint_valid = False
        for q in self.queue:
            if isinstance(q, QueuedLine):
                self._emit_line(q.kind, q.source, self._xyz(*q.end))
            elif isinstance(q, QueuedArc):
                self._emit_arc(q.source, q.end, q.centre, q.turn)
            else:
                self._pass(q)
        self.queue.clear()

    def _flush_at(self, u: float, v: float) -> None:
        """Move the held moves' end to (u, v), then emit them (move_endpoint_and_flush)."""
        if not self.queue:
            return
        mm = self.units_m == 0.001
        for q in self.queue:
            if isinstance(q, QueuedArc):
                cu, cv = q.centre
                r1 = math.hypot(q.end[0] - cu, q.end[1] - cv)
                r2 = math.hypot(u - cu, v - cv)
                l2 = find_turn(self.endpoint[0], self.endpoint[1], cu, cv, q.turn, u, v)
                if abs(r1 - r2) > 0.01 * self.units_m:
                    self._raise('cutter compensation made an arc with mismatched radii '
                                f'{r1 * 1e3:.4f} and {r2 * 1e3:.4f} mm', 'G')
                # LinuxCNC compares the sweeps [rad] with .0254 (G21) or .001 (G20).
                if (q.original != 0.0 and self.endpoint_valid
                        and abs(l2) > abs(q.original) + (0.0254 if mm else 0.001)):
                    self._raise(f'Arc move in concave corner {_GOUGE}', 'G')
                q.end[0], q.end[1] = u, v
            elif isinstance(q, QueuedLine):
                dot = (q.direction[0] * (u - self.endpoint[0])
                       + q.direction[1] * (v - self.endpoint[1]))
                if self.endpoint_valid and dot < 0.0:
                    what = 'traverse' if q.kind == MoveKind.RAPID else 'feed'
                    self._raise(f'Straight {what} in concave corner {_GOUGE}', 'G')
                q.end[0], q.end[1] = u, v
        self._dequeue()
        self._set_endpoint(u, v)


def _replace(move: Move, **changes) -> Move:
    """A copy of a frozen Move with some fields changed."""
    values = {f.name: getattr(move, f.name) for f in fields(Move)}
    values.update(changes)
    return Move(**values)
