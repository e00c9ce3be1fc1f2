"""Energy by cause: which physical term of the axis model the drawn power goes to.

The drawn power of axis ``k`` (:mod:`.energy`, :mod:`.simulate`) is split, sample by sample,
into parts that add up to it exactly (to rounding; ``docs/breakdown.md``):

==================  =================================================================
cause               power of axis ``k`` [W]
==================  =================================================================
``friction``        ``F_loss·v``, the passive resistances of the loss function, >= 0
``screw``           ``M_F·omega - F·v``, the ball screw's efficiency loss, >= 0 (0 for
                    ``eta = 1``)
``gravity_lift``    ``max(F_g·v, 0)``, lifting the weight on an inclined axis, >= 0
``gravity_lower``   ``min(F_g·v, 0)``, the weight coming down, <= 0
``linear_inertia``  ``m·a·v``, kinetic energy of the moved mass (signed)
``rotary_inertia``  ``J·alpha·omega``, kinetic energy of motor, coupling and screw (signed)
``effect:<id>``     each declared effect's extra power (``effect:<id>:<axis>`` when it is
                    declared for one axis)
``braking_burned``  ``max(-M·omega, 0)`` with ``'dissipated'`` braking, else 0
==================  =================================================================

The first six add up to the mechanical power ``M·omega``. While an axis brakes
(``M·omega < 0``) every term keeps its own sign: the inertia and lowering terms are negative
and outweigh the others. With ``'regenerative'`` braking that negative sum is energy
returned to the DC link and lowers the total; with ``'dissipated'`` braking the drawn power
is ``max(M·omega, 0)``, so ``braking_burned`` adds back exactly what the terms returned,
and the braking energy shows as burned instead of being credited. Either way the causes add
up to the drawn power of every axis at every sample, hence to the energy per axis, per
block and in total.
"""
from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import cast

import numpy as np

from .dynamics import AxisDynamics
from ..errors import ConfigError
from ..machine import BRAKING_MODES

__all__ = ['FIXED_CAUSES', 'BRAKING_CAUSE', 'cause_names', 'cause_powers', 'cause_rows',
           'BreakdownAccumulator', 'LineEnergy']

FIXED_CAUSES = ('friction', 'screw', 'gravity_lift', 'gravity_lower', 'linear_inertia',
                'rotary_inertia')
BRAKING_CAUSE = 'braking_burned'


def cause_names(effect_labels: Sequence[str] = (),
                extra_labels: Sequence[str] = ()) -> tuple[str, ...]:
    """All cause names in display order: the fixed ones, the effects, the extra causes (the
    electrical ones, :mod:`.electrical`), ``braking_burned``."""
    return FIXED_CAUSES + tuple(effect_labels) + tuple(extra_labels) + (BRAKING_CAUSE,)


