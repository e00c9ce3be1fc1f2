"""Energy by phase: each axis's energy as quadrature on the planned phases (issue 23, part 1).

The planner's phases (constant jerk) are cut into pieces where the motion is one smooth
function of time (:meth:`feed_axis_energy.plan.WindowMotion.pieces`: phases, block junctions,
an axis turning on an arc). Two things the motion does not show make the power kink inside
a piece: the screw's efficiency, applied one way where the motor drives (``F v >= 0``) and
the other way where the load drives it back, and the braking rule ``'dissipated'``, which
cuts negative ``M omega`` at zero. Both happen where a sign changes: the power is evaluated at
each piece's ends and quadrature nodes, and where the sign of ``F v`` or ``M omega`` of an
axis changes between two of these points the time of the change is found (regula falsi) and
the piece is cut there too. On every piece the energy is then the Gauss-Legendre sum of the
same per-sample dynamics (:func:`feed_axis_energy.physics.compute_dynamics`, the braking
rule) at its nodes. The rule of ``order`` nodes is compared with the rule of ``order - 2``
on the same pieces: their difference is the estimate of the quadrature's error that is
reported beside the energy.

The cost grows with the pieces (a handful per move), not with duration x sample rate.

Covered so far: the model of :func:`~feed_axis_energy.physics.compute_dynamics` (rigid-body
dynamics, passive resistances, screw efficiency, gravity) and the braking rule, per axis and
per source line and per cause (net), the velocity steps of corners passed at speed (G64) as
ramps over one interpolation cycle (:mod:`feed_axis_energy.plan.nodes`). Not yet (the sampled
pipeline, :mod:`.stream`, gives them): declared effects, the electrical side, the gross
energy per cause. A machine that declares effects or drives is refused with a
:class:`ConfigError`.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..gcode import Move
from ..machine import Machine, PlannerOptions
from ..physics import (apply_braking, cause_names, cause_powers, compute_dynamics,
                       LineEnergy)
from ..plan import gauss_legendre, iter_window_motions, WindowMotion

__all__ = ['PhaseEnergy', 'phase_energy', 'PHASE_ORDER']

PHASE_ORDER = 8
"""Gauss-Legendre nodes per piece (exact for polynomials of degree 15 in time)."""

_ROOT_STEPS = 60        # at most, to find where a sign changes (usually about ten)


@dataclass(frozen=True)
class PhaseEnergy:
    """Per-axis energy of a program by quadrature on its phases.

    Attributes
    ----------
    axes
        Axis names.
    energy_j
        Energy drawn per axis after the braking rule [J], ``(k,)``.
    mechanical_j
        ``integral M omega dt`` per axis before the braking rule [J], ``(k,)``.
    error_j
        Estimated quadrature error of ``energy_j`` [J], ``(k,)``: the difference from the
        rule with two nodes fewer on the same pieces.
    duration_s
        Time covered [s].
    causes, by_cause_j
        Cause names (:func:`~feed_axis_energy.physics.cause_names`) and the net energy of
        each cause per axis [J], ``(c, k)``: they add up to ``energy_j``.
    by_line
        Energy (after the braking rule, summed over the axes), time and energy per axis of
        every source line that has time (:class:`~feed_axis_energy.physics.LineEnergy`):
        each piece lies in one block, so the attribution is exact.
    pieces, nodes, sign_cuts
        Pieces integrated, nodes evaluated (both rules), cuts added where a sign changes.
    """

    axes: tuple[str, ...]
    energy_j: np.ndarray
    mechanical_j: np.ndarray
    error_j: np.ndarray
    duration_s: float
    causes: tuple[str, ...]
    by_cause_j: np.ndarray
    by_line: LineEnergy
    pieces: int
    nodes: int
    sign_cuts: int


def phase_energy(moves: Iterable[Move], machine: Machine, *, load_kg: float = 0.0,
                 options: PlannerOptions | None = None, file: str = '',
                 order: int = PHASE_ORDER) -> PhaseEnergy:
    """Energy per axis of ``moves`` on ``machine`` by quadrature on the planned phases.

    Raises
    ------
    ConfigError
        ``order < 3``, or a machine with declared effects or drives (not covered yet).
    PlanningError
        As the planner.
    """
    if order < 3:
        raise ConfigError(f'the quadrature needs at least 3 nodes per piece, got {order}',
                          key='order')
    if (machine.effects or machine.supply is not None
            or any(a.drive is not None for a in machine.axes)):
        raise ConfigError('energy by phase covers the machine without declared effects or '
                          'drives so far; simulate samples them', key='effects')
    if options is None:
        options = machine.planner.options()
    limits = machine.limits()
    axes = tuple(limits)
    k = len(axes)
    energy = np.zeros(k)
    low = np.zeros(k)
    mech = np.zeros(k)
    duration = 0.0
    pieces = nodes = cuts_added = 0
    lines = _ByLine(k)
    causes = cause_names()
    by_cause = np.zeros((len(causes), k))
    # only a sign that switches something is a kink: F v where the screw's efficiency is
    # not 1 (divided or multiplied by it), M omega where braking power is cut at zero
    eta = np.array([machine.axis(a).screw.efficiency for a in axes])
    watch = np.concatenate((eta != 1.0, np.full(k, machine.braking == 'dissipated')))
    for at in iter_window_motions(moves, limits, options=options, file=file):
        win = at.win
        cut = at.pieces()
        cuts = _sign_cuts(at, cut, watch, machine, load_kg, order)
        if cuts.size:
            cut = at.pieces(cuts)
        cuts_added += cuts.size
        for rule, into in ((order, energy), (order - 2, low)):
            chunk = at.nodes(rule, pieces=cut)
            dyn = compute_dynamics(chunk.motion, machine, load_kg=load_kg)
            m = dyn.torque_nm * dyn.omega_rad_s
            drawn = apply_braking(m, braking=machine.braking)
            into += chunk.weight_s @ drawn
            nodes += chunk.weight_s.size
            if rule == order:
                mech += chunk.weight_s @ m
                pieces += cut[0].size
                lines.add(chunk.motion.line, chunk.weight_s, drawn)
                by_cause += cause_powers(dyn, m, braking=machine.braking) @ chunk.weight_s
        duration += win.t_end - win.t_begin
    return PhaseEnergy(axes=axes, energy_j=energy, mechanical_j=mech,
                       error_j=np.abs(energy - low), duration_s=duration, causes=causes,
                       by_cause_j=by_cause, by_line=lines.result(axes), pieces=pieces,
                       nodes=nodes, sign_cuts=cuts_added)


class _ByLine:
    """Time and energy per axis summed by source line number (arrays grown as lines come)."""

    def __init__(self, k: int) -> None:
        self.time = np.zeros(1024)
        self.energy = np.zeros((1024, k))

    def add(self, line: np.ndarray, weight: np.ndarray, power: np.ndarray) -> None:
        top = int(line.max()) + 1 if line.size else 0
        if top > self.time.size:
            size = max(top, 2 * self.time.size)
            self.time = np.concatenate((self.time, np.zeros(size - self.time.size)))
            self.energy = np.vstack((self.energy,
                                     np.zeros((size - self.energy.shape[0],
                                               self.energy.shape[1]))))
        self.time += np.bincount(line, weights=weight, minlength=self.time.size)
        for j in range(power.shape[1]):
            self.energy[:, j] += np.bincount(line, weights=weight * power[:, j],
                                             minlength=self.time.size)

    def result(self, axes: tuple[str, ...]) -> LineEnergy:
        seen = np.nonzero(self.time > 0.0)[0]
        by_axis = self.energy[seen]
        return LineEnergy(seen.astype(np.int64), by_axis.sum(axis=1), self.time[seen],
                          axes=axes, by_axis_j=by_axis)


def _values(machine: Machine, load_kg: float, motion) -> np.ndarray:
    """``F v`` and ``M omega`` per axis at the rows of ``motion``: ``(n, 2 k)`` [W]."""
    dyn = compute_dynamics(motion, machine, load_kg=load_kg)
    return np.hstack((dyn.force_n * dyn.velocity_m_s, dyn.torque_nm * dyn.omega_rad_s))


def _sign_cuts(at: WindowMotion, pieces: tuple[np.ndarray, np.ndarray], watch: np.ndarray,
               machine: Machine, load_kg: float, order: int) -> np.ndarray:
    """Times inside ``pieces`` where ``F v`` or ``M omega`` of an axis changes sign, for the
    columns ``watch`` (``F v`` of each axis, then ``M omega``).

    Both are continuous inside a piece (the efficiency switches where ``F v`` is zero, so
    ``M omega`` is zero on both sides of the switch): the bracket between two probes of
    opposite sign is narrowed by regula falsi with the Illinois modification (superlinear;
    a bisection step where it stalls) to the rounding of the time."""
    a, b = pieces
    if a.size == 0 or not np.any(watch):
        return np.zeros(0)
    x, _ = gauss_legendre(order)
    # probes: each piece's ends and nodes (the ends a hair inside, on the piece's own side)
    frac = np.concatenate(([1e-9], x, [1.0 - 1e-9]))
    t = (a[:, None] + (b - a)[:, None] * frac[None, :])
    g = _values(machine, load_kg, at.at(t.ravel()))
    g = g.reshape(a.size, frac.size, -1)
    change = (g[:, :-1, :] * g[:, 1:, :] < 0.0) & watch    # a strict change between probes
    piece, step, col = np.nonzero(change)
    if piece.size == 0:
        return np.zeros(0)
    lo, hi = t[piece, step], t[piece, step + 1]
    g_lo, g_hi = g[piece, step, col], g[piece, step + 1, col]
    order_rows = np.argsort(lo, kind='stable')
    lo, hi, g_lo, g_hi, col = (lo[order_rows], hi[order_rows], g_lo[order_rows],
                               g_hi[order_rows], col[order_rows])
    rows = np.arange(lo.size)
    side = np.zeros(lo.size, dtype=np.int8)      # which end moved last (Illinois)
    for i in range(_ROOT_STEPS):
        width = hi - lo
        open_ = width > 4.0 * np.finfo(float).eps * np.maximum(np.abs(hi), 1.0)
        if not np.any(open_):
            break
        falsi = hi - g_hi * width / (g_hi - g_lo)
        mid = np.where((i % 8 == 7) | ~np.isfinite(falsi) | (falsi <= lo) | (falsi >= hi),
                       0.5 * (lo + hi), falsi)
        gm = _values(machine, load_kg, at.at(mid))[rows, col]
        left = gm * g_lo > 0.0                        # the root is in (mid, hi)
        hit = gm == 0.0
        lo = np.where(hit, mid, np.where(left, mid, lo))
        hi = np.where(hit, mid, np.where(left, hi, mid))
        g_hi = np.where(left & (side == 1), 0.5 * g_hi, g_hi)
        g_lo = np.where(~left & (side == -1), 0.5 * g_lo, g_lo)
        g_lo = np.where(left, gm, g_lo)
        g_hi = np.where(left, g_hi, gm)
        side = np.where(left, 1, -1).astype(np.int8)
    return np.unique(0.5 * (lo + hi))
