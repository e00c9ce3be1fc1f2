"""Trajectory planner: NC program -> sampled axis motion (path-parameter method).

Method
------
1. *Geometry.* Every move is a curve parameterised by its path length ``s``. Lines are
   ``p0 + u s``. Arcs and helices are ``centre + r(theta) e_r(theta) + c(theta) n`` in the arc
   plane (G17 XY, G18 ZX, G19 YZ) with ``theta = theta0 + sweep s / L``; the radius is
   interpolated linearly from the start to the end radius so that the end point is met
   exactly even when the program's radii differ slightly, and the helix coordinate ``c``
   is linear in ``theta``.
2. *Path limits per move.* A line with unit direction ``u`` gets
   ``v <= min_k vmax_k / |u_k|`` (and ``<= feed``), likewise acceleration and jerk. On an arc
   the direction turns, so the in-plane axes' smallest limits apply: tangential acceleration
   ``<= a/2`` and centripetal ``v^2 / r <= a/2`` (their sum stays inside the axis limit), so
   ``v <= sqrt(a r / 2)``; path jerk ``<= j/2`` and the centripetal jerk ``v^3 / r^2 <= j/2``.
   The helix axis adds ``limit_c / |u_c|``. Rapids (``feed = inf``) use the axis limits only.
3. *Look-ahead.* The speed at each junction is capped by two rules. The junction-deviation
   rule: the speed at which a circular blend that deviates ``corner_tolerance_m`` from the
   corner would reach the smaller path acceleration of the two moves,
   ``v^2 = a delta sin(theta/2) / (1 - sin(theta/2))`` with ``theta`` the angle between the
   reversed incoming and the outgoing tangents (tangent junctions: no cap; reversals: 0).
   The velocity-step rule (see *Corners* below): ``v |du_k| <= a_k T`` for every axis ``k``,
   with ``du = tangent_out - tangent_in`` and ``T`` the control's interpolation cycle
   (``PlannerOptions.cycle_s``, 1 ms by default; independent of the output ``rate_hz``, so
   the planned motion is the same at every sample rate).
   The speed is zero at program start and end, at exact stops and around dwells and stops.
   *Groups* (see :mod:`.lookahead`): junctions between two short blocks (too short to reach
   their own speed limit from rest) that are tangent or nearly so are passed *through*: the
   blocks joined by them form one group, and the group gets one profile over its total length
   with the smallest limits of its blocks, its speed ceiling lowered to the through junctions'
   caps and its acceleration to what each through junction's velocity step leaves of the axis
   limits. All other junctions are *anchors* (stops, sharp corners, ceiling changes).
   A backward and a forward pass then lower every anchor speed to what the neighbouring
   group can reach in its length (closed-form minimum distance, zero acceleration at both
   ends, see :mod:`.profiles`).
4. *Profiles.* Each group gets a seven-phase constant-jerk profile (``profile='jerk'``) or a
   constant-acceleration trapezoid (``profile='trapezoid'``), see :mod:`.profiles`: the
   acceleration is zero at anchors only, so a run of short collinear or nearly tangent blocks
   (CAM polylines) reaches the feed as one long line would, with the acceleration continuous
   across its block boundaries.
5. *Sampling.* The program becomes one table of constant-jerk phases (start time, duration,
   ``s0``, ``v0``, ``a0``, ``j``, group). Uniform sample times are located with
   ``numpy.searchsorted`` and the cubic is evaluated vectorised; the group's ``s`` is mapped
   to the block containing it (a second ``searchsorted`` on the blocks' start lengths) and
   then to axis position, velocity and acceleration per block kind (arcs include the
   centripetal term). The last sample is the program end. A junction inside a group is
   timed by bisection of the group's monotone ``s(t)`` in the phase that contains it.

6. *Corners.* A non-tangent junction passed at speed ``v`` changes the axis velocities by
   ``dv = v (tangent_out - tangent_in)`` within one interpolation cycle ``T``, as on a control
   that limits the per-axis velocity step per cycle (the blend itself is not sampled). The
   look-ahead keeps ``|dv_k| <= a_k T``. In the samples (period ``T_s = 1 / rate_hz``; the
   bounds below are stated for ``T_s = T``, the default) the step is put so that the
   dynamics sees the force that changes the kinetic energy: the sample nearest to the
   junction carries half the step in its velocity (the mean of the velocities just before and
   just after the junction, plus the path's own change) and ``dv / T_s`` in addition to its path
   acceleration. Read with the piecewise-linear (trapezoid) convention, the acceleration is a
   triangle of area ``dv`` and ``vel[i+1] - vel[i] = (acc[i] + acc[i+1]) T / 2`` holds on
   both intervals next to the junction, so ``integral F v dt`` by the trapezoid rule gets the
   kinetic energy change ``m dv (v_in + v_out) / 2`` of the step exactly.

Sampling conventions: ``Motion.acc`` integrates to ``Motion.vel`` by the trapezoid rule,
interval by interval. Inside a phase the acceleration is linear in time (lines), so the rule is
exact; the residuals are ``<= |dj| T^2 / 8`` where the jerk switches inside an interval,
``<= |da| T / 2`` where a trapezoid profile switches acceleration (so its energy balance is
off by up to ``m |da| T |v| / 2`` per switch), ``O(T^3)`` on arcs, and
``<= a_path T |du| / 4`` at a corner. With the jerk profile the path acceleration at an anchor
junction is zero, so the sampled axis acceleration stays within ``a_k + j_k T / 2`` at a
corner sample and the finite-difference acceleration ``(vel[i+1] - vel[i]) / T`` within
``a_k / 2 + 1.5 j_k T`` next to it (plus the centripetal term of an arc at the corner
speed). At a through junction the group's acceleration limit leaves room for the step, so
both stay within ``a_k`` (the trapezoid-rule residual there is ``<= a_group T |du| / 4``).
A corner sample lies up to ``T / 2`` from its junction while its position stays on the path,
so positions and velocities there disagree by up to ``|dv| T / 2``. With the
trapezoid profile (infinite jerk) the step and a full path acceleration can fall into the
same cycle: up to ``2 a_k`` (sampled) or ``1.5 a_k``
(finite difference). Junctions less than a cycle apart put their steps into the same or
neighbouring samples; the sums are still consistent, but the per-cycle bound then holds per
junction, not per sample.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from itertools import chain
import math

import numpy as np

from .errors import PlanningError
from .motion import Motion
from .lookahead import (BlockGroups, group_blocks, look_ahead, path_cumsum,
                        through_acceleration)
from .profiles import plan_profiles, ProfilePhases
from .program import Move, MoveKind, Program, PROGRAM_AXES

__all__ = ['AxisLimits', 'PlannerOptions', 'plan', 'line_speed_limits']

_TWO_PI = 2.0 * math.pi
_MIN_LENGTH_M = 1e-12      # shorter moves are dropped (their exact stop is kept)
_GAP_TOLERANCE_M = 1e-6    # allowed mismatch between a move's start and the previous end
_CHUNK = 1 << 18           # samples evaluated per vectorised block
_JUNCTION_BISECT = 60      # bisection steps for the time of a junction inside a group
# arc plane -> (first in-plane axis, second in-plane axis, normal axis), right-handed
_PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}
_LINE, _ARC, _REST = 0, 1, 2
# plain ints: attribute look-ups on the enum class are slow in a per-move loop
_DWELL, _STOP = int(MoveKind.DWELL), int(MoveKind.STOP)
_ARC_CW, _ARC_CCW = int(MoveKind.ARC_CW), int(MoveKind.ARC_CCW)


@dataclass(frozen=True)
class AxisLimits:
    """Kinematic limits of one machine axis.

    Attributes
    ----------
    velocity_m_s, acceleration_m_s2, jerk_m_s3
        Maximum speed [m/s], acceleration [m/s^2] and jerk [m/s^3]; all must be > 0.
    """

    velocity_m_s: float
    acceleration_m_s2: float
    jerk_m_s3: float

    def __post_init__(self) -> None:
        for name in ('velocity_m_s', 'acceleration_m_s2', 'jerk_m_s3'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and value > 0.0 and math.isfinite(value)):
                msg = f'AxisLimits.{name} must be a finite number > 0, got {value!r}'
                raise ValueError(msg)


@dataclass(frozen=True)
class PlannerOptions:
    """Options of :func:`plan`.

    Attributes
    ----------
    rate_hz
        Sample rate of the output [Hz]; default 1000 (1 ms, a typical interpolation cycle).
    profile
        ``'jerk'`` (default; seven-phase S-curve, jerk-limited) or ``'trapezoid'``
        (constant acceleration phases, jerk limit ignored).
    corner_tolerance_m
        Path deviation allowed at a non-tangent corner for the junction-deviation rule [m];
        default 1e-4 (0.1 mm). 0 makes every non-tangent corner an exact stop.
    cycle_s
        Interpolation cycle of the control [s], default 1 ms: a corner's per-axis velocity
        step must fit into one cycle (``v |du_k| <= a_k cycle_s``). A property of the
        control, not of the output, so the planned motion does not depend on ``rate_hz``.
    """

    rate_hz: float = 1000.0
    profile: str = 'jerk'
    corner_tolerance_m: float = 0.0001
    cycle_s: float = 0.001

    def __post_init__(self) -> None:
        if not (self.rate_hz > 0.0 and math.isfinite(self.rate_hz)):
            msg = f'PlannerOptions.rate_hz must be > 0, got {self.rate_hz!r}'
            raise ValueError(msg)
        if self.profile not in ('jerk', 'trapezoid'):
            msg = f"PlannerOptions.profile must be 'jerk' or 'trapezoid', got {self.profile!r}"
            raise ValueError(msg)
        if not (self.cycle_s > 0.0 and math.isfinite(self.cycle_s)):
            msg = f'PlannerOptions.cycle_s must be > 0, got {self.cycle_s!r}'
            raise ValueError(msg)
        if not self.corner_tolerance_m >= 0.0:
            value = self.corner_tolerance_m
            msg = f'PlannerOptions.corner_tolerance_m must be >= 0, got {value!r}'
            raise ValueError(msg)


@dataclass
class _Segments:
    """Per-segment arrays (a segment is a move with length, a dwell or a stop)."""

    kind: np.ndarray        # _LINE, _ARC or _REST
    move: list[Move]
    p0: np.ndarray          # (m, 3) start point
    p1: np.ndarray          # (m, 3) end point
    dwell: np.ndarray       # rest duration [s]
    stop_after: np.ndarray  # bool: must be at rest at the end


class _Collector:
    """Turns moves into segments one at a time (streaming form of :func:`_collect`).

    Drops empty moves, turns dwells/stops into rests and checks continuity. The stop flag
    of the newest segment may still be set by the next move (a dwell, a stop or a dropped
    exact-stop move), so only segments before the newest one are final.
    """

    def __init__(self, file: str) -> None:
        self.file = file
        self.kinds: list[int] = []
        self.moves: list[Move] = []
        self.p0: list[tuple[float, float, float]] = []
        self.p1: list[tuple[float, float, float]] = []
        self.dwell: list[float] = []
        self.stop: list[bool] = []
        self.here: tuple[float, float, float] | None = None
        self.first_start: tuple[float, float, float] | None = None

    def add(self, mv: Move) -> None:
        """Take one move."""
        if self.first_start is None:
            self.first_start = tuple(mv.start)
        k = int(mv.kind)
        stop = self.stop
        if k == _DWELL or k == _STOP:
            pos = self.here if self.here is not None else mv.start
            if stop:
                stop[-1] = True
            self.kinds.append(_REST)
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
        if not is_arc and math.dist(start, end) < _MIN_LENGTH_M:
            if mv.exact_stop and stop:
                stop[-1] = True
            return
        self.kinds.append(_ARC if is_arc else _LINE)
        self.moves.append(mv)
        self.p0.append(start)
        self.p1.append(end)
        self.dwell.append(0.0)
        stop.append(bool(mv.exact_stop))

    def __len__(self) -> int:
        return len(self.kinds)

    def segments(self, *, final: bool) -> _Segments:
        """Arrays of the segments collected so far (``final``: the program has ended)."""
        if final and self.stop:
            self.stop[-1] = True
        m = len(self.kinds)
        # fromiter over the flattened points: half the time of asarray on a list of tuples
        return _Segments(kind=np.asarray(self.kinds, dtype=np.int8), move=list(self.moves),
                         p0=np.fromiter(chain.from_iterable(self.p0), float,
                                        count=3 * m).reshape(m, 3),
                         p1=np.fromiter(chain.from_iterable(self.p1), float,
                                        count=3 * m).reshape(m, 3),
                         dwell=np.asarray(self.dwell, dtype=float),
                         stop_after=np.asarray(self.stop, bool))

    def drop(self, count: int) -> None:
        """Forget the first ``count`` segments (they have been planned)."""
        for lst in (self.kinds, self.moves, self.p0, self.p1, self.dwell, self.stop):
            del lst[:count]


def _collect(program: Program) -> _Segments:
    """Walk the moves once: drop empty moves, turn dwells/stops into rests, check continuity."""
    collector = _Collector(program.file)
    for mv in program.moves:
        collector.add(mv)
    return collector.segments(final=True)


@dataclass
class _Geometry:
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


def _geometry(seg: _Segments, file: str) -> _Geometry:
    m = seg.kind.shape[0]
    d = seg.p1 - seg.p0
    length = np.zeros(m)
    u = np.zeros((m, 3))
    is_line = seg.kind == _LINE
    ln = np.linalg.norm(d[is_line], axis=1)
    length[is_line] = ln
    u[is_line] = d[is_line] / ln[:, None]
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
    arcs = np.nonzero(seg.kind == _ARC)[0]
    if arcs.size:
        mv = [seg.move[i] for i in arcs]
        try:
            perm[arcs] = [_PLANE_AXES[x.plane] for x in mv]
        except KeyError as err:
            bad = next(x for x in mv if x.plane not in _PLANE_AXES)
            msg = f'arc plane must be 17, 18 or 19, got {bad.plane!r}'
            raise PlanningError(msg, file=file, line=bad.line) from err
        centre[arcs] = [x.center for x in mv]
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
            which[arcs] = out
    return _Geometry(length=length, u=u, tan0=tan0, tan1=tan1, centre=centre, perm=perm,
                     plane_ref=plane_ref,
                     theta0=theta0, sweep=sweep, r0=r0, kr=kr, kc=kc, r_min=r_min)


def line_speed_limits(u: np.ndarray, axis_vmax: np.ndarray) -> np.ndarray:
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


def _path_limits(seg: _Segments, geo: _Geometry, lim: np.ndarray,
                 file: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Path speed, acceleration and jerk limits per segment; ``lim`` is (3 kinds, 3 axes)."""
    m = seg.kind.shape[0]
    feed = np.array([x.feed_m_s if x.feed_m_s > 0 else math.inf for x in seg.move])
    missing = ~np.isfinite(lim[0])
    moved = np.abs(seg.p1 - seg.p0) > _GAP_TOLERANCE_M
    arcs = np.nonzero(seg.kind == _ARC)[0]
    moved[arcs, geo.perm[arcs, 0]] = True       # an arc always moves both in-plane axes
    moved[arcs, geo.perm[arcs, 1]] = True
    bad = np.nonzero(np.any(moved & missing[None, :], axis=1))[0]
    if bad.size:
        mv = seg.move[bad[0]]
        names = [PROGRAM_AXES[k] for k in range(3) if missing[k] and moved[bad[0], k]]
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
        arcs = seg.kind == _ARC
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
    return vmax, amax, jmax


