"""Streaming planner: moves from any iterable -> bounded chunks of sampled motion.

:func:`.trajectory.plan` plans a whole program at once. Here the same steps run on a bounded
*window* of blocks and the samples come out in chunks of at most ``chunk_samples``, so a
program of any length (or a dwell of a week) costs memory for one window and one chunk only.

Committing a window
-------------------
The look-ahead's backward pass is the only step that needs the future, and only as far as the
stopping distance. A window of blocks is grouped (:mod:`.lookahead`; a junction's grouping is
final once two blocks after it are known) and the backward pass runs from the end of the last
complete group, whose following speed is unknown. Going backwards, the first boundary whose
speed is its own cap whatever follows fixes the speeds of all boundaries before it to the
whole-program values. A cap holds when it is 0 (a dwell, a stop, an exact stop, a reversal),
or when even the worst following speed lets the group reach it: the bound is
``reach_speed(0, L / 2)`` (see :func:`_commit_point`; the reachable speed is not monotone in
the end speed for jerk-limited ramps), with a relative margin of ``1e-9``. The groups before
that boundary are *committed*: forward pass, profiles, phase table and samples are computed
with the whole-program formulas (running sums continued from the previous window, so times
and path lengths carry the same bits), and the window restarts at that boundary with its
final speed. When no boundary qualifies, the window grows (doubles) until one does or the
program ends. The window is therefore bounded by the number of blocks within about two
stopping distances (plus one group), not by the program length.

Samples follow the whole-program rule (sample ``i`` at ``i / rate_hz``, owned by the last
phase starting at or before it; the last sample is the program end). A corner's velocity step
goes to the sample nearest the junction, which may lie before the window's first sample or
after its last: the samples from ``rint(t_window_end / T)`` on are held back until the next
window's steps are known, and steps beyond the window's samples are carried forward.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, fields, replace
from itertools import chain
import math

import numpy as np

from .lookahead import BlockGroups, group_blocks, path_cumsum, through_acceleration
from .motion import Motion
from .phases import (corner_terms, junction_times, phase_table, PlannedWindow, step_rows,
                     window_corners)
from .profiles import plan_profiles, reach_speed
from ..gcode import Move
from .chunks import Chunk, GridCursor, PendingSteps, WindowSampler
from .segments import (Collector, segment_geometry, junction_speeds, path_limits, PLAN_AXES,
                       REST)
from .standstill import first_grid_index, standstill_runs
from .trajectory import limits_array, rest_rotary
from ..machine import AxisLimits, PlannerOptions

__all__ = ['DEFAULT_CHUNK_SAMPLES', 'WINDOW_BLOCKS', 'iter_plan',
           'iter_motion', 'concat_motion', 'PlanEstimate', 'estimate_plan', 'grid_samples']

DEFAULT_CHUNK_SAMPLES = 1 << 16   # samples per Motion chunk (65 536: 65.5 s at 1 kHz)
WINDOW_BLOCKS = 4096              # blocks read before the first commit attempt of a window
_SATURATION_MARGIN = 1e-9         # relative margin for "the cap holds whatever follows"


def _take(obj, count: int):
    """The first ``count`` rows of every array/list field of a dataclass."""
    return replace(obj, **{f.name: getattr(obj, f.name)[:count] for f in fields(obj)})


def _commit_point(v: list[float], usable: list[float], amax: list[float], jmax: list[float],
                  complete: int, ended: bool) -> tuple[int, list[float]]:
    """Backward pass over the complete groups; return the commit boundary.

    Returns ``(k, speeds)``: boundaries ``0..k`` have their whole-program backward-pass speeds
    (``k = 0``: nothing can be committed yet).

    The speed after the last complete group is unknown (between 0 and its cap), and
    :func:`.profiles.reach_speed` is not monotone in the end speed (a jerk-limited ramp from
    a low speed may reach higher than one from a slightly higher speed), so the bound used is
    one that holds for every end speed: a ramp from ``x`` to ``v`` covers at most ``v T(v)``
    (``T`` the ramp duration, increasing in the speed change), twice the distance from rest
    to ``v``, hence ``reach_speed(x, L) >= reach_speed(0, L / 2)`` for all ``x >= 0``.
    A boundary whose cap is 0, or at most a lower bound of the next speed, or at most that
    reach from ``L / 2``, keeps its cap whatever follows.
    """
    low = list(v)
    exact = ended
    k = complete if ended else 0
    next_low = 0.0           # lower bound of the (unknown) speed at the next boundary
    for i in range(complete - 1, 0, -1):
        vi = low[i]
        if exact:
            nxt = low[i + 1]
            if vi > nxt:
                low[i] = min(vi, reach_speed(nxt, usable[i], amax[i], jmax[i]))
            continue
        bound = reach_speed(0.0, 0.5 * usable[i], amax[i], jmax[i])
        if (vi == 0.0 or vi <= next_low * (1.0 - _SATURATION_MARGIN)
                or bound >= vi * (1.0 + _SATURATION_MARGIN)):
            exact = True
            k = i
        else:
            next_low = min(vi, bound) * (1.0 - _SATURATION_MARGIN)
    return k, low


def iter_plan(moves: Iterable[Move], limits: Mapping[str, AxisLimits], *,
              options: PlannerOptions = PlannerOptions(), file: str = '',
              window_blocks: int = WINDOW_BLOCKS,
              on_move: Callable[[int], None] | None = None) -> Iterator[PlannedWindow]:
    """Plan ``moves`` window by window (see the module docstring).

    Parameters
    ----------
    moves
        Canonical moves in program order: ``Program.moves`` or a generator.
    limits
        Kinematic limits per machine axis (as for :func:`.trajectory.plan`).
    options
        Planner options (the sample rate is not used here).
    file
        Program file, for error messages.
    window_blocks
        Blocks read before a window is first tried for a commit (it doubles while nothing
        can be committed).
    on_move
        Called with the number of moves read so far, once per window.

    Yields
    ------
    PlannedWindow
        Committed windows in time order; the last has ``final=True``. Nothing is yielded for
        a program without motion.

    Raises
    ------
    PlanningError
        As :func:`.trajectory.plan`, naming the move's line.
    """
    lim = limits_array(limits, file)
    collector = Collector(file, dims=lim.shape[1])
    it = iter(moves)
    ended = False
    read = 0
    want = max(int(window_blocks), 2)
    v_entry, t_offset, path_start = 0.0, 0.0, 0.0
    tan_entry: np.ndarray | None = None
    cycle_s = options.cycle_s
    while True:
        while not ended and len(collector) < want:
            mv = next(it, None)
            if mv is None:
                ended = True
                break
            collector.add(mv)
            read += 1
        if on_move is not None:
            on_move(read)
        m = len(collector)
        if m == 0:
            return
        seg = collector.segments(final=ended)
        geo = segment_geometry(seg, file)
        vmax, amax, jmax = path_limits(seg, geo, lim, file)
        if options.profile == 'trapezoid':
            jmax = np.full(m, np.inf)
        vj = junction_speeds(seg, geo, vmax, amax, options.corner_tolerance_m, lim[1],
                             cycle_s)
        a_through = through_acceleration(geo.tan1[:-1], geo.tan0[1:], geo.r_min[:-1],
                                         geo.r_min[1:], vj[1:-1], lim[1], cycle_s)
        grp = group_blocks(geo.length, vmax, amax, jmax, vj, a_through,
                           rest=seg.kind == REST, path_start_m=path_start)
        g = grp.first.size
        # a junction's grouping needs two blocks after it (the next block's ceiling depends on
        # the junction after that): groups ending at or before junction m - 3 are complete
        complete = g if ended else int(np.searchsorted(grp.first[1:], m - 2, side='right'))
        v = grp.v_junction.tolist()
        v[0] = v_entry
        usable = (grp.length * (1.0 - 1e-9)).tolist()
        ga, gj = grp.amax.tolist(), grp.jmax.tolist()
        k, low = _commit_point(v, usable, ga, gj, complete, ended)
        if k == 0:
            want = 2 * max(m, want)
            continue
        want = max(int(window_blocks), 2)
        fwd = low[:k + 1]
        for i in range(k):
            if fwd[i + 1] > fwd[i]:
                fwd[i + 1] = min(fwd[i + 1], reach_speed(fwd[i], usable[i], ga[i], gj[i]))
        gv = np.asarray(fwd)
        nb = int(grp.first[k]) if k < g else m
        last = ended and k == g
        cgrp = BlockGroups(first=grp.first[:k], group_of=grp.group_of[:nb],
                           offset=grp.offset[:nb], length=grp.length[:k], vmax=grp.vmax[:k],
                           amax=grp.amax[:k], jmax=grp.jmax[:k], v_junction=gv,
                           through=grp.through[:max(nb - 1, 0)])
        cseg, cgeo = _take(seg, nb), _take(geo, nb)
        prof = plan_profiles(cgrp.length, gv[:-1], gv[1:], cgrp.vmax, cgrp.amax, cgrp.jmax)
        t_start, phases = phase_table(prof, gv, cseg.dwell[cgrp.first], t_offset)
        yield PlannedWindow(seg=cseg, geo=cgeo, groups=cgrp, t_start=t_start, phases=phases,
                            path_start_m=path_start, tan_entry=tan_entry, final=last)
        if last:
            return
        v_entry = float(gv[-1])
        t_offset = float(t_start[-1])
        path_start = float(path_cumsum(cgeo.length, path_start)[-1])
        tan_entry = cgeo.tan1[-1].copy()
        collector.drop(nb)


def iter_motion(moves: Iterable[Move], limits: Mapping[str, AxisLimits], *,
                options: PlannerOptions = PlannerOptions(), file: str = '',
                chunk_samples: int = DEFAULT_CHUNK_SAMPLES, window_blocks: int = WINDOW_BLOCKS,
                total_moves: int | None = None, duration_s: float | None = None,
                progress: Callable[[float], None] | None = None,
                compact_min_samples: int = 0) -> Iterator[Motion]:
    """Plan ``moves`` and yield the sampled motion in chunks of at most ``chunk_samples``.

    The concatenated chunks equal :func:`.trajectory.plan` of the same moves (same samples,
    values within rounding of the continued running sums; see the module docstring).

    Parameters
    ----------
    moves
        Canonical moves in program order: ``Program.moves`` or a generator.
    limits
        Kinematic limits per machine axis; its keys become ``Motion.axes``.
    options
        Sample rate, profile, corner tolerance, interpolation cycle.
    file
        Program file (error messages, ``Motion.source``).
    chunk_samples
        Largest chunk [rows], ``>= 2``.
    window_blocks
        Passed on to :func:`iter_plan`.
    total_moves
        Number of moves, if known (``len(program.moves)``), for ``progress``.
    duration_s
        Program duration, if known (:func:`estimate_plan`): ``progress`` then reports the
        fraction of time sampled, which also advances through a long dwell.
    progress
        Called with the fraction of time sampled (with ``duration_s``) or of moves planned
        (with ``total_moves``).
    compact_min_samples
        0 (default): every sample is a row. Otherwise the interior of every standstill phase
        (a dwell) of at least this many samples is left out of the rows and listed in
        ``Motion.gaps`` (:mod:`.standstill`); chunks then hold up to ``chunk_samples`` rows.

    Yields
    ------
    Motion
        Consecutive chunks; every chunk has at least one row.
    """
    if chunk_samples < 2:
        msg = f'chunk_samples must be >= 2, got {chunk_samples}'
        raise ValueError(msg)
    limits_array(limits, file)
    axes = tuple(limits)
    cols = [PLAN_AXES.index(a) for a in axes]
    k = len(axes)
    rate = options.rate_hz
    sample_s = 1.0 / rate
    # the first move is kept for a program without motion; chain() passes the others on
    # without a Python frame per move
    source = iter(moves)
    first = next(source, None)
    if first is not None:
        source = chain((first,), source)

    def on_move(count: int) -> None:
        if progress is not None and total_moves and not duration_s:
            progress(min(count / total_moves, 1.0))

    def emit(count: int, *, report: bool = True) -> Motion:
        motion = chunk.take(count, axes, file)
        if report and progress is not None and duration_s:
            progress(min(float(motion.t[-1]) / duration_s, 1.0))
        return motion

    chunk = Chunk(k, chunk_samples)
    steps = PendingSteps.none(k)                     # not yet wholly in the rows
    cycle_s = options.cycle_s
    next_index = 0
    any_window = False
    for win in iter_plan(source, limits, options=options, file=file,
                         window_blocks=window_blocks, on_move=on_move):
        any_window = True
        t_j, v_j, tan_in, tan_out = window_corners(
            win, *junction_times(win.groups, win.t_start, win.groups.v_junction, win.phases))
        tc, dv = corner_terms(t_j, v_j, tan_in, tan_out, cols)
        steps = steps.join(*step_rows(tc, sample_s, cycle_s), tc, dv)
        t_end = win.t_end
        t_last = None
        if win.final:
            n_last = int(math.floor(t_end * rate + 1e-9))
            stop_index = max(n_last + 1, next_index)
            if stop_index > next_index and t_end - (stop_index - 1) / rate <= 1e-9:
                t_last = t_end               # the last grid sample becomes the program end
            else:
                stop_index += 1              # one more sample at the program end
                t_last = t_end
            steps = steps.clip(stop_index - 1)
            final_until = stop_index         # samples below this have all their steps
        else:
            stop_index = first_grid_index(t_end, rate)
            # later junctions (at or after the window end) reach back to these samples
            final_until = int(np.rint(t_end / sample_s))
            if cycle_s > sample_s:
                # a step spread over the samples of its cycle reaches back half a cycle
                final_until = min(final_until,
                                  int(np.ceil((t_end - 0.5 * cycle_s) / sample_s)))
        # rows held from the previous window may now be complete
        steps = chunk.apply(steps, sample_s)
        if chunk.fill == chunk.capacity:
            yield emit(chunk.fill)
        sampler = WindowSampler(win, cols)
        runs = []
        if compact_min_samples > 0:
            limit = stop_index - 2 if win.final else min(stop_index, final_until) - 1
            runs = standstill_runs(win.phases, rate_hz=rate, lo=next_index, hi=limit,
                                   min_samples=compact_min_samples)
            if runs and steps.lo.size:
                # a run keeps no sample a pending velocity step would land on
                runs = [r for r in runs if not steps.touch(r[0] - 1, r[1])]
        cursor = GridCursor([next_index] + [b for _a, b, _p in runs],
                            [a for a, _b, _p in runs] + [stop_index])
        while not cursor.done:
            index, gaps = cursor.take(chunk.space)
            if index.size == 0:
                break
            sampler.fill(chunk, index, gaps, rate,
                         t_last if index[-1] == stop_index - 1 else None)
            steps = chunk.apply(steps, sample_s)
            if chunk.fill == chunk.capacity:
                # rows from final_until on wait for the next window's steps
                ready = int(np.searchsorted(chunk.index[:chunk.fill], final_until))
                if ready:
                    yield emit(ready)
        next_index = stop_index
    if not any_window:
        start = first.start if first is not None else (0.0, 0.0, 0.0)
        rot = rest_rotary([first] if first is not None else [])
        pos = np.asarray(start + rot, dtype=float)[cols][None, :]
        yield Motion(t=np.zeros(1), axes=axes, pos=pos, vel=np.zeros_like(pos),
                     acc=np.zeros_like(pos), line=np.zeros(1, np.int32), source=file)
        return
    if chunk.fill:
        yield emit(chunk.fill, report=False)


def concat_motion(chunks: Iterable[Motion]) -> Motion:
    """Join consecutive motion chunks into one :class:`Motion` (for small programs, tests).

    ``gaps`` are carried over with their rows shifted.
    """
    parts = list(chunks)
    if not parts:
        msg = 'concat_motion: no chunks'
        raise ValueError(msg)
    first = parts[0]
    gaps = []
    offset = 0
    for c in parts:
        gaps += [(row + offset, lo, count) for row, lo, count in c.gaps]
        offset += c.n_samples
    return Motion(t=np.concatenate([c.t for c in parts]), axes=first.axes,
                  pos=np.concatenate([c.pos for c in parts]),
                  vel=np.concatenate([c.vel for c in parts]),
                  acc=np.concatenate([c.acc for c in parts]),
                  line=np.concatenate([c.line for c in parts]), source=first.source,
                  gaps=tuple(gaps))


@dataclass(frozen=True)
class PlanEstimate:
    """What a run will cost, known from the plan before any sample is computed.

    Attributes
    ----------
    duration_s
        Program duration [s].
    samples
        Number of samples at the planned rate.
    moves
        Moves read.
    """

    duration_s: float
    samples: int
    moves: int


def estimate_plan(moves: Iterable[Move], limits: Mapping[str, AxisLimits], *,
                  options: PlannerOptions = PlannerOptions(), file: str = '') -> PlanEstimate:
    """Plan without sampling: duration and sample count (cost: per block, not per sample).

    Parameters
    ----------
    moves, limits, options, file
        As for :func:`iter_motion`.

    Returns
    -------
    PlanEstimate
        Duration, samples (as :func:`iter_motion` will produce) and moves read.
    """
    count = [0]

    def on_move(n: int) -> None:
        count[0] = n

    t_end = 0.0
    for win in iter_plan(moves, limits, options=options, file=file, on_move=on_move):
        t_end = win.t_end
    return PlanEstimate(duration_s=t_end, samples=grid_samples(t_end, options.rate_hz),
                        moves=count[0])


def grid_samples(duration_s: float, rate_hz: float) -> int:
    """Samples of the uniform grid of ``rate_hz`` over ``duration_s`` with the program end
    as the last sample, as :func:`iter_motion` makes them (one more where the end is not on
    the grid)."""
    n_last = int(math.floor(duration_s * rate_hz + 1e-9))
    return n_last + 1 + (1 if duration_s - n_last / rate_hz > 1e-9 else 0)
