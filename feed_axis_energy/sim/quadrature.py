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
rule) at its nodes. The Gauss sum is compared with a lower rule on the same rows (the
interpolatory rule on the pieces' ends and the nodes but the outermost two, exact to degree
``order - 1``: no evaluation of its own): their difference is the estimate of the
quadrature's error reported beside the energy. It errs large (a rule with two nodes fewer,
as before, needs its own evaluation and can err small: on ``1 / (1 + 25 (t - 0.3)^2)`` it
estimates 4e-5 where the 8-node rule is 1e-3 off; this one says 3e-3).

A sign read below :data:`_NOISE` of its piece's largest value is no sign, and a cut is
found to :data:`_ROOT_REL` of its piece's duration.

The cost grows with the pieces (a handful per move), not with duration x sample rate.

Covered so far: the model of :func:`~feed_axis_energy.physics.compute_dynamics` (rigid-body
dynamics, passive resistances, screw efficiency, gravity) and the braking rule, per axis and
per source line and per cause (net), the velocity steps of corners passed at speed (G64) as
ramps over one interpolation cycle (:mod:`feed_axis_energy.plan.nodes`), and with motors and
drives the electrical side (:func:`~feed_axis_energy.physics.electrical_power` at the same
rows; the pieces also cut where the motor power and what the chopper would burn change sign,
and where ``v`` does). Not yet (the sampled pipeline, :mod:`.stream`, gives them): declared
effects. A machine that declares effects is refused with a :class:`ConfigError`.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any, cast

import numpy as np

from ..errors import ConfigError
from ..gcode import Move
from ..machine import Machine, PlannerOptions
from ..physics import (apply_braking, AxisDynamics, cause_names, cause_powers,
                       compute_dynamics, electrical_power, ElectricalPower, LineEnergy)
from ..plan import gauss_legendre, iter_window_motions, Motion, WindowMotion

__all__ = ['PhaseEnergy', 'phase_energy', 'PHASE_ORDER', 'WindowNodes', 'iter_window_nodes',
           'phase_covered', 'LineSums', 'weighted_sum', 'WindowRows', 'window_rows',
           'WindowEvaluator']

PHASE_ORDER = 8
"""Gauss-Legendre nodes per piece (exact for polynomials of degree 15 in time)."""

_ROOT_STEPS = 60        # at most, to find where a sign changes (usually about ten)
_ROOT_TOL_S = 1e-12     # a sign change is found to this [s] ...
_ROOT_REL = 1e-5        # ... or to this fraction of its piece's duration if that is more
_HAIR = 1e-9            # the pieces' ends are evaluated this fraction inside them
_NOISE = 1e-9           # a sign read below this fraction of its piece's largest value is no sign


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
        lower rule on the same rows (:class:`WindowNodes` ``low_j``).
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


@dataclass(frozen=True)
class WindowNodes:
    """One planned window evaluated on its pieces (:func:`iter_window_nodes`).

    Every piece has ``points`` rows, consecutive: its start (a hair inside), its ``order``
    Gauss-Legendre nodes, its end (a hair inside). The pieces are not in time order
    (those cut where a sign changes come last; a piece that was cut stays, with no length
    and so weight 0 on its rows); each lies in one block.

    Attributes
    ----------
    at
        The window's motion (:class:`~feed_axis_energy.plan.WindowMotion`).
    piece_a, piece_b
        Start and end time of every piece [s], ``(p,)``.
    motion, dyn, mechanical_w, drawn_w
        Motion, dynamics, ``M omega`` before and power drawn after the braking rule [W] at
        the rows, ``(p points, ...)``.
    weight_s
        Quadrature weight of every row [s] (0 at the pieces' ends): ``weight_s @ f`` is
        the integral of ``f`` over the window.
    low_j
        Energy drawn per axis by the lower rule on the same rows [J], ``(k,)`` (exact for
        polynomials of degree ``order - 1``; :func:`_rows_rule`): its difference from
        ``weight_s @ drawn_w`` estimates the error.
    points, sign_cuts
        Rows per piece (``order + 2``) and cuts added where a sign changes.
    elec
        The electrical power at the rows (:func:`~feed_axis_energy.physics.electrical_power`)
        when the machine declares drives, else ``None``.
    """

    at: WindowMotion
    piece_a: np.ndarray
    piece_b: np.ndarray
    motion: Motion
    dyn: AxisDynamics
    mechanical_w: np.ndarray
    drawn_w: np.ndarray
    weight_s: np.ndarray
    low_j: np.ndarray
    points: int
    sign_cuts: int
    elec: ElectricalPower | None = None


