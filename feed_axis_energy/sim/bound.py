"""How far the sampled sums can lie from the energy by phase: a bound per axis (issue 23).

The sampled pipeline sums the drawn power ``f`` of an axis by the trapezoid rule over the
grid ``t_i = i T`` (:mod:`.stream`); the energy by phase (:mod:`.quadrature`) integrates the
same model exactly (to its quadrature error). Their difference, per axis, is bounded here
from the phase representation itself, the trapezoid sum written as a sum over cells
``[t_i - T/2, t_i + T/2]`` of ``T f_i``:

* **Smooth pieces**: on a cell where ``f`` is smooth, ``|T f(t_i) - integral| <= T^3/24
  max|f''|`` (the midpoint rule), so a piece of length ``h`` contributes at most
  ``T^2 / 24 h max|f''|``; ``f''`` is taken from the interpolant of the piece's nodes (the
  largest of its values at the nodes and ends).
* **Edges** (where a piece ends: ``f`` or its slope jumps, a phase switch, a sign change of
  the force under a screw efficiency or of the braking power): a jump ``df`` inside a cell
  adds at most ``T |df| / 2``, a kink with a slope change ``df'`` at most ``T^2 |df'| / 8``;
  the same at the program's start and end (half cells).
* **Pieces shorter than two samples** (a sign change close to an edge, the halves of a
  corner's ramp at low rates): computed as the corners' cells are (next item).
* **Corners passed at speed**: near a junction the samples do not hold the model's motion
  at their times (the velocity step sits in the samples of its cycle, or in one sample at
  ``T >= cycle``, :func:`feed_axis_energy.plan.phases.apply_steps`), so the cells around it
  are not bounded but computed: ``sum T f~_i`` over them (the samples as the grid holds them,
  :meth:`feed_axis_energy.plan.WindowMotion.sampled`) minus the integral over the same cells
  (quadrature on the pieces cut at the cell boundaries); the absolute value of that per run
  of overlapping cells counts.

Added to it: the estimated error of the energy by phase itself (its quadrature error), so
that the bound is of the distance to the model's exact energy, and the sums' rounding
(:data:`ROUNDING` of the integral of ``|f|``).

The bound holds for the sampled pipeline's own sums (:func:`.stream.simulate_stream`) at
rate ``1 / T``; it is worst-case: the errors at the many edges of a program have both signs
and mostly cancel, so the observed differences are far below it.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..gcode import Move
from ..machine import Machine, PlannerOptions
from ..physics import apply_braking, compute_dynamics
from ..plan import gauss_legendre
from .quadrature import iter_window_nodes, PHASE_ORDER, weighted_sum, WindowNodes

__all__ = ['SamplingBound', 'sampling_bound', 'ROUNDING']

ROUNDING = 1e-11
"""Relative rounding allowed for the sums (of the integral of ``|f|``)."""


@dataclass(frozen=True)
class SamplingBound:
    """A bound of ``|sampled - by phase|`` per axis at one sample rate (:func:`sampling_bound`).

    Attributes
    ----------
    axes
        Axis names.
    rate_hz
        The sample rate the bound is for [Hz].
    energy_j
        Energy drawn per axis by phase [J], ``(k,)``.
    bound_j
        The bound per axis [J], ``(k,)``: ``smooth_j + edges_j + corners_j +
        quadrature_j + rounding_j``.
    smooth_j, edges_j, corners_j
        The sampled sums' parts [J], ``(k,)`` (see the module docstring).
    quadrature_j
        The estimated error of the energy by phase itself [J], ``(k,)`` (difference from
        a lower rule on the same rows, :class:`.quadrature.WindowNodes` ``low_j``): the
        sums converge to the model's exact energy, which lies within this of ``energy_j``.
    rounding_j
        ``1e-11`` of the integral of ``|f|`` per axis [J]: the floating-point rounding of
        the sums (where the corners' cells are the whole difference, both sides are the same
        number up to it).
    corners
        Runs of cells around corners computed exactly.
    """

    axes: tuple[str, ...]
    rate_hz: float
    energy_j: np.ndarray
    bound_j: np.ndarray
    smooth_j: np.ndarray
    edges_j: np.ndarray
    corners_j: np.ndarray
    quadrature_j: np.ndarray
    rounding_j: np.ndarray
    corners: int


@lru_cache(maxsize=8)
def _maps(order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """From the node values of a piece on ``[-1, 1]``: the Legendre coefficients
    ``(order, order)``, the first derivative at both ends ``(2, order)`` and the second
    derivative at the nodes and ends ``(order + 2, order)`` (from the coefficients)."""
    x, w = gauss_legendre(order)
    xs = 2.0 * x - 1.0
    vander = np.polynomial.legendre.legvander(xs, order - 1)
    coeff = (2.0 * np.arange(order)[:, None] + 1.0) * (w[None, :] * vander.T)
    eye = np.eye(order)
    ends = np.array([-1.0, 1.0])
    d1 = np.array([np.polynomial.legendre.legval(ends, np.polynomial.legendre.legder(e))
                   for e in eye]).T
    pts = np.concatenate(([-1.0], xs, [1.0]))
    d2 = np.array([np.polynomial.legendre.legval(pts, np.polynomial.legendre.legder(e, 2))
                   for e in eye]).T
    return coeff, d1, d2


class _State:
    """What :func:`_account` carries from window to window."""

    def __init__(self) -> None:
        self.runs = 0                 # runs of corner cells computed
        self.first = True             # the next window is the program's first
        self.last: tuple[np.ndarray, np.ndarray] | None = None   # f, f' at the last end


class _Window:
    """One window's pieces in time order, the drawn power at their rows and its slopes."""

    def __init__(self, w: WindowNodes, order: int, T: float) -> None:
        self.w = w
        self.at = w.at
        self.t_begin, self.t_end = w.at.win.t_begin, w.at.win.t_end
        idx = np.argsort(w.piece_a, kind='stable')
        idx = idx[w.piece_b[idx] > w.piece_a[idx]]     # not the pieces cut (no length)
        self.a, self.b = w.piece_a[idx], w.piece_b[idx]
        p, npt = w.piece_a.size, w.points
        f = w.drawn_w.reshape(p, npt, w.drawn_w.shape[1])[idx]
        self.f0, self.f1 = f[:, 0, :], f[:, -1, :]
        coeff, d1, d2 = _maps(order)
        c = np.einsum('ij,pjk->pik', coeff, f[:, 1:-1, :])
        scale = 2.0 / np.maximum(self.b - self.a, 1e-300)
        ends = np.einsum('ij,pjk->pik', d1, c) * scale[:, None, None]
        self.df0, self.df1 = ends[:, 0, :], ends[:, 1, :]
        curv = np.abs(np.einsum('ij,pjk->pik', d2, c)).max(axis=1)
        # pieces shorter than two samples: their slopes and curvature from the nodes are
        # not what the cells see (and blow up as 1/h); their cells are computed instead
        self.short = (self.b - self.a) < 2.0 * T
        self.h_curv = weighted_sum(np.where(self.short, 0.0, (self.b - self.a) * scale ** 2),
                                   curv)                           # sum h max|f''|


