"""Residual by motion state: where in the motion is the model's error?

Every measured sample is labelled by the simulated motion around its stamp (at the offset
used, on the machine's full-rate motion):

* ``standstill``: path speed below ``still_m_s`` (0.1 mm/s) at the stamp and no
  acceleration above ``accel_m_s2`` within one sampling period either side;
* ``transient``: some axis accelerates by more than ``accel_m_s2`` (0.05 m/s², the steady
  limit of ``fit-loss``) within one sampling period either side of the stamp (starts, stops,
  direction and speed changes). The acceleration is the mean over one sampling period, the
  velocity change across it divided by the period, not the instantaneous one: what a
  sample can see, and blind to the noise of a measured acceleration column (the UMich
  actual accelerations scatter by about 0.1 m/s² in steady feed while the velocity holds);
* ``steady``: moving, without such acceleration (feed moves, steady rapids).

Per state: share of samples, mean and RMS of ``dP = P_meas - P_sim`` [W], and share of the
summed ``dP^2``.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math

import numpy as np

__all__ = ['STATES', 'StateResidual', 'pool_states', 'residual_by_state', 'state_labels']

STATES = ('standstill', 'steady', 'transient')


@dataclass(frozen=True)
class StateResidual:
    """Residual of the samples in one motion state.

    Attributes
    ----------
    state
        One of :data:`STATES`.
    n_samples
        Samples in that state.
    sum_w, sum_sq_w2
        Sums of ``dP`` [W] and ``dP^2`` [W²] (pooled by adding).
    total_samples, total_sq_w2
        The same over every state (for shares).
    """

    state: str
    n_samples: int
    sum_w: float
    sum_sq_w2: float
    total_samples: int
    total_sq_w2: float

    def to_dict(self) -> dict[str, float | int | str]:
        """Plain dict; keys carry units; NaN where the state has no sample."""
        n = self.n_samples
        return {
            'state': self.state,
            'n_samples': n,
            'samples_pct': 100.0 * n / self.total_samples if self.total_samples else math.nan,
            'mean_w': self.sum_w / n if n else math.nan,
            'rms_w': math.sqrt(self.sum_sq_w2 / n) if n else math.nan,
            'squared_error_pct': (100.0 * self.sum_sq_w2 / self.total_sq_w2
                                  if self.total_sq_w2 > 0.0 else math.nan),
        }


_CHUNK = 1 << 17   # stamps labelled at once


def state_labels(t_sim: np.ndarray, vel: np.ndarray, tau: np.ndarray, *,
                 period_s: float, still_m_s: float = 1e-4,
                 accel_m_s2: float = 0.05, offset_s: float = 0.0) -> np.ndarray:
    """Index into :data:`STATES` of every sample (see the module docstring).

    Parameters
    ----------
    t_sim
        Simulated times [s], ``(m,)``, increasing.
    vel
        Simulated velocity [m/s] per axis, ``(m, k)``.
    tau
        Simulated time of each measured stamp [s], ``(n,)``, increasing.
    period_s
        Measured sampling period [s].
    still_m_s, accel_m_s2
        Thresholds.
    offset_s
        Subtracted from ``tau`` (a chunk at a time: no shifted copy of a long record).

    Returns
    -------
    numpy.ndarray
        ``(n,)`` small integers (``int8``).
    """
    vel = np.asarray(vel, dtype=float)
    m = t_sim.size
    labels = np.full(tau.shape, STATES.index('steady'), dtype=np.int8)
    for a in range(0, tau.size, _CHUNK):
        # stamps a chunk at a time, with the simulated samples they reach: the temporaries
        # stay bounded on long records (the values are those of one pass over everything)
        part = tau[a:a + _CHUNK]
        if offset_s != 0.0:
            part = part - offset_s
        lo = np.clip(np.searchsorted(t_sim, part - period_s), 0, m - 1)
        hi = np.clip(np.searchsorted(t_sim, part + period_s, side='right'), 1, m)
        hi = np.maximum(hi, lo + 1)
        first = max(0, min(int(lo[0]), int(np.searchsorted(t_sim, part[0])) - 1))
        stop = min(m, max(int(hi[-1]), int(np.searchsorted(t_sim, part[-1])) + 2))
        near = _range_max(_accel_max(t_sim, vel, first, stop, period_s), lo - first,
                          hi - first)
        speed = np.sqrt(np.sum(vel[first:stop] ** 2, axis=1))
        at = np.interp(part, t_sim[first:stop], speed)
        out = labels[a:a + _CHUNK]
        out[near > accel_m_s2] = STATES.index('transient')
        out[(at < still_m_s) & (near <= accel_m_s2)] = STATES.index('standstill')
    return labels


def _accel_max(t_sim: np.ndarray, vel: np.ndarray, first: int, stop: int,
               period_s: float) -> np.ndarray:
    """Largest |mean acceleration| of any axis over one period centred at each simulated
    sample ``first`` .. ``stop - 1`` [m/s^2]."""
    half = 0.5 * period_s
    t = t_sim[first:stop]
    amax = np.zeros(t.shape)
    for j in range(vel.shape[1]):
        dv = np.interp(t + half, t_sim, vel[:, j]) - np.interp(t - half, t_sim, vel[:, j])
        np.maximum(amax, np.abs(dv) / period_s, out=amax)
    return amax


def _range_max(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``max(values[lo[i]:hi[i]])`` for nondecreasing ``lo < hi`` (sliding windows), O(n).

    The window edges cut ``values`` into elementary pieces whose maxima are one
    ``maximum.reduceat``; a window is a run of consecutive pieces (a few: the edges inside it
    belong to its neighbours), combined piece by piece for all windows at once.
    """
    if lo.size == 0:
        return np.zeros(0)
    base, end = int(lo[0]), int(hi[-1])
    lo, hi = lo - base, hi - base
    edges = np.union1d(lo, hi)
    edges = edges[edges < end - base]
    piece = np.maximum.reduceat(values[base:end], edges)
    first = np.searchsorted(edges, lo)
    stop = np.searchsorted(edges, hi)
    out = piece[first].copy()
    for k in range(1, int(np.max(stop - first))):
        np.maximum(out, piece[np.minimum(first + k, stop - 1)], out=out)
    return out


def residual_by_state(labels: np.ndarray, residual: np.ndarray) -> tuple[StateResidual, ...]:
    """Per-state sums of the residual ``(n,)`` [W] for the labels from :func:`state_labels`."""
    r = np.asarray(residual, dtype=float)
    total_sq = float(r @ r)
    out = []
    for i, name in enumerate(STATES):
        sel = r[labels == i]
        out.append(StateResidual(name, int(sel.size), float(sel.sum()), float(sel @ sel),
                                 int(r.size), total_sq))
    return tuple(out)


def pool_states(runs: Sequence[Sequence[StateResidual]]) -> tuple[StateResidual, ...]:
    """Pool per-run state residuals (as if the runs' samples were concatenated)."""
    total_n = sum(s[0].total_samples for s in runs if s)
    total_sq = sum(s[0].total_sq_w2 for s in runs if s)
    out = []
    for i, name in enumerate(STATES):
        parts = [s[i] for s in runs if s]
        out.append(StateResidual(name, sum(p.n_samples for p in parts),
                                 sum(p.sum_w for p in parts), sum(p.sum_sq_w2 for p in parts),
                                 total_n, total_sq))
    return tuple(out)
