"""The canonical interface between the interpreter and the planner, and the arc rules.

LinuxCNC's interpreter talks to its motion planner through a small set of canonical calls
(``STRAIGHT_TRAVERSE``, ``STRAIGHT_FEED``, ``ARC_FEED``, ``DWELL``, ``PROGRAM_STOP`` in
``canon.hh``); here they build :class:`~..program.Move` values in machine coordinates [m]
with the path length, the signed sweep of arcs and the source line. Like LinuxCNC, a
programmed move of zero length is still issued (the planner drops it).

One full-circle rule for parser and planner: an arc's sweep is the angle from start to
end taken the arc's way round; an end within :data:`FULL_TURN_EPS_RAD` of the start angle
is a full turn (this is how the reference's canonical arc is measured). The sweep travels
with the move (``Move.sweep_rad``), so the planner never decides it again.

Arc tolerances, LinuxCNC 2.9 (``interp_internal.hh``; behaviour checked with its
interpreter): the radius to the end may differ from the radius to the start by
``CENTER_ARC_RADIUS_TOLERANCE`` (in program units), or by more as long as the difference
is within :data:`SPIRAL_RELATIVE_TOLERANCE` of the radius, but never by more than 100
times the absolute tolerance. Radii below ``RADIUS_TOLERANCE`` are zero. An R-form arc
may fall short of reaching its end point by ``RADIUS_TOLERANCE``.
"""
from __future__ import annotations

import math

from .program import Move, MoveKind

__all__ = ['straight_traverse', 'straight_feed', 'arc_feed', 'dwell', 'stop', 'arc_sweep_rad',
           'arc_length', 'radius_error', 'radius_tolerance_m', 'centre_tolerance_m',
           'CENTER_ARC_RADIUS_TOLERANCE_INCH', 'CENTER_ARC_RADIUS_TOLERANCE_MM',
           'RADIUS_TOLERANCE_INCH', 'RADIUS_TOLERANCE_MM', 'SPIRAL_RELATIVE_TOLERANCE',
           'FULL_TURN_EPS_RAD']

Vec3 = tuple[float, float, float]

# LinuxCNC 2.9, src/emc/rs274ngc/interp_internal.hh (program units).
CENTER_ARC_RADIUS_TOLERANCE_INCH = 2 * 0.001 * math.sqrt(2.0)
CENTER_ARC_RADIUS_TOLERANCE_MM = 2 * 0.01 * math.sqrt(2.0)
RADIUS_TOLERANCE_INCH = 0.00005
RADIUS_TOLERANCE_MM = RADIUS_TOLERANCE_INCH * 25.4
SPIRAL_RELATIVE_TOLERANCE = 0.001
# An end angle this close to the start angle is a whole turn (cutter_corners.arc_sweep).
FULL_TURN_EPS_RAD = 1e-12

_INF = float('inf')
_INCH_M = 0.0254
# Plane -> (first in-plane axis, second in-plane axis, normal axis), right-handed.
_PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}


def centre_tolerance_m(units_m: float) -> float:
    """LinuxCNC's centre-format radius tolerance [m] in the program's unit system."""
    if units_m == _INCH_M:
        return CENTER_ARC_RADIUS_TOLERANCE_INCH * _INCH_M
    return CENTER_ARC_RADIUS_TOLERANCE_MM * 1e-3


def radius_tolerance_m(units_m: float) -> float:
    """LinuxCNC's zero-radius / R-reach tolerance [m] in the program's unit system."""
    if units_m == _INCH_M:
        return RADIUS_TOLERANCE_INCH * _INCH_M
    return RADIUS_TOLERANCE_MM * 1e-3


def radius_error(r0: float, r1: float, tolerance_m: float) -> bool:
    """True when start and end radius [m] differ more than LinuxCNC allows.

    ``tolerance_m`` is the absolute tolerance (:func:`centre_tolerance_m`); beyond it the
    relative difference must stay within :data:`SPIRAL_RELATIVE_TOLERANCE`, and beyond 100
    times it nothing is accepted.
    """
    err = abs(r1 - r0)
    if err > 100.0 * tolerance_m:
        return True
    return err > tolerance_m and err > SPIRAL_RELATIVE_TOLERANCE * max(r0, r1)


def arc_sweep_rad(sa: float, sb: float, ea: float, eb: float, turn: int) -> float:
    """Signed sweep [rad] from the start vector ``(sa, sb)`` to the end vector ``(ea, eb)``
    (from the centre) of an arc of LinuxCNC rotation ``turn``: the angle taken the arc's way
    round, a whole turn if it is below :data:`FULL_TURN_EPS_RAD`, plus ``|turn| - 1`` turns.
    (The interpreter's arc inlines this.)"""
    ang = math.atan2(sa * eb - sb * ea, sa * ea + sb * eb)
    sweep = (ang if turn > 0 else -ang) % (2.0 * math.pi)
    if sweep < FULL_TURN_EPS_RAD:
        sweep = 2.0 * math.pi
    sweep += (abs(turn) - 1) * 2.0 * math.pi
    return sweep if turn > 0 else -sweep


def arc_length(sweep: float, r0: float, r1: float, dz: float) -> float:
    """Length [m] of a helical spiral arc: mean radius times sweep, with the normal rise."""
    return math.hypot(abs(sweep) * 0.5 * (r0 + r1), dz)


def straight_traverse(line: int, start: Vec3, end: Vec3, *, exact_stop: bool = False) -> Move:
    """G0 (and the rapids of cycles and G28/G30): at the machine's rapid limits."""
    return Move(kind=MoveKind.RAPID, line=line, start=start, end=end, feed_m_s=_INF,
                exact_stop=exact_stop, length_m=math.dist(start, end))


def straight_feed(line: int, start: Vec3, end: Vec3, feed_m_s: float, *,
                  exact_stop: bool = False) -> Move:
    """G1 (and the feeds of cycles) at ``feed_m_s`` [m/s]."""
    return Move(kind=MoveKind.LINEAR, line=line, start=start, end=end, feed_m_s=feed_m_s,
                exact_stop=exact_stop, length_m=math.dist(start, end))


def arc_feed(line: int, start: Vec3, end: Vec3, centre: tuple[float, float], *, plane: int,
             turn: int, feed_m_s: float, sweep: float, length_m: float,
             exact_stop: bool = False) -> Move:
    """G2/G3: ``centre`` in the plane's (first, second) axes [m]; ``turn`` as LinuxCNC's
    ARC_FEED rotation (+n counter-clockwise, -n clockwise, n - 1 extra full turns);
    ``sweep``/``length_m`` from :func:`arc_sweep_rad` and :func:`arc_length`."""
    a, b, n = _PLANE_AXES[plane]
    c = [0.0, 0.0, 0.0]
    c[a] = centre[0]
    c[b] = centre[1]
    c[n] = start[n]
    return Move(kind=MoveKind.ARC_CCW if turn > 0 else MoveKind.ARC_CW, line=line,
                start=start, end=end, feed_m_s=feed_m_s, exact_stop=exact_stop,
                center=(c[0], c[1], c[2]), plane=plane, turns=abs(turn) - 1,
                length_m=length_m, sweep_rad=sweep)


def dwell(line: int, position: Vec3, seconds: float) -> Move:
    """G4 (and the dwells of cycles): stand still for ``seconds``."""
    return Move(kind=MoveKind.DWELL, line=line, start=position, end=position,
                dwell_s=seconds)


def stop(line: int, position: Vec3) -> Move:
    """M0/M1/M2/M30 and G88's stop: come to rest."""
    return Move(kind=MoveKind.STOP, line=line, start=position, end=position)
