"""Look-ahead of the planner: which junctions are passed *through*, block groups, speed passes.

A *through* junction is one that the path speed profile crosses without returning to zero
acceleration; consecutive blocks joined by through junctions form one *group* that gets a
single seven-phase profile (:mod:`.profiles`) over its total length, so on a run of short
collinear or nearly tangent blocks the speed climbs to the feed as on one long line. The other
junctions are *anchors*: the profile reaches them at zero acceleration (a stop, a sharp corner
or a change of the speed ceiling), as every junction was before groups existed.

Through junctions
-----------------
Only junctions between two *short* blocks can be through: blocks too short to reach their own
speed limit from rest (``length < min_distance(0, vmax)``). That is where per-block profiles
fail (each block adds only a little speed, as on a polygon of 1-2 mm chords); a longer block
reaches its limit on its own and would only lose acceleration to a group (the group's limit is
the smallest of its blocks', and an arc keeps half of the axis acceleration for the
centripetal term).

A non-tangent junction passed at speed ``v`` steps the velocity of axis ``k`` by
``v |du_k|`` in one interpolation cycle ``T`` (``du = tangent_out - tangent_in``), which shows
as ``v |du_k| / T`` in that cycle's acceleration. With the path accelerating at ``a`` the
same cycle carries ``a |tangent_k|`` on top (plus the centripetal ``v^2 / r`` next to an arc).
So a junction may be passed with path acceleration only up to::

    a_through = min_k (a_k - v |du_k| / T - v^2 / r) / |tangent_k|      (both sides)

evaluated at the junction's speed cap (the largest speed it can be passed at). A junction is
through when ``a_through >= THROUGH_ACC_FRACTION`` of the smaller path acceleration limit of
its two blocks; the group's acceleration limit is then lowered to the smallest
``a_through`` of its junctions, so the axis acceleration at a corner sample stays within
``a_k`` however the profile passes it. Exactly tangent junctions (``du = 0``) between lines
cost nothing. Where the velocity-step rule itself sets the junction speed the step uses the
whole budget (``a_through = 0``) and the junction stays an anchor.

Ceilings
--------
A block's speed ceiling is its own limit ``vmax`` lowered to the caps of its through
junctions. Blocks join a group while its ceilings stay within ``CEILING_MERGE`` (relative) of
each other; the group's ceiling is their smallest (so up to 2 % of speed may be given away on
blocks whose limits differ slightly, e.g. arcs of slightly different radius, in exchange for a
continuous profile). A larger change of ceiling is an anchor at the lower ceiling, where the
time-optimal profile would be at a plateau with zero acceleration anyway.

Speed passes
------------
A backward and a forward pass lower every anchor speed to what the neighbouring group can
reach in its length (closed form, zero acceleration at both ends, :func:`.profiles.reach_speed`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .profiles import min_distance, reach_speed

__all__ = ['THROUGH_ACC_FRACTION', 'CEILING_MERGE', 'BlockGroups', 'through_acceleration',
           'group_blocks', 'look_ahead', 'path_cumsum']

THROUGH_ACC_FRACTION = 0.25
CEILING_MERGE = 0.02


@dataclass(frozen=True)
class BlockGroups:
    """Blocks grouped into runs that get one speed profile each.

    Attributes
    ----------
    first
        Shape ``(g,)``: index of the first block of each group.
    group_of
        Shape ``(m,)``: group of each block.
    offset
        Shape ``(m,)``: path length from the group's start to the block's start [m].
    length, vmax, amax, jmax
        Shape ``(g,)``: total length [m], speed ceiling [m/s], path acceleration [m/s^2] and
        jerk [m/s^3] limits of each group.
    v_junction
        Shape ``(g + 1,)``: speed caps at the group boundaries [m/s] (0 at the ends).
    through
        Shape ``(m - 1,)``: the block junctions that lie inside a group.
    """

    first: np.ndarray
    group_of: np.ndarray
    offset: np.ndarray
    length: np.ndarray
    vmax: np.ndarray
    amax: np.ndarray
    jmax: np.ndarray
    v_junction: np.ndarray
    through: np.ndarray


def path_cumsum(length: np.ndarray, start_m: float) -> np.ndarray:
    """Running sum of ``length`` continued from ``start_m`` (the same bits as one long sum).

    ``numpy.cumsum`` adds strictly in order, so continuing from the previous window's total
    repeats exactly the additions of the whole-program sum.
    """
    if start_m == 0.0:
        return np.cumsum(length)
    return np.cumsum(np.concatenate(([start_m], length)))[1:]


def through_acceleration(tan_in: np.ndarray, tan_out: np.ndarray, r_in: np.ndarray,
                         r_out: np.ndarray, v: np.ndarray, axis_acc: np.ndarray,
                         cycle_s: float) -> np.ndarray:
    """Largest path acceleration [m/s^2] with which each junction may be passed at ``v``.

    Parameters
    ----------
    tan_in, tan_out
        Shape ``(n, 3)``: unit tangents at the end of the incoming and the start of the
        outgoing block.
    r_in, r_out
        Shape ``(n,)``: smallest radius of each block (``inf`` for lines).
    v
        Shape ``(n,)``: speed at the junction [m/s].
    axis_acc
        Shape ``(3,)``: acceleration limit of each program axis (``inf`` if absent).
    cycle_s
        Interpolation cycle ``T`` [s].

    Returns
    -------
    numpy.ndarray
        ``min_k (a_k - v |du_k| / T - v^2 / r) / |tangent_k|`` over both sides; may be
        negative (no room at all).
    """
    step = v[:, None] * np.abs(tan_out - tan_in) / cycle_s
    out = np.full(v.shape, np.inf)
    with np.errstate(invalid='ignore', divide='ignore'):
        for tan, r in ((tan_in, r_in), (tan_out, r_out)):
            room = axis_acc[None, :] - step - (v * v / r)[:, None]
            mag = np.abs(tan)
            per_axis = np.where(mag > 1e-12, room / np.where(mag > 1e-12, mag, 1.0), np.inf)
            out = np.minimum(out, np.min(per_axis, axis=1))
    return out


def group_blocks(length: np.ndarray, vmax: np.ndarray, amax: np.ndarray, jmax: np.ndarray,
                 vj: np.ndarray, a_through: np.ndarray, *,
                 rest: np.ndarray, path_start_m: float = 0.0) -> BlockGroups:
    """Group blocks joined by through junctions with similar speed ceilings.

    Parameters
    ----------
    length, vmax, amax, jmax
        Shape ``(m,)``: per-block length and path limits.
    vj
        Shape ``(m + 1,)``: junction speed caps (0 at stops and the ends).
    a_through
        Shape ``(m - 1,)``: :func:`through_acceleration` at each junction's cap.
    rest
        Shape ``(m,)``: dwells and stops (never grouped).
    path_start_m
        Program path length before the first block [m] (a streamed window of a longer
        program): offsets are computed from the running sum as for the whole program, so a
        window gives the same bits.

    Returns
    -------
    BlockGroups
        The groups, their limits and the speed caps at their boundaries.
    """
    m = length.shape[0]
    inner = vj[1:-1]
    # a block that can reach its own speed limit from rest within its length gains little
    # from a group but would lose its own acceleration limit to the group's smallest
    short = length < min_distance(np.zeros(m), vmax, amax, jmax)
    if m > 1:
        through = ((inner > 0.0) & ~rest[:-1] & ~rest[1:] & short[:-1] & short[1:]
                   & (a_through >= THROUGH_ACC_FRACTION * np.minimum(amax[:-1], amax[1:])))
    else:
        through = np.zeros(0, bool)
    ceiling = vmax.copy()
    if m > 1:
        ceiling[:-1] = np.where(through, np.minimum(ceiling[:-1], inner), ceiling[:-1])
        ceiling[1:] = np.where(through, np.minimum(ceiling[1:], inner), ceiling[1:])
    # greedy: a group grows while its ceilings stay within CEILING_MERGE of each other
    joined = through.tolist()
    c = ceiling.tolist()
    lo = hi = c[0] if m else 0.0
    for i, ok in enumerate(joined):
        nxt = c[i + 1]
        if ok:
            n_lo, n_hi = min(lo, nxt), max(hi, nxt)
            if n_hi <= n_lo * (1.0 + CEILING_MERGE):
                lo, hi = n_lo, n_hi
                continue
            joined[i] = False
        lo = hi = nxt
    through = np.asarray(joined, dtype=bool)
    first = np.concatenate(([0], np.nonzero(~through)[0] + 1)).astype(np.int64)
    group_of = np.cumsum(np.concatenate(([False], ~through))).astype(np.int64)
    g_len = np.add.reduceat(length, first)
    cum = path_cumsum(length, path_start_m) - length
    offset = cum - cum[first][group_of]
    g_vmax = np.minimum.reduceat(ceiling, first)
    # a through junction limits its group's acceleration; its slot belongs to the block before
    a_junction = np.full(m, np.inf)
    if m > 1:
        a_junction[:-1] = np.where(through, a_through, np.inf)
    g_amax = np.minimum(np.minimum.reduceat(amax, first), np.minimum.reduceat(a_junction, first))
    g_jmax = np.minimum.reduceat(jmax, first)
    g = first.size
    v_junction = np.zeros(g + 1)
    if g > 1:
        v_junction[1:-1] = np.minimum.reduce([vj[first[1:]], g_vmax[:-1], g_vmax[1:]])
    return BlockGroups(first=first, group_of=group_of, offset=offset, length=g_len,
                       vmax=g_vmax, amax=g_amax, jmax=g_jmax, v_junction=v_junction,
                       through=through)


def look_ahead(vj: np.ndarray, length: np.ndarray, amax: np.ndarray, jmax: np.ndarray) -> None:
    """Backward then forward pass (in place) so every group can reach its boundary speeds.

    Parameters
    ----------
    vj
        Shape ``(g + 1,)``: boundary speed caps, lowered in place.
    length, amax, jmax
        Shape ``(g,)``: length and path limits of each group (``jmax = inf``: trapezoid).
    """
    m = length.shape[0]
    # a hair shorter so the profile solver always finds the pair reachable despite rounding
    usable = (length * (1.0 - 1e-9)).tolist()
    a = amax.tolist()
    j = jmax.tolist()
    v = vj.tolist()
    for i in range(m - 1, -1, -1):
        if v[i] > v[i + 1]:
            v[i] = min(v[i], reach_speed(v[i + 1], usable[i], a[i], j[i]))
    for i in range(m):
        if v[i + 1] > v[i]:
            v[i + 1] = min(v[i + 1], reach_speed(v[i], usable[i], a[i], j[i]))
    vj[:] = v