def cause_rows(dyn: AxisDynamics, mechanical_w: np.ndarray, *, braking: str,
               effects: Sequence[tuple[str, np.ndarray]] = (),
               buffers: dict | None = None, extra: Sequence[tuple[str, np.ndarray]] = (),
               burned: np.ndarray | None = None) -> list[tuple[int, int, np.ndarray]]:
    """The power of every cause on every axis that can be non-zero, as
    ``(cause index, axis index, power (n,))`` [W] (see :func:`cause_powers`).

    ``extra``: further causes ``(label, power (n, k))`` after the effects (the electrical
    losses); ``burned``: the ``braking_burned`` power ``(n, k)`` when the caller applies the
    braking rule itself (the electrical chain), instead of ``max(-M·omega, 0)`` with
    ``'dissipated'``.

    ``buffers``: a dict kept by the caller from chunk to chunk; the rows are written into
    its arrays (valid until the next call with the same dict).

    Left out (zero by construction): ``screw`` on axes with ``eta = 1``, the gravity terms
    on horizontal axes, ``braking_burned`` with regenerative braking, an effect on the axes
    it is not declared for. The per-axis arrays of the planner are column-major, so a
    column is read without a copy.
    """
    if braking not in BRAKING_MODES:
        msg = f'braking must be one of {", ".join(BRAKING_MODES)}, got {braking!r}'
        raise ConfigError(msg, key='braking')
    v = dyn.velocity_m_s
    n, k = v.shape
    mech = np.asarray(mechanical_w)
    rows: list[tuple[int, int, np.ndarray]] = []
    pool = {} if buffers is None else buffers

    def buf(key: tuple) -> np.ndarray:
        # reused from chunk to chunk: a fresh large array costs page faults every time
        b = pool.get(key)
        if b is None or b.shape[0] < n:
            b = pool[key] = np.empty(n)
        return b[:n]

    for j in range(k):
        vj = v[:, j]
        friction = np.multiply(dyn.loss_force_n[:, j], vj, out=buf((0, j)))
        linear = np.multiply(vj, dyn.mass_kg[j], out=buf((4, j)))
        linear *= dyn.acceleration_m_s2[:, j]
        rotary = np.multiply(dyn.omega_rad_s[:, j], dyn.inertia_kg_m2[j], out=buf((5, j)))
        rotary *= dyn.alpha_rad_s2[:, j]
        rows += [(0, j, friction), (4, j, linear), (5, j, rotary)]
        g = dyn.gravity_force_n[:, j]
        gravity = None
        if g.size and not (g[0] == 0.0 and not np.any(g)):
            gravity = np.multiply(g, vj, out=buf(('g', j)))
            rows += [(2, j, np.maximum(gravity, 0.0, out=buf((2, j)))),
                     (3, j, np.minimum(gravity, 0.0, out=buf((3, j))))]
        if dyn.efficiency[j] != 1.0:
            # what M·omega holds beyond the force terms and the rotor: exact by construction
            screw = np.subtract(mech[:, j], rotary, out=buf((1, j)))
            screw -= friction
            screw -= linear
            if gravity is not None:
                screw -= gravity
            rows.append((1, j, screw))
    for i, (_label, power) in enumerate(list(effects) + list(extra)):
        power = np.asarray(power)
        for j in range(k):
            column = power[:, j]
            if np.any(column):
                rows.append((len(FIXED_CAUSES) + i, j, column))
    c = len(FIXED_CAUSES) + len(effects) + len(extra)
    if burned is not None:
        for j in range(k):
            column = burned[:, j]
            if np.any(column):
                rows.append((c, j, column))
    elif braking == 'dissipated':
        for j in range(k):
            burned = np.negative(mech[:, j], out=buf((c, j)))
            np.maximum(burned, 0.0, out=burned)
            rows.append((c, j, burned))
    return rows


def cause_powers(dyn: AxisDynamics, mechanical_w: np.ndarray, *, braking: str,
                 effects: Sequence[tuple[str, np.ndarray]] = (),
                 extra: Sequence[tuple[str, np.ndarray]] = (),
                 burned: np.ndarray | None = None) -> np.ndarray:
    """Power of every cause per axis, ``(c, k, n)`` in :func:`cause_names` order [W].

    Parameters
    ----------
    dyn
        Forces, speeds and parameters of the axes (:func:`.dynamics.compute_dynamics`).
    mechanical_w
        ``M·omega`` per axis before the braking rule [W], ``(n, k)``.
    braking
        ``'regenerative'`` or ``'dissipated'``.
    effects
        ``(label, power (n, k))`` of every declared effect, in declaration order.
    extra, burned
        Further causes and the burned braking power (:func:`cause_rows`).

    Returns
    -------
    numpy.ndarray
        ``out.sum(axis=0)`` over the causes is the drawn power per axis, ``(k, n)`` (to
        rounding).

    Raises
    ------
    ConfigError
        An unknown braking rule.
    """
    n, k = dyn.velocity_m_s.shape
    out = np.zeros((len(FIXED_CAUSES) + len(effects) + len(extra) + 1, k, n))
    for c, j, row in cause_rows(dyn, mechanical_w, braking=braking, effects=effects,
                                extra=extra, burned=burned):
        out[c, j] = row
    return out


