"""Planner output: the table of constant-jerk phases and its evaluation at sample times.

Steps 5 and 6 of the method in :mod:`.trajectory`: :func:`phase_table` integrates the
groups' profiles into one table of phases, :func:`sample_phases` evaluates it at uniform times and
maps the path length to axis motion per block (lines here, arcs and helices in
:func:`_sample_arcs`), :func:`junction_times` times the block junctions and
:func:`corner_steps` puts the corners' velocity steps into the samples (:func:`step_rows`,
:func:`apply_steps`). Used by
:func:`.trajectory.plan`, the streaming planner (:mod:`.stream`) and its window sampler
(:mod:`.chunks`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lookahead import BlockGroups, path_cumsum
from .profiles import ProfilePhases
from .segments import ARC, PLANE_AXES, SegmentGeometry, SegmentTable

_JUNCTION_BISECT = 60      # bisection steps for the time of a junction inside a group


def phase_table(prof: ProfilePhases, gv: np.ndarray, dwell: np.ndarray,
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


class BlockLocator:
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


def junction_times(grp: BlockGroups, t_start: np.ndarray, gv: np.ndarray,
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
    t_j[inner - 1], v_j[inner - 1] = path_times(grp.group_of[inner], grp.offset[inner], phases)
    return t_j, v_j


def path_times(group: np.ndarray, target: np.ndarray,
               phases: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Time and path speed at which group ``group`` reaches its path length ``target``: the
    group's ``s(t)`` is monotone, so by vectorised bisection inside the phase holding it."""
    t0, dur, s0, v0, a0, jk, owner = phases
    # phases are sorted by (group, s): search on a combined key (group, then s)
    lo_ph = np.searchsorted(owner, group, side='left')
    hi_ph = np.searchsorted(owner, group, side='right')
    k = lo_ph.copy()
    # the last phase of the group that starts at or before the target: a short loop over
    # the (at most 7) phases of a group
    for _ in range(7):
        nxt = k + 1
        step = (nxt < hi_ph) & (np.take(s0, np.minimum(nxt, s0.size - 1)) <= target)
        k = np.where(step, nxt, k)
    tau_lo = np.zeros(target.size)
    tau_hi = dur[k].copy()
    sk, vk, ak, jj = s0[k], v0[k], a0[k], jk[k]
    for _ in range(_JUNCTION_BISECT):
        mid = 0.5 * (tau_lo + tau_hi)
        s_mid = sk + (vk + (0.5 * ak + jj * mid / 6.0) * mid) * mid
        below = s_mid < target
        tau_lo = np.where(below, mid, tau_lo)
        tau_hi = np.where(below, tau_hi, mid)
    tau = 0.5 * (tau_lo + tau_hi)
    return t0[k] + tau, vk + (ak + 0.5 * jj * tau) * tau


