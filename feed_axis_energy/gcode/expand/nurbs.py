"""The spline memory of the interpreter: NURBS control points and the G5.x modes in force.

Data only, shared by :mod:`.splines` (which fills and runs it) and the interpreter's state.
"""
from __future__ import annotations

from typing import NamedTuple

__all__ = ['ControlPoint', 'NurbsState']


class ControlPoint(NamedTuple):
    """A NURBS control point: machine X, Y [m] and its weight."""

    x: float
    y: float
    w: float


class NurbsState:
    """The spline memory of the interpreter (LinuxCNC's one list of control points).

    Attributes
    ----------
    points
        Control points collected by G5.2 lines (machine coordinates [m]).
    order
        NURBS order of the curve being collected (3, or the last L above 3).
    first_line
        Line of the G5.2 that started ``points`` (for warnings).
    before
        Motion mode in force before the line with a spline G code (``motion_line``).
    motion_line
        Line whose G words included G5, G5.1 or G5.2.
    end_line
        Line with G5.3 (run after the line's modes, before its motion).
    """

    __slots__ = ('points', 'order', 'first_line', 'before', 'motion_line', 'end_line')

    def __init__(self) -> None:
        self.points: list[ControlPoint] = []
        self.order = 3
        self.first_line = 0
        self.before: int | None = None
        self.motion_line = -1
        self.end_line = -1
