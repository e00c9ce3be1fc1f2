"""Corner geometry of cutter radius compensation (pure functions for :mod:`.cutter`).

Where the offset paths of two moves meet at a concave corner, as LinuxCNC 2.9 computes it
(``convert_straight_comp2`` / ``convert_arc_comp2`` in ``interp_convert.cc``), and the
sweep of an arc (``find_turn`` in ``interp_find.cc``). Points are (u, v) in the plane of
compensation; ``turn`` is LinuxCNC's arc count: +n counter-clockwise, -n clockwise.
"""
from __future__ import annotations

import math

__all__ = ['CornerError', 'arc_sweep', 'find_turn', 'tool_inside', 'arc_then_line',
           'line_then_arc', 'arc_then_arc']

Point = tuple[float, float]
_PI = math.pi
_HALF_PI = 0.5 * math.pi
_TWO_PI = 2.0 * math.pi
_GOUGE = "makes a corner the compensated tool can't fit in without gouging"


class CornerError(ValueError):
    """The tool cannot reach the corner (the caller turns it into a placed GcodeError)."""


def find_turn(x1: float, y1: float, cx: float, cy: float, turn: int, x2: float,
              y2: float) -> float:
    """Signed sweep [rad] from (x1, y1) to (x2, y2) about (cx, cy); 0 when ``turn`` is 0."""
    if turn == 0:
        return 0.0
    alpha = math.atan2(y1 - cy, x1 - cx)
    beta = math.atan2(y2 - cy, x2 - cx)
    if turn > 0:
        if beta <= alpha:
            beta += _TWO_PI
        return beta - alpha + (turn - 1) * _TWO_PI
    if alpha <= beta:
        alpha += _TWO_PI
    return beta - alpha + (turn + 1) * _TWO_PI


def arc_sweep(start: Point, end: Point, centre: Point, turn: int) -> float:
    """Signed sweep [rad] of an arc as the reference's canon draws it.

    An end within 1e-12 rad of the start is a full turn (so ``turn`` = +-1 with start ==
    end is a full circle); a sweep within 1e-9 (relative) of whole turns is made exact.
    """
    d = (math.atan2(end[1] - centre[1], end[0] - centre[0])
         - math.atan2(start[1] - centre[1], start[0] - centre[0]))
    d = (d if turn > 0 else -d) % _TWO_PI
    if d < 1e-12:
        d = _TWO_PI
    sweep = d + (abs(turn) - 1) * _TWO_PI
    whole = round(sweep / _TWO_PI)
    if whole >= 1 and abs(sweep / _TWO_PI - whole) < 1e-9 * whole:
        sweep = whole * _TWO_PI
    return sweep if turn > 0 else -sweep


def tool_inside(left: bool, turn: int) -> bool:
    """True when the tool runs on the centre side of the arc (LinuxCNC TOOL_INSIDE_ARC)."""
    return (left and turn > 0) or (not left and turn < 0)


def arc_then_line(*, left: bool, radius: float, centre: Point, end: Point, turn: int,
                  corner: Point, target: Point) -> Point:
    """Concave corner from a compensated arc to a line: the new end of the arc.

    Parameters
    ----------
    left, radius
        Compensation side (G41) and tool radius.
    centre, end, turn
        The compensated arc held back: centre, end point, LinuxCNC turn.
    corner, target
        The programmed corner (start of the line) and the line's programmed end.
    """
    c1, c2 = centre
    oldrad = math.hypot(c2 - end[1], c1 - end[0])
    if oldrad == 0.0:
        raise CornerError(f'Arc to straight motion {_GOUGE}')
    base = math.atan2(target[1] - corner[1], target[0] - corner[0])
    theta = base + _HALF_PI if turn > 0 else base - _HALF_PI
    phi = math.atan2(c2 - corner[1], c1 - corner[0])
    inside = tool_inside(left, turn)
    d = (oldrad + radius if inside else oldrad - radius) * math.cos(theta - phi)
    ratio = (d - radius if inside else d + radius) / oldrad
    if not -1.0 <= ratio <= 1.0:
        raise CornerError(f'Arc to straight motion {_GOUGE}')
    sign = -1.0 if (turn > 0) == inside else 1.0
    ang = sign * math.acos(ratio) + theta + _PI
    return c1 + oldrad * math.cos(ang), c2 + oldrad * math.sin(ang)


def line_then_arc(*, left: bool, radius: float, beta: float, theta: float, arc_r: float,
                  centre: Point, turn: int) -> Point:
    """Concave corner from a line to an arc: the point on the arc's offset circle.

    ``beta`` is the corner angle and ``theta`` the direction of the line's end as
    ``convert_arc_comp2`` computes them; ``arc_r`` the programmed arc radius.
    """
    rise = arc_r * math.sin(beta - _HALF_PI)
    if arc_r == 0.0:
        raise CornerError(f'Line to arc motion {_GOUGE}')
    if tool_inside(left, turn):
        dist = arc_r - radius
        ratio = (rise + radius) / dist
        _check(ratio)
        ang = theta + math.asin(ratio) if turn > 0 else theta - math.asin(ratio)
    else:
        dist = arc_r + radius
        ratio = (rise - radius) / dist
        _check(ratio)
        ang = theta + _PI - math.asin(ratio) if turn > 0 else theta + _PI + math.asin(ratio)
    return centre[0] + dist * math.cos(ang), centre[1] + dist * math.sin(ang)


def arc_then_arc(*, left: bool, radius: float, prev_centre: Point, prev_end: Point,
                 prev_turn: int, arc_r: float, centre: Point, turn: int) -> Point:
    """Concave corner between two arcs: where their offset circles meet."""
    p1, p2 = prev_centre
    oldrad = math.hypot(p2 - prev_end[1], p1 - prev_end[0])
    newrad = arc_r - radius if tool_inside(left, turn) else arc_r + radius
    arc_cc = math.hypot(p2 - centre[1], p1 - centre[0])
    if oldrad == 0.0 or arc_cc == 0.0:
        raise CornerError('Arc to arc motion is invalid because the arcs have the same centre')
    a = (oldrad * oldrad + arc_cc * arc_cc - newrad * newrad) / (2.0 * oldrad * arc_cc)
    if not -1.0 <= a <= 1.0:
        raise CornerError(f'Arc to arc motion {_GOUGE}')
    pullback = math.acos(a)
    cc_dir = math.atan2(centre[1] - p2, centre[0] - p1)
    if tool_inside(left, prev_turn):
        ang = cc_dir + pullback if turn > 0 else cc_dir - pullback
    else:
        ang = cc_dir - pullback if turn > 0 else cc_dir + pullback
    return p1 + oldrad * math.cos(ang), p2 + oldrad * math.sin(ang)


def _check(ratio: float) -> None:
    if not -1.0 <= ratio <= 1.0:
        raise CornerError('Arc move in concave corner cannot be reached by the tool without '
                          'gouging')