def corner_terms(t_junction: np.ndarray, v_junction: np.ndarray, tan_in: np.ndarray,
                 tan_out: np.ndarray, cols: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Velocity steps of the non-tangent junctions passed at speed: ``(time, dv)``, ``dv``
    the per-axis step ``(h, len(cols))``; the samples that carry them: :func:`step_rows`.
    """
    dv = v_junction[:, None] * (tan_out - tan_in)[:, cols]
    hit = np.nonzero((v_junction > 0.0) & np.any(dv != 0.0, axis=1))[0]
    return t_junction[hit], dv[hit]


def step_rows(tc: np.ndarray, sample_s: float,
              cycle_s: float) -> tuple[np.ndarray, np.ndarray]:
    """First and last grid index ``(lo, hi)`` of the samples that carry each velocity step.

    A step happens within one interpolation cycle ``cycle_s`` centred on its junction time
    ``tc`` (see :mod:`.trajectory`, *Corners*): the grid samples in ``[tc - T/2, tc + T/2)``
    carry it. Where that holds fewer than two samples (the sample period at least the cycle,
    the default) the sample nearest to the junction carries it alone (``lo == hi``).
    """
    half = 0.5 * cycle_s
    lo = np.ceil((tc - half) / sample_s).astype(np.int64)
    hi = np.ceil((tc + half) / sample_s).astype(np.int64) - 1
    near = np.rint(tc / sample_s).astype(np.int64)
    single = hi <= lo
    return np.where(single, near, lo), np.where(single, near, hi)


def step_index(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every grid index of the ranges ``[lo, hi]`` and the range it belongs to:
    ``(step, index)``."""
    count = np.maximum(hi - lo + 1, 0)
    step = np.repeat(np.arange(lo.size), count)
    first = np.cumsum(count) - count
    index = np.repeat(lo, count) + (np.arange(step.size) - np.repeat(first, count))
    return step, index


def apply_steps(t: np.ndarray, rows: np.ndarray, index: np.ndarray, lo: np.ndarray,
                hi: np.ndarray, tc: np.ndarray, dv: np.ndarray, sample_s: float, *,
                vel: np.ndarray, acc: np.ndarray) -> None:
    """Add the velocity steps to ``vel`` and ``acc`` at ``rows`` (one row per carrying sample,
    given per row: its grid ``index``, its step's range ``lo..hi``, time ``tc`` and ``dv``).

    The ``n = hi - lo + 1`` samples of a step carry it as a ramp: the ``j``-th has the share
    ``(j + 1/2) / n`` of the step in its velocity (less the whole step where the path itself
    shows it: at or after the junction, phases own the samples from the first one at or
    after their start) and ``dv / (n T_s)`` in its acceleration, so that the acceleration
    integrates to the velocity by the trapezoid rule across them. One sample (``n = 1``):
    half the step and ``dv / T_s``.
    """
    n = hi - lo + 1
    frac = (index - lo + 0.5) / n
    jump = np.where(t[rows] >= tc, frac - 1.0, frac)
    np.add.at(vel, rows, dv * jump[:, None])
    np.add.at(acc, rows, dv * (1.0 / (n * sample_s))[:, None])


def give_steps(t: np.ndarray, index: np.ndarray, lo: np.ndarray, hi: np.ndarray,
               tc: np.ndarray, dv: np.ndarray, sample_s: float, *, vel: np.ndarray,
               acc: np.ndarray, first: np.ndarray | None = None,
               last: np.ndarray | None = None) -> None:
    """Give the steps (carried by the grid samples ``lo..hi`` each, :func:`step_rows`) their
    shares in the rows of ``t``, ``vel``, ``acc`` whose grid indices are ``index`` (sorted):
    for the grid indices ``first..last`` of each step (default ``lo..hi``); a grid index
    without a row (a standstill sample left out) gets nothing (:func:`apply_steps`)."""
    step, grid = step_index(lo if first is None else first, hi if last is None else last)
    if grid.size == 0 or index.size == 0:
        return
    rows = np.minimum(np.searchsorted(index, grid), index.size - 1)
    here = index[rows] == grid
    s = step[here]
    apply_steps(t, rows[here], grid[here], lo[s], hi[s], tc[s], dv[s], sample_s, vel=vel,
                acc=acc)


def corner_steps(t: np.ndarray, t_junction: np.ndarray, v_junction: np.ndarray,
                 geo: SegmentGeometry, cols: list[int], sample_s: float, cycle_s: float, *,
                 vel: np.ndarray, acc: np.ndarray) -> None:
    """Put the velocity steps of non-tangent junctions into ``vel`` and ``acc`` (in place),
    on the whole grid ``t`` (sample ``i`` at grid index ``i``): :func:`step_rows`,
    :func:`apply_steps`.
    """
    tc, dv = corner_terms(t_junction, v_junction, geo.tan1[:-1], geo.tan0[1:], cols)
    if tc.size == 0:
        return
    top = t.size - 1
    lo, hi = step_rows(tc, sample_s, cycle_s)
    give_steps(t, np.arange(t.size), np.clip(lo, 0, top), np.clip(hi, 0, top), tc, dv,
               sample_s, vel=vel, acc=acc)


def sample_phases(t: np.ndarray, k: np.ndarray, phases: tuple[np.ndarray, ...],
                  locate: BlockLocator, seg: SegmentTable, geo: SegmentGeometry, cols: list[int],
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
    on_arc = np.nonzero(seg.kind[mi] == ARC)[0]
    if on_arc.size:
        _sample_arcs(on_arc, mi[on_arc], s[on_arc], v[on_arc], a[on_arc], geo, cols, out)
    return mi


def _sample_arcs(rows: np.ndarray, ma: np.ndarray, s: np.ndarray, v: np.ndarray,
                 a: np.ndarray, geo: SegmentGeometry, cols: list[int],
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
    for plane_axes in set(PLANE_AXES.values()):
        sel = np.nonzero(first_axis == plane_axes[0])[0]
        if sel.size == 0:
            continue
        whole = sel.size == rows.size
        dst_rows = rows if whole else rows[sel]
        for j, axis in enumerate(cols):
            if axis > 2:
                continue        # a rotary column: linear in s, sampled with the lines
            role = plane_axes.index(axis)
            for dst, src in zip(out, local[role]):
                dst[dst_rows, j] = src if whole else src[sel]


@dataclass(frozen=True)
class PlannedWindow:
    """A committed run of groups: everything needed to sample it.

    Attributes
    ----------
    seg, geo
        Segments and geometry of the window's blocks.
    groups
        The groups (``v_junction`` holds the final boundary speeds).
    t_start
        Start time of every phase, ``7 g + 1`` values; ``t_start[0]`` is the window's start,
        ``t_start[-1]`` its end [s].
    phases
        The table of phases with a duration (see :func:`phase_table`).
    path_start_m
        Program path length before the first block [m].
    tan_entry
        Tangent at the end of the previous window's last block (``None`` for the first).
    final
        True for the program's last window.
    """

    seg: SegmentTable
    geo: SegmentGeometry
    groups: BlockGroups
    t_start: np.ndarray
    phases: tuple[np.ndarray, ...]
    path_start_m: float
    tan_entry: np.ndarray | None
    final: bool

    @property
    def t_begin(self) -> float:
        """Start of the window [s]."""
        return float(self.t_start[0])

    @property
    def t_end(self) -> float:
        """End of the window [s]."""
        return float(self.t_start[-1])


def window_corners(win: PlannedWindow, t_j: np.ndarray,
                   v_j: np.ndarray) -> tuple[np.ndarray, ...]:
    """The window's junctions ``(t, v, tangent in, tangent out)`` for :func:`corner_terms`:
    those of :func:`junction_times` (``t_j``, ``v_j``), after the junction with the previous
    window's last block when there is one (at the window's start)."""
    geo = win.geo
    tan_in, tan_out = geo.tan1[:-1], geo.tan0[1:]
    if win.tan_entry is not None:
        t_j = np.concatenate(([win.t_begin], t_j))
        v_j = np.concatenate(([float(win.groups.v_junction[0])], v_j))
        tan_in = np.vstack((win.tan_entry[None, :], tan_in))
        tan_out = np.vstack((geo.tan0[:1], tan_out))
    return t_j, v_j, tan_in, tan_out
