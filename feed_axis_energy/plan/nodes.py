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

Not yet covered here (issue 23, to come): the velocity steps of non-tangent corners passed at
speed (the sampled grid spreads each over one sample, :func:`.phases.corner_steps`), where a
piece's integrand has a kink inside (a sign change of an axis's speed on an arc, braking power
cut at zero) and the error bound of the rule.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..gcode import Move
from ..machine import AxisLimits, PlannerOptions
from .motion import Motion
from .phases import (BlockLocator, corner_terms, junction_times, PlannedWindow,
                     sample_phases)
from .segments import PLAN_AXES
from .trajectory import limits_array
from .stream import iter_plan

__all__ = ['DEFAULT_ORDER', 'NodeChunk', 'gauss_legendre', 'iter_nodes', 'window_nodes']

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
    corner_t, corner_dv
        The velocity steps of the non-tangent block junctions passed at speed in this
        window: their times ``(h,)`` [s] and per-axis steps ``(h, k)`` [m/s]. The pieces'
        motion is continuous up to them: the integral of an axis's acceleration over the
        nodes plus the sum of its steps is its speed change.
    """

    motion: Motion
    weight_s: np.ndarray
    piece: np.ndarray
    t_begin: float
    t_end: float
    corner_t: np.ndarray
    corner_dv: np.ndarray


def window_nodes(win: PlannedWindow, axes: tuple[str, ...], *, order: int = DEFAULT_ORDER,
                 file: str = '', first_piece: int = 0) -> NodeChunk:
    """The quadrature nodes of one planned window (:func:`.stream.iter_plan`)."""
    x, w = gauss_legendre(order)
    cols = [PLAN_AXES.index(a) for a in axes]
    t0, dur = win.phases[0], win.phases[1]
    t_j, v_j = junction_times(win.groups, win.t_start, win.groups.v_junction, win.phases)
    corner_t, corner_dv = _corners(win, t_j, v_j, cols)
    inside = t_j[(t_j > win.t_begin) & (t_j < win.t_end)]
    cuts = np.unique(np.concatenate((t0, t0 + dur, inside, [win.t_begin, win.t_end])))
    cuts = cuts[(cuts >= win.t_begin) & (cuts <= win.t_end)]
    a, b = cuts[:-1], cuts[1:]
    keep = b > a
    a, b = a[keep], b[keep]
    h = b - a
    t = (a[:, None] + h[:, None] * x[None, :]).ravel()
    weight = (h[:, None] * w[None, :]).ravel()
    piece = np.repeat(np.arange(first_piece, first_piece + a.size), order)
    # each node belongs to the phase it lies in (phases are sorted by start time)
    k = np.clip(np.searchsorted(t0, t, side='right') - 1, 0, max(t0.size - 1, 0))
    n = t.size
    pos = np.empty((n, len(cols)), order='F')
    vel = np.empty((n, len(cols)), order='F')
    acc = np.empty((n, len(cols)), order='F')
    locate = BlockLocator(win.groups, win.geo.length, path_start_m=win.path_start_m)
    mi = sample_phases(t, k, win.phases, locate, win.seg, win.geo, cols, win.seg.p0[:, cols],
                       win.geo.u[:, cols], out=(pos, vel, acc))
    lines = np.fromiter((mv.line for mv in win.seg.move), dtype=np.int32,
                        count=len(win.seg.move))
    motion = Motion(t=t, axes=axes, pos=pos, vel=vel, acc=acc, line=lines[mi], source=file)
    return NodeChunk(motion=motion, weight_s=weight, piece=piece, t_begin=win.t_begin,
                     t_end=win.t_end, corner_t=corner_t, corner_dv=corner_dv)


def _corners(win: PlannedWindow, t_j: np.ndarray, v_j: np.ndarray,
             cols: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Time and per-axis step of the window's corners (the junction with the previous
    window's last block included), as :func:`.stream.iter_motion` puts them on the grid."""
    geo = win.geo
    tan_in, tan_out = geo.tan1[:-1], geo.tan0[1:]
    if win.tan_entry is not None:
        t_j = np.concatenate(([win.t_begin], t_j))
        v_j = np.concatenate(([float(win.groups.v_junction[0])], v_j))
        tan_in = np.vstack((win.tan_entry[None, :], tan_in))
        tan_out = np.vstack((geo.tan0[:1], tan_out))
    _, tc, dv = corner_terms(t_j, v_j, tan_in, tan_out, cols, 1.0)
    return tc, dv


def iter_nodes(moves: Iterable[Move], limits: Mapping[str, AxisLimits], *,
               options: PlannerOptions = PlannerOptions(), file: str = '',
               order: int = DEFAULT_ORDER) -> Iterator[NodeChunk]:
    """Plan ``moves`` (:func:`.stream.iter_plan`, window by window) and yield the quadrature
    nodes of every window; memory is one window's pieces, whatever the program's length.

    Raises
    ------
    PlanningError
        As :func:`.stream.iter_plan`.
    """
    limits_array(limits, file)
    axes = tuple(limits)
    pieces = 0
    for win in iter_plan(moves, limits, options=options, file=file):
        chunk = window_nodes(win, axes, order=order, file=file, first_piece=pieces)
        if chunk.piece.size:
            pieces = int(chunk.piece[-1]) + 1
        yield chunk
