"""Planner input: moves -> segments with their geometry, path limits and junction caps.

Steps 1 to 3 of the method in :mod:`.trajectory` up to the look-ahead: :class:`Collector`
turns moves into segments (lines, arcs/helices, rests; empty moves dropped, continuity
checked), :func:`segment_geometry` gives each its length, tangents and arc parameters,
:func:`path_limits` its path speed, acceleration and jerk limits, and
:func:`junction_speeds` the speed caps at the junctions. Used by :func:`.trajectory.plan`
and the streaming planner (:mod:`.stream`).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import chain
import math
from typing import cast

import numpy as np

from ..errors import PlanningError
from ..gcode import Move, MoveKind, Program, PROGRAM_AXES, ROTARY_AXES

PLAN_AXES = PROGRAM_AXES + ROTARY_AXES
"""Columns of the planner's points: X, Y, Z, then A, B, C [rad] when the machine has a
rotary axis (``dims`` 6; else only X, Y, Z)."""
_TWO_PI = 2.0 * math.pi
_MIN_LENGTH_M = 1e-12      # shorter moves are dropped (their exact stop is kept)
_GAP_TOLERANCE_M = 1e-6    # allowed mismatch between a move's start and the previous end
# arc plane -> (first in-plane axis, second in-plane axis, normal axis), right-handed
PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}
_LINE, ARC, REST = 0, 1, 2
# plain ints: attribute look-ups on the enum class are slow in a per-move loop
_DWELL, _STOP = int(MoveKind.DWELL), int(MoveKind.STOP)
_ARC_CW, _ARC_CCW = int(MoveKind.ARC_CW), int(MoveKind.ARC_CCW)


@dataclass
class SegmentTable:
    """Per-segment arrays (a segment is a move with length, a dwell or a stop)."""

    kind: np.ndarray        # _LINE, ARC or REST
    move: list[Move]
    p0: np.ndarray          # (m, dims) start point (X, Y, Z [m], then A, B, C [rad])
    p1: np.ndarray          # (m, dims) end point
    dwell: np.ndarray       # rest duration [s]
    stop_after: np.ndarray  # bool: must be at rest at the end


class Collector:
    """Turns moves into segments one at a time (streaming form of :func:`collect_segments`).

    Drops empty moves, turns dwells/stops into rests and checks continuity. The stop flag
    of the newest segment may still be set by the next move (a dwell, a stop or a dropped
    exact-stop move), so only segments before the newest one are final.

    With ``dims`` 6 (a machine with rotary axes) the points carry A, B, C [rad] after X, Y,
    Z: a move's ``rot_start``/``rot_end``, else the rotary position so far. A pure rotary
    move (no XYZ travel) is parameterised by its angle, so it starts and ends at rest.
    """

    def __init__(self, file: str, *, dims: int = 3) -> None:
        self.file = file
        self.dims = dims
        self.rot: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.kinds: list[int] = []
        self.moves: list[Move] = []
        self.p0: list[tuple[float, ...]] = []
        self.p1: list[tuple[float, ...]] = []
        self.dwell: list[float] = []
        self.stop: list[bool] = []
        self.here: tuple[float, float, float] | None = None
        self.first_start: tuple[float, float, float] | None = None

    def add(self, mv: Move) -> None:
        """Take one move."""
        if self.first_start is None:
            self.first_start = cast('tuple[float, float, float]', tuple(mv.start))
        k = int(mv.kind)
        stop = self.stop
        if k == _DWELL or k == _STOP:
            pos: tuple[float, ...] = self.here if self.here is not None else mv.start
            if self.dims > 3:
                pos = tuple(pos) + self.rot
            if stop:
                stop[-1] = True
            self.kinds.append(REST)
            self.moves.append(mv)
            self.p0.append(pos)
            self.p1.append(pos)
            self.dwell.append(max(float(mv.dwell_s), 0.0) if k == _DWELL else 0.0)
            stop.append(True)
            return
        start = mv.start
        end = mv.end
        here = self.here
        if here is not None and start != here and max(
                abs(start[0] - here[0]), abs(start[1] - here[1]),
                abs(start[2] - here[2])) > _GAP_TOLERANCE_M:
            msg = f'move starts at {start} but the previous move ended at {here}'
            raise PlanningError(msg, file=self.file, line=mv.line)
        is_arc = k == _ARC_CW or k == _ARC_CCW
        if is_arc and mv.center is None:
            raise PlanningError('arc move without a centre', file=self.file, line=mv.line)
        self.here = end
        rs = mv.rot_start
        if self.dims > 3:
            self.add_rotary(mv, is_arc)
            return
        if rs is not None and mv.rot_end != rs:
            msg = 'move turns a rotary axis, which the machine does not have'
            raise PlanningError(msg, file=self.file, line=mv.line)
        if not is_arc and math.dist(start, end) < _MIN_LENGTH_M:
            if mv.exact_stop and stop:
                stop[-1] = True
            return
        self.kinds.append(ARC if is_arc else _LINE)
        self.moves.append(mv)
        self.p0.append(start)
        self.p1.append(end)
        self.dwell.append(0.0)
        stop.append(bool(mv.exact_stop))

    def add_rotary(self, mv: Move, is_arc: bool) -> None:
        """The move's segment with its rotary columns (``dims`` 6)."""
        stop = self.stop
        rs = mv.rot_start if mv.rot_start is not None else self.rot
        re_ = mv.rot_end if mv.rot_end is not None else rs
        self.rot = re_
        pure = not is_arc and math.dist(mv.start, mv.end) < _MIN_LENGTH_M
        if pure and math.dist(rs, re_) < _MIN_LENGTH_M:
            if mv.exact_stop and stop:
                stop[-1] = True
            return
        if pure and stop:
            stop[-1] = True         # a path in rad meets a path in m only at rest
        self.kinds.append(ARC if is_arc else _LINE)
        self.moves.append(mv)
        self.p0.append(mv.start + rs)
        self.p1.append(mv.end + re_)
        self.dwell.append(0.0)
        stop.append(bool(mv.exact_stop) or pure)

    def __len__(self) -> int:
        return len(self.kinds)

    def segments(self, *, final: bool) -> SegmentTable:
        """Arrays of the segments collected so far (``final``: the program has ended)."""
        if final and self.stop:
            self.stop[-1] = True
        m = len(self.kinds)
        n = self.dims
        # fromiter over the flattened points: half the time of asarray on a list of tuples
        return SegmentTable(kind=np.asarray(self.kinds, dtype=np.int8), move=list(self.moves),
                            p0=np.fromiter(chain.from_iterable(self.p0), float,
                                           count=n * m).reshape(m, n),
                            p1=np.fromiter(chain.from_iterable(self.p1), float,
                                           count=n * m).reshape(m, n),
                            dwell=np.asarray(self.dwell, dtype=float),
                            stop_after=np.asarray(self.stop, bool))

    def drop(self, count: int) -> None:
        """Forget the first ``count`` segments (they have been planned)."""
        for lst in (self.kinds, self.moves, self.p0, self.p1, self.dwell, self.stop):
            del lst[:count]


