"""Motion from a measured or commanded trajectory: positions sampled in time (and, where the
data have them, velocities and accelerations) turned into a :class:`.motion.Motion` the
dynamics take, as the planner's output is for an NC program.

The samples are taken as they are: the motion keeps their time base, nothing is resampled or
interpolated, and a derivative the data lack is a finite difference (optionally smoothed) of
the samples. This is the checked way in for any sampled motion: a trajectory CSV
(``sim/trajcsv.py``), a measured run with ``motion.reconstruct: samples``. It differs from
``measured/motiondata.py`` (:func:`~feed_axis_energy.measured.motiondata.reconstruct_motion`),
which resamples coarse measured records onto the simulation rate with a model of the motion
between the stamps, and validates its samples through this function.
"""
from __future__ import annotations

import numpy as np

from ..errors import DataError
from .motion import Motion

__all__ = ['motion_from_samples']


def motion_from_samples(t: np.ndarray, pos: np.ndarray, *, axes: tuple[str, ...],
                        line: np.ndarray | None = None, source: str = '',
                        smooth_samples: int = 1, vel: np.ndarray | None = None,
                        acc: np.ndarray | None = None) -> Motion:
    """Build a :class:`Motion` from a measured or commanded trajectory.

    Velocity and acceleration are central finite differences on the (possibly non-uniform)
    time base, ``numpy.gradient(pos, t, axis=0)`` (second order inside, first order at the
    ends), applied once for velocity and again for acceleration. With ``smooth_samples > 1``
    each derivative is smoothed by a centred moving average of that many samples (odd; the
    window shrinks at the ends) before it is used.

    Parameters
    ----------
    t
        Sample times [s], shape ``(n,)``, finite and strictly increasing, ``n >= 2``.
    pos
        Positions [m], shape ``(n, k)`` (or ``(n,)`` for a single axis).
    axes
        Axis names, ``k`` of them.
    line
        Source line per sample (default 0).
    source
        Where the data came from; used in error messages and as ``Motion.source``.
    smooth_samples
        Moving-average window for the derivatives (1: no smoothing).
    vel, acc
        Measured velocities [m/s] and accelerations [m/s^2], shape ``(n, k)``, used instead
        of the finite differences where given (a measured velocity is usually far cleaner
        than differentiated, coarsely rounded positions). Without ``acc`` the acceleration
        is the finite difference of the velocity used.

    Returns
    -------
    Motion
        The motion with differentiated velocity and acceleration.

    Raises
    ------
    DataError
        Wrong shapes, non-finite values or a time base that is not strictly increasing.
    """
    where = source or '<samples>'
    t = np.asarray(t, dtype=float)
    pos = np.asarray(pos, dtype=float)
    axes = tuple(axes)
    if pos.ndim == 1:
        pos = pos[:, None]
    if t.ndim != 1 or t.size < 2:
        raise DataError(f'time must be 1-D with at least 2 samples, got shape {t.shape}',
                        file=where, column='t')
    if pos.shape != (t.size, len(axes)):
        msg = f'positions have shape {pos.shape}, expected ({t.size}, {len(axes)})'
        raise DataError(msg, file=where)
    bad = np.nonzero(~np.isfinite(t))[0]
    if bad.size:
        raise DataError('time is not finite', file=where, column='t', row=int(bad[0]) + 1)
    bad = np.nonzero(np.diff(t) <= 0.0)[0]
    if bad.size:
        msg = f'time is not strictly increasing ({t[bad[0]]!r} then {t[bad[0] + 1]!r})'
        raise DataError(msg, file=where, column='t', row=int(bad[0]) + 2)
    bad_rows, bad_cols = np.nonzero(~np.isfinite(pos))
    if bad_rows.size:
        raise DataError('position is not finite', file=where, column=axes[bad_cols[0]],
                        row=int(bad_rows[0]) + 1)
    if smooth_samples < 1 or smooth_samples % 2 == 0:
        raise DataError(f'smooth_samples must be a positive odd number, got {smooth_samples}',
                        file=where)
    if line is None:
        line_arr = np.zeros(t.size, dtype=np.int32)
    else:
        line_arr = np.asarray(line).astype(np.int32)
        if line_arr.shape != t.shape:
            msg = f'line has shape {line_arr.shape}, expected {t.shape}'
            raise DataError(msg, file=where, column='line')
    vel = (_smooth(np.gradient(pos, t, axis=0), smooth_samples) if vel is None
           else _measured(vel, 'velocity', t=t, axes=axes, where=where))
    acc = (_smooth(np.gradient(vel, t, axis=0), smooth_samples) if acc is None
           else _measured(acc, 'acceleration', t=t, axes=axes, where=where))
    return Motion(t=t, axes=axes, pos=pos, vel=vel, acc=acc, line=line_arr, source=source)


def _measured(values: np.ndarray, what: str, *, t: np.ndarray, axes: tuple[str, ...],
              where: str) -> np.ndarray:
    """Validate a measured derivative given to :func:`motion_from_samples`."""
    arr = np.asarray(values, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.shape != (t.size, len(axes)):
        msg = f'{what} has shape {arr.shape}, expected ({t.size}, {len(axes)})'
        raise DataError(msg, file=where)
    bad_rows, bad_cols = np.nonzero(~np.isfinite(arr))
    if bad_rows.size:
        raise DataError(f'{what} is not finite', file=where, column=axes[bad_cols[0]],
                        row=int(bad_rows[0]) + 1)
    return arr


def _smooth(x: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average along axis 0; the window shrinks symmetrically at the ends."""
    if window <= 1 or x.shape[0] < 3:
        return x
    half = window // 2
    n = x.shape[0]
    cum = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    idx = np.arange(n)
    h = np.minimum(np.minimum(idx, n - 1 - idx), half)
    return (cum[idx + h + 1] - cum[idx - h]) / (2 * h + 1)[:, None]
