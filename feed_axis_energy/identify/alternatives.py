"""Would something outside the catalog explain the residual? Alternatives of ``analyze``.

Some effects outside the catalog leave residuals that no single catalog effect has, but
that a few of them together imitate on a stroke campaign; ``analyze`` would name them.
Each alternative here is fitted (its columns per measured axis, beside the selected effects
that describe the records rather than the machine, ``time_offset``) and its BIC compared
with that of the selection. When an alternative is at least as good, the finding is not
one of the catalog's: ``analyze`` claims nothing and reports it in ``unexplained``.

* **A different meter** (diagnostic ``instrument``, :func:`meter_columns`): a meter that
  reads a few per cent high or low (or a loss function off by a factor) leaves ``g·P``, with
  ``P`` the declared power as recorded (``iron``, ``coulomb`` + ``viscous`` or a flat
  ``position_friction`` imitate it); a meter that smooths beyond its window (a first-order
  lag ``tau``) leaves, to second order, ``-tau·P' + tau²·P''`` (the offset search takes the
  delay; ``mass_error`` and ``viscous`` imitate the rest). Three columns per axis: gain,
  delay, smoothing.
* **A force pulse after every reversal** (diagnostic ``reversal``,
  :func:`reversal_columns`): backlash or preload take-up in the nut, ``F·exp(-s/s0)·|v|``
  with ``s`` the travel since the axis last changed direction (``s0`` from
  :data:`REVERSAL_DECAYS_M`, the best fitting one is kept). When every stroke reverses at
  the same positions, ``coulomb`` + a ``position_friction`` bump at the travel's ends
  imitate it.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
import math
from typing import Any

import numpy as np

from ..effects import get_effect
from .selection import Block, Design

__all__ = ['REVERSAL_DECAYS_M', 'meter_columns', 'reversal_columns', 'check_alternatives']

REVERSAL_DECAYS_M = (0.002, 0.005, 0.01, 0.02)
"""Decay lengths [m] of the reversal pulse tried."""


def meter_columns(t: np.ndarray, power_w: np.ndarray, sim_index: Sequence[int | None],
                  aligned: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """The alternative's columns of one run, flattened like its residual: ``(m*k, 3k)``.

    Parameters
    ----------
    t, power_w
        Simulated times [s] ``(n,)`` and declared power per simulated axis [W] ``(n, a)``.
    sim_index
        Measured axis ``j`` -> column of ``power_w`` (``None``: not simulated).
    aligned
        The run's instrument model: 1 kHz columns ``(n, c)`` -> measured stamps ``(m, c)``.

    Returns
    -------
    numpy.ndarray
        Per measured axis ``j`` three columns, ``P`` [W], ``-P'`` [W/s] and ``P''`` [W/s²]
        (coefficients: gain [-], delay [s], smoothing [s²]), each zero on the other axes'
        samples.
    """
    cols = []
    for j in sim_index:
        p = power_w[:, j] if j is not None else np.zeros(t.size)
        d1 = np.gradient(p, t)
        cols += [p, -d1, np.gradient(d1, t)]
    return _per_axis(aligned(np.column_stack(cols)), len(sim_index), 3)


def _per_axis(on: np.ndarray, k: int, q: int) -> np.ndarray:
    """``(m, q·k)`` aligned columns to ``(m·k, q·k)``: axis ``j``'s on its own samples."""
    m = on.shape[0]
    out = np.zeros((m, k, q * k))
    for j in range(k):
        out[:, j, q * j:q * j + q] = on[:, q * j:q * j + q]
    return out.reshape(m * k, q * k)