class LineEnergy(Sequence):
    """Energy and time per source line as arrays, read as ``(line, energy_j, duration_s)``.

    A sequence of tuples like :func:`.energy.energy_by_line` returns, without a Python
    tuple per line (a 24-hour contour has millions of lines). With the per-block breakdown
    on, ``by_axis_j`` ``(n, k)`` and ``by_cause_j`` ``(n, c)`` hold the energy of each line
    per axis (``axes``) and per cause summed over the axes (``causes``); else ``None``. With
    declared drives (:mod:`.electrical`), ``motor_j`` and ``supply_j`` ``(n,)`` hold each
    line's electrical energy at the motor terminals and at the supply side; else ``None``.
    """

    def __init__(self, lines: np.ndarray, energy_j: np.ndarray, duration_s: np.ndarray, *,
                 axes: tuple[str, ...] = (), causes: tuple[str, ...] = (),
                 by_axis_j: np.ndarray | None = None,
                 by_cause_j: np.ndarray | None = None,
                 motor_j: np.ndarray | None = None,
                 supply_j: np.ndarray | None = None) -> None:
        self.lines = lines
        self.energy_j = energy_j
        self.duration_s = duration_s
        self.axes = axes
        self.causes = causes
        self.by_axis_j = by_axis_j
        self.by_cause_j = by_cause_j
        self.motor_j = motor_j
        self.supply_j = supply_j

    def __len__(self) -> int:
        return int(self.lines.shape[0])

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        return (int(self.lines[i]), float(self.energy_j[i]), float(self.duration_s[i]))

    def __iter__(self) -> Iterator[tuple[int, float, float]]:
        step = 65536
        for lo in range(0, len(self), step):
            yield from zip(self.lines[lo:lo + step].tolist(),
                           self.energy_j[lo:lo + step].tolist(),
                           self.duration_s[lo:lo + step].tolist())