def sampling_bound(moves: Iterable[Move], machine: Machine, *, rate_hz: float,
                   load_kg: float = 0.0, options: PlannerOptions | None = None,
                   file: str = '', order: int = PHASE_ORDER) -> SamplingBound:
    """The bound of the difference between the sampled energy at ``rate_hz`` and the energy
    by phase, per axis (see the module docstring).

    ``options`` are the planner's (``None``: the machine's); its ``rate_hz`` is not used.

    Raises
    ------
    ConfigError
        A machine the energy by phase does not cover yet.
    PlanningError
        As the planner.
    """
    if options is None:
        options = machine.planner.options()
    T = 1.0 / float(rate_hz)
    half_cycle = 0.5 * options.cycle_s
    k = len(machine.limits())
    parts = {'energy': np.zeros(k), 'low': np.zeros(k), 'abs': np.zeros(k),
             'smooth': np.zeros(k), 'edges': np.zeros(k), 'corners': np.zeros(k)}
    state = _State()
    held: list[_Window] = []
    for w in iter_window_nodes(moves, machine, load_kg=load_kg, options=options, file=file,
                               order=order):
        held.append(_Window(w, order, T))
        if len(held) >= 2:
            _account(held, len(held) - 2, T, half_cycle, rate_hz, machine, load_kg, order,
                     parts, state)
        if len(held) > 3:
            held.pop(0)
    if held:
        _account(held, len(held) - 1, T, half_cycle, rate_hz, machine, load_kg, order, parts,
                 state)
        if state.last is not None:
            # the program's end: the last sample is the end, less than T after the one
            # before (an uneven cell: a first-order term; at rest the slope is zero)
            parts['edges'] += T * T / 4.0 * np.abs(state.last[1])
    quadrature = np.abs(parts['energy'] - parts['low'])
    rounding = ROUNDING * parts['abs']
    bound = parts['smooth'] + parts['edges'] + parts['corners'] + quadrature + rounding
    return SamplingBound(axes=tuple(machine.limits()), rate_hz=float(rate_hz),
                         energy_j=parts['energy'], bound_j=bound, smooth_j=parts['smooth'],
                         edges_j=parts['edges'], corners_j=parts['corners'],
                         quadrature_j=quadrature, rounding_j=rounding, corners=state.runs)


