"""The per-move geometry of :class:`.cutter.CutterComp`: entry, straight and arc moves
under cutter radius compensation (LinuxCNC 2.9's ``convert_straight_comp1/2`` and
``convert_arc_comp1/2`` in ``interp_convert.cc``), and the queue entries they make.

A mixin: the state (radius, side, queue, current and programmed points) and the queue
handling (``_uvw``, ``_set_endpoint``, ``_dequeue``, ``_raise``) live in
:class:`.cutter.CutterComp`.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import cast, NoReturn, TYPE_CHECKING

from .cutter_corners import (arc_then_arc, arc_then_line, CornerError, find_turn, line_then_arc,
                             tool_inside)
from ..program import Move, MoveKind

if TYPE_CHECKING:
    from abc import abstractmethod

    Vec3 = tuple[float, float, float]

    class CutterState:
        """What :class:`CompMoves` uses of :class:`.cutter.CutterComp` (declarations for the
        type checker; at run time the mixin's base is ``object``)."""

        left: bool
        radius: float
        first: bool
        prog: list[float]
        cur: list[float]
        queue: list[QueuedLine | QueuedArc | Move]

        @abstractmethod
        def _raise(self, message: str, letter: str) -> NoReturn: ...

        @abstractmethod
        def _uvw(self, p: tuple[float, float, float]) -> list[float]: ...

        @abstractmethod
        def _xyz(self, u: float, v: float, w: float) -> tuple[float, float, float]: ...

        @abstractmethod
        def _emit_line(self, kind: MoveKind, src: Move,
                       end: tuple[float, float, float]) -> None: ...

        @abstractmethod
        def _emit_arc(self, src: Move, end_uvw: list[float], centre: tuple[float, float],
                      turn: int) -> None: ...

        @abstractmethod
        def _set_endpoint(self, u: float, v: float) -> None: ...

        @abstractmethod
        def _dequeue(self) -> None: ...

        @abstractmethod
        def _flush_at(self, u: float, v: float) -> None: ...
else:
    CutterState = object        # the declarations are for the type checker only

__all__ = ['CompMoves', 'QueuedLine', 'QueuedArc', 'CORNER_TOLERANCE_RAD']

# LinuxCNC interp_internal.hh: TOLERANCE_CONCAVE_CORNER, TOLERANCE_EQUAL.
CORNER_TOLERANCE_RAD = 0.05
TOL_EQUAL = 0.0001
_PI = math.pi
_HALF_PI = 0.5 * math.pi
_TWO_PI = 2.0 * math.pi
TOO_BIG = 'tool too big for the arc'


@dataclass(slots=True)
class QueuedLine:
    kind: MoveKind
    source: Move
    end: list[float]            # (u, v, w) plane coordinates
    direction: tuple[float, float]


@dataclass(slots=True)
class QueuedArc:
    source: Move
    end: list[float]
    centre: tuple[float, float]
    turn: int                   # LinuxCNC: +n CCW, -n CW, n = 1 + extra full turns
    original: float             # programmed sweep [rad] (0: never checked)


class CompMoves(CutterState):
    """Entry, straight and arc moves of :class:`.cutter.CutterComp` (a mixin)."""

    __slots__ = ()

    def _turn(self, move: Move) -> int:
        return (move.turns + 1) * (1 if move.kind == MoveKind.ARC_CCW else -1)

    # -- straight moves ------------------------------------------------------------------
    def _straight_first(self, move: Move) -> None:
        r = self.radius
        cx, cy, _ = self.cur
        px, py, pz = self._uvw(move.end)
        if math.hypot(px - cx, py - cy) <= r:
            self._raise('Length of cutter compensation entry move is not greater than the '
                        f'tool radius ({r * 1e3:.4f} mm)', 'G')
        alpha = math.atan2(py - cy, px - cx) + (_HALF_PI if self.left else -_HALF_PI)
        end = [px + r * math.cos(alpha), py + r * math.sin(alpha), pz]
        self._set_endpoint(cx, cy)
        self.queue.append(QueuedLine(move.kind, move, end, (math.cos(alpha), math.sin(alpha))))
        self.first = False
        self.cur = list(end)
        self.prog = [px, py, pz]

    def _straight_next(self, move: Move) -> None:
        r = self.radius
        cx, cy, cz = self.cur
        opx, opy, _ = self.prog
        px, py, pz = self._uvw(move.end)
        small = CORNER_TOLERANCE_RAD
        if px == opx and py == opy:
            end = [cx, cy, pz]
            self.queue.append(QueuedLine(move.kind, move, list(end), (0.0, 0.0)))
            self.cur = end
            self.prog = [px, py, pz]
            return
        theta = math.atan2(cy - opy, cx - opx)
        alpha = math.atan2(py - opy, px - opx)
        if self.left:
            if theta < alpha:
                theta += _TWO_PI
            beta = theta - alpha - _HALF_PI
            gamma = _HALF_PI
        else:
            if alpha < theta:
                alpha += _TWO_PI
            beta = alpha - theta - _HALF_PI
            gamma = -_HALF_PI
        end = [px + r * math.cos(alpha + gamma), py + r * math.sin(alpha + gamma), pz]
        mid = (opx + r * math.cos(alpha + gamma), opy + r * math.sin(alpha + gamma))
        head = self.queue[0] if self.queue else None
        concave = beta < -small or beta > _PI + small or (
            beta > _PI - small and isinstance(head, QueuedArc)
            and ((not self.left and head.turn > 0) or (self.left and head.turn < 0)))
        if not concave and beta > small:
            # Convex corner: an arc of the tool radius around it (a rapid for G0).
            self._flush_at(cx, cy)
            if move.kind == MoveKind.LINEAR:
                self._emit_arc(move, [mid[0], mid[1], cz], (opx, opy),
                               -1 if self.left else 1)
            else:
                self._emit_line(MoveKind.RAPID, move, self._xyz(mid[0], mid[1], cz))
            self._set_endpoint(*mid)
        elif concave:
            if not isinstance(head, QueuedArc):
                half = 0.5 * (beta + _PI)
                if half == 0.0:
                    self._raise('Zero degree inside corner is invalid for cutter '
                                'compensation', 'G')
                back = r / math.tan(half)
                self._flush_at(cx + back * math.cos(theta + gamma),
                               cy + back * math.sin(theta + gamma))
            else:
                try:
                    mid = arc_then_line(left=self.left, radius=r, centre=head.centre,
                                        end=(head.end[0], head.end[1]), turn=head.turn,
                                        corner=(opx, opy), target=(px, py))
                except CornerError as err:
                    self._raise(str(err), 'G')
                self._flush_at(*mid)
        else:
            self._dequeue()
            self._set_endpoint(cx, cy)
        self.queue.append(QueuedLine(move.kind, move, list(end), (px - opx, py - opy)))
        self.cur = end
        self.prog = [px, py, pz]

    # -- arcs ------------------------------------------------------------------------------
    def _arc_first(self, move: Move) -> None:
        r = self.radius
        cx, cy, _ = self.cur
        ex, ey, ez = self._uvw(move.end)
        ccx, ccy, _ = self._uvw(cast('Vec3', move.center))     # an arc has its centre
        turn = self._turn(move)
        if math.hypot(ex - cx, ey - cy) <= r:
            self._raise('Radius of cutter compensation entry arc is not greater than the '
                        f'tool radius ({r * 1e3:.4f} mm)', 'G')
        arc_r = math.hypot(ccx - cx, ccy - cy)
        if arc_r <= r and tool_inside(self.left, turn):
            self._raise(f'{TOO_BIG}: arc radius {arc_r * 1e3:.4f} mm is not greater than '
                        f'the tool radius {r * 1e3:.4f} mm', 'G')
        if tool_inside(self.left, turn):
            gamma = math.atan2(ccy - ey, ccx - ex)
        else:
            gamma = math.atan2(ey - ccy, ex - ccx)
        self.prog = [ex, ey, ez]
        ex += r * math.cos(gamma)
        ey += r * math.sin(gamma)
        half_chord = math.hypot(cy - ey, cx - ex) / 2.0
        ab = math.atan2(ccy - ey, ccx - ex)
        cos_a = math.cos(math.atan2(cy - ey, cx - ex) - ab)
        if abs(cos_a) < TOL_EQUAL:
            self._raise(f'{TOO_BIG}: the compensated entry arc has no centre', 'G')
        c_len = half_chord / cos_a
        ncx = ex + c_len * math.cos(ab)
        ncy = ey + c_len * math.sin(ab)
        self.queue.append(QueuedArc(move, [ex, ey, ez], (ncx, ncy), turn,
                                    find_turn(cx, cy, ncx, ncy, turn, ex, ey)))
        self.first = False
        self.cur = [ex, ey, ez]

    def _arc_next(self, move: Move) -> None:
        r = self.radius
        small = CORNER_TOLERANCE_RAD
        opx, opy, _ = self.prog
        cx, cy, cz = self.cur
        ex, ey, ez = self._uvw(move.end)
        ccx, ccy, _ = self._uvw(cast('Vec3', move.center))     # an arc has its centre
        turn = self._turn(move)
        ccw = turn > 0
        arc_r = math.hypot(ccx - ex, ccy - ey)
        theta = math.atan2(cy - opy, cx - opx) + (-_HALF_PI if self.left else _HALF_PI)
        delta = math.atan2(ccy - opy, ccx - opx)
        alpha = delta - _HALF_PI if ccw else delta + _HALF_PI
        beta = theta - alpha if self.left else alpha - theta
        if beta > 1.5 * _PI:
            beta -= _TWO_PI
        elif beta < -_HALF_PI:
            beta += _TWO_PI
        inside = tool_inside(self.left, turn)
        if inside:
            gamma = math.atan2(ccy - ey, ccx - ex)
            if arc_r <= r:
                self._raise(f'{TOO_BIG}: arc radius {arc_r * 1e3:.4f} mm is not greater '
                            f'than the tool radius {r * 1e3:.4f} mm', 'G')
        else:
            gamma = math.atan2(ey - ccy, ex - ccx)
            delta += _PI
        new_end = [ex + r * math.cos(gamma), ey + r * math.sin(gamma), ez]
        original = find_turn(opx, opy, ccx, ccy, turn, ex, ey)
        head = self.queue[0] if self.queue else None
        if (beta < -small or beta > _PI + small
                or (abs(beta - _PI) < small and not inside)):
            try:
                if not isinstance(head, QueuedArc):
                    mid = line_then_arc(left=self.left, radius=r, beta=beta, theta=theta,
                                        arc_r=arc_r, centre=(ccx, ccy), turn=turn)
                else:
                    mid = arc_then_arc(left=self.left, radius=r, prev_centre=head.centre,
                                       prev_end=(head.end[0], head.end[1]),
                                       prev_turn=head.turn, arc_r=arc_r,
                                       centre=(ccx, ccy), turn=turn)
            except CornerError as err:
                self._raise(str(err), 'G')
            self._flush_at(*mid)
        elif beta > small:
            mid = (opx + r * math.cos(delta), opy + r * math.sin(delta))
            self._dequeue()
            self._emit_arc(move, [mid[0], mid[1], cz], (opx, opy), -1 if self.left else 1)
            self._set_endpoint(*mid)
        else:
            self._dequeue()
            self._set_endpoint(cx, cy)
        self.queue.append(QueuedArc(move, new_end, (ccx, ccy), turn, original))
        self.prog = [ex, ey, ez]
        self.cur = new_end
