"""Comparison metrics of measured and simulated power: the rows of the paper's Table 1, plus more.

Definitions (``dP = P_meas - P_sim`` on the measured stamps, after alignment):

- average differential error [W] = mean ``|dP|``; maximum differential error [W] = max ``|dP|``;
- percentual error [%] = ``100 |dP| / |P_meas|``, evaluated **only where**
  ``|P_meas| >= floor_fraction * max |P_meas|`` (5 % of the run's peak by default), so that
  standstill samples with near-zero measured power do not divide by ~0. The paper does not
  define its percentual error; this is our choice. Average and maximum are taken over those
  samples only (``n_pct_samples`` says how many);
- RMSE [W] = ``sqrt(mean(dP^2))``;
- energies [J] = trapezoidal integrals of the (signed) powers over ``t``, i.e. the cumulative
  energies at the end of the run; energy error = ``E_sim - E_meas`` [J] and
  ``100 (E_sim - E_meas) / |E_meas|`` [%].

:func:`group_metrics` pools runs (e.g. all runs at one load) as if their samples were
concatenated: means are weighted by sample counts, maxima are maxima, RMSE is pooled from
squared errors, energies are summed. Each run keeps its own percentual-error floor.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
import math
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..errors import DataError

__all__ = ['CHUNK', 'Metrics', 'group_metrics', 'table1_metrics']

CHUNK = 1 << 18
"""Samples a metric evaluates at once: a long run's temporaries are this size, not the run's."""


@dataclass(frozen=True)
class Metrics:
    """Agreement of simulated with measured power over one run (or a pooled group).

    Attributes
    ----------
    n_samples
        Samples compared.
    n_pct_samples
        Samples above the floor, over which percentual errors are taken.
    duration_s
        Time covered [s] (sum over runs for a group).
    avg_diff_error_w, max_diff_error_w
        Mean and maximum ``|P_meas - P_sim|`` [W].
    avg_pct_error_pct, max_pct_error_pct
        Mean and maximum ``100 |dP| / |P_meas|`` above the floor [%] (NaN if no sample is).
    rmse_w
        Root-mean-square of ``dP`` [W].
    energy_meas_j, energy_sim_j
        Energies at the end of the run [J].
    energy_error_j, energy_error_pct
        ``E_sim - E_meas`` [J] and relative to ``|E_meas|`` [%] (NaN if ``E_meas`` is 0).
    pct_floor_w
        The floor ``floor_fraction * max |P_meas|`` [W] (NaN for a group).
    """

    n_samples: int
    n_pct_samples: int
    duration_s: float
    avg_diff_error_w: float
    max_diff_error_w: float
    avg_pct_error_pct: float
    max_pct_error_pct: float
    rmse_w: float
    energy_meas_j: float
    energy_sim_j: float
    energy_error_j: float
    energy_error_pct: float
    pct_floor_w: float

    def to_dict(self) -> dict[str, float | int]:
        """Plain dict; every key carries its unit (``_w``, ``_pct``, ``_j``, ``_s``)."""
        return asdict(self)


def _energy_pct(e_meas: float, e_sim: float) -> float:
    return 100.0 * (e_sim - e_meas) / abs(e_meas) if e_meas != 0.0 else math.nan


def table1_metrics(t: ArrayLike, p_meas: ArrayLike, p_sim: ArrayLike, *,
                   floor_fraction: float = 0.05, file: str = '<arrays>',
                   rows: ArrayLike | None = None,
                   columns: tuple[str, str, str] = ('t', 'p_meas', 'p_sim')) -> Metrics:
    """Table-1 metrics of one run, from aligned measured and simulated power.

    Parameters
    ----------
    t
        Measured stamps [s], strictly increasing, shape ``(n,)``.
    p_meas, p_sim
        Measured and simulated power on those stamps [W], shape ``(n,)``.
    floor_fraction
        Percentual errors are taken where ``|P_meas| >= floor_fraction * max |P_meas|``.
    file, rows, columns
        Name the data in errors: the run's file, the 1-based file data row of every sample
        (default: sample numbers) and the names of ``t``, ``p_meas`` and ``p_sim``.

    Returns
    -------
    Metrics
        See the module docstring for the definitions.

    Raises
    ------
    DataError
        On mismatched shapes, non-finite values, fewer than 2 samples or non-increasing time.
    """
    t = np.asarray(t, dtype=np.float64)
    pm = np.asarray(p_meas, dtype=np.float64)
    ps = np.asarray(p_sim, dtype=np.float64)
    given = None if rows is None else np.asarray(rows).reshape(-1)

    def row_of(i: int) -> int:
        # the file's data row of sample i (1-based sample numbers when rows do not fit)
        return int(given[i]) if given is not None and given.shape == t.shape else i + 1
    for name, arr in zip(columns, (t, pm, ps)):
        if arr.ndim != 1 or arr.shape != t.shape or arr.size < 2:
            msg = f'expected shape ({t.size},) with at least 2 samples, got {arr.shape}'
            raise DataError(msg, file=file, column=name)
    if not (0.0 < floor_fraction < 1.0):
        msg = f'floor_fraction must lie in (0, 1), got {floor_fraction!r}'
        raise DataError(msg, file=file, column='floor_fraction')
    n = t.size
    # two passes of bounded chunks: a long run's temporaries are a chunk, not the run
    peak = 0.0
    for a in range(0, n, CHUNK):
        for name, arr in zip(columns, (t, pm, ps)):
            bad = np.flatnonzero(~np.isfinite(arr[a:a + CHUNK]))
            if bad.size:
                raise DataError('not a finite number', file=file, column=name,
                                row=row_of(a + int(bad[0])))
        # a chunk's steps and the one into it from the chunk before
        bad = np.flatnonzero(np.diff(t[max(a - 1, 0):a + CHUNK]) <= 0.0)
        if bad.size:
            raise DataError('time must increase strictly', file=file, column=columns[0],
                            row=row_of(max(a - 1, 0) + int(bad[0]) + 1))
        peak = max(peak, float(np.max(np.abs(pm[a:a + CHUNK]))))
    floor = floor_fraction * peak
    n_pct = 0
    err_sum = err_max = err_sq = pct_sum = 0.0
    pct_max = -math.inf
    e_meas = e_sim = 0.0
    for a in range(0, n, CHUNK):
        err = pm[a:a + CHUNK] - ps[a:a + CHUNK]
        np.abs(err, out=err)
        err_sum += float(err.sum())
        err_max = max(err_max, float(err.max()))
        err_sq += float(err @ err)
        size = np.abs(pm[a:a + CHUNK])
        above = (size >= floor) & (size > 0.0)
        pct = err[above]
        pct /= size[above]
        pct *= 100.0
        if pct.size:
            n_pct += int(pct.size)
            pct_sum += float(pct.sum())
            pct_max = max(pct_max, float(pct.max()))
        # the trapezoids up to the next chunk's first sample
        part = slice(a, min(a + CHUNK + 1, n))
        e_meas += float(np.trapezoid(pm[part], t[part]))
        e_sim += float(np.trapezoid(ps[part], t[part]))
    return Metrics(
        n_samples=int(n),
        n_pct_samples=n_pct,
        duration_s=float(t[-1] - t[0]),
        avg_diff_error_w=err_sum / n,
        max_diff_error_w=err_max,
        avg_pct_error_pct=pct_sum / n_pct if n_pct else math.nan,
        max_pct_error_pct=pct_max if n_pct else math.nan,
        rmse_w=math.sqrt(err_sq / n),
        energy_meas_j=e_meas,
        energy_sim_j=e_sim,
        energy_error_j=e_sim - e_meas,
        energy_error_pct=_energy_pct(e_meas, e_sim),
        pct_floor_w=floor,
    )


def group_metrics(runs: Sequence[Metrics]) -> Metrics:
    """Pool the metrics of several runs (e.g. one load) as if their samples were concatenated.

    Parameters
    ----------
    runs
        Per-run metrics from :func:`table1_metrics`.

    Returns
    -------
    Metrics
        Sample-weighted means, maxima, pooled RMSE and summed energies; ``pct_floor_w`` is
        NaN because every run keeps its own floor.

    Raises
    ------
    DataError
        If ``runs`` is empty.
    """
    if not runs:
        raise DataError('no runs to pool', file='<metrics>')
    n = sum(m.n_samples for m in runs)
    n_pct = sum(m.n_pct_samples for m in runs)
    with_pct = [m for m in runs if m.n_pct_samples]
    e_meas = sum(m.energy_meas_j for m in runs)
    e_sim = sum(m.energy_sim_j for m in runs)
    return Metrics(
        n_samples=n,
        n_pct_samples=n_pct,
        duration_s=sum(m.duration_s for m in runs),
        avg_diff_error_w=sum(m.n_samples * m.avg_diff_error_w for m in runs) / n,
        max_diff_error_w=max(m.max_diff_error_w for m in runs),
        avg_pct_error_pct=(sum(m.n_pct_samples * m.avg_pct_error_pct for m in with_pct) / n_pct
                           if n_pct else math.nan),
        max_pct_error_pct=max(m.max_pct_error_pct for m in with_pct) if with_pct else math.nan,
        rmse_w=math.sqrt(sum(m.n_samples * m.rmse_w ** 2 for m in runs) / n),
        energy_meas_j=e_meas,
        energy_sim_j=e_sim,
        energy_error_j=e_sim - e_meas,
        energy_error_pct=_energy_pct(e_meas, e_sim),
        pct_floor_w=math.nan,
    )
