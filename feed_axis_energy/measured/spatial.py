"""Spatial alignment: the work offset between a trace's machine positions and the program's.

A drive trace records positions in machine coordinates; a run simulated from its NC program
moves in the program's coordinates plus whatever work offset the machine config declares
(``gcode.work_offsets_m``: the control's ``G54``..``G59`` values). Once the records are aligned
in time (:func:`.align.estimate_offset`), what is left between the two position records of
an axis is, for a program that ran as simulated, a constant: the part of the work offset the
config does not declare. It is estimated per axis as the median of
``measured - simulated`` over the samples both cover (the median: a few samples of a stop
the simulation reaches earlier or later weigh nothing), with the RMS of what the translation
leaves as its spread. A work offset declared in the manifest (``work_offset_m``) wins: it is
the one used and reported, with the estimate beside it.

A result, never an exception: ``status`` ``'ok'`` (the spread within the tolerance),
``'loose'`` (the program did not run as simulated, or not at this time offset: the
translation alone does not explain the positions), ``'declared'``.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
import math
from typing import Any

import numpy as np

__all__ = ['WorkOffset', 'estimate_work_offset', 'TOLERANCE_M']

TOLERANCE_M = 1.0e-3
"""Spread [m] of the positions about the translation up to which it is ``'ok'``."""


@dataclass(frozen=True)
class WorkOffset:
    """The translation per axis from the simulated (program) to the measured positions.

    Attributes
    ----------
    axes
        Axes with positions on both sides.
    found_m
        Estimated ``measured - simulated`` position per axis [m] (median).
    spread_m
        RMS of ``measured - simulated - found`` per axis [m].
    declared_m
        The manifest's ``work_offset_m`` per axis [m], or ``None``.
    status, message
        ``'ok'``, ``'loose'`` or ``'declared'``, and the words.
    n_samples
        Samples compared.
    """

    axes: tuple[str, ...]
    found_m: tuple[float, ...]
    spread_m: tuple[float, ...]
    declared_m: tuple[float, ...] | None
    status: str
    message: str
    n_samples: int

    @property
    def used_m(self) -> tuple[float, ...]:
        """The declared offset where given, else the estimate [m]."""
        return self.declared_m if self.declared_m is not None else self.found_m

    def to_dict(self) -> dict[str, Any]:
        """JSON form: per-axis mappings in metres (docs/compare.md, ``work_offset``)."""
        def per_axis(values: Sequence[float] | None) -> dict[str, float] | None:
            return None if values is None else dict(zip(self.axes, map(float, values)))
        return {'found_m': per_axis(self.found_m), 'used_m': per_axis(self.used_m),
                'declared_m': per_axis(self.declared_m), 'spread_m': per_axis(self.spread_m),
                'status': self.status, 'message': self.message, 'n_samples': self.n_samples}


def estimate_work_offset(t_meas: np.ndarray, pos_meas: np.ndarray, t_sim: np.ndarray,
                         pos_sim: np.ndarray, *, axes: Sequence[str], offset_s: float,
                         declared: Mapping[str, float] | None = None,
                         tolerance_m: float = TOLERANCE_M) -> WorkOffset:
    """Estimate the translation ``measured - simulated`` per axis at a time offset.

    Parameters
    ----------
    t_meas, pos_meas
        Measured stamps [s] ``(n,)`` and machine positions [m] ``(n, k)``.
    t_sim, pos_sim
        Simulated times [s] ``(m,)`` and positions [m] ``(m, k)``, columns as ``pos_meas``.
    axes
        The ``k`` axis names.
    offset_s
        How much later the measured record is [s] (as :func:`.align.align_simulated`).
    declared
        Axis -> declared work offset [m] (``measured - simulated``); wins where given.
    tolerance_m
        Spread up to which the estimate is ``'ok'``.

    Returns
    -------
    WorkOffset
        The estimate (``'loose'`` with fewer than 2 samples in common, NaN found values).
    """
    k = len(axes)
    declared_m = None
    if declared:
        declared_m = tuple(float(declared.get(a, 0.0)) for a in axes)
    at = np.asarray(t_meas, dtype=float) - float(offset_s)
    t_sim = np.asarray(t_sim, dtype=float)
    inside = (at >= t_sim[0]) & (at <= t_sim[-1])
    n = int(inside.sum())
    if n < 2:
        nan = tuple(math.nan for _ in range(k))
        return WorkOffset(tuple(axes), nan, nan, declared_m,
                          'declared' if declared_m is not None else 'loose',
                          f'{n} measured sample(s) lie within the simulation at offset '
                          f'{offset_s:+.3f} s: no work offset can be estimated', n)
    found, spread = [], []
    for j in range(k):
        sim = np.interp(at[inside], t_sim, pos_sim[:, j])
        d = pos_meas[inside, j] - sim
        c = float(np.median(d))
        found.append(c)
        spread.append(math.sqrt(float(np.mean((d - c) ** 2))))
    words = ', '.join(f'{a} {1e3 * c:+.3f} mm' for a, c in zip(axes, found))
    worst = max(spread)
    if declared_m is not None:
        given = ', '.join(f'{a} {1e3 * c:+.3f} mm' for a, c in zip(axes, declared_m))
        status = 'declared'
        message = (f'work offset declared ({given}); estimated from the positions: {words} '
                   f'(spread up to {1e3 * worst:.3g} mm over {n} samples)')
    elif worst <= tolerance_m:
        status = 'ok'
        message = (f'work offset (machine - program) {words}; the positions agree after the '
                   f'translation within {1e3 * worst:.3g} mm RMS ({n} samples)')
    else:
        status = 'loose'
        message = (f'work offset (machine - program) {words}, but the positions scatter by up '
                   f'to {1e3 * worst:.3g} mm RMS about it ({n} samples): the program did not '
                   'run as simulated at this time offset (a translation alone does not '
                   'explain the trace)')
    return WorkOffset(tuple(axes), tuple(found), tuple(spread), declared_m, status, message, n)