def _travel_since_reversal(x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Travel [m] since the axis started moving in its current direction after moving in the
    other (the first move of a record counts as one); ``inf`` where it never moved."""
    out = np.full(x.shape, np.inf)
    d = np.sign(v)
    moving = np.flatnonzero(d != 0.0)
    if moving.size == 0:
        return out
    # a new direction starts where the sign differs from the previous moving sample's
    starts = moving[np.concatenate([[True], d[moving[1:]] != d[moving[:-1]]])]
    bounds = np.append(starts, x.size)
    for a, b in zip(bounds[:-1], bounds[1:]):
        out[a:b] = np.abs(x[a:b] - x[a])
    return out


def reversal_columns(t: np.ndarray, power_w: np.ndarray, position_m: np.ndarray,
                     velocity_m_s: np.ndarray, sim_index: Sequence[int | None],
                     aligned: Callable[[np.ndarray], np.ndarray], *,
                     decay_m: float) -> np.ndarray:
    """A unit force pulse after every reversal, and a delay, per measured axis: ``(m*k, 2k)``.

    Parameters
    ----------
    t, power_w, position_m, velocity_m_s
        Simulated times [s] ``(n,)``, declared power, positions and velocities ``(n, a)``.
    sim_index, aligned
        As for :func:`meter_columns`.
    decay_m
        Travel over which the pulse decays by ``1/e`` [m].

    Returns
    -------
    numpy.ndarray
        Columns ``2j``: ``exp(-s/decay_m)·|v|`` on axis ``j`` [W per N of pulse];
        ``2j+1``: ``-P'`` [W/s], the delay by which the baseline offset, estimated without
        the pulse, is off.
    """
    cols = []
    for j in sim_index:
        if j is None:
            cols += [np.zeros(t.size), np.zeros(t.size)]
            continue
        s = _travel_since_reversal(position_m[:, j], velocity_m_s[:, j])
        cols += [np.exp(-s / decay_m) * np.abs(velocity_m_s[:, j]),
                 -np.gradient(power_w[:, j], t)]
    return _per_axis(aligned(np.column_stack(cols)), len(sim_index), 2)


def _bic(sse: float, n: float, p: int) -> float:
    return n * math.log(max(sse, 1e-300) / n) + p * math.log(n)


def _fit(design: Design, blocks: Sequence[Block],
         columns: Sequence[np.ndarray]) -> tuple[np.ndarray, float]:
    """Least squares of the alternative's columns beside the record effects: theta, BIC."""
    record_cols = [c for b in blocks if not get_effect(b.key[0]).machine_property
                   for c in b.cols]
    runs = range(design.runs)
    x = [np.hstack([np.asarray(columns[r], dtype=float), design.columns(r, record_cols)])
         for r in runs]
    gram = sum(a.T @ a for a in x)
    rhs = sum(a.T @ design.y[r] for r, a in zip(runs, x))
    # columns of very different scales (W, W/s, W/s²): solve on unit-norm columns
    scale = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    theta = np.linalg.lstsq(gram / np.outer(scale, scale), rhs / scale, rcond=1e-12)[0] / scale
    sse = float(sum(np.sum((design.y[r] - a @ theta) ** 2) for r, a in zip(runs, x)))
    return theta, _bic(sse, float(design.n.sum()), x[0].shape[1])


def check_alternatives(design: Design, blocks: Sequence[Block],
                       runs: Iterable[tuple[Any, Sequence[int | None], Callable]], *,
                       axes: Sequence[str]) -> dict[str, Any] | None:
    """The best alternative, as an entry, when it fits at least as well as the selection.

    Parameters
    ----------
    design
        The residuals and candidate columns of ``analyze``.
    blocks
        The selected effects.
    runs
        Per run ``(state, sim_index, aligned)``: the 1 kHz :class:`..effects.EffectState`
        of the declared model, measured axis -> its column, and the instrument model. It is
        iterated once per alternative and only one state is used at a time, so it may
        produce each state when iterated (memory-mapped: :mod:`.statestore`).
    axes
        The measured axes.

    Returns
    -------
    dict or None
        An ``unexplained`` entry (``diagnostic`` ``'instrument'`` or ``'reversal'``,
        ``statistic``: the first axis's gain or pulse force [N], the fitted values in the
        message) when the best alternative's BIC is not larger than the selection's; ``None``
        otherwise, or when no machine effect was selected.
    """
    machine = [b for b in blocks if get_effect(b.key[0]).machine_property]
    if not machine:
        return None
    bic_sel = design.bic([c for b in blocks for c in b.cols])
    names = ', '.join(f'{b.key[0]} on {b.key[1]}' for b in machine)
    effect = ','.join(b.key[0] for b in machine)
    meter, bic_meter = _fit(design, blocks, [meter_columns(st.t, st.power_w, idx, al)
                                             for st, idx, al in runs])
    fits = [(_fit(design, blocks, [reversal_columns(st.t, st.power_w, st.position_m,
                                                    st.velocity_m_s, idx, al, decay_m=s0)
                                   for st, idx, al in runs]), s0)
            for s0 in REVERSAL_DECAYS_M]
    (pulse, bic_pulse), s0 = min(fits, key=lambda f: f[0][1])
    bic = min(bic_meter, bic_pulse)
    if not (math.isfinite(bic) and bic <= bic_sel):
        return None
    if bic_meter <= bic_pulse:
        parts = []
        for j, a in enumerate(axes):
            g, d, sm = meter[3 * j:3 * j + 3]
            smooth = f'{1e3 * math.sqrt(sm):.1f} ms' if sm > 0.0 else 'none'
            parts.append(f'{a}: gain {100.0 * g:+.2f} %, delay {1e3 * d:+.1f} ms, '
                         f'smoothing time {smooth}')
        msg = (f'a different meter explains the residual at least as well as {names} '
               f'(BIC {bic:.1f} against {bic_sel:.1f}): {"; ".join(parts)} (a meter gain '
               f'or lag, or a loss function off by that factor): not claimed')
        return {'diagnostic': 'instrument', 'axis': ','.join(axes), 'effect': effect,
                'statistic': float(meter[0]), 'message': msg}
    forces = ', '.join(f'{pulse[2 * j]:.3g} N on {a}' for j, a in enumerate(axes))
    msg = (f'a force pulse after every change of direction ({forces}, decaying over '
           f'{1e3 * s0:g} mm: backlash or preload take-up, not in the catalog) explains the '
           f'residual at least as well as {names} (BIC {bic:.1f} against {bic_sel:.1f}): '
           f'not claimed')
    return {'diagnostic': 'reversal', 'axis': ','.join(axes), 'effect': effect,
            'statistic': float(pulse[0]), 'message': msg}