def _junction_speeds(seg: _Segments, geo: _Geometry, vmax: np.ndarray, amax: np.ndarray,
                     delta: float, axis_acc: np.ndarray, cycle_s: float) -> np.ndarray:
    """Speed caps at the m + 1 segment boundaries before the look-ahead passes.

    ``axis_acc`` holds the acceleration limit of each program axis (``inf`` if absent);
    ``cycle_s`` is the interpolation cycle in which a corner's velocity step happens.
    """
    m = seg.kind.shape[0]
    vj = np.zeros(m + 1)
    if m < 2:
        return vj
    cos_t = -np.einsum('ij,ij->i', geo.tan1[:-1], geo.tan0[1:])
    sin_half = np.sqrt(np.clip(0.5 * (1.0 - cos_t), 0.0, 1.0))
    a = np.minimum(amax[:-1], amax[1:])
    du = np.abs(geo.tan0[1:] - geo.tan1[:-1])
    with np.errstate(divide='ignore', invalid='ignore'):
        v2 = np.where(sin_half > 1.0 - 1e-12, np.inf,
                      a * delta * sin_half / (1.0 - sin_half))
        # per-axis velocity step of the corner within one cycle: v |du_k| <= a_k T
        v_step = np.min(np.where(du > 0.0, axis_acc * cycle_s / du, np.inf), axis=1)
    v = np.minimum.reduce([np.sqrt(v2), v_step, vmax[:-1], vmax[1:]])
    stop = seg.stop_after[:-1] | (seg.kind[:-1] == _REST) | (seg.kind[1:] == _REST)
    vj[1:-1] = np.where(stop, 0.0, v)
    return vj


