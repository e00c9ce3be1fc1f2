"""Motion from measured or commanded samples at coarse rates: acceleration rebuilt per interval.

A record sampled every 100 ms cannot show everything an axis does between two stamps: a
rapid move can reach 45 mm/s within one sample while an acceleration column, a point value
at each stamp, reads 0 at both ends. The inertia power of that start is real.

Method (:func:`reconstruct_motion`), on every interval ``[t_i, t_i+1]`` of length ``h``,
with ``s = (t - t_i) / h``:

* acceleration ``a(s) = a_i + (a_i+1 - a_i) s + 6 c s (1 - s)``: the sampled accelerations
  (0 where no acceleration column is mapped), linear between the stamps, plus a smooth pulse
  that vanishes at both stamps, whose mean ``c = (v_i+1 - v_i) / h - (a_i + a_i+1) / 2``
  carries the velocity change the sampled accelerations do not explain;
* velocity: the integral of ``a`` from ``v_i``; it reaches ``v_i+1`` exactly at ``t_i+1``;
* position: the integral of the velocity from ``p_i``, with the interval's mismatch against
  the sampled ``p_i+1`` spread linearly over the interval (positions may be rounded: the
  UMich files print 3 significant digits).

So, whatever the data: positions, velocities and accelerations at the stamps are the sampled
ones (a point-sampling meter sees exactly what the samples say); each interval's velocity
change, hence the kinetic-energy change ``m (v1^2 - v0^2) / 2`` of the inertia power, is the
sampled one; and a transient inside an interval appears as a pulse at its centre, which an
averaging meter sees. Velocities come from the data's velocity columns (else central
differences of the positions); without acceleration columns ``a_i = 0``.

How it differs from :func:`feed_axis_energy.plan.motion_from_samples`: that one takes samples
as they are (their time base, derivatives by finite differences) and is the way in for any
sampled motion (trajectory CSV, ``motion.reconstruct: samples``); this one makes new samples
at the simulation rate from a model of what happens between coarse stamps, a choice about
measured records and the meter that reads them (``motion.reconstruct: pulses``, used by
:mod:`.compare` when the data are coarser than the simulation rate), so it lives with the
measured runs. It checks its input through ``motion_from_samples``.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import DataError
from ..plan import Motion, motion_from_samples

__all__ = ['MAX_RECONSTRUCTED_SAMPLES', 'reconstruct_motion']

MAX_RECONSTRUCTED_SAMPLES = 20_000_000
"""Most samples x axes a reconstruction may allocate (about 480 MB of pos/vel/acc)."""
_CHUNK = 200_000


def reconstruct_motion(t: np.ndarray, pos: np.ndarray, *, axes: tuple[str, ...],
                       rate_hz: float, vel: np.ndarray | None = None,
                       acc: np.ndarray | None = None, source: str = '') -> Motion:
    """Rebuild a motion at ``rate_hz`` from coarse samples (see the module docstring).

    Parameters
    ----------
    t
        Sample times [s], strictly increasing, ``(n,)``, ``n >= 2``.
    pos
        Positions [m], ``(n, k)``.
    axes
        Axis names, ``k`` of them.
    rate_hz
        Output rate [Hz] (the machine's simulation rate).
    vel
        Sampled velocities [m/s], ``(n, k)``; default: central differences of ``pos``.
    acc
        Sampled accelerations [m/s^2], ``(n, k)``; default: 0 at every stamp.
    source
        Where the samples came from (messages, ``Motion.source``).

    Returns
    -------
    Motion
        On the grid ``t[0] + j / rate_hz`` up to ``t[-1]``, plus the last stamp.

    Raises
    ------
    DataError
        Malformed samples (as :func:`~feed_axis_energy.plan.motion_from_samples`), a bad rate, or a
        reconstruction larger than :data:`MAX_RECONSTRUCTED_SAMPLES` (estimated first).
    """
    # validation (shapes, finite values, increasing time) as for samples taken as they are
    coarse = motion_from_samples(t, pos, axes=axes, source=source, vel=vel,
                                 acc=np.zeros_like(np.asarray(pos, dtype=float))
                                 if acc is None else acc)
    t, pos, vel, acc = coarse.t, coarse.pos, coarse.vel, coarse.acc
    where = source or '<samples>'
    if not (math.isfinite(rate_hz) and rate_hz > 0.0):
        raise DataError(f'rate_hz must be a finite number > 0, got {rate_hz!r}', file=where)
    span = float(t[-1] - t[0])
    n_fine = int(math.floor(span * rate_hz + 1e-9)) + 1
    cost = n_fine * len(axes)
    if cost > MAX_RECONSTRUCTED_SAMPLES:
        msg = (f'reconstructing {span:.6g} s of motion at {rate_hz:g} Hz needs {n_fine} '
               f'samples per axis ({cost} values, limit {MAX_RECONSTRUCTED_SAMPLES}); '
               'use motion reconstruct: samples or a shorter run')
        raise DataError(msg, file=where)
    tf = t[0] + np.arange(n_fine) / rate_hz
    if tf[-1] < t[-1]:
        tf = np.append(tf, t[-1])
    k = len(axes)
    out_p = np.empty((tf.size, k))
    out_v = np.empty((tf.size, k))
    out_a = np.empty((tf.size, k))
    for start in range(0, tf.size, _CHUNK):
        sl = slice(start, start + _CHUNK)
        out_p[sl], out_v[sl], out_a[sl] = _pulses(t, pos, vel, acc, tf[sl])
    line = np.zeros(tf.size, dtype=np.int32)
    return Motion(t=tf, axes=tuple(axes), pos=out_p, vel=out_v, acc=out_a, line=line,
                  source=source)


def _pulses(t: np.ndarray, p: np.ndarray, v: np.ndarray, a: np.ndarray,
            tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Acceleration: the sampled one, linear between stamps, plus a pulse ``6 s (1 - s)``
    per interval carrying the velocity change the samples do not explain."""
    i = np.clip(np.searchsorted(t, tau, side='right') - 1, 0, t.size - 2)
    hh = t[i + 1] - t[i]
    h = hh[:, None]
    s = ((tau - t[i]) / hh)[:, None]
    a0, a1 = a[i], a[i + 1]
    # c: mean pulse acceleration so that the interval's velocity change is the sampled one
    c = (v[i + 1] - v[i]) / h - 0.5 * (a0 + a1)
    s2, s3 = s * s, s * s * s
    acc = a0 + (a1 - a0) * s + 6.0 * c * s * (1.0 - s)
    vel = v[i] + h * (a0 * s + 0.5 * (a1 - a0) * s2 + c * (3.0 * s2 - 2.0 * s3))

    # position: the integral of that velocity, with the interval's mismatch against the
    # sampled end position spread linearly (positions may be coarsely rounded)
    def travelled(x: np.ndarray) -> np.ndarray:
        x2, x3 = x * x, x * x * x
        return h * (v[i] * x + h * (0.5 * a0 * x2 + (a1 - a0) * x3 / 6.0
                                    + c * (x3 - 0.5 * x3 * x)))

    ones = np.ones_like(s)
    pos = p[i] + travelled(s) + s * (p[i + 1] - p[i] - travelled(ones))
    return pos, vel, acc
