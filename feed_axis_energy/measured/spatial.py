"""Alignment on the measured motion: the time offset from the velocities, the work offset from
the positions.

**Time (the motion anchor).** A record that holds the axes' measured motion (actual or
commanded velocity, or positions) beside its power or drive trace gives the time offset
without any power model: the measured velocities are correlated with the simulated ones
(:func:`motion_anchor`, point samples, each axis scaled by its measured RMS, signs kept). An
effect the model lacks changes the power of a move, never when the move starts, stops or
which way it goes, so this offset survives a large missing effect (the power correlation is
pulled towards a lag that hides it), and the signs tell the up and down strokes of a
periodic program apart. The power correlation then only refines it, within
:func:`refine_range_s`: the meter's own lag behind the motion columns. The same velocities
also time the record's clock: the offsets of its two halves differ by the clock's rate
(``drift_ppm``, on records of at least :data:`MOTION_DRIFT_MIN_S`), which ``compare`` then
corrects (:func:`.align.clock_corrected`).

**Space (the work offset).**

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

from .align import estimate_offset, OffsetResult
from .run import MeasuredRun

__all__ = ['WorkOffset', 'estimate_work_offset', 'TOLERANCE_M', 'motion_anchor',
           'measured_velocity', 'refine_range_s', 'MIN_REFINE_S', 'MOTION_DRIFT_MIN_S',
           'MOTION_FEATURE_S']

TOLERANCE_M = 1.0e-3
"""Spread [m] of the positions about the translation up to which it is ``'ok'``."""
MIN_REFINE_S = 0.25
"""Smallest half-width [s] of the power refinement around the motion anchor."""
MOTION_FEATURE_S = 0.1
"""Lags of the velocities closer than this [s] to the best are the same alignment (the
shoulders of a broad peak: velocities are smooth), not a rival one."""
MOTION_DRIFT_MIN_S = 4.0
"""Shortest record [s] whose clock rate the measured motion estimates (two halves of 2 s:
a missing effect does not move the velocities, and their edges time them to a few
microseconds, so a few seconds tell tens of ppm; the power's own estimate needs a minute,
:data:`.align.DRIFT_MIN_DURATION_S`)."""


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


def measured_velocity(run: MeasuredRun, axes: Sequence[str]) -> np.ndarray | None:
    """The measured velocity [m/s] of ``axes``, ``(n, len(axes))``, or ``None``.

    The actual velocity where mapped, else the commanded one, else the actual (then the
    commanded) positions differentiated over the stamps; ``None`` when the run maps none of
    these or an axis is not among its axes.
    """
    if not axes or any(a not in run.axes for a in axes):
        return None
    cols = [run.axes.index(a) for a in axes]
    for vel in (run.velocity_m_s, run.command_velocity_m_s):
        if vel is not None:
            return np.asarray(vel[:, cols], dtype=float)
    for pos in (run.position_m, run.command_position_m):
        if pos is not None and run.t.size >= 2:
            return np.gradient(np.asarray(pos[:, cols], dtype=float), run.t, axis=0)
    return None


def refine_range_s(window_s: float, period_s: float) -> float:
    """Half-width [s] of the power refinement around the motion anchor.

    The meter's lag behind the motion columns of the same record: a filter or an averaging
    window, a few of its windows or periods at most; at least :data:`MIN_REFINE_S`.
    """
    return max(MIN_REFINE_S, 4.0 * float(window_s), 4.0 * float(period_s))


def motion_anchor(t_meas: np.ndarray, v_meas: np.ndarray, t_sim: np.ndarray,
                  v_sim: np.ndarray, *, max_lag_s: float,
                  min_correlation: float = 0.5) -> OffsetResult | None:
    """The time offset of a record from its measured velocities (module docstring).

    Parameters
    ----------
    t_meas, v_meas
        Measured stamps [s] ``(n,)`` and velocities [m/s] ``(n, k)``.
    t_sim, v_sim
        Simulated times [s] ``(m,)`` and velocities [m/s] ``(m, k)``, columns as ``v_meas``.
    max_lag_s
        Largest offset searched, in either direction [s].
    min_correlation
        Correlation below which the estimate is ``'weak'``.

    Returns
    -------
    OffsetResult or None
        The estimate on the velocities (``rms_w`` and ``runner_up_rms_w`` are residuals of
        the scaled velocities, not watts), or ``None`` when no axis moves in the record or
        in the simulation (nothing to align on).
    """
    v_meas = np.asarray(v_meas, dtype=float)
    v_sim = np.asarray(v_sim, dtype=float)
    finite = np.isfinite(v_meas).all(axis=1)
    if finite.sum() < 4:
        return None
    rms = np.sqrt(np.mean(v_meas[finite] ** 2, axis=0))
    sim_rms = np.sqrt(np.mean(v_sim ** 2, axis=0)) if v_sim.size else np.zeros(0)
    use = [j for j in range(v_meas.shape[1]) if rms[j] > 0.0 and sim_rms[j] > 0.0]
    if not use:
        return None
    y_meas = (v_meas[finite][:, use] / rms[use]).sum(axis=1)
    y_sim = (v_sim[:, use] / rms[use]).sum(axis=1)
    return estimate_offset(np.asarray(t_meas, dtype=float)[finite], y_meas,
                           np.asarray(t_sim, dtype=float), y_sim, max_lag_s=max_lag_s,
                           window_s=0.0, min_correlation=min_correlation,
                           feature_s=MOTION_FEATURE_S, drift_min_duration_s=MOTION_DRIFT_MIN_S)