def _check_limits(limits: Mapping[str, AxisLimits], file: str) -> np.ndarray:
    lim = np.full((3, 3), np.inf)
    for name, al in limits.items():
        if name not in PROGRAM_AXES:
            msg = f'unknown machine axis {name!r}; expected one of {PROGRAM_AXES}'
            raise PlanningError(msg, file=file)
        if not isinstance(al, AxisLimits):
            msg = f'limits[{name!r}] must be an AxisLimits, got {type(al).__name__}'
            raise PlanningError(msg, file=file)
        k = PROGRAM_AXES.index(name)
        lim[:, k] = (al.velocity_m_s, al.acceleration_m_s2, al.jerk_m_s3)
    if not limits:
        raise PlanningError('no machine axes given in limits', file=file)
    return lim


def plan(program: Program, limits: Mapping[str, AxisLimits], *,
         options: PlannerOptions = PlannerOptions(),
         progress: Callable[[float], None] | None = None) -> Motion:
    """Plan and sample the motion of the machine axes for a program.

    Parameters
    ----------
    program
        The parsed program (SI units).
    limits
        Kinematic limits per machine axis; its keys (among ``X``, ``Y``, ``Z``), in order,
        become ``Motion.axes``.
    options
        Sample rate, profile type and corner tolerance.
    progress
        Called with the completed fraction (0..1) a few times, not per sample.

    Returns
    -------
    Motion
        Uniformly sampled positions, velocities and accelerations; every sample carries the
        source line of its move; the last sample is the end of the program.

    Raises
    ------
    PlanningError
        A move on an axis missing from ``limits``, a discontinuous or degenerate move.
    """
    lim = _check_limits(limits, program.file)
    axes = tuple(limits)
    cols = [PROGRAM_AXES.index(a) for a in axes]
    seg = _collect(program)
    m = seg.kind.shape[0]
    if m == 0:
        start = program.moves[0].start if program.moves else (0.0, 0.0, 0.0)
        pos = np.asarray(start, dtype=float)[cols][None, :]
        return Motion(t=np.zeros(1), axes=axes, pos=pos, vel=np.zeros_like(pos),
                      acc=np.zeros_like(pos), line=np.zeros(1, np.int32), source=program.file)
    geo = _geometry(seg, program.file)
    vmax, amax, jmax = _path_limits(seg, geo, lim, program.file)
    if options.profile == 'trapezoid':
        jmax = np.full(m, np.inf)
    _report(progress, 0.05)
    cycle_s = options.cycle_s
    vj = _junction_speeds(seg, geo, vmax, amax, options.corner_tolerance_m, lim[1], cycle_s)
    a_through = through_acceleration(geo.tan1[:-1], geo.tan0[1:], geo.r_min[:-1],
                                     geo.r_min[1:], vj[1:-1], lim[1], cycle_s)
    grp = group_blocks(geo.length, vmax, amax, jmax, vj, a_through, rest=seg.kind == _REST)
    gv = grp.v_junction
    look_ahead(gv, grp.length, grp.amax, grp.jmax)
    _report(progress, 0.15)
    prof = plan_profiles(grp.length, gv[:-1], gv[1:], grp.vmax, grp.amax, grp.jmax)
    t_start, phases = _phase_table(prof, gv, seg.dwell[grp.first], 0.0)
    t_end = float(t_start[-1])
    _report(progress, 0.25)

    n = int(math.floor(t_end * options.rate_hz + 1e-9))
    t = np.arange(n + 1, dtype=float) / options.rate_hz
    if t_end - t[-1] > 1e-9:
        t = np.append(t, t_end)
    else:
        t[-1] = t_end
    lines = np.array([x.line for x in seg.move], dtype=np.int32)
    # t is uniform: each phase owns the samples from the first one at or after its start
    first = np.searchsorted(t, phases[0], side='left')
    owner_phase = np.repeat(np.arange(first.size), np.diff(np.append(first, t.size)))
    # column-major (n, k): per-axis columns are contiguous (see _sample)
    pos = np.empty((t.size, len(axes)), order='F')
    vel = np.empty_like(pos)
    acc = np.empty_like(pos)
    line = np.empty(t.size, dtype=np.int32)
    p0c, uc = seg.p0[:, cols], geo.u[:, cols]
    locate = _BlockLocator(grp, geo.length)
    for lo in range(0, t.size, _CHUNK):
        hi = min(lo + _CHUNK, t.size)
        mi = _sample(t[lo:hi], owner_phase[lo:hi], phases, locate, seg, geo, cols, p0c, uc,
                     out=(pos[lo:hi], vel[lo:hi], acc[lo:hi]))
        line[lo:hi] = lines[mi]
        _report(progress, 0.25 + 0.75 * hi / t.size)
    t_junction, v_junction = _junction_times(grp, t_start, gv, phases)
    _corner_steps(t, t_junction, v_junction, geo, cols, 1.0 / options.rate_hz, vel=vel,
                  acc=acc)
    return Motion(t=t, axes=axes, pos=pos, vel=vel, acc=acc, line=line, source=program.file)


