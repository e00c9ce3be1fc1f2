"""What a parsed program does, summed in one pass: counts, path lengths, dwell, bounding box.

The figures are the ones the reference interpreter's summary (LinuxCNC's rs274ngc driven
headless, ``shared/tools/run_oracle.py``) gives for a program, counted the same way, so the
two can be compared:

* every canonical call counts once, zero-length moves included (LinuxCNC issues them);
  arcs are not counted as feed moves; a G4 dwell and a canned-cycle dwell count as dwells;
  a G33.1 rigid tap, in and back, is one call (``Move.tap_return`` marks the way back);
* the feed path is the XYZ length of feed moves plus arcs, an arc or helix taken as
  ``hypot(|sweep| * (r_start + r_end) / 2, axial travel)``; the traverse path is the XYZ
  length of rapids;
* the bounding box holds the start point and every point the tool visits, an arc by its
  exact axis-aligned extremes (the angles that are multiples of 90 degrees within its
  sweep, the radius interpolated linearly along the sweep for a spiral);
* the final position is the end of the last move (the start point without moves);
* rotary travel is ``|dA| + |dB| + |dC|`` in degrees over all moves, a rotary move one that
  turns a rotary axis (``Move.rot_end``);
* the nominal feed time is the sum of length / feed over feed moves and arcs, without
  acceleration or rapids: the XYZ length, or the rotary angle of a pure rotary move (its feed
  is then an angular speed); a move without a feed rate (``inf``) adds nothing.

Positions are the moves' own (machine coordinates, metres). The module is pure and
streaming: :class:`MoveStats` takes moves one at a time and keeps a fixed amount of state.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import cast, Iterable, Sequence

import numpy as np

from .program import Move, MoveKind

__all__ = ['ProgramStats', 'MoveStats', 'summarize', 'arc_geometry', 'arc_extremes']

Vec3 = tuple[float, float, float]

_TWO_PI = 2.0 * math.pi
_HALF_PI = 0.5 * math.pi
# In-plane axes (first, second) and normal of G17 (XY), G18 (ZX) and G19 (YZ): each triple
# is right-handed, so a positive sweep is counter-clockwise seen from the normal's tip.
_PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}


@dataclass(frozen=True)
class ProgramStats:
    """Summary of a program's moves (SI units, machine coordinates).

    Attributes
    ----------
    n_feed_moves, n_traverses, n_arcs, n_dwells, n_stops
        Counts of G1-type feed moves, rapids, arcs (G2/G3), dwells and stops.
    feed_length_m, traverse_length_m
        XYZ path length of feed moves and arcs, and of rapids [m].
    dwell_s
        Sum of the dwell times [s].
    final_position
        Tool position after the last move [m].
    bbox_min, bbox_max
        Corners of the axis-aligned box of every visited point [m]; ``None`` when the
        program never moves (dwells and stops do not count as moves).
    rotary_travel_deg, n_rotary_moves
        Sum of ``|dA| + |dB| + |dC|`` [deg] and number of moves that turn a rotary axis.
    nominal_feed_time_s
        Sum of length / feed over feed moves and arcs [s] (module docstring).
    """

    n_feed_moves: int
    n_traverses: int
    n_arcs: int
    n_dwells: int
    n_stops: int
    feed_length_m: float
    traverse_length_m: float
    dwell_s: float
    final_position: Vec3
    bbox_min: Vec3 | None
    bbox_max: Vec3 | None
    rotary_travel_deg: float = 0.0
    n_rotary_moves: int = 0
    nominal_feed_time_s: float = 0.0

    @property
    def n_motions(self) -> int:
        """Moves that change (or could change) the position: feeds, rapids and arcs."""
        return self.n_feed_moves + self.n_traverses + self.n_arcs


def arc_geometry(move: Move) -> tuple[tuple[int, int, int], float, float, float, float]:
    """Return the in-plane geometry of an arc move.

    Parameters
    ----------
    move
        An ``ARC_CW`` or ``ARC_CCW`` move with its ``center``.

    Returns
    -------
    tuple
        ``((a, b, n), theta0, sweep, r0, r1)``: the plane's first, second and normal axis
        indices, the start angle [rad], the signed sweep [rad] (negative for G2), and the
        start and end radius [m]. The sweep is the move's ``sweep_rad`` when it carries
        one; otherwise it is derived as the planner does (start == end in the plane is a
        full circle, plus ``turns`` extra revolutions).
    """
    a, b, n = _PLANE_AXES[move.plane]
    c = cast(Vec3, move.center)   # an arc move always has its centre
    sa, sb = move.start[a] - c[a], move.start[b] - c[b]
    ea, eb = move.end[a] - c[a], move.end[b] - c[b]
    theta0 = math.atan2(sb, sa)
    sweep = getattr(move, 'sweep_rad', None)
    if sweep is None:
        ang = math.atan2(sa * eb - sb * ea, sa * ea + sb * eb)
        raw = ang % _TWO_PI if move.kind == MoveKind.ARC_CCW else (-ang) % _TWO_PI
        if raw < 1e-9:
            raw = _TWO_PI
        raw += _TWO_PI * max(int(move.turns), 0)
        sweep = raw if move.kind == MoveKind.ARC_CCW else -raw
    return (a, b, n), theta0, float(sweep), math.hypot(sa, sb), math.hypot(ea, eb)


def arc_extremes(move: Move) -> list[Vec3]:
    """Return the points of an arc where an in-plane coordinate is extreme.

    Parameters
    ----------
    move
        An arc move.

    Returns
    -------
    list of tuple
        Points strictly inside the sweep at angles that are multiples of 90 degrees (at
        most 4 per revolution, so a long helix gives up to ``4 * (turns + 1)`` points);
        with the start and end points they bound the arc.
    """
    (a, b, n), theta0, sweep, r0, r1 = arc_geometry(move)
    if sweep == 0.0:
        return []
    lo, hi = (theta0, theta0 + sweep) if sweep > 0 else (theta0 + sweep, theta0)
    c = cast(Vec3, move.center)   # an arc move always has its centre
    out: list[Vec3] = []
    # One revolution holds all four extremes: more turns only repeat them.
    k = math.ceil(lo / _HALF_PI)
    last = math.floor(hi / _HALF_PI)
    if last - k > 4:
        last = k + 4
    while k <= last:
        ang = k * _HALF_PI
        f = (ang - theta0) / sweep
        if 0.0 < f < 1.0:
            r = r0 + (r1 - r0) * f
            p = [0.0, 0.0, 0.0]
            p[a] = c[a] + r * math.cos(ang)
            p[b] = c[b] + r * math.sin(ang)
            p[n] = move.start[n] + (move.end[n] - move.start[n]) * f
            out.append((p[0], p[1], p[2]))
        k += 1
    return out


def _length(start: Vec3, end: Vec3) -> float:
    """Length [m] of a straight move, computed as :meth:`MoveStats.add_straight` computes it
    with numpy (squares added in axis order, then the root), so both give the same bits."""
    dx = end[0] - start[0]
    dy = end[1] - start[1]
    dz = end[2] - start[2]
    return math.sqrt((dx * dx + dy * dy) + dz * dz)


class MoveStats:
    """Accumulate :class:`ProgramStats` over a stream of moves.

    Parameters
    ----------
    start
        Tool position before the first move [m] (part of the box once the tool moves).
    """

    def __init__(self, start: Vec3 = (0.0, 0.0, 0.0)) -> None:
        self.start = cast(Vec3, tuple(float(v) for v in start))
        self.position: Vec3 = self.start
        self.counts = {k: 0 for k in MoveKind}
        self.feed_length_m = 0.0
        self.traverse_length_m = 0.0
        self.dwell_s = 0.0
        self.lo: list[float] | None = None
        self.hi: list[float] | None = None
        self.rotary_rad = 0.0
        self.n_rotary = 0
        self.nominal_s = 0.0

    def _timed(self, move: Move, length: float) -> None:
        """Rotary travel and nominal time of a feed move or arc of XYZ ``length`` [m]."""
        rs, re_ = move.rot_start, move.rot_end
        if rs is not None and re_ is not None and rs != re_:
            self.n_rotary += 1
            self.rotary_rad += abs(re_[0] - rs[0]) + abs(re_[1] - rs[1]) + abs(re_[2] - rs[2])
            if length < 1e-12 and move.kind != MoveKind.RAPID:
                length = math.dist(rs, re_)
        feed = move.feed_m_s
        if move.kind != MoveKind.RAPID and 0.0 < feed < math.inf:
            self.nominal_s += length / feed

    def _grow(self, p: Vec3) -> None:
        lo: list[float]
        hi: list[float]
        lo, hi = self.lo, self.hi  # type: ignore[assignment]  # add() sets the box first
        for i in range(3):
            v = p[i]
            if v < lo[i]:
                lo[i] = v
            elif v > hi[i]:
                hi[i] = v

    def add(self, move: Move) -> None:
        """Count one move.

        Parameters
        ----------
        move
            The next move of the program.
        """
        kind = move.kind
        if not move.tap_return:
            self.counts[kind] += 1
        if kind == MoveKind.DWELL:
            self.dwell_s += move.dwell_s
            return
        if kind == MoveKind.STOP:
            return
        if self.lo is None:
            self.lo = list(self.position)
            self.hi = list(self.position)
        self._grow(move.start)
        if kind == MoveKind.RAPID:
            length = _length(move.start, move.end)
            self.traverse_length_m += length
        elif kind == MoveKind.LINEAR:
            length = _length(move.start, move.end)
            self.feed_length_m += length
        else:
            length = move.length_m
            self.feed_length_m += length
            for p in arc_extremes(move):
                self._grow(p)
        self._timed(move, length)
        self._grow(move.end)
        self.position = move.end

    def add_straight(self, moves: Sequence[Move], start: np.ndarray, end: np.ndarray,
                     rapid: np.ndarray) -> None:
        """Count a run of feeds and rapids (no arcs, dwells or stops) given as arrays.

        Parameters
        ----------
        moves
            The moves, in order.
        start, end
            Their start and end points [m], ``(n, 3)``.
        rapid
            True for the rapids, ``(n,)``.
        """
        if not moves:
            return
        n_rapid = int(np.count_nonzero(rapid))
        self.counts[MoveKind.RAPID] += n_rapid
        self.counts[MoveKind.LINEAR] += len(moves) - n_rapid
        d = end - start
        # the length as add() computes it, bit for bit (_length: squares added in axis
        # order, one rounding each), added one by one as add() does (sum() adds in order)
        dist = np.sqrt((d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2])
        self.traverse_length_m = sum(dist[rapid].tolist(), self.traverse_length_m)
        self.feed_length_m = sum(dist[~rapid].tolist(), self.feed_length_m)
        for m, length in zip(moves, dist.tolist()):
            self._timed(m, length)
        if self.lo is None:
            self.lo = list(self.position)
            self.hi = list(self.position)
        low = np.minimum(start.min(axis=0), end.min(axis=0)).tolist()
        high = np.maximum(start.max(axis=0), end.max(axis=0)).tolist()
        self.lo = [min(a, b) for a, b in zip(self.lo, low)]
        self.hi = [max(a, b) for a, b in zip(cast('list[float]', self.hi), high)]
        self.position = moves[-1].end

    def result(self) -> ProgramStats:
        """Return the summary of the moves added so far.

        Returns
        -------
        ProgramStats
            Counts, lengths, dwell total, final position and bounding box.
        """
        c = self.counts
        return ProgramStats(
            n_feed_moves=c[MoveKind.LINEAR], n_traverses=c[MoveKind.RAPID],
            n_arcs=c[MoveKind.ARC_CW] + c[MoveKind.ARC_CCW], n_dwells=c[MoveKind.DWELL],
            n_stops=c[MoveKind.STOP], feed_length_m=self.feed_length_m,
            traverse_length_m=self.traverse_length_m, dwell_s=self.dwell_s,
            final_position=cast(Vec3, tuple(self.position)),
            bbox_min=None if self.lo is None else cast(Vec3, tuple(self.lo)),
            bbox_max=None if self.hi is None else cast(Vec3, tuple(self.hi)),
            rotary_travel_deg=math.degrees(self.rotary_rad), n_rotary_moves=self.n_rotary,
            nominal_feed_time_s=self.nominal_s)


def summarize(moves: Iterable[Move], *, start: Vec3 = (0.0, 0.0, 0.0)) -> ProgramStats:
    """Summarize a program's moves in one pass.

    Parameters
    ----------
    moves
        The moves in order (a list, a :class:`~.program.Program`'s ``moves`` or an
        iterator).
    start
        Tool position before the first move [m].

    Returns
    -------
    ProgramStats
        See :class:`MoveStats`.
    """
    acc = MoveStats(start)
    add = acc.add
    for move in moves:
        add(move)
    return acc.result()
