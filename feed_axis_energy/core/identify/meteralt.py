"""Would a different meter explain the residual? The instrument alternative of ``analyze``.

Two instrument faults leave residuals that no catalog effect has, but that a few of them
together can imitate on a campaign whose power is mostly speed-dependent loss:

* a **gain** error (the meter reads a few per cent high or low, or the loss function is off
  by a factor): ``r = g·P`` with ``P`` the declared power as recorded (``iron``, ``coulomb``
  + ``viscous`` or a flat ``position_friction`` imitate it);
* a **lag** (a meter that smooths beyond its averaging window, e.g. a first-order filter of
  time constant ``tau``): to second order ``r = -tau·P' + tau²·P''``; the offset search takes
  the delay, ``mass_error`` and ``viscous`` imitate the rest.

:func:`meter_alternative` fits these three columns per measured axis (gain, delay,
smoothing; the derivatives of the 1 kHz declared power, averaged by the same instrument
model) beside the selected effects that describe the records rather than the machine
(``time_offset``), and compares its BIC with that of the selection. When the alternative is
at least as good, the finding is not one of the catalog's: ``analyze`` claims nothing and
reports it in ``unexplained`` (diagnostic ``instrument``).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
import math
from typing import Any

import numpy as np

from ..effects import get_effect
from .selection import Block, Design

__all__ = ['meter_columns', 'meter_alternative']


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
    k = len(sim_index)
    cols = []
    for j in sim_index:
        p = power_w[:, j] if j is not None else np.zeros(t.size)
        d1 = np.gradient(p, t)
        cols += [p, -d1, np.gradient(d1, t)]
    on = aligned(np.column_stack(cols))           # (m, 3k)
    m = on.shape[0]
    out = np.zeros((m, k, 3 * k))
    for j in range(k):
        out[:, j, 3 * j:3 * j + 3] = on[:, 3 * j:3 * j + 3]
    return out.reshape(m * k, 3 * k)


def _bic(sse: float, n: float, p: int) -> float:
    return n * math.log(max(sse, 1e-300) / n) + p * math.log(n)


def meter_alternative(design: Design, blocks: Sequence[Block], columns: Sequence[np.ndarray],
                      *, axes: Sequence[str]) -> dict[str, Any] | None:
    """The instrument explanation when it fits at least as well as the selection.

    Parameters
    ----------
    design
        The residuals and candidate columns of ``analyze``.
    blocks
        The selected effects.
    columns
        Per run, :func:`meter_columns`.
    axes
        The measured axes.

    Returns
    -------
    dict or None
        An ``unexplained`` entry (``diagnostic`` ``'instrument'``; gain, delay and
        smoothing time in its message, the first axis's gain as ``statistic``) when the
        alternative's BIC is not larger than the selection's; ``None`` otherwise, or when no
        machine effect was selected.
    """
    machine = [b for b in blocks if get_effect(b.key[0]).machine_property]
    if not machine:
        return None
    record_cols = [c for b in blocks if not get_effect(b.key[0]).machine_property
                   for c in b.cols]
    runs = range(design.runs)
    x = [np.hstack([np.asarray(columns[r], dtype=float), design.x[r][:, record_cols]])
         for r in runs]
    gram = sum(a.T @ a for a in x)
    rhs = sum(a.T @ design.y[r] for r, a in zip(runs, x))
    # columns of very different scales (W, W·s, W·s²): solve on unit-norm columns
    scale = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    theta = np.linalg.lstsq(gram / np.outer(scale, scale), rhs / scale, rcond=1e-12)[0] / scale
    sse_alt = float(sum(np.sum((design.y[r] - a @ theta) ** 2) for r, a in zip(runs, x)))
    n = float(design.n.sum())
    bic_sel = design.bic([c for b in blocks for c in b.cols])
    bic_alt = _bic(sse_alt, n, x[0].shape[1])
    if not (math.isfinite(bic_alt) and bic_alt <= bic_sel):
        return None
    parts = []
    for j, a in enumerate(axes):
        g, d, s = theta[3 * j:3 * j + 3]
        smooth = f'{1e3 * math.sqrt(s):.1f} ms' if s > 0.0 else 'none'
        parts.append(f'{a}: gain {100.0 * g:+.2f} %, delay {1e3 * d:+.1f} ms, '
                     f'smoothing time {smooth}')
    names = ', '.join(f'{b.key[0]} on {b.key[1]}' for b in machine)
    msg = (f'a different meter explains the residual at least as well as {names} '
           f'(BIC {bic_alt:.1f} against {bic_sel:.1f}): {"; ".join(parts)} (a meter gain or '
           f'lag, or a loss function off by that factor): not claimed')
    return {'diagnostic': 'instrument', 'axis': ','.join(axes),
            'effect': ','.join(b.key[0] for b in machine), 'statistic': float(theta[0]),
            'message': msg}
