"""One-dimensional velocity profiles along a path parameter ``s`` (metres).

A move of length ``L`` starts at speed ``v0`` and ends at ``v1`` with zero acceleration at both
ends; its speed never exceeds ``vmax``, its acceleration ``amax`` and (for the jerk profile) its
jerk ``jmax``. Every profile is expressed as seven consecutive phases of constant jerk::

    0: jerk +J   1: constant acceleration   2: jerk -J   3: cruise
    4: jerk -J   5: constant deceleration   6: jerk +J

Each phase is described by its duration, the acceleration at its start and its jerk, so the
trapezoid profile (``jmax = inf``) is the same seven phases with the jerk phases of zero
duration and the constant-acceleration phases starting at ``+amax`` / ``-amax``.

Speed change ``dv`` with zero acceleration at both ends (closed form)::

    ap = min(amax, sqrt(dv * jmax))          peak acceleration
    T  = dv / ap + ap / jmax                 duration (dv / amax for the trapezoid)
    D  = (v_a + v_b) / 2 * T                 distance (the ramp is point-symmetric)

When a move is too short to reach ``vmax`` the peak speed is found by bisection (vectorised
over all moves) on the monotone distance ``D(v0 -> vp) + D(vp -> v1) = L``, keeping the
feasible lower bound so the remaining length becomes a (tiny) cruise and the end is exact.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

__all__ = ['ProfilePhases', 'ramp', 'min_distance', 'reach_speed', 'plan_profiles']

_BISECT_ITERATIONS = 60


@dataclass(frozen=True)
class ProfilePhases:
    """Seven constant-jerk phases per move.

    Attributes
    ----------
    duration, a_start, jerk
        Shape ``(m, 7)``: phase durations [s], acceleration at the phase start [m/s^2] and
        constant jerk inside the phase [m/s^3].
    v_peak
        Shape ``(m,)``: the highest speed of each move [m/s].
    """

    duration: np.ndarray
    a_start: np.ndarray
    jerk: np.ndarray
    v_peak: np.ndarray

    @property
    def move_duration(self) -> np.ndarray:
        """Duration of each move [s], shape ``(m,)``."""
        return self.duration.sum(axis=1)


def ramp(dv: np.ndarray, amax: np.ndarray,
         jmax: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Shape of a speed change ``dv >= 0`` starting and ending at zero acceleration.

    Parameters
    ----------
    dv
        Speed change magnitude [m/s] (>= 0).
    amax, jmax
        Acceleration [m/s^2] and jerk [m/s^3] limits; ``jmax = inf`` gives the trapezoid ramp.

    Returns
    -------
    ap, t_jerk, t_const, t_total
        Peak acceleration, duration of each jerk phase, duration of the constant-acceleration
        phase and total duration ``2 * t_jerk + t_const``.
    """
    dv = np.maximum(np.asarray(dv, dtype=float), 0.0)
    amax = np.broadcast_to(np.asarray(amax, dtype=float), dv.shape)
    jmax = np.broadcast_to(np.asarray(jmax, dtype=float), dv.shape)
    with np.errstate(invalid='ignore', divide='ignore'):
        ap = np.where(dv > 0.0, np.minimum(amax, np.sqrt(dv * jmax)), 0.0)
        t_jerk = np.where(np.isfinite(jmax) & (dv > 0.0), ap / jmax, 0.0)
        t_const = np.where(dv > 0.0, np.maximum(dv / np.where(ap > 0, ap, 1.0) - t_jerk, 0.0),
                           0.0)
    return ap, t_jerk, t_const, 2.0 * t_jerk + t_const


def min_distance(v_a: np.ndarray, v_b: np.ndarray, amax: np.ndarray,
                 jmax: np.ndarray) -> np.ndarray:
    """Shortest distance [m] to change speed from ``v_a`` to ``v_b`` (zero end accelerations).

    Parameters
    ----------
    v_a, v_b
        Speeds at the two ends [m/s].
    amax, jmax
        Limits; ``jmax = inf`` for constant-acceleration ramps.

    Returns
    -------
    numpy.ndarray
        ``(v_a + v_b) / 2 * T`` with ``T`` the ramp duration.
    """
    v_a = np.asarray(v_a, dtype=float)
    v_b = np.asarray(v_b, dtype=float)
    _, _, _, t_total = ramp(np.abs(v_b - v_a), amax, jmax)
    return 0.5 * (v_a + v_b) * t_total


def reach_speed(v_end: float, length: float, amax: float, jmax: float) -> float:
    """Highest speed at one end of a move from which ``v_end`` is reachable within ``length``.

    Inverse of :func:`min_distance` in closed form (scalar, used by the look-ahead passes).

    Parameters
    ----------
    v_end
        Speed at the other end [m/s].
    length
        Distance available [m].
    amax, jmax
        Limits; ``jmax = inf`` for the trapezoid (``sqrt(v_end**2 + 2 * amax * length)``).

    Returns
    -------
    float
        The speed [m/s], ``>= v_end``.
    """
    if length <= 0.0:
        return v_end
    if not math.isfinite(jmax):
        return math.sqrt(v_end * v_end + 2.0 * amax * length)
    dv_star = amax * amax / jmax
    d_star = (2.0 * v_end + dv_star) * amax / jmax
    if length >= d_star:
        # (v_end + x / 2) (x / amax + amax / jmax) = length, solved for x = dv >= dv_star
        qa = 0.5 / amax
        qb = v_end / amax + 0.5 * amax / jmax
        qc = v_end * amax / jmax - length
        x = -2.0 * qc / (qb + math.sqrt(qb * qb - 4.0 * qa * qc))
        return v_end + x
    # (2 v_end + y^2) y / sqrt(jmax) = length with y = sqrt(dv): y^3 + p y + q = 0
    p = 2.0 * v_end
    q = -length * math.sqrt(jmax)
    if p <= 1e-300:
        y = (-q) ** (1.0 / 3.0)
    else:
        # hyperbolic form of the single real root; no cancellation for large p
        y = 2.0 * math.sqrt(p / 3.0) * math.sinh(
            math.asinh(-1.5 * q / p * math.sqrt(3.0 / p)) / 3.0)
    return v_end + y * y