def collect_segments(program: Program, *, dims: int = 3) -> SegmentTable:
    """Walk the moves once: drop empty moves, turn dwells/stops into rests, check continuity."""
    collector = Collector(program.file, dims=dims)
    for mv in program.moves:
        collector.add(mv)
    return collector.segments(final=True)


@dataclass
class SegmentGeometry:
    length: np.ndarray
    u: np.ndarray            # (m, 3) line direction (0 for rests and arcs)
    tan0: np.ndarray         # (m, 3) unit tangent at the start
    tan1: np.ndarray         # (m, 3) unit tangent at the end
    centre: np.ndarray       # (m, 3)
    perm: np.ndarray         # (m, 3) axis indices (in-plane a, b, normal c) for arcs
    plane_ref: np.ndarray    # (m, 3) arc centre a, b and start normal coordinate c
    theta0: np.ndarray
    sweep: np.ndarray
    r0: np.ndarray
    kr: np.ndarray           # dr / dtheta
    kc: np.ndarray           # dc / dtheta (helix)
    r_min: np.ndarray


def segment_geometry(seg: SegmentTable, file: str) -> SegmentGeometry:
    m, dims = seg.p0.shape
    d = seg.p1 - seg.p0
    length = np.zeros(m)
    u = np.zeros((m, dims))
    is_line = seg.kind == _LINE
    dl = d[is_line]
    ln = np.linalg.norm(dl[:, :3], axis=1)
    if dims > 3:
        # a pure rotary move: its path is the angle [rad] (F in degrees per minute)
        ln = np.where(ln < _MIN_LENGTH_M, np.linalg.norm(dl[:, 3:], axis=1), ln)
    length[is_line] = ln
    u[is_line] = dl / ln[:, None]
    tan0 = u.copy()
    tan1 = u.copy()
    centre = seg.p0.copy()
    perm = np.tile(np.arange(3), (m, 1))
    plane_ref = np.zeros((m, 3))
    theta0 = np.zeros(m)
    sweep = np.zeros(m)
    r0 = np.zeros(m)
    kr = np.zeros(m)
    kc = np.zeros(m)
    r_min = np.full(m, np.inf)
    arcs = np.nonzero(seg.kind == ARC)[0]
    if arcs.size:
        mv = [seg.move[i] for i in arcs]
        try:
            perm[arcs] = [PLANE_AXES[x.plane] for x in mv]
        except KeyError as err:
            bad_move = next(x for x in mv if x.plane not in PLANE_AXES)
            msg = f'arc plane must be 17, 18 or 19, got {bad_move.plane!r}'
            raise PlanningError(msg, file=file, line=bad_move.line) from err
        centre[arcs, :3] = [x.center for x in mv]
        ccw = np.array([int(x.kind) == _ARC_CCW for x in mv])
        turns = np.array([max(int(x.turns), 0) for x in mv], dtype=float)
        s = np.take_along_axis(seg.p0[arcs], perm[arcs], axis=1)
        e = np.take_along_axis(seg.p1[arcs], perm[arcs], axis=1)
        c = np.take_along_axis(centre[arcs], perm[arcs], axis=1)
        plane_ref[arcs] = np.stack([c[:, 0], c[:, 1], s[:, 2]], axis=1)
        ra = np.hypot(s[:, 0] - c[:, 0], s[:, 1] - c[:, 1])
        rb = np.hypot(e[:, 0] - c[:, 0], e[:, 1] - c[:, 1])
        bad = np.nonzero((ra < _MIN_LENGTH_M) | (rb < _MIN_LENGTH_M))[0]
        if bad.size:
            msg = 'arc with zero radius (centre on the start or end point)'
            raise PlanningError(msg, file=file, line=mv[bad[0]].line)
        th0 = np.arctan2(s[:, 1] - c[:, 1], s[:, 0] - c[:, 0])
        th1 = np.arctan2(e[:, 1] - c[:, 1], e[:, 0] - c[:, 0])
        raw = np.where(ccw, th1 - th0, th0 - th1) % _TWO_PI
        # start == end in the plane is a full circle
        raw = np.where(raw < 1e-9, _TWO_PI, raw) + _TWO_PI * turns
        sw = np.where(ccw, raw, -raw)
        # The parser's sweep wins where it gave one (one full-circle rule for both).
        given = np.array([np.nan if x.sweep_rad is None else x.sweep_rad for x in mv])
        sw = np.where(np.isnan(given), sw, given)
        theta0[arcs] = th0
        sweep[arcs] = sw
        r0[arcs] = ra
        kr[arcs] = (rb - ra) / sw
        kc[arcs] = (e[:, 2] - s[:, 2]) / sw
        r_min[arcs] = np.minimum(ra, rb)
        rm = 0.5 * (ra + rb)
        length[arcs] = np.abs(sw) * np.sqrt(rm ** 2 + kr[arcs] ** 2 + kc[arcs] ** 2)
        for which, th, rr in ((tan0, th0, ra), (tan1, th0 + sw, rb)):
            cs, sn = np.cos(th), np.sin(th)
            # d p / d theta in (a, b, c), times the direction of travel
            loc = np.stack([kr[arcs] * cs - rr * sn, kr[arcs] * sn + rr * cs, kc[arcs]], axis=1)
            loc *= np.sign(sw)[:, None]
            loc /= np.linalg.norm(loc, axis=1)[:, None]
            out = np.zeros((arcs.size, 3))
            np.put_along_axis(out, perm[arcs], loc, axis=1)
            which[arcs, :3] = out
        if dims > 3:
            # rotary axes turn linearly along the helix [rad/m]
            rate = d[arcs, 3:] / length[arcs][:, None]
            for which in (u, tan0, tan1):
                which[arcs, 3:] = rate
    return SegmentGeometry(length=length, u=u, tan0=tan0, tan1=tan1, centre=centre, perm=perm,
                           plane_ref=plane_ref,
                           theta0=theta0, sweep=sweep, r0=r0, kr=kr, kc=kc, r_min=r_min)


