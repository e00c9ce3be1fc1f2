"""Energy by phase: each axis's energy as quadrature on the planned phases (issue 23, part 1).

The planner's phases (constant jerk) are cut into pieces where the motion is one smooth
function of time (:func:`feed_axis_energy.plan.nodes.window_pieces`: phases, block junctions,
an axis turning on an arc). Two things the motion does not show make the power kink inside
a piece: the screw's efficiency, applied one way where the motor drives (``F v >= 0``) and
the other way where the load drives it back, and the braking rule ``'dissipated'``, which
cuts negative ``M omega`` at zero. Both happen where a sign changes: the power is evaluated at
each piece's ends and quadrature nodes, and where the sign of ``F v`` or ``M omega`` of an
axis changes between two of these points the time of the change is found by bisection and
the piece is cut there too. On every piece the energy is then the Gauss-Legendre sum of the
same per-sample dynamics (:func:`feed_axis_energy.physics.compute_dynamics`, the braking
rule) at its nodes. The rule of ``order`` nodes is compared with the rule of ``order - 2``
on the same pieces: their difference is the estimate of the quadrature's error that is
reported beside the energy.

The cost grows with the pieces (a handful per move), not with duration x sample rate.

Covered so far: the model of :func:`~feed_axis_energy.physics.compute_dynamics` (rigid-body
dynamics, passive resistances, screw efficiency, gravity) and the braking rule, per axis.
Not yet (the sampled pipeline, :mod:`.stream`, gives them): declared effects, the electrical
side, the velocity steps of corners passed at speed, energy per block and per cause. A
machine that declares effects or drives is refused with a :class:`ConfigError`.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..gcode import Move
from ..machine import Machine, PlannerOptions
from ..physics import apply_braking, compute_dynamics
from ..plan import gauss_legendre, iter_plan, motion_at, window_nodes, window_pieces

__all__ = ['PhaseEnergy', 'phase_energy', 'PHASE_ORDER']

PHASE_ORDER = 8
"""Gauss-Legendre nodes per piece (exact for polynomials of degree 15 in time)."""

_BISECT = 52            # halvings of a sign change's bracket: to the rounding of the time


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
    pieces, nodes, sign_cuts
        Pieces integrated, nodes evaluated (both rules), cuts added where a sign changes.
    """

    axes: tuple[str, ...]
    energy_j: np.ndarray
    mechanical_j: np.ndarray
    error_j: np.ndarray
    duration_s: float
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
    for win in iter_plan(moves, limits, options=options, file=file):
        cuts = _sign_cuts(win, axes, machine, load_kg, order, file)
        cuts_added += cuts.size
        for rule, into in ((order, energy), (order - 2, low)):
            chunk = window_nodes(win, axes, order=rule, file=file, cuts=cuts)
            dyn = compute_dynamics(chunk.motion, machine, load_kg=load_kg)
            m = dyn.torque_nm * dyn.omega_rad_s
            into += chunk.weight_s @ apply_braking(m, braking=machine.braking)
            nodes += chunk.weight_s.size
            if rule == order:
                mech += chunk.weight_s @ m
                pieces += int(chunk.piece.size // order)
        duration += win.t_end - win.t_begin
    return PhaseEnergy(axes=axes, energy_j=energy, mechanical_j=mech,
                       error_j=np.abs(energy - low), duration_s=duration, pieces=pieces,
                       nodes=nodes, sign_cuts=cuts_added)


def _signs(machine: Machine, load_kg: float, motion) -> np.ndarray:
    """Signs of ``F v`` and ``M omega`` per axis at the rows of ``motion``: ``(n, 2 k)``."""
    dyn = compute_dynamics(motion, machine, load_kg=load_kg)
    return np.sign(np.hstack((dyn.force_n * dyn.velocity_m_s,
                              dyn.torque_nm * dyn.omega_rad_s)))


def _sign_cuts(win, axes: tuple[str, ...], machine: Machine, load_kg: float, order: int,
               file: str) -> np.ndarray:
    """Times inside the window's pieces where ``F v`` or ``M omega`` of an axis changes sign."""
    a, b = window_pieces(win, axes)
    if a.size == 0:
        return np.zeros(0)
    x, _ = gauss_legendre(order)
    # probes: each piece's ends and nodes (the ends a hair inside, on the piece's own side)
    frac = np.concatenate(([1e-9], x, [1.0 - 1e-9]))
    t = (a[:, None] + (b - a)[:, None] * frac[None, :])
    s = _signs(machine, load_kg, motion_at(win, axes, t.ravel(), file=file))
    s = s.reshape(a.size, frac.size, -1)
    change = s[:, :-1, :] * s[:, 1:, :] < 0.0          # a strict change between two probes
    piece, step, col = np.nonzero(change)
    if piece.size == 0:
        return np.zeros(0)
    lo = t[piece, step]
    hi = t[piece, step + 1]
    first = s[piece, step, col]
    order_rows = np.argsort(lo, kind='stable')
    lo, hi, first, col = lo[order_rows], hi[order_rows], first[order_rows], col[order_rows]
    rows = np.arange(lo.size)
    for _ in range(_BISECT):
        mid = 0.5 * (lo + hi)
        sm = _signs(machine, load_kg, motion_at(win, axes, mid, file=file))[rows, col]
        same = sm * first > 0.0
        lo = np.where(same, mid, lo)
        hi = np.where(same, hi, mid)
    return np.unique(0.5 * (lo + hi))