def _path_distance(v0: np.ndarray, vp: np.ndarray, v1: np.ndarray, amax: np.ndarray,
                   jmax: np.ndarray) -> np.ndarray:
    return min_distance(v0, vp, amax, jmax) + min_distance(vp, v1, amax, jmax)


def _bisect_peak(v0: np.ndarray, v1: np.ndarray, amax: np.ndarray, jmax: np.ndarray,
                 length: np.ndarray, a_lo: np.ndarray, a_hi: np.ndarray) -> np.ndarray:
    """Highest peak speed in ``[a_lo, a_hi]`` with ``D(v0 -> vp) + D(vp -> v1) <= length``.

    Bisection, :data:`_BISECT_ITERATIONS` steps, the same arithmetic as :func:`min_distance`
    element by element (so the same bits), with both ramps of a move evaluated as one
    ``(2, n)`` array, and stopped early once a step changes nothing (then no later step
    would: every step depends only on the bracket).
    """
    n = v0.shape[0]
    a2 = np.broadcast_to(amax, (2, n))
    j2 = np.broadcast_to(jmax, (2, n))
    finite = np.isfinite(j2)
    dv = np.empty((2, n))
    both = np.empty((2, n))
    for _ in range(_BISECT_ITERATIONS):
        mid = 0.5 * (a_lo + a_hi)
        np.subtract(mid, v0, out=dv[0])
        np.subtract(v1, mid, out=dv[1])
        np.abs(dv, out=dv)
        np.add(v0, mid, out=both[0])
        np.add(mid, v1, out=both[1])
        with np.errstate(invalid='ignore', divide='ignore'):
            moving = dv > 0.0
            ap = np.where(moving, np.minimum(a2, np.sqrt(dv * j2)), 0.0)
            t_jerk = np.where(finite & moving, ap / j2, 0.0)
            t_const = np.where(moving, np.maximum(dv / np.where(ap > 0, ap, 1.0) - t_jerk, 0.0),
                               0.0)
        dist = 0.5 * both * (2.0 * t_jerk + t_const)
        ok = dist[0] + dist[1] <= length
        new_lo = np.where(ok, mid, a_lo)
        new_hi = np.where(ok, a_hi, mid)
        if np.array_equal(new_lo, a_lo) and np.array_equal(new_hi, a_hi):
            break
        a_lo, a_hi = new_lo, new_hi
    return a_lo


def plan_profiles(length: np.ndarray, v0: np.ndarray, v1: np.ndarray, vmax: np.ndarray,
                  amax: np.ndarray, jmax: np.ndarray) -> ProfilePhases:
    """Seven-phase profiles for many moves at once.

    Parameters
    ----------
    length
        Move lengths [m], shape ``(m,)``.
    v0, v1
        Entry and exit speeds [m/s]; must be mutually reachable within ``length`` (the
        look-ahead guarantees it; a tiny excess is absorbed by a ramp at the reachable speed).
    vmax
        Speed limits [m/s] (>= ``v0``, ``v1``).
    amax, jmax
        Acceleration and jerk limits; ``jmax = inf`` gives trapezoid profiles.

    Returns
    -------
    ProfilePhases
        The phases of every move.
    """
    length = np.asarray(length, dtype=float)
    v0 = np.asarray(v0, dtype=float)
    v1 = np.asarray(v1, dtype=float)
    amax = np.broadcast_to(np.asarray(amax, dtype=float), length.shape)
    jmax = np.broadcast_to(np.asarray(jmax, dtype=float), length.shape)
    vmax = np.maximum(np.asarray(vmax, dtype=float), np.maximum(v0, v1))

    lo = np.maximum(v0, v1)
    vp = vmax.copy()
    short = _path_distance(v0, vmax, v1, amax, jmax) > length
    if np.any(short):
        idx = np.nonzero(short)[0]
        a_lo = lo[idx]
        a_hi = vmax[idx]
        vp[idx] = _bisect_peak(v0[idx], v1[idx], amax[idx], jmax[idx], length[idx], a_lo,
                               a_hi)

    ap_a, tj_a, tc_a, _ = ramp(vp - v0, amax, jmax)
    ap_d, tj_d, tc_d, _ = ramp(vp - v1, amax, jmax)
    rest = length - _path_distance(v0, vp, v1, amax, jmax)
    with np.errstate(divide='ignore', invalid='ignore'):
        t_cruise = np.where(vp > 0.0, np.maximum(rest, 0.0) / np.where(vp > 0, vp, 1.0), 0.0)

    m = length.shape[0]
    duration = np.stack([tj_a, tc_a, tj_a, t_cruise, tj_d, tc_d, tj_d], axis=1)
    jf = np.where(np.isfinite(jmax), jmax, 0.0)
    zero = np.zeros(m)
    jerk = np.stack([jf, zero, -jf, zero, -jf, zero, jf], axis=1)
    # trapezoid: the constant phases start at the full acceleration (jerk phases last 0 s)
    a_start = np.stack([zero, ap_a, ap_a, zero, zero, -ap_d, -ap_d], axis=1)
    jerk = np.where(duration > 0.0, jerk, 0.0)
    return ProfilePhases(duration=duration, a_start=a_start, jerk=jerk, v_peak=vp)
