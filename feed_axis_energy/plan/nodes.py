"""Quadrature nodes on the planned phases: the motion where an integral over time is exact.

Inside a phase of constant jerk the path speed is quadratic in time, the path acceleration
linear and the path position cubic; along one straight block every axis moves by that times
a constant direction (:func:`.phases.sample_phases`). A *piece* is a phase cut at the block
junctions inside it, so the motion of every axis is one polynomial on a piece (an arc's axes
are smooth, not polynomial, functions of it). An integral over time of a function of the
motion (power, force times speed, a loss model) is then the sum over pieces of Gauss-Legendre
quadrature: ``order`` nodes integrate a polynomial of degree ``2 order - 1`` exactly, and a
smooth function (a power regression of the speed, an arc's sine and cosine) to an error that
falls quickly with the order. The nodes are evaluated by the same code that evaluates the
sample grid, so whatever is computed per sample is computed per node with the same
physics; only the weights differ (the piece's length times the rule's weights, instead of
the trapezoid's sample interval).

The cost grows with the moves (pieces x order), not with duration x sample rate.

Where an axis stops and turns inside an arc (its speed changes sign: Coulomb friction
jumps there) the piece is cut as well (:func:`_arc_turns`); a kink the motion does not show
(a force changing sign under a screw efficiency, braking power cut at zero) is the caller's
to find and pass as ``cuts`` (:mod:`feed_axis_energy.sim.quadrature` does).

A non-tangent junction passed at speed changes the axis velocities by ``dv`` within one
interpolation cycle ``T`` centred on it (:mod:`.trajectory`, *Corners*): here as a ramp, the
velocity going linearly from before to after over ``[t_c - T/2, t_c + T/2]`` with ``dv / T``
added to the acceleration (the position's bump of at most ``|dv| T / 8`` is left out, as in
the samples); the pieces are cut at both ends of the ramp. A ramp can reach into the
neighbouring window: :func:`iter_window_motions` gives every window the ramps of its
neighbours as well. The sampled grid at rates above ``1 / T`` spreads the step over the same
cycle (:func:`.phases.apply_steps`) and converges to this.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..gcode import Move
from ..machine import AxisLimits, PlannerOptions
from .chunks import WindowSampler
from .motion import Motion
from .phases import (corner_terms, give_steps, junction_times, path_times, PlannedWindow,
                     sample_phases, step_rows, window_corners)
from .segments import ARC, PLAN_AXES
from .stream import iter_plan

__all__ = ['DEFAULT_ORDER', 'NodeChunk', 'gauss_legendre', 'iter_nodes', 'iter_window_motions',
           'WindowMotion']

DEFAULT_ORDER = 5
"""Gauss-Legendre nodes per piece: exact for polynomials of degree 9 in time."""


@lru_cache(maxsize=16)
def gauss_legendre(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes in ``[0, 1]`` and their weights (summing to 1) of the ``order``-point rule."""
    if order < 1:
        raise ValueError(f'order must be >= 1, got {order}')
    x, w = np.polynomial.legendre.leggauss(order)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    x.setflags(write=False)
    w.setflags(write=False)
    return x, w


@dataclass(frozen=True)
class NodeChunk:
    """The motion at the quadrature nodes of consecutive pieces, and each node's weight.

    Attributes
    ----------
    motion
        :class:`.Motion` whose rows are the nodes, in time order (``t``, per-axis ``pos``,
        ``vel``, ``acc``, the source ``line`` of each node's block).
    weight_s
        ``(n,)`` quadrature weight of every node [s]: ``sum(weight_s * f)`` is the integral
        of ``f`` over the pieces' time.
    piece
        ``(n,)`` index of the node's piece, counted from the program start.
    t_begin, t_end
        The time the pieces cover [s].
    """

    motion: Motion
    weight_s: np.ndarray
    piece: np.ndarray
    t_begin: float
    t_end: float


