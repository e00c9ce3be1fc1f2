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
   look-ahead keeps ``|dv_k| <= a_k T``. The truth is a ramp: over ``[t_c - T/2, t_c + T/2]``
   the velocity goes linearly from before to after and ``dv / T`` is added to the path
   acceleration (the position's bump, at most ``|dv| T / 8``, is left out); the energy by
   phase (:mod:`.nodes`) integrates it exactly. In the samples (period ``T_s = 1 / rate_hz``)
   the ``n`` grid samples in that cycle carry the step (:func:`.phases.step_rows`,
   :func:`.phases.apply_steps`): the ``j``-th the share ``(j + 1/2) / n`` of it in its
   velocity and ``dv / (n T_s)`` in its acceleration. Where the cycle holds fewer than two
   samples (``T_s >= T``, the default ``T_s = T``) the sample nearest to the junction carries
   it alone: half the step in its velocity (the mean of the velocities just before and just
   after the junction, plus the path's own change) and ``dv / T_s`` in addition to its path
   acceleration. Read with the piecewise-linear (trapezoid) convention, the acceleration
   integrates to the velocity across the carrying samples (at ``n = 1`` a triangle of area
   ``dv``), so ``integral F v dt`` by the trapezoid rule gets the kinetic energy change
   ``m dv (v_in + v_out) / 2`` of the step exactly; at rates above ``1 / T`` the sampled sums
   converge to the ramp's energy (friction, screw efficiency and braking during the step
   included), at ``T_s >= T`` they differ from it by a discretization error of the order of
   the step's power times ``T_s``.

Where the steps live: 1 to 3 up to the look-ahead (segments, geometry, path limits,
junction caps) in :mod:`.segments`, the look-ahead in :mod:`.lookahead`, the profiles in
:mod:`.profiles`, 5 and 6 (phase table, sampling, corner steps) in :mod:`.phases`;
:func:`plan` here runs them in order over the whole program.

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
junction, not per sample. These corner bounds are for one sample carrying the step
(``T_s >= T``); spread over ``n >= 2`` samples (``T_s < T``) the step adds ``dv / (n T_s)``,
about ``dv / T <= a_k``, to each of them.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
import math

import numpy as np

from ..errors import PlanningError
from ..machine import AxisLimits, PlannerOptions
from .lookahead import group_blocks, look_ahead, through_acceleration
from .motion import Motion
# the planner's steps live in segments (input) and phases (output), shared with stream
from .phases import BlockLocator, corner_steps, junction_times, phase_table, sample_phases
from .profiles import plan_profiles
from ..gcode import Move, Program
from .segments import (collect_segments, segment_geometry, junction_speeds, path_limits,
                       PLAN_AXES, REST)

__all__ = ['plan']

_CHUNK = 1 << 18           # samples evaluated per vectorised block


def limits_array(limits: Mapping[str, AxisLimits], file: str) -> np.ndarray:
    """``(3 kinds, dims)``: speed, acceleration, jerk limit per planner column (``inf``
    where the machine lacks the axis); ``dims`` is 6 when a rotary axis is among the limits
    (their values in rad/s, rad/s^2, rad/s^3), else 3."""
    dims = 6 if any(name in PLAN_AXES[3:] for name in limits) else 3
    lim = np.full((3, dims), np.inf)
    for name, al in limits.items():
        if name not in PLAN_AXES:
            msg = f'unknown machine axis {name!r}; expected one of {PLAN_AXES}'
            raise PlanningError(msg, file=file)
        if not isinstance(al, AxisLimits):
            msg = f'limits[{name!r}] must be an AxisLimits, got {type(al).__name__}'
            raise PlanningError(msg, file=file)
        k = PLAN_AXES.index(name)
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
        Kinematic limits per machine axis; its keys (among ``X``, ``Y``, ``Z`` and the
        rotary ``A``, ``B``, ``C``, whose limits and positions are in rad), in order, become
        ``Motion.axes``.
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
    lim = limits_array(limits, program.file)
    axes = tuple(limits)
    cols = [PLAN_AXES.index(a) for a in axes]
    seg = collect_segments(program, dims=lim.shape[1])
    m = seg.kind.shape[0]
    if m == 0:
        start = program.moves[0].start if program.moves else (0.0, 0.0, 0.0)
        pos = np.asarray(start + rest_rotary(program.moves), dtype=float)[cols][None, :]
        return Motion(t=np.zeros(1), axes=axes, pos=pos, vel=np.zeros_like(pos),
                      acc=np.zeros_like(pos), line=np.zeros(1, np.int32), source=program.file)
    geo = segment_geometry(seg, program.file)
    vmax, amax, jmax = path_limits(seg, geo, lim, program.file)
    if options.profile == 'trapezoid':
        jmax = np.full(m, np.inf)
    _report(progress, 0.05)
    cycle_s = options.cycle_s
    vj = junction_speeds(seg, geo, vmax, amax, options.corner_tolerance_m, lim[1], cycle_s)
    a_through = through_acceleration(geo.tan1[:-1], geo.tan0[1:], geo.r_min[:-1],
                                     geo.r_min[1:], vj[1:-1], lim[1], cycle_s)
    grp = group_blocks(geo.length, vmax, amax, jmax, vj, a_through, rest=seg.kind == REST)
    gv = grp.v_junction
    look_ahead(gv, grp.length, grp.amax, grp.jmax)
    _report(progress, 0.15)
    prof = plan_profiles(grp.length, gv[:-1], gv[1:], grp.vmax, grp.amax, grp.jmax)
    t_start, phases = phase_table(prof, gv, seg.dwell[grp.first], 0.0)
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
    # column-major (n, k): per-axis columns are contiguous (see sample_phases)
    pos = np.empty((t.size, len(axes)), order='F')
    vel = np.empty_like(pos)
    acc = np.empty_like(pos)
    line = np.empty(t.size, dtype=np.int32)
    p0c, uc = seg.p0[:, cols], geo.u[:, cols]
    locate = BlockLocator(grp, geo.length)
    for lo in range(0, t.size, _CHUNK):
        hi = min(lo + _CHUNK, t.size)
        mi = sample_phases(t[lo:hi], owner_phase[lo:hi], phases, locate, seg, geo, cols, p0c, uc,
                           out=(pos[lo:hi], vel[lo:hi], acc[lo:hi]))
        line[lo:hi] = lines[mi]
        _report(progress, 0.25 + 0.75 * hi / t.size)
    t_junction, v_junction = junction_times(grp, t_start, gv, phases)
    corner_steps(t, t_junction, v_junction, geo, cols, 1.0 / options.rate_hz, cycle_s,
                 vel=vel, acc=acc)
    return Motion(t=t, axes=axes, pos=pos, vel=vel, acc=acc, line=line, source=program.file)


def rest_rotary(moves: Sequence[Move]) -> tuple[float, float, float]:
    """Rotary position of a program without motion (its first move's, else 0)."""
    first = moves[0] if moves else None
    if first is not None and first.rot_start is not None:
        return first.rot_start
    return (0.0, 0.0, 0.0)


def _report(progress: Callable[[float], None] | None, fraction: float) -> None:
    if progress is not None:
        progress(float(min(max(fraction, 0.0), 1.0)))