def _phase_table(prof: ProfilePhases, gv: np.ndarray, dwell: np.ndarray,
                 t_offset: float) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """Phase start times (all ``7 g + 1``) and the table of phases with a duration.

    ``dwell`` is the rest time of each group (0 unless the group is a rest); ``t_offset`` the
    program time at the first group's start: the running sum continues from it, so a window
    of a longer program gets the same bits as the whole program.
    """
    g = gv.shape[0] - 1
    dur = prof.duration.copy()
    dur[:, 3] += dwell      # a rest is a group of its own
    # integrate the seven phases of every group to get s and v at each phase start
    v_start = np.empty((g, 7))
    s_start = np.empty((g, 7))
    v_start[:, 0] = gv[:-1]
    s_start[:, 0] = 0.0
    for k in range(6):
        T, a0, j = dur[:, k], prof.a_start[:, k], prof.jerk[:, k]
        v_start[:, k + 1] = v_start[:, k] + a0 * T + 0.5 * j * T * T
        s_start[:, k + 1] = s_start[:, k] + (v_start[:, k] + (0.5 * a0 + j * T / 6.0) * T) * T
    flat_dur = dur.ravel()
    t_start = np.cumsum(np.concatenate(([t_offset], flat_dur)))
    keep = np.nonzero(flat_dur > 0.0)[0]
    if keep.size == 0:
        keep = np.array([0])
    phases = (t_start[keep], flat_dur[keep], s_start.ravel()[keep], v_start.ravel()[keep],
              prof.a_start.ravel()[keep], prof.jerk.ravel()[keep], keep // 7)
    return t_start, phases


class _BlockLocator:
    """Maps a path length inside a group to the block containing it."""

    def __init__(self, grp: BlockGroups, length: np.ndarray, *,
                 path_start_m: float = 0.0) -> None:
        cum = path_cumsum(length, path_start_m) - length
        self.group_first = grp.first
        self.group_last = np.append(grp.first[1:], length.shape[0]) - 1
        self.group_start = cum[grp.first]     # program path length at each group's start
        self.block_start = cum                # ... at each block's start
        self.offset = grp.offset              # block start within its group
        self.single = bool(np.all(self.group_last == self.group_first))

    def __call__(self, group: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Block index and path length inside that block for group-local ``s``."""
        if self.single:                       # every group is one block
            b = np.take(self.group_first, group)
            return b, s - np.take(self.offset, b)
        b = _last_at_or_below(self.block_start, np.take(self.group_start, group) + s)
        b = np.clip(b, np.take(self.group_first, group), np.take(self.group_last, group))
        return b, s - np.take(self.offset, b)


def _last_at_or_below(starts: np.ndarray, key: np.ndarray) -> np.ndarray:
    """``searchsorted(starts, key, side='right') - 1`` for sorted ``starts``.

    Samples come in time order, so ``key`` (program path length) is usually sorted too, and
    many samples share a block: then the blocks are searched among the samples (a few
    thousand searches instead of one per sample) and counted up.
    """
    n = key.shape[0]
    if n < 256 or not np.all(key[1:] >= key[:-1]):
        return np.searchsorted(starts, key, side='right') - 1
    lo = int(np.searchsorted(starts, key[0], side='right'))
    hi = int(np.searchsorted(starts, key[-1], side='right'))
    # block j in lo..hi-1 holds the samples from the first key >= starts[j] on
    first = np.searchsorted(key, starts[lo:hi], side='left')
    b = np.cumsum(np.bincount(first, minlength=n))
    b += lo - 1
    return b


def _junction_times(grp: BlockGroups, t_start: np.ndarray, gv: np.ndarray,
                    phases: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Time and path speed at each of the m - 1 block junctions.

    Group boundaries start a group's first phase; a junction inside a group is where the
    group's ``s(t)`` (monotone) reaches the block's offset, found by vectorised bisection
    inside the phase that contains it.
    """
    m = grp.group_of.shape[0]
    t_j = np.zeros(max(m - 1, 0))
    v_j = np.zeros_like(t_j)
    if m < 2:
        return t_j, v_j
    boundary = ~grp.through
    gb = grp.group_of[1:][boundary]
    t_j[boundary] = t_start[7 * gb]
    v_j[boundary] = gv[gb]
    inner = np.nonzero(grp.through)[0] + 1          # blocks that start inside their group
    if inner.size == 0:
        return t_j, v_j
    t0, dur, s0, v0, a0, jk, owner = phases
    target = grp.offset[inner]
    gi = grp.group_of[inner]
    # phases are sorted by (group, s): search on a combined key (group, then s)
    lo_ph = np.searchsorted(owner, gi, side='left')
    hi_ph = np.searchsorted(owner, gi, side='right')
    k = lo_ph.copy()
    # the last phase of the group that starts at or before the target: a short loop over
    # the (at most 7) phases of a group
    for _ in range(7):
        nxt = k + 1
        step = (nxt < hi_ph) & (np.take(s0, np.minimum(nxt, s0.size - 1)) <= target)
        k = np.where(step, nxt, k)
    tau_lo = np.zeros(inner.size)
    tau_hi = dur[k].copy()
    sk, vk, ak, jj = s0[k], v0[k], a0[k], jk[k]
    for _ in range(_JUNCTION_BISECT):
        mid = 0.5 * (tau_lo + tau_hi)
        s_mid = sk + (vk + (0.5 * ak + jj * mid / 6.0) * mid) * mid
        below = s_mid < target
        tau_lo = np.where(below, mid, tau_lo)
        tau_hi = np.where(below, tau_hi, mid)
    tau = 0.5 * (tau_lo + tau_hi)
    t_j[inner - 1] = t0[k] + tau
    v_j[inner - 1] = vk + (ak + 0.5 * jj * tau) * tau
    return t_j, v_j


def _corner_terms(t_junction: np.ndarray, v_junction: np.ndarray, tan_in: np.ndarray,
                  tan_out: np.ndarray, cols: list[int],
                  sample_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity steps of the non-tangent junctions passed at speed: ``(index, time, dv)``.

    ``index`` is the sample nearest to the junction (``rint(t / T)``, not yet clipped to the
    last sample), ``dv`` the per-axis step ``(h, len(cols))``.
    """
    dv = v_junction[:, None] * (tan_out - tan_in)[:, cols]
    hit = np.nonzero((v_junction > 0.0) & np.any(dv != 0.0, axis=1))[0]
    tc = t_junction[hit]
    return np.rint(tc / sample_s).astype(np.int64), tc, dv[hit]


def _apply_steps(t: np.ndarray, idx: np.ndarray, tc: np.ndarray, dv: np.ndarray,
                 sample_s: float, *, vel: np.ndarray, acc: np.ndarray) -> None:
    """Add the steps ``dv`` at samples ``idx`` (indices into ``t``) to ``vel`` and ``acc``."""
    # the sample already shows the whole step if it lies at or after the junction
    # (phases own the samples from the first one at or after their start)
    half = np.where(t[idx] >= tc, -0.5, 0.5)
    np.add.at(vel, idx, dv * half[:, None])
    np.add.at(acc, idx, dv * (1.0 / sample_s))


def _corner_steps(t: np.ndarray, t_junction: np.ndarray, v_junction: np.ndarray,
                  geo: _Geometry, cols: list[int], sample_s: float, *, vel: np.ndarray,
                  acc: np.ndarray) -> None:
    """Put the velocity steps of non-tangent junctions into ``vel`` and ``acc`` (in place).

    The sample nearest to a junction gets ``+dv / T`` acceleration (``T`` the sample period,
    so that acceleration integrates to velocity on the samples) and half the step in its
    velocity (see the module docstring, *Corners*).
    """
    idx, tc, dv = _corner_terms(t_junction, v_junction, geo.tan1[:-1], geo.tan0[1:], cols,
                                sample_s)
    if idx.size == 0:
        return
    _apply_steps(t, np.clip(idx, 0, t.size - 1), tc, dv, sample_s, vel=vel, acc=acc)


def _report(progress: Callable[[float], None] | None, fraction: float) -> None:
    if progress is not None:
        progress(float(min(max(fraction, 0.0), 1.0)))


def _sample(t: np.ndarray, k: np.ndarray, phases: tuple[np.ndarray, ...],
            locate: _BlockLocator, seg: _Segments, geo: _Geometry, cols: list[int],
            p0c: np.ndarray, uc: np.ndarray, *,
            out: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """Evaluate phases ``k`` at times ``t`` into ``out`` (pos, vel, acc of ``cols``).

    Returns the segment (block) index of every sample.
    """
    t0, dur, s0, v0, a0, jk, owner = phases
    tau = np.minimum(t - np.take(t0, k), np.take(dur, k))
    jt = np.take(jk, k) * tau
    aa = np.take(a0, k)
    vv = np.take(v0, k)
    a = aa + jt
    v = vv + (aa + 0.5 * jt) * tau
    s_group = np.take(s0, k) + (vv + (0.5 * aa + (1.0 / 6.0) * jt) * tau) * tau
    mi, s = locate(np.take(owner, k), s_group)
    pos, vel, acc = out
    # column by column: an (n, k) operation with a per-row factor runs its inner loop over
    # the k columns, about ten times slower than over the rows
    for j in range(uc.shape[1]):
        u = np.take(uc[:, j], mi)
        np.multiply(u, s, out=pos[:, j])
        pos[:, j] += np.take(p0c[:, j], mi)
        np.multiply(u, v, out=vel[:, j])
        np.multiply(u, a, out=acc[:, j])
    on_arc = np.nonzero(seg.kind[mi] == _ARC)[0]
    if on_arc.size:
        _sample_arcs(on_arc, mi[on_arc], s[on_arc], v[on_arc], a[on_arc], geo, cols, out)
    return mi


def _sample_arcs(rows: np.ndarray, ma: np.ndarray, s: np.ndarray, v: np.ndarray,
                 a: np.ndarray, geo: _Geometry, cols: list[int],
                 out: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    """Overwrite ``rows`` of ``out`` with the arc/helix motion of segments ``ma``."""
    length = np.take(geo.length, ma)
    frac = np.take(geo.sweep, ma) / length         # dtheta / ds
    dth = frac * np.clip(s, 0.0, length)
    th = np.take(geo.theta0, ma) + dth
    w = frac * v                                   # dtheta / dt
    w_dot = frac * a
    kr = np.take(geo.kr, ma)
    kc = np.take(geo.kc, ma)
    r = np.take(geo.r0, ma) + kr * dth
    cs, sn = np.cos(th), np.sin(th)
    ref = np.take(geo.plane_ref, ma, axis=0)
    d1a, d1b = kr * cs - r * sn, kr * sn + r * cs     # dp/dtheta (in-plane)
    d2a, d2b = -2.0 * kr * sn - r * cs, 2.0 * kr * cs - r * sn
    w2 = w * w
    local = (
        (ref[:, 0] + r * cs, d1a * w, d2a * w2 + d1a * w_dot),
        (ref[:, 1] + r * sn, d1b * w, d2b * w2 + d1b * w_dot),
        (ref[:, 2] + kc * dth, kc * w, kc * w_dot),
    )
    first_axis = np.take(geo.perm[:, 0], ma)
    for plane_axes in set(_PLANE_AXES.values()):
        sel = np.nonzero(first_axis == plane_axes[0])[0]
        if sel.size == 0:
            continue
        whole = sel.size == rows.size
        dst_rows = rows if whole else rows[sel]
        for j, axis in enumerate(cols):
            role = plane_axes.index(axis)
            for dst, src in zip(out, local[role]):
                dst[dst_rows, j] = src if whole else src[sel]
