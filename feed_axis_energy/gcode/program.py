"""Parsed NC program: a flat list of moves in machine coordinates (SI units).

This is the contract between :mod:`.gcode` (which produces it) and :mod:`.trajectory`
(which consumes it). Positions are metres in the program's X, Y, Z frame; feeds are m/s.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

__all__ = ['MoveKind', 'Move', 'Program', 'PROGRAM_AXES', 'ROTARY_AXES', 'make_move',
           'straight_move', 'arc_move']

PROGRAM_AXES = ('X', 'Y', 'Z')
ROTARY_AXES = ('A', 'B', 'C')

Vec3 = tuple[float, float, float]


class MoveKind(IntEnum):
    """What a move does."""

    RAPID = 0      # G0: traverse at the machine's rapid limits
    LINEAR = 1     # G1
    ARC_CW = 2     # G2, seen looking down the plane normal (right-handed)
    ARC_CCW = 3    # G3
    DWELL = 4      # G4: stand still for ``dwell_s``
    STOP = 5       # M0/M1/M2/M30: come to rest; M2/M30 also end the program


@dataclass(frozen=True)
class Move:
    """One motion (or pause) of the program.

    Attributes
    ----------
    kind
        The :class:`MoveKind`.
    line
        1-based source line the move comes from (energy is attributed to it).
    start, end
        Tool position before and after the move [m], program X, Y, Z.
    feed_m_s
        Path feed [m/s] requested for the move; ``inf`` for rapids (machine limits apply).
        Under G93 the parser converts the inverse-time F to the feed that finishes on time.
    exact_stop
        True when the path must come to rest at the end of the move (G61 modal, G9, a dwell
        or stop that follows is handled by the planner itself).
    center
        Arc centre [m] (for ARC_CW/ARC_CCW), with the plane-normal coordinate equal to
        ``start``'s; ``None`` otherwise.
    plane
        17, 18 or 19 (XY, ZX, YZ): the arc plane.
    turns
        Number of full extra turns of a helix/arc (0 for an ordinary arc; a full circle
        is start == end in the plane with turns == 0 meaning one revolution).
    dwell_s
        Dwell time [s] for DWELL moves.
    length_m
        Path length [m] (helical arcs included).
    sweep_rad
        Signed sweep of an arc [rad] (counter-clockwise positive in the plane's first and
        second axes, extra turns included), as the parser decided it; ``None``: the planner
        derives it from start, end and ``turns`` (start == end in the plane: full circle).
    tap_return
        True for the way back of a G33.1 rigid tap. RS274NGC issues the way in and back as
        one canonical call (``RIGID_TAP``); the planner runs both moves, the program's
        summary (:mod:`.stats`) counts the pair once, as the reference does.
    rot_start, rot_end
        Rotary axis positions ``(A, B, C)`` [rad, machine coordinates] before and after the
        move, for a move on which a rotary axis turns (the machine declares it, see
        :mod:`.interp.rotary`); ``None`` (the default): no rotary axis turns during the move.
        They turn linearly with the path: with the XYZ length when the move has one (the
        feed is the XYZ path speed), otherwise the move is a pure rotary one and
        ``feed_m_s`` is the angular speed [rad/s] along ``|rot_end - rot_start|``.
    """

    kind: MoveKind
    line: int
    start: Vec3
    end: Vec3
    feed_m_s: float = float('inf')
    exact_stop: bool = False
    center: Vec3 | None = None
    plane: int = 17
    turns: int = 0
    dwell_s: float = 0.0
    length_m: float = 0.0
    sweep_rad: float | None = None
    tap_return: bool = False
    rot_start: Vec3 | None = None
    rot_end: Vec3 | None = None


_NEW = object.__new__
_SET = object.__setattr__
_MOVE_DEFAULTS = {name: f.default for name, f in Move.__dataclass_fields__.items()
                  if name not in ('kind', 'line', 'start', 'end')}
_PLANE = _MOVE_DEFAULTS['plane']
_DWELL = _MOVE_DEFAULTS['dwell_s']


def make_move(kind: MoveKind, line: int, start: Vec3, end: Vec3, **fields) -> Move:
    """``Move(kind, line, start, end, **fields)`` built without the frozen dataclass's
    ``object.__setattr__`` per field (2-3x faster; the parser builds one per block).

    The result equals, hashes and prints as the ``Move`` the constructor makes; ``fields``
    must be names of :class:`Move` fields (unchecked: callers are the parser's hot paths).
    """
    m = _NEW(Move)
    d = m.__dict__
    d.update(_MOVE_DEFAULTS)
    d['kind'] = kind
    d['line'] = line
    d['start'] = start
    d['end'] = end
    d.update(fields)
    return m


def straight_move(kind: MoveKind, line: int, start: Vec3, end: Vec3, feed_m_s: float,
                  exact_stop: bool, length_m: float) -> Move:
    """A RAPID or LINEAR :class:`Move` from positional fields: :func:`make_move` without
    its keyword dictionary and dictionary growth (the field dictionary is built whole, in
    field order; about a third faster than ``make_move``)."""
    m = _NEW(Move)
    _SET(m, '__dict__', {'kind': kind, 'line': line, 'start': start, 'end': end,
                         'feed_m_s': feed_m_s, 'exact_stop': exact_stop, 'center': None,
                         'plane': _PLANE, 'turns': 0, 'dwell_s': _DWELL,
                         'length_m': length_m, 'sweep_rad': None, 'tap_return': False,
                         'rot_start': None, 'rot_end': None})
    return m


def arc_move(kind: MoveKind, line: int, start: Vec3, end: Vec3, feed_m_s: float,
             exact_stop: bool, center: Vec3, plane: int, turns: int, length_m: float,
             sweep_rad: float) -> Move:
    """An ARC_CW or ARC_CCW :class:`Move` from positional fields (as :func:`straight_move`)."""
    m = _NEW(Move)
    _SET(m, '__dict__', {'kind': kind, 'line': line, 'start': start, 'end': end,
                         'feed_m_s': feed_m_s, 'exact_stop': exact_stop, 'center': center,
                         'plane': plane, 'turns': turns, 'dwell_s': _DWELL,
                         'length_m': length_m, 'sweep_rad': sweep_rad, 'tap_return': False,
                         'rot_start': None, 'rot_end': None})
    return m


@dataclass(frozen=True)
class Program:
    """A parsed program: its moves in order and where it came from."""

    file: str
    moves: tuple[Move, ...]
    n_lines: int = 0
    warnings: tuple[str, ...] = field(default_factory=tuple)