def line_speed_limits(u: np.ndarray | Sequence[float],
                      axis_vmax: np.ndarray | Sequence[float]) -> np.ndarray:
    """Path speed [m/s] of straight moves at which the first axis reaches its speed limit.

    ``min_k vmax_k / |u_k|`` over the program axes; an axis that does not move sets no limit.
    The one rule for the planner's lines and rapids and for :mod:`.sweep`'s rapid override.

    Parameters
    ----------
    u
        Unit directions, shape ``(3,)`` or ``(m, 3)``.
    axis_vmax
        Speed limit [m/s] of each program axis, shape ``(3,)`` (``inf`` where absent).

    Returns
    -------
    numpy.ndarray
        Shape ``()`` or ``(m,)``; ``inf`` when no moving axis has a limit.
    """
    with np.errstate(divide='ignore'):
        return np.min(np.asarray(axis_vmax, dtype=float) / np.abs(np.asarray(u, dtype=float)),
                      axis=-1)


def path_limits(seg: SegmentTable, geo: SegmentGeometry, lim: np.ndarray,
                file: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Path speed, acceleration and jerk limits per segment; ``lim`` is (3 kinds, 3 axes)."""
    m, dims = seg.p0.shape
    feed = np.array([x.feed_m_s if x.feed_m_s > 0 else math.inf for x in seg.move])
    missing = ~np.isfinite(lim[0])
    moved = np.abs(seg.p1 - seg.p0) > _GAP_TOLERANCE_M
    arcs = np.nonzero(seg.kind == ARC)[0]
    moved[arcs, geo.perm[arcs, 0]] = True       # an arc always moves both in-plane axes
    moved[arcs, geo.perm[arcs, 1]] = True
    bad = np.nonzero(np.any(moved & missing[None, :], axis=1))[0]
    if bad.size:
        mv = seg.move[bad[0]]
        names = [PLAN_AXES[k] for k in range(dims) if missing[k] and moved[bad[0], k]]
        msg = f'move on axis {", ".join(names)} which the machine does not have'
        raise PlanningError(msg, file=file, line=mv.line)

    vmax = np.zeros(m)
    amax = np.ones(m)
    jmax = np.ones(m)
    with np.errstate(divide='ignore'):
        is_line = seg.kind == _LINE
        au = np.abs(geo.u[is_line])
        vmax[is_line] = np.minimum(line_speed_limits(au, lim[0]), feed[is_line])
        amax[is_line] = np.min(lim[1] / au, axis=1)
        jmax[is_line] = np.min(lim[2] / au, axis=1)
        arcs = seg.kind == ARC
        if np.any(arcs):
            pa = geo.perm[arcs]
            in_plane = np.minimum(lim[:, pa[:, 0]], lim[:, pa[:, 1]])   # (3, n_arc)
            rm = geo.r0[arcs] + 0.5 * geo.kr[arcs] * geo.sweep[arcs]
            uc = np.abs(geo.kc[arcs]) / np.sqrt(rm ** 2 + geo.kr[arcs] ** 2 + geo.kc[arcs] ** 2)
            helix = lim[:, pa[:, 2]] / uc                                 # inf when planar
            r = geo.r_min[arcs]
            vmax[arcs] = np.minimum.reduce([
                feed[arcs], in_plane[0], helix[0], np.sqrt(0.5 * in_plane[1] * r),
                np.cbrt(0.5 * in_plane[2] * r * r)])
            amax[arcs] = np.minimum(0.5 * in_plane[1], helix[1])
            jmax[arcs] = np.minimum(0.5 * in_plane[2], helix[2])
            if dims > 3:
                rate = np.abs(geo.u[arcs, 3:])                           # [rad/m]
                for kind, out in enumerate((vmax, amax, jmax)):
                    out[arcs] = np.minimum(out[arcs], np.min(lim[kind, 3:] / rate, axis=1))
    return vmax, amax, jmax


def junction_speeds(seg: SegmentTable, geo: SegmentGeometry, vmax: np.ndarray, amax: np.ndarray,
                    delta: float, axis_acc: np.ndarray, cycle_s: float) -> np.ndarray:
    """Speed caps at the m + 1 segment boundaries before the look-ahead passes.

    ``axis_acc`` holds the acceleration limit of each program axis (``inf`` if absent);
    ``cycle_s`` is the interpolation cycle in which a corner's velocity step happens.
    """
    m = seg.kind.shape[0]
    vj = np.zeros(m + 1)
    if m < 2:
        return vj
    # the corner angle of the XYZ path (rotary axes enter through the velocity step below)
    cos_t = -np.einsum('ij,ij->i', geo.tan1[:-1, :3], geo.tan0[1:, :3])
    sin_half = np.sqrt(np.clip(0.5 * (1.0 - cos_t), 0.0, 1.0))
    a = np.minimum(amax[:-1], amax[1:])
    du = np.abs(geo.tan0[1:] - geo.tan1[:-1])
    with np.errstate(divide='ignore', invalid='ignore'):
        v2 = np.where(sin_half > 1.0 - 1e-12, np.inf,
                      a * delta * sin_half / (1.0 - sin_half))
        # per-axis velocity step of the corner within one cycle: v |du_k| <= a_k T
        v_step = np.min(np.where(du > 0.0, axis_acc * cycle_s / du, np.inf), axis=1)
    v = np.minimum.reduce([np.sqrt(v2), v_step, vmax[:-1], vmax[1:]])
    stop = seg.stop_after[:-1] | (seg.kind[:-1] == REST) | (seg.kind[1:] == REST)
    vj[1:-1] = np.where(stop, 0.0, v)
    return vj