class WindowMotion:
    """One planned window's motion at any times, its pieces and their quadrature nodes.

    The grid sampler's per-window setup (:class:`.chunks.WindowSampler`: block lines, block
    locator, directions) and the window's junctions, arc turns and corners are made once and
    reused by every evaluation (probes, root finding, rules of several orders).

    ``corner_t``, ``corner_dv``: the window's own non-tangent junctions passed at speed (the
    one with the previous window at its start included), their times ``(h,)`` [s] and
    per-axis velocity steps ``(h, k)`` [m/s]. Until :meth:`spread` is called the motion
    shows each as a jump at its time.
    """

    def __init__(self, win: PlannedWindow, axes: tuple[str, ...], *, file: str = '') -> None:
        self.win = win
        self.axes = axes
        self.file = file
        self.cols = [PLAN_AXES.index(a) for a in axes]
        self._sampler = WindowSampler(win, self.cols)
        self._junctions = junction_times(win.groups, win.t_start, win.groups.v_junction,
                                         win.phases)
        t0, dur = win.phases[0], win.phases[1]
        # the edges every piece set has: phases, block junctions, arc turns, the window
        self._edges = np.concatenate((t0, t0 + dur, self._junctions[0],
                                      _arc_turns(win, self.cols),
                                      np.array([win.t_begin, win.t_end])))
        t_j, v_j, tan_in, tan_out = window_corners(win, *self._junctions)
        self.corner_t, self.corner_dv = corner_terms(t_j, v_j, tan_in, tan_out, self.cols)
        self._ramp_start = np.zeros(0)
        self._ramp_t = np.zeros(0)
        self._ramp_dv = np.zeros((0, len(self.cols)))
        self._cycle_s = 0.0

    def spread(self, tc: np.ndarray, dv: np.ndarray, cycle_s: float) -> None:
        """Spread the velocity steps ``dv`` at ``tc`` (this window's and its neighbours')
        over one interpolation cycle ``cycle_s`` each (see the module docstring); the
        pieces are cut where a ramp starts and ends."""
        half = 0.5 * cycle_s
        order = np.argsort(tc - half, kind='stable')
        self._ramp_start = tc[order] - half
        self._ramp_t, self._ramp_dv = tc[order], dv[order]
        self._cycle_s = float(cycle_s)
        self._edges = np.concatenate((self._edges, tc - half, tc + half))

    @property
    def ramps(self) -> tuple[np.ndarray, np.ndarray, float]:
        """The velocity steps spread here (:meth:`spread`): junction times ``(h,)`` [s],
        per-axis steps ``(h, k)`` [m/s] and the cycle [s]."""
        return self._ramp_t, self._ramp_dv, self._cycle_s

    def at(self, t: np.ndarray, *, ramps: bool = True) -> Motion:
        """The motion at the times ``t`` (inside the window), evaluated as the sample grid is
        (:func:`.phases.sample_phases`), the velocity steps as ramps (:meth:`spread`;
        ``ramps=False``: the path's own motion, each step a jump at its junction)."""
        sampler, win = self._sampler, self.win
        t = np.asarray(t, dtype=float)
        t0 = sampler.t0
        # each time belongs to the phase it lies in (phases are sorted by start time)
        k = np.clip(np.searchsorted(t0, t, side='right') - 1, 0, max(t0.size - 1, 0))
        n = t.size
        pos = np.empty((n, len(self.cols)), order='F')
        vel = np.empty((n, len(self.cols)), order='F')
        acc = np.empty((n, len(self.cols)), order='F')
        mi = sample_phases(t, k, win.phases, sampler.locate, win.seg, win.geo, self.cols,
                           sampler.p0c, sampler.uc, out=(pos, vel, acc))
        if ramps and self._ramp_t.size:
            self._add_ramps(t, vel, acc)
        return Motion(t=t, axes=self.axes, pos=pos, vel=vel, acc=acc, line=sampler.lines[mi],
                      source=self.file)

    def sampled(self, index: np.ndarray, rate_hz: float) -> Motion:
        """Grid samples ``index`` (sorted; times ``index / rate_hz``, inside the window) as
        the sample grid holds them: the path's motion with the velocity steps the samples
        carry (:func:`.phases.step_rows`, :func:`.phases.apply_steps`; the steps of the
        corners given to :meth:`spread`)."""
        index = np.asarray(index, dtype=np.int64)
        t = index / rate_hz
        motion = self.at(t, ramps=False)
        tc, dv, cycle = self.ramps
        if tc.size:
            sample_s = 1.0 / rate_hz
            give_steps(t, index, *step_rows(tc, sample_s, cycle), tc, dv, sample_s,
                       vel=motion.vel, acc=motion.acc)
        return motion

    def _add_ramps(self, t: np.ndarray, vel: np.ndarray, acc: np.ndarray) -> None:
        """Velocity and acceleration of the ramps covering each time (ramps of one width,
        sorted by start: those covering ``t`` are the last ones starting at or before it)."""
        start, tc, dv, cycle = self._ramp_start, self._ramp_t, self._ramp_dv, self._cycle_s
        last = np.searchsorted(start, t, side='right') - 1
        back = 0
        while True:
            i = last - back
            inside = (i >= 0) & (t < start[np.maximum(i, 0)] + cycle)
            if not np.any(inside):
                break
            rows = np.nonzero(inside)[0]
            r = i[rows]
            frac = (t[rows] - start[r]) / cycle
            share = np.where(t[rows] >= tc[r], frac - 1.0, frac)
            vel[rows] += dv[r] * share[:, None]
            acc[rows] += dv[r] * (1.0 / cycle)
            back += 1

    def pieces(self, cuts: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Start and end times [s] of the pieces: the phases cut at the block junctions,
        where an axis turns on an arc, where a ramp starts and ends, and at the times
        ``cuts`` (the caller's own, e.g. where a force changes sign)."""
        win = self.win
        edges = (self._edges if cuts is None else
                 np.concatenate((self._edges, np.asarray(cuts, dtype=float))))
        edges = np.unique(edges)
        edges = edges[(edges >= win.t_begin) & (edges <= win.t_end)]
        a, b = edges[:-1], edges[1:]
        keep = b > a
        return a[keep], b[keep]

    def nodes(self, order: int = DEFAULT_ORDER, *,
              pieces: tuple[np.ndarray, np.ndarray] | None = None,
              first_piece: int = 0) -> NodeChunk:
        """The quadrature nodes of ``order`` points on ``pieces`` (default: :meth:`pieces`)."""
        x, w = gauss_legendre(order)
        a, b = self.pieces() if pieces is None else pieces
        h = b - a
        t = (a[:, None] + h[:, None] * x[None, :]).ravel()
        weight = (h[:, None] * w[None, :]).ravel()
        piece = np.repeat(np.arange(first_piece, first_piece + a.size), order)
        return NodeChunk(motion=self.at(t), weight_s=weight, piece=piece,
                         t_begin=self.win.t_begin, t_end=self.win.t_end)


def iter_window_motions(moves: Iterable[Move], limits: Mapping[str, AxisLimits], *,
                        options: PlannerOptions = PlannerOptions(), file: str = '',
                        on_move: Callable[[int], None] | None = None
                        ) -> Iterator[WindowMotion]:
    """Plan ``moves`` (:func:`.stream.iter_plan`) and yield each window's
    :class:`WindowMotion` with the velocity steps of its own corners and of its neighbours'
    spread over the interpolation cycle (``options.cycle_s``). A window is yielded once the
    next one is planned (a corner at its end belongs to the next); memory is two windows.
    ``on_move``: as :func:`.stream.iter_plan` (moves read so far, once per window).

    Raises
    ------
    PlanningError
        As :func:`.stream.iter_plan`.
    """
    axes = tuple(limits)
    cycle = options.cycle_s
    prev: WindowMotion | None = None
    held: WindowMotion | None = None
    for win in iter_plan(moves, limits, options=options, file=file, on_move=on_move):
        now = WindowMotion(win, axes, file=file)
        if held is not None:
            _spread_around(held, prev, now, cycle)
            yield held
        prev, held = held, now
    if held is not None:
        _spread_around(held, prev, None, cycle)
        yield held


def _spread_around(at: WindowMotion, prev: WindowMotion | None, after: WindowMotion | None,
                   cycle_s: float) -> None:
    near = [w for w in (prev, at, after) if w is not None]
    at.spread(np.concatenate([w.corner_t for w in near]),
              np.concatenate([w.corner_dv for w in near]), cycle_s)


def _arc_turns(win: PlannedWindow, cols: list[int]) -> np.ndarray:
    """Times at which an axis moving on an arc of the window stops and turns (its speed
    changes sign inside the block: a kink of anything with the sign of the speed, Coulomb
    friction): the pieces are cut there too."""
    geo, seg = win.geo, win.seg
    arcs = np.nonzero((seg.kind == ARC) & (geo.length > 0.0))[0]
    if arcs.size == 0:
        return np.zeros(0)
    lo = np.minimum(geo.theta0[arcs], geo.theta0[arcs] + geo.sweep[arcs])
    hi = np.maximum(geo.theta0[arcs], geo.theta0[arcs] + geo.sweep[arcs])
    found_block, found_theta = [], []
    # in-plane a: d(pos)/d(theta) = kr cos - r sin (zero near k pi); b: kr sin + r cos (zero
    # near pi/2 + k pi); a spiral (kr != 0) moves the zeros a little: Newton from there
    for shift, role in ((0.0, 0), (0.5 * np.pi, 1)):
        axis = geo.perm[arcs, role]
        moving = np.isin(axis, cols)
        if not np.any(moving):
            continue
        k_lo = np.floor((lo - shift) / np.pi) - 1
        count = (np.ceil((hi - shift) / np.pi) + 1 - k_lo).astype(np.int64) + 1
        which = np.repeat(np.arange(arcs.size), count)
        k = np.repeat(k_lo, count) + (np.arange(which.size)
                                      - np.repeat(np.cumsum(count) - count, count))
        th = shift + k * np.pi
        b = arcs[which]
        r0, kr, th0 = geo.r0[b], geo.kr[b], geo.theta0[b]
        for _ in range(4):
            r = r0 + kr * (th - th0)
            if role == 0:
                f = kr * np.cos(th) - r * np.sin(th)
                df = -2.0 * kr * np.sin(th) - r * np.cos(th)
            else:
                f = kr * np.sin(th) + r * np.cos(th)
                df = 2.0 * kr * np.cos(th) - r * np.sin(th)
            th = th - np.where(df != 0.0, f / np.where(df != 0.0, df, 1.0), 0.0)
        keep = moving[which] & (th > lo[which]) & (th < hi[which])
        found_block.append(b[keep])
        found_theta.append(th[keep])
    block = np.concatenate(found_block) if found_block else np.zeros(0, np.int64)
    if block.size == 0:
        return np.zeros(0)
    theta = np.concatenate(found_theta)
    s_block = (theta - geo.theta0[block]) * geo.length[block] / geo.sweep[block]
    grp = win.groups
    return path_times(grp.group_of[block], grp.offset[block] + s_block, win.phases)[0]


def iter_nodes(moves: Iterable[Move], limits: Mapping[str, AxisLimits], *,
               options: PlannerOptions = PlannerOptions(), file: str = '',
               order: int = DEFAULT_ORDER) -> Iterator[NodeChunk]:
    """Plan ``moves`` (:func:`iter_window_motions`, window by window) and yield the
    quadrature nodes of every window; memory is two windows' pieces, whatever the program's
    length.

    Raises
    ------
    PlanningError
        As :func:`.stream.iter_plan`.
    """
    pieces = 0
    for at in iter_window_motions(moves, limits, options=options, file=file):
        chunk = at.nodes(order, first_piece=pieces)
        if chunk.piece.size:
            pieces = int(chunk.piece[-1]) + 1
        yield chunk