def weighted_sum(weight: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``weight @ values`` over the rows, by einsum's own loop: a threaded BLAS burns a
    second core for nothing on these shapes (one vector against a few columns)."""
    return np.einsum('n,nk->k', weight, values)


def phase_covered(machine: Machine) -> bool:
    """True when the energy by phase covers ``machine``: no declared effects (the sampled
    pipeline computes those); drives and supply are covered."""
    return not machine.effects


def _check_covered(machine: Machine) -> None:
    """Raise :class:`ConfigError` for a machine :func:`phase_covered` refuses."""
    if not phase_covered(machine):
        raise ConfigError('energy by phase covers the machine without declared effects so '
                          'far; simulate samples them', key='effects')


@lru_cache(maxsize=8)
def _rule(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Row positions in ``[0, 1]`` (the ends a hair inside) and row weights (0 at the
    ends)."""
    x, w = gauss_legendre(order)
    return (np.concatenate(([_HAIR], x, [1.0 - _HAIR])), np.concatenate(([0.0], w, [0.0])))


@lru_cache(maxsize=8)
def _rows_rule(order: int) -> np.ndarray:
    """Weights on a piece's rows of the lower rule the error is estimated with: the
    interpolatory rule on the ends (a hair inside) and the Gauss nodes but the outermost
    two, ``order`` points in all, exact for polynomials of degree ``order - 1`` (the Gauss
    rule: ``2 order - 1``); positive weights. The difference of the two sums errs large
    (it is nearer the lower rule's error than the Gauss rule's), and it costs no
    evaluation of its own."""
    frac, _ = _rule(order)
    idx = np.r_[0, 2:order, order + 1]       # rows: start, nodes 2..order-1, end
    x = 2.0 * frac[idx] - 1.0                # on [-1, 1], where Legendre polynomials live
    basis = np.polynomial.legendre.legvander(x, idx.size - 1)      # (points, degree + 1)
    moments = np.zeros(idx.size)
    moments[0] = 1.0                         # integral over [0, 1] of P0; the others 0
    weights = np.zeros(frac.size)
    weights[idx] = np.linalg.solve(basis.T, moments)
    weights.setflags(write=False)
    return weights


def iter_window_nodes(moves: Iterable[Move], machine: Machine, *, load_kg: float = 0.0,
                      options: PlannerOptions | None = None, file: str = '',
                      order: int = PHASE_ORDER, every_sign: bool = False,
                      on_move: Callable[[int], None] | None = None) -> Iterator[WindowNodes]:
    """Plan ``moves`` and evaluate every window on its pieces (memory: two windows).

    The pieces are cut where ``F v`` changes sign on an axis whose screw efficiency is not
    1 and where ``M omega`` changes sign under dissipated braking (the kinks of the energy);
    with ``every_sign`` also where ``M omega`` changes sign under any braking (the returned
    power) and where ``v a`` does (the inertia's power: its gross share). The signs are
    read at the rows themselves; only the pieces that are cut are evaluated again.

    Raises
    ------
    ConfigError
        ``order < 3``, or a machine :func:`phase_covered` refuses.
    PlanningError
        As the planner.
    """
    evaluate = WindowEvaluator(machine, load_kg=load_kg, order=order, every_sign=every_sign)
    if options is None:
        options = machine.planner.options()
    for at in iter_window_motions(moves, machine.limits(), options=options, file=file,
                                  on_move=on_move):
        yield evaluate(at, window_rows(at, order))


@dataclass(frozen=True)
class WindowRows:
    """A window's pieces and the motion at their rows (:func:`window_rows`): what every
    machine variant planned the same way shares.

    Attributes
    ----------
    piece_a, piece_b
        Start and end time of every piece [s], ``(p,)``.
    motion
        The motion at the rows, ``points`` consecutive rows per piece.
    order
        Quadrature nodes per piece.
    """

    piece_a: np.ndarray
    piece_b: np.ndarray
    motion: Motion
    order: int


def window_rows(at: WindowMotion, order: int = PHASE_ORDER) -> WindowRows:
    """The pieces of a planned window and its motion at their rows (ends a hair inside and
    ``order`` Gauss-Legendre nodes each)."""
    frac, _ = _rule(order)
    a, b = at.pieces()
    m = at.at((a[:, None] + (b - a)[:, None] * frac).ravel())
    # rows in C order (the planner's columns are Fortran order): the dynamics keep the
    # layout, and appending the parts of the pieces cut is then a plain copy
    m = replace(m, pos=np.ascontiguousarray(m.pos), vel=np.ascontiguousarray(m.vel),
                acc=np.ascontiguousarray(m.acc))
    return WindowRows(a, b, m, order)


class WindowEvaluator:
    """Evaluates planned windows on one machine and load (:func:`iter_window_nodes`): the
    dynamics at the shared rows (:func:`window_rows`), the cuts where a sign changes, the
    energy by the rule and by the lower rule on the same rows. Several evaluators (the variants
    of a sweep with the same plan) share each window's rows.

    Raises
    ------
    ConfigError
        ``order < 3``, or a machine :func:`phase_covered` refuses.
    """

    def __init__(self, machine: Machine, *, load_kg: float = 0.0, order: int = PHASE_ORDER,
                 every_sign: bool = False) -> None:
        if order < 3:
            raise ConfigError(f'the quadrature needs at least 3 nodes per piece, got {order}',
                              key='order')
        _check_covered(machine)
        self.machine = machine
        self.load_kg = load_kg
        self.order = order
        axes = tuple(machine.limits())
        k = len(axes)
        # only a sign that switches something is a kink: F v where the screw's efficiency is
        # not 1 (divided or multiplied by it), M omega where braking power is cut at zero
        eta = np.array([machine.axis(a).screw.efficiency for a in axes])
        self.k = k
        self.electrical = bool(machine.electrical)
        watch = [eta != 1.0, np.full(k, every_sign or machine.braking == 'dissipated'),
                 np.full(k, every_sign),
                 # v itself with drives: copper (k M²) jumps where Coulomb friction flips
                 # with v, iron (k_h |omega|) kinks there
                 np.full(k, self.electrical)]
        if self.electrical:
            drives = []
            for a in axes:
                drive = machine.axis(a).drive
                if drive is None:       # machine_from_dict refuses this; code may build it
                    raise ConfigError('the electrical model needs a drive on every axis',
                                      key=f'axes.{a}.drive')
                drives.append(drive)
            # the converter takes P/eta_c motoring and returns P eta_c braking: a kink where
            # P_motor changes sign; the chopper burns what exceeds the regeneration limit
            eta_c = np.array([d.converter_efficiency for d in drives])
            self.limit = np.array([0.0 if machine.braking == 'dissipated' else
                                   (np.inf if d.regeneration_limit_w is None
                                    else d.regeneration_limit_w) for d in drives])
            watch += [eta_c != 1.0, np.isfinite(self.limit)]
        self.watch = np.concatenate(watch)
        self.frac, self.wrow = _rule(order)
        self.wlow = _rows_rule(order)

    def __call__(self, at: WindowMotion, rows: WindowRows) -> WindowNodes:
        """The window ``at`` on its ``rows`` (made with this evaluator's ``order``)."""
        if rows.order != self.order:
            raise ValueError(f'rows of {rows.order} nodes for a rule of {self.order}')
        machine, load_kg = self.machine, self.load_kg
        npt = self.order + 2
        a, b, motion = rows.piece_a, rows.piece_b, rows.motion
        dyn = compute_dynamics(motion, machine, load_kg=load_kg)
        elec = self._electrical(dyn)
        cuts = np.zeros(0)
        if np.any(self.watch) and a.size:
            def signs_at(times: np.ndarray) -> np.ndarray:
                d = compute_dynamics(at.at(times), machine, load_kg=load_kg)
                return self._signs(d, self._electrical(d))
            cuts = _sign_cuts(motion.t.reshape(a.size, npt),
                              self._signs(dyn, elec).reshape(a.size, npt, -1), self.watch,
                              self.k, signs_at)
        if cuts.size:
            a, b, part = _split(at, a, b, cuts, self.frac)
            motion = _append(motion, part)
            part_dyn = compute_dynamics(part, machine, load_kg=load_kg)
            dyn = _append_dynamics(dyn, part_dyn)
            if elec is not None:      # row by row too: the bits of the joined rows at once
                elec = elec.append(cast(ElectricalPower, self._electrical(part_dyn)))
        h = b - a
        m = dyn.torque_nm * dyn.omega_rad_s
        drawn = apply_braking(m, braking=machine.braking)
        low_j = weighted_sum((h[:, None] * self.wlow[None, :]).ravel(), drawn)
        return WindowNodes(at=at, piece_a=a, piece_b=b, motion=motion, dyn=dyn,
                           mechanical_w=m, drawn_w=drawn,
                           weight_s=(h[:, None] * self.wrow[None, :]).ravel(), low_j=low_j,
                           points=npt, sign_cuts=int(cuts.size), elec=elec)

    def _electrical(self, dyn: AxisDynamics) -> ElectricalPower | None:
        """The electrical power at the rows of ``dyn`` (``None`` without drives)."""
        if not self.electrical:
            return None
        return electrical_power(dyn, dyn.torque_nm * dyn.omega_rad_s, self.machine)

    def _signs(self, dyn: AxisDynamics, elec: ElectricalPower | None) -> np.ndarray:
        """The functions whose sign changes are kinks, per axis at the rows: ``F v``,
        ``M omega`` [W], ``v a`` [m²/s³], ``v`` [m/s], and with drives (``elec``, the
        electrical power at the same rows) ``P_motor`` [W] and what the chopper would burn,
        ``-(P_motor + P_converter) - limit`` [W] (1 where nothing is burned ever):
        ``(n, 4 k)`` or ``(n, 6 k)``."""
        v = dyn.velocity_m_s
        m = dyn.torque_nm * dyn.omega_rad_s
        cols = [dyn.force_n * v, m, v * dyn.acceleration_m_s2, v]
        if elec is not None:
            conv = dict(elec.parts)['converter']
            burn = -(elec.motor_w + conv) - np.where(np.isfinite(self.limit), self.limit, 0.0)
            cols += [elec.motor_w, np.where(np.isfinite(self.limit), burn, 1.0)]
        return np.hstack(cols)


def _split(at: WindowMotion, a: np.ndarray, b: np.ndarray, cuts: np.ndarray,
           frac: np.ndarray) -> tuple[np.ndarray, np.ndarray, Motion]:
    """Cut the pieces at ``cuts`` (times inside them). A piece cut keeps its rows as a
    piece of no length (its end moved to its start: weight 0); its parts are appended with
    the motion at their rows. Returns the new starts and ends and the parts' motion.

    (Keeping the rows costs nothing; taking them out would copy every row of the window.)
    """
    which = np.searchsorted(a, cuts, side='right') - 1
    hit = np.unique(which)
    edges = np.unique(np.concatenate((a[hit], b[hit], cuts)))
    lo, hi = edges[:-1], edges[1:]
    owner = np.searchsorted(a[hit], lo, side='right') - 1
    inside = (hi > lo) & (owner >= 0) & (hi <= b[hit][np.maximum(owner, 0)])
    lo, hi = lo[inside], hi[inside]
    part = at.at((lo[:, None] + (hi - lo)[:, None] * frac).ravel())
    b = b.copy()
    b[hit] = a[hit]
    return np.concatenate((a, lo)), np.concatenate((b, hi)), part


def _append(motion: Motion, part: Motion) -> Motion:
    """The rows of ``motion`` followed by those of ``part``."""
    return Motion(t=np.concatenate((motion.t, part.t)), axes=motion.axes,
                  pos=np.concatenate((motion.pos, part.pos)),
                  vel=np.concatenate((motion.vel, part.vel)),
                  acc=np.concatenate((motion.acc, part.acc)),
                  line=np.concatenate((motion.line, part.line)),
                  source=motion.source)


_ROW_FIELDS = ('t', 'position_m', 'velocity_m_s', 'acceleration_m_s2', 'angle_rad',
               'omega_rad_s', 'alpha_rad_s2', 'force_n', 'loss_force_n', 'gravity_force_n',
               'torque_nm', 'line')


def _append_dynamics(dyn: AxisDynamics, part: AxisDynamics) -> AxisDynamics:
    """The rows of ``dyn`` followed by those of ``part`` (the dynamics are row by row:
    the bits of computing the joined motion at once)."""
    joined: dict[str, Any] = {f: np.concatenate((getattr(dyn, f), getattr(part, f)))
                              for f in _ROW_FIELDS}
    return replace(dyn, **joined)


def phase_energy(moves: Iterable[Move], machine: Machine, *, load_kg: float = 0.0,
                 options: PlannerOptions | None = None, file: str = '',
                 order: int = PHASE_ORDER) -> PhaseEnergy:
    """Energy per axis of ``moves`` on ``machine`` by quadrature on the planned phases.

    Raises
    ------
    ConfigError
        ``order < 3``, or a machine with declared effects (not covered yet).
    PlanningError
        As the planner.
    """
    axes = tuple(machine.limits())
    k = len(axes)
    energy = np.zeros(k)
    low = np.zeros(k)
    mech = np.zeros(k)
    duration = 0.0
    pieces = nodes = cuts_added = 0
    lines = LineSums(k)
    causes = cause_names()
    by_cause = np.zeros((len(causes), k))
    for w in iter_window_nodes(moves, machine, load_kg=load_kg, options=options, file=file,
                               order=order):
        weight = w.weight_s
        energy += weighted_sum(weight, w.drawn_w)
        low += w.low_j
        mech += weighted_sum(weight, w.mechanical_w)
        lines.add(w.motion.line, weight, w.drawn_w)
        by_cause += np.einsum('ckn,n->ck',
                              cause_powers(w.dyn, w.mechanical_w, braking=machine.braking),
                              weight)
        pieces += w.piece_a.size
        nodes += weight.size
        cuts_added += w.sign_cuts
        duration += w.at.win.t_end - w.at.win.t_begin
    return PhaseEnergy(axes=axes, energy_j=energy, mechanical_j=mech,
                       error_j=np.abs(energy - low),
                       duration_s=duration, causes=causes, by_cause_j=by_cause,
                       by_line=lines.result(axes), pieces=pieces, nodes=nodes,
                       sign_cuts=cuts_added)


class LineSums:
    """Time and energy per axis summed by source line number (arrays grown as lines come:
    ``8 (k + 1)`` bytes per line up to the largest line number)."""

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


def _sign_cuts(t: np.ndarray, g: np.ndarray, watch: np.ndarray, k: int,
               signs_at: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Times inside the pieces where a watched column of ``g`` changes sign: ``g``
    ``(p, points, c k)`` holds the columns of :meth:`WindowEvaluator._signs` (``F v``,
    ``M omega``, ``v a``, ``v`` of each axis, ...) at the pieces' rows ``t``
    ``(p, points)``; ``watch`` ``(c k,)`` says which; ``signs_at(times)`` evaluates the
    columns at other times (the root finding).

    Each is continuous inside a piece (the efficiency switches where ``F v`` is zero, so
    ``M omega`` is zero on both sides of the switch); where ``v`` changes sign between the
    same rows, the root of ``v`` is the product's (``g`` carries ``v`` in its columns
    ``3 k`` to ``4 k``, :meth:`WindowEvaluator._signs`). The bracket between two rows of
    opposite sign is narrowed by regula falsi with the Illinois modification (superlinear;
    a bisection step where it stalls) to :data:`_ROOT_TOL_S` or :data:`_ROOT_REL` of the
    piece (a cut that far off the kink changes the integral by about half the kink's change
    of slope times its square: 5e-15 of the piece's energy). A value below
    :data:`_NOISE` of the largest on the piece is a zero: the bracket closes there."""
    # the few pieces where a watched column takes both signs, from its least and largest
    # value on each piece (row by row: 3x faster than min/max over axis 1)
    high, low = g[:, 0, :].copy(), g[:, 0, :].copy()
    for j in range(1, g.shape[1]):
        np.maximum(high, g[:, j, :], out=high)
        np.minimum(low, g[:, j, :], out=low)
    noise = _NOISE * np.maximum(high, -low)
    both = np.flatnonzero((low < -noise) & (high > noise) & watch) // g.shape[2]
    if both.size == 0:
        return np.zeros(0)
    pieces = np.unique(both)
    g = g[pieces]
    t = t[pieces]
    noise = noise[pieces]
    # a strict change between probes, both above the rounding noise: where the motion
    # stops at a piece's end, the row a hair inside reads F v of about 1e-14 W of either
    # sign against watts elsewhere; no kink there is worth a cut, and such a bracket would
    # hold the root finding for dozens of steps
    live = np.abs(g) > noise[:, None, :]
    change = (g[:, :-1, :] * g[:, 1:, :] < 0.0) & live[:, :-1, :] & live[:, 1:, :] & watch
    piece, step, col = np.nonzero(change)
    if piece.size == 0:
        return np.zeros(0)
    # where the axis's speed changes sign in the bracket too, the product changes sign
    # there (its other factor keeps its sign): find the root of v, smooth, instead of the
    # product's kink (Coulomb friction flips F with v: regula falsi crawls on a kink)
    v_col = 3 * k + col % k
    on_v = (col < 3 * k) & live[piece, step, v_col] & live[piece, step + 1, v_col] & (
        g[piece, step, v_col] * g[piece, step + 1, v_col] < 0.0)
    col = np.where(on_v, v_col, col)
    piece, step, col = np.unique(np.stack((piece, step, col)), axis=1)   # one bracket each
    lo, hi = t[piece, step], t[piece, step + 1]
    g_lo, g_hi = g[piece, step, col], g[piece, step + 1, col]
    tol = np.maximum(_ROOT_TOL_S, _ROOT_REL * (t[piece, -1] - t[piece, 0]))
    small = noise[piece, col]
    order_rows = np.argsort(lo, kind='stable')
    lo, hi, g_lo, g_hi, col, tol, small = (
        lo[order_rows], hi[order_rows], g_lo[order_rows], g_hi[order_rows], col[order_rows],
        tol[order_rows], small[order_rows])
    rows = np.arange(lo.size)
    side = np.zeros(lo.size, dtype=np.int8)      # which end moved last (Illinois)
    for i in range(_ROOT_STEPS):
        width = hi - lo
        open_ = width > np.maximum(tol,
                                   4.0 * np.finfo(float).eps * np.maximum(np.abs(hi), 1.0))
        if not np.any(open_):
            break
        falsi = hi - g_hi * width / (g_hi - g_lo)
        mid = np.where((i % 8 == 7) | ~np.isfinite(falsi) | (falsi <= lo) | (falsi >= hi),
                       0.5 * (lo + hi), falsi)
        gm = signs_at(mid)[rows, col]
        left = gm * g_lo > 0.0                        # the root is in (mid, hi)
        hit = np.abs(gm) <= small        # at the noise: the sign changes here
        lo = np.where(hit, mid, np.where(left, mid, lo))
        hi = np.where(hit, mid, np.where(left, hi, mid))
        g_hi = np.where(left & (side == 1), 0.5 * g_hi, g_hi)
        g_lo = np.where(~left & (side == -1), 0.5 * g_lo, g_lo)
        g_lo = np.where(left, gm, g_lo)
        g_hi = np.where(left, g_hi, gm)
        side = np.where(left, 1, -1).astype(np.int8)
    return np.unique(0.5 * (lo + hi))