class BreakdownAccumulator:
    """Energy by cause and axis (and optionally per source line), chunk by chunk.

    Each trapezoid interval goes to the line of its end sample, as in
    :func:`.energy.energy_by_line`. Memory: ``(c, k)`` numbers, plus ``k + c`` per source
    line when ``per_line`` (8 bytes each, allocated as lines appear).

    Parameters
    ----------
    per_line
        Also keep the energy of every source line per axis and per cause.
    """

    def __init__(self, *, per_line: bool = False) -> None:
        self.per_line = bool(per_line)
        self.axes: tuple[str, ...] = ()
        self.causes: tuple[str, ...] = ()
        self.energy: np.ndarray | None = None       # (c, k)
        self.gross: np.ndarray | None = None        # (c, k): integral of max(power, 0)
        self._signed = slice(4, 4)                   # causes of both signs (inertia, effects)
        self._t_last = 0.0
        self._last: np.ndarray | None = None         # (c, k): the previous chunk's last row
        self._lines = np.zeros((0, 0))               # (lines, k + c)
        self._buffers: dict = {}                     # work arrays reused from chunk to chunk

    def add(self, dyn: AxisDynamics, mechanical_w: np.ndarray, *, braking: str,
            effects: Sequence[tuple[str, np.ndarray]] = (),
            extra: Sequence[tuple[str, np.ndarray]] = (),
            burned: np.ndarray | None = None, weights: np.ndarray | None = None) -> None:
        """Take one chunk (in time order); arguments as :func:`cause_powers`.

        ``weights``: the rows are quadrature nodes (:mod:`feed_axis_energy.plan.nodes`), the
        integral of a power is its sum times these weights [s] (instead of the trapezoid
        rule over the samples, continued from the previous chunk); each node's energy goes
        to its own source line."""
        t = dyn.t
        m = int(t.shape[0])
        if m == 0:
            return
        if braking not in BRAKING_MODES:
            msg = f'braking must be one of {", ".join(BRAKING_MODES)}, got {braking!r}'
            raise ConfigError(msg, key='braking')
        k = len(dyn.axes)
        c = len(FIXED_CAUSES) + len(effects) + len(extra) + 1
        if self.energy is None:
            self.axes = tuple(dyn.axes)
            self.causes = cause_names([label for label, _ in effects],
                                      [label for label, _ in extra])
            self.energy = np.zeros((c, k))
            self.gross = np.zeros((c, k))
            self._signed = slice(4, c - 1)      # inertia (4, 5), then the effects
            self._last = None
            self._lines = np.zeros((1024 if self.per_line else 0, k + c))
        elif c != self.energy.shape[0] or tuple(dyn.axes) != self.axes:
            msg = 'BreakdownAccumulator: a chunk with other axes or effects than the first'
            raise ValueError(msg)
        gross = cast(np.ndarray, self.gross)        # set with self.energy (above)
        if weights is not None:
            self._add_weighted(dyn, np.asarray(mechanical_w), braking, effects, extra, burned,
                               np.asarray(weights, dtype=float))
            return
        dt = np.diff(t)
        # trapezoid sum as one weighted sum over the samples: w_i = (dt_{i-1} + dt_i) / 2
        w = np.zeros(m)
        w[:-1] += 0.5 * dt
        w[1:] += 0.5 * dt
        first = self._last is None
        d0 = 0.0 if first else float(t[0] - self._t_last)
        if not first:
            w[0] += 0.5 * d0
            prev = cast(np.ndarray, self._last)     # not the first chunk: its last row
            self.energy += 0.5 * d0 * prev
            gross[self._signed] += 0.5 * d0 * np.maximum(prev[self._signed], 0.0)
        if not self.per_line:
            self._last = self._add_sums(dyn, np.asarray(mechanical_w), braking,
                                        list(effects) + list(extra), burned, w)
            self._t_last = float(t[-1])
            return
        rows = cause_rows(dyn, mechanical_w, braking=braking, effects=effects,
                          buffers=self._buffers, extra=extra, burned=burned)
        last = np.zeros((c, k))
        signed = range(4, c - 1)
        # einsum's own loop, not BLAS: a threaded BLAS burns CPU on a loaded machine
        for ci, j, row in rows:
            self.energy[ci, j] += np.einsum('i,i', row, w)
            if ci in signed:
                positive = np.maximum(row, 0.0, out=self._work('positive', (1, m))[0])
                gross[ci, j] += np.einsum('i,i', positive, w)
            last[ci, j] = row[-1]
        self._add_lines(rows, k, c, dyn.line, dt, d0, first, m)
        self._last = last
        self._t_last = float(t[-1])

    def _add_weighted(self, dyn: AxisDynamics, mech: np.ndarray, braking: str,
                      effects: Sequence[tuple[str, np.ndarray]],
                      extra: Sequence[tuple[str, np.ndarray]], burned: np.ndarray | None,
                      w: np.ndarray) -> None:
        """Quadrature nodes with weights ``w``: no interval to the previous chunk."""
        if not self.per_line:
            self._add_sums(dyn, mech, braking, list(effects) + list(extra), burned, w)
            return
        energy, gross = cast(np.ndarray, self.energy), cast(np.ndarray, self.gross)
        k = energy.shape[1]
        rows = cause_rows(dyn, mech, braking=braking, effects=effects, buffers=self._buffers,
                          extra=extra, burned=burned)
        line = np.asarray(dyn.line, dtype=np.int64)
        top = int(line.max()) + 1 if line.size else 0
        if top > self._lines.shape[0]:
            grown = np.zeros((max(2 * self._lines.shape[0], top), self._lines.shape[1]))
            grown[:self._lines.shape[0]] = self._lines
            self._lines = grown
        signed = range(4, energy.shape[0] - 1)
        size = self._lines.shape[0]
        for ci, j, row in rows:
            rw = row * w
            energy[ci, j] += float(rw.sum())
            if ci in signed:
                gross[ci, j] += float(np.einsum('i,i', np.maximum(row, 0.0), w))
            per = np.bincount(line, weights=rw, minlength=size)
            self._lines[:, j] += per
            self._lines[:, k + ci] += per

    def _add_sums(self, dyn: AxisDynamics, mech: np.ndarray, braking: str,
                  effects: Sequence[tuple[str, np.ndarray]], burned: np.ndarray | None,
                  w: np.ndarray) -> np.ndarray:
        """The chunk's energy by cause and axis without a power array per cause (no
        per-line table): each cause's weighted sum taken from the dynamics' columns
        directly, the screw's as the rest of ``M·omega``. ``effects``: the declared effects
        then the extra causes, in row order; ``burned`` as in :func:`cause_rows`. Equal to
        the sums over :func:`cause_rows` to rounding. Returns the last sample's power per
        cause."""
        m = w.shape[0]
        # the casts: add() sets both before it calls this
        energy, gross = cast(np.ndarray, self.energy), cast(np.ndarray, self.gross)
        c, k = energy.shape
        last = np.zeros((c, k))
        tmp = self._work('positive', (1, m))[0]
        v, a, loss, g = (dyn.velocity_m_s, dyn.acceleration_m_s2, dyn.loss_force_n,
                         dyn.gravity_force_n)
        om, al = dyn.omega_rad_s, dyn.alpha_rad_s2
        for j in range(k):
            vj = v[:, j]
            mass, inertia = float(dyn.mass_kg[j]), float(dyn.inertia_kg_m2[j])
            # einsum's own loop, not BLAS: a threaded BLAS burns CPU on a loaded machine
            e_fric = float(np.einsum('i,i,i', loss[:, j], vj, w))
            parts = [e_fric]
            last[0, j] = loss[-1, j] * vj[-1]
            for ci, x, y, factor in ((4, vj, a[:, j], mass), (5, om[:, j], al[:, j], inertia)):
                prod = np.multiply(x, y, out=tmp)
                e = factor * float(np.einsum('i,i', prod, w))
                energy[ci, j] += e
                parts.append(e)
                np.maximum(prod, 0.0, out=prod)
                gross[ci, j] += factor * float(np.einsum('i,i', prod, w))
                last[ci, j] = x[-1] * factor * y[-1]
            gj = g[:, j]
            if gj.size and not (gj[0] == 0.0 and not np.any(gj)):
                gv = np.multiply(gj, vj, out=tmp)
                e_grav = float(np.einsum('i,i', gv, w))
                parts.append(e_grav)
                np.maximum(gv, 0.0, out=gv)
                lift = float(np.einsum('i,i', gv, w))
                energy[2, j] += lift
                energy[3, j] += e_grav - lift
                p_last = gj[-1] * vj[-1]
                last[2, j], last[3, j] = max(p_last, 0.0), min(p_last, 0.0)
            energy[0, j] += e_fric
            if dyn.efficiency[j] != 1.0:
                e_mech = float(np.einsum('i,i', mech[:, j], w))
                energy[1, j] += e_mech - sum(parts)
                last[1, j] = mech[-1, j] - sum(last[i, j] for i in (0, 2, 3, 4, 5))
        signed_effect = len(FIXED_CAUSES)
        for i, (_label, power) in enumerate(effects):
            power = np.asarray(power)
            ci = signed_effect + i
            for j in range(k):
                column = power[:, j]
                if np.any(column):
                    energy[ci, j] += float(np.einsum('i,i', column, w))
                    positive = np.maximum(column, 0.0, out=tmp)
                    gross[ci, j] += float(np.einsum('i,i', positive, w))
                    last[ci, j] = column[-1]
        ci = c - 1
        if burned is not None:
            for j in range(k):
                column = burned[:, j]
                if np.any(column):
                    energy[ci, j] += float(np.einsum('i,i', column, w))
                    last[ci, j] = column[-1]
        elif braking == 'dissipated':
            for j in range(k):
                low = np.minimum(mech[:, j], 0.0, out=tmp)
                energy[ci, j] -= float(np.einsum('i,i', low, w))
                last[ci, j] = max(-mech[-1, j], 0.0)
        return last

    def _add_lines(self, rows: list, k: int, c: int, line: np.ndarray, dt: np.ndarray,
                   d0: float, first: bool, m: int) -> None:
        """Add the chunk's energy per line, per axis and per cause (interval -> end line)."""
        # one column per axis and per cause that has a row in this chunk (column 0 of the
        # samples: the previous chunk's last)
        live = sorted({ci for ci, _, _ in rows})
        where = {ci: k + i for i, ci in enumerate(live)}
        width = k + len(live)
        cols = self._work('cols', (width, m + 1))
        cols[...] = 0.0
        for ci, j, row in rows:
            cols[j, 1:] += row
            cols[where[ci], 1:] += row
        if first:
            cols, steps, ends = cols[:, 1:], dt, np.asarray(line[1:], dtype=np.int64)
        else:
            prev = cast(np.ndarray, self._last)     # not the first chunk: its last row
            cols[:k, 0] = prev.sum(axis=0)
            cols[k:, 0] = prev[live].sum(axis=1)
            steps = np.empty(m)
            steps[0] = d0
            steps[1:] = dt
            ends = np.asarray(line, dtype=np.int64)
        if steps.size == 0:
            return
        de = self._work('de', (width, steps.size))
        np.add(cols[:, 1:], cols[:, :-1], out=de)
        de *= steps
        de *= 0.5
        starts = np.concatenate(([0], np.nonzero(ends[1:] != ends[:-1])[0] + 1))
        keys = ends[starts]
        sums = np.add.reduceat(de, starts, axis=1)
        top = int(keys.max())
        if top >= self._lines.shape[0]:
            grown = np.zeros((max(2 * self._lines.shape[0], top + 1), k + c))
            grown[:self._lines.shape[0]] = self._lines
            self._lines = grown
        target = list(range(k)) + [k + ci for ci in live]
        if keys.shape[0] == 1:
            self._lines[keys[0], target] += sums[:, 0]
        else:
            for i, col in enumerate(target):          # a line may have several runs
                np.add.at(self._lines[:, col], keys, sums[i])

    def _work(self, name: str, shape: tuple[int, int]) -> np.ndarray:
        """A work array of ``shape`` reused from chunk to chunk (no page faults)."""
        size = shape[0] * shape[1]
        b = self._buffers.get(name)
        if b is None or b.size < size:
            b = self._buffers[name] = np.empty(size)
        return b[:size].reshape(shape)

    def by_cause(self, *, gross: bool = False) -> dict[str, dict[str, float]]:
        """``{cause: {axis: J, ..., 'total': J}}``; empty before the first chunk.

        ``gross``: the energy put in, ``integral max(P, 0) dt`` per axis, instead of the net
        ``integral P dt``; the total is the sum over the axes.
        """
        values = self.energy
        if values is None:
            return {}
        if gross:
            # one-signed causes: gross = net (>= 0) or 0 (<= 0, gravity_lower)
            values = np.maximum(values, 0.0)
            values[3] = 0.0
            values[self._signed] = cast(np.ndarray, self.gross)[self._signed]   # set with energy
        out: dict[str, dict[str, float]] = {}
        for i, cause in enumerate(self.causes):
            row = {a: float(values[i, j]) for j, a in enumerate(self.axes)}
            row['total'] = float(values[i].sum())
            out[cause] = row
        return out

    def lines_table(self, lines: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Per-axis ``(n, k)`` and per-cause ``(n, c)`` energy of the given source lines."""
        if not self.per_line or self.energy is None:
            return None
        k = len(self.axes)
        idx = np.asarray(lines, dtype=np.int64)
        inside = idx < self._lines.shape[0]
        rows = np.zeros((idx.shape[0], self._lines.shape[1]))
        rows[inside] = self._lines[idx[inside]]
        return rows[:, :k], rows[:, k:]


def add_breakdown(summary: dict, acc: BreakdownAccumulator) -> dict:
    """Add the breakdown keys to a summary dict (``docs/breakdown.md``); return it.

    Sets ``causes``, ``energy_by_cause_j`` (net, the causes add up to ``energy_j``),
    ``gross_by_cause_j`` (energy put in, ``integral max(P, 0) dt``; gross minus net is what
    the cause gave back) and ``braking_returned_j`` (the same number as
    ``regenerated_energy_j``); with ``acc.per_line``, every ``top_blocks`` item gets
    ``energy_by_axis_j`` ({axis: J}) and ``energy_by_cause_j`` ({cause: J}, over the axes).
    """
    summary['causes'] = list(acc.causes)
    summary['energy_by_cause_j'] = acc.by_cause()
    summary['gross_by_cause_j'] = acc.by_cause(gross=True)
    summary['braking_returned_j'] = float(summary.get('regenerated_energy_j', 0.0))
    blocks = summary.get('top_blocks') or []
    table = acc.lines_table(np.array([b['line'] for b in blocks], dtype=np.int64))
    if table is not None:
        by_axis, by_cause = table
        for i, block in enumerate(blocks):
            block['energy_by_axis_j'] = {a: float(by_axis[i, j])
                                         for j, a in enumerate(acc.axes)}
            block['energy_by_cause_j'] = {c: float(by_cause[i, j])
                                          for j, c in enumerate(acc.causes)}
    return summary