def _account(held: list[_Window], i: int, T: float, half_cycle: float, rate: float,
             machine: Machine, load_kg: float, order: int, parts: dict,
             state: '_State') -> None:
    """Add window ``held[i]`` (its neighbours in ``held``) to the parts."""
    win = held[i]
    parts['energy'] += weighted_sum(win.w.weight_s, win.w.drawn_w)
    parts['low'] += win.w.low_j
    parts['abs'] += weighted_sum(win.w.weight_s, np.abs(win.w.drawn_w))
    parts['smooth'] += T * T / 24.0 * win.h_curv
    near = held[max(i - 1, 0):i + 2]
    runs = _runs(near, T, half_cycle)
    # runs that start in this window are computed here (each once)
    mine = [(lo, hi) for lo, hi in runs if win.t_begin <= lo * T - 0.5 * T < win.t_end]
    for lo, hi in mine:
        parts['corners'] += np.abs(_run_error(near, lo, hi, T, rate, machine, load_kg, order))
        state.runs += 1
    if win.a.size == 0:             # a window of no duration: no piece, no edge
        return
    # the edges: between this window's pieces and with the previous window's last piece
    f_prev, df_prev = state.last if state.last is not None else (None, None)
    t_edge = win.a
    f_before = np.vstack((win.f1[:1] * 0.0 if f_prev is None else f_prev[None, :],
                          win.f1[:-1]))
    df_before = np.vstack((win.df1[:1] * 0.0 if df_prev is None else df_prev[None, :],
                           win.df1[:-1]))
    jump = np.abs(win.f0 - f_before)
    kink = np.abs(win.df0 - df_before)
    if state.first:
        # the program's start: the half cell [0, T/2] of the first sample, |T/2 f(0) -
        # integral| <= T^2/8 max|f'| (no jump: nothing before)
        jump[0] = 0.0
        kink[0] = np.abs(win.df0[0])
        state.first = False
    spans = np.array([(lo * T - 0.5 * T, hi * T + 0.5 * T) for lo, hi in runs])
    if spans.size:
        j = np.searchsorted(spans[:, 0], t_edge, side='right') - 1
        inside = (j >= 0) & (t_edge <= spans[np.maximum(j, 0), 1])
        jump[inside] = 0.0
        kink[inside] = 0.0
    parts['edges'] += 0.5 * T * jump.sum(axis=0) + T * T / 8.0 * kink.sum(axis=0)
    state.last = (win.f1[-1], win.df1[-1])


def _runs(near: list[_Window], T: float, half_cycle: float) -> list[tuple[int, int]]:
    """Grid index ranges ``[lo, hi]`` of the cells around the corners and the pieces
    shorter than two samples of ``near``, those that overlap merged (one sample more on both
    sides than the samples that carry a step or touch the piece)."""
    tc = np.concatenate([x.at.corner_t for x in near])
    start = np.concatenate([tc - half_cycle] + [x.a[x.short] for x in near])
    end = np.concatenate([tc + half_cycle] + [x.b[x.short] for x in near])
    if start.size == 0:
        return []
    order = np.argsort(start, kind='stable')
    start, end = start[order], end[order]
    lo = np.maximum(np.floor(start / T).astype(np.int64) - 1, 0)
    hi = np.ceil(end / T).astype(np.int64) + 1
    runs: list[tuple[int, int]] = []
    for a, b in zip(lo.tolist(), hi.tolist()):
        if runs and a <= runs[-1][1] + 1:
            runs[-1] = (runs[-1][0], max(runs[-1][1], b))
        else:
            runs.append((a, b))
    return runs


def _run_error(near: list[_Window], lo: int, hi: int, T: float, rate: float,
               machine: Machine, load_kg: float, order: int) -> np.ndarray:
    """``sum T f~_i`` over the cells ``lo..hi`` minus the integral over them, per axis."""
    index = np.arange(lo, hi + 1, dtype=np.int64)
    t = index / rate
    k = len(machine.limits())
    sampled = np.zeros(k)
    for x in near:
        mine = (t >= x.t_begin) & (t < x.t_end)
        if np.any(mine):
            dyn = compute_dynamics(x.at.sampled(index[mine], rate), machine, load_kg=load_kg)
            drawn = apply_braking(dyn.torque_nm * dyn.omega_rad_s, braking=machine.braking)
            sampled += T * drawn.sum(axis=0)
    s0, s1 = lo * T - 0.5 * T, hi * T + 0.5 * T
    cells = s0 + T * np.arange(hi - lo + 2)
    xg, wg = gauss_legendre(order)
    exact = np.zeros(k)
    for x in near:
        a, b = max(s0, x.t_begin), min(s1, x.t_end)
        if b <= a:
            continue
        edges = np.concatenate((cells, x.a, x.b, [a, b]))
        edges = np.unique(edges[(edges >= a) & (edges <= b)])
        pa, pb = edges[:-1], edges[1:]
        keep = pb > pa
        pa, pb = pa[keep], pb[keep]
        h = pb - pa
        motion = x.at.at((pa[:, None] + h[:, None] * xg).ravel())
        dyn = compute_dynamics(motion, machine, load_kg=load_kg)
        drawn = apply_braking(dyn.torque_nm * dyn.omega_rad_s, braking=machine.braking)
        exact += weighted_sum((h[:, None] * wg).ravel(), drawn)
    return sampled - exact
