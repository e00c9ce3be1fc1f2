"""Offsets searched with a candidate effect in the model: records of the power alone.

A run recorded without motion columns is aligned on its power, against the declared model.
A large effect the model lacks pulls that lag: a missing inertia puts power into every
acceleration and takes it out of every deceleration, so each stroke's power looks earlier
(on the demonstrator's strokes with an inertia worth a sixth of the energy, by 30-80 ms,
more at higher feeds). At the pulled lag the residual is mostly the timing error; the
candidate's columns, fitted there, take a fraction of the effect, and the selection finds
nothing that carries over to unseen runs. :mod:`.pinning` re-estimates offsets only with
effects *found*, so nothing moves.

:func:`joint_screen` asks, for each candidate, which offset each run would have *with some
amount of that effect in the model*: every run's offset is searched near today's (within
:data:`JOINT_REACH_S`), each lag scored by the residual sum of squares left after the
run's mean and the candidate's columns, fitted on that run alone (free per run: the screen
asks whether a lag fits with an amount of the effect; the selection afterwards fits one
amount for all runs and scores it on unseen runs). A coarse grid of :data:`JOINT_STEP_S` is
refined by the parabola through the best lag and its neighbours, then scored exactly. The
candidates are those with at most :data:`MAX_SCREEN_COLUMNS` linear parameters (a free
per-run fit of many columns, a position-friction's bumps, fits any timing error) and every
shape of their grid.

Cost: the measured stamps are thinned to at most :data:`MAX_SCREEN_SAMPLES` per run (evenly
over the record: every stroke is seen; the instrument's average at each kept stamp is exact)
and every lag averages all candidates' columns at once (:class:`.measured.ShiftedAverage`,
one running integral per run), so a run costs O(lags x samples x columns), independent of
the record's length beyond its simulation.

The screen only proposes a start: ``analyze`` runs its rounds from the best candidate's
offsets (:func:`.analyze.analyze_campaign`) and keeps that analysis only when the data's
model is better by BIC, the offsets counted as estimated.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
import math

import numpy as np

from ...measured import ShiftedAverage

__all__ = ['JOINT_REACH_S', 'JOINT_STEP_S', 'JointFit', 'MAX_SCREEN_COLUMNS',
           'MAX_SCREEN_SAMPLES', 'MAX_SCREEN_SPAN_S', 'ScreenCandidate', 'ScreenRun',
           'joint_screen', 'screen_span']

JOINT_REACH_S = 0.15
"""Farthest a run's offset is searched from today's, either way [s]."""
JOINT_STEP_S = 0.005
"""Step of the coarse lag grid [s] (refined by a parabola through the best three)."""
MAX_SCREEN_COLUMNS = 2
"""Candidates with more linear parameters are not screened."""
MAX_SCREEN_SAMPLES = 8000
"""Measured stamps per run the screen scores (thinned evenly over its span)."""
MAX_SCREEN_SPAN_S = 120.0
"""Longest stretch of a record the screen scores [s], from its start: the offset is one
for the record, and two minutes of a program hold many of its moves."""


@dataclass(frozen=True)
class ScreenRun:
    """One run as the screen sees it.

    Attributes
    ----------
    name
        Run name.
    t, y
        Measured stamps [s] and summed measured power [W], ``(n,)``.
    t_sim, y_sim
        Simulation times [s] and the declared model's summed power [W], ``(m,)``, already
        through the meter's first-order filter if it has one (only the span
        :func:`screen_span` names is needed).
    offset_s
        Today's offset [s] (the module's sign convention: :mod:`.measured.align`).
    window_s, stamp
        The instrument's window [s] and where it stamps it.
    """

    name: str
    t: np.ndarray
    y: np.ndarray
    t_sim: np.ndarray
    y_sim: np.ndarray
    offset_s: float
    window_s: float
    stamp: str


@dataclass(frozen=True)
class ScreenCandidate:
    """A candidate effect: ``key`` ``(effect id, axis)`` and its ``shape`` parameters."""

    key: tuple[str, str]
    shape: Mapping[str, float]


@dataclass(frozen=True)
class JointFit:
    """What one candidate does to the runs' offsets.

    Attributes
    ----------
    key, shape
        The candidate.
    offsets_s
        Per run, the offset with the candidate in the model [s] (today's where its best lag
        lies at the end of the searched range: not found within it).
    moves_s
        Per run, that offset minus today's [s].
    sse_today, sse_joint
        Residual sum of squares over the thinned stamps of all runs [W²], the candidate fitted
        per run, at today's offsets and at ``offsets_s``.
    """

    key: tuple[str, str]
    shape: Mapping[str, float]
    offsets_s: tuple[float, ...]
    moves_s: tuple[float, ...]
    sse_today: float
    sse_joint: float

    @property
    def gain(self) -> float:
        """Relative drop of the residual sum of squares from moving the offsets."""
        if not self.sse_today > 0.0:
            return 0.0
        return (self.sse_today - self.sse_joint) / self.sse_today

    @property
    def median_move_s(self) -> float:
        """Median absolute move [s]."""
        return float(np.median(np.abs(self.moves_s))) if self.moves_s else 0.0

    @property
    def largest_move_s(self) -> float:
        """Largest absolute move [s]."""
        return float(np.max(np.abs(self.moves_s))) if self.moves_s else 0.0


def _sse(e: np.ndarray, x: np.ndarray) -> float:
    """Residual sum of squares of ``e`` after its mean and the columns ``x`` (least squares,
    ill-conditioned directions dropped)."""
    ec = e - e.mean()
    total = float(ec @ ec)
    if x.shape[1] == 0:
        return total
    xc = x - x.mean(axis=0)
    g = xc.T @ xc
    b = xc.T @ ec
    theta, *_ = np.linalg.lstsq(g, b, rcond=1e-10)
    return max(total - float(b @ theta), 0.0)


def _vertex(s: np.ndarray, k: int) -> float:
    """Where the parabola through ``s[k-1], s[k], s[k+1]`` has its minimum, relative to
    ``k`` in steps (within ±1; 0 when flat or not convex)."""
    a, b, c = float(s[k - 1]), float(s[k]), float(s[k + 1])
    den = a - 2.0 * b + c
    if not den > 0.0:
        return 0.0
    return float(np.clip(0.5 * (a - c) / den, -1.0, 1.0))


def screen_span(t: np.ndarray, offset_s: float, window_s: float, *,
                reach_s: float = JOINT_REACH_S) -> tuple[int, float, float]:
    """What the screen reads of a record: the number of its first stamps it scores (at most
    :data:`MAX_SCREEN_SPAN_S` of them) and the simulated times ``(lo, hi)`` [s] those stamps
    can see within the searched lags (a crop of the simulation to that span aligns the same).
    """
    n = int(np.searchsorted(t, t[0] + MAX_SCREEN_SPAN_S, side='right'))
    n = max(min(n, t.size), 1)
    lo = float(t[0]) - offset_s - reach_s - 2.0 * window_s
    hi = float(t[n - 1]) - offset_s + reach_s + 2.0 * window_s
    return n, lo, hi


def joint_screen(items: Iterable[tuple[ScreenRun, Sequence[np.ndarray]]],
                 candidates: Sequence[ScreenCandidate], *, reach_s: float = JOINT_REACH_S,
                 step_s: float = JOINT_STEP_S,
                 max_samples: int = MAX_SCREEN_SAMPLES) -> list[JointFit]:
    """Every candidate's offsets of the runs with the candidate in the model, best fit first.

    Parameters
    ----------
    items
        Per run, the run and every candidate's basis on its simulation times (``(m, p)``,
        ``p <= MAX_SCREEN_COLUMNS``, in the order of ``candidates``, through the meter's
        filter if any); consumed one run at a time (a generator holds one run's bases).
    candidates
        The candidates.
    reach_s, step_s
        Search range either side of today's offset and coarse step [s].
    max_samples
        Measured stamps scored per run.

    Returns
    -------
    list of JointFit
        One per candidate, sorted by ``sse_joint`` (the best joint fit first).
    """
    steps = max(int(math.ceil(reach_s / step_s - 1e-9)), 1)
    grid = np.arange(-steps, steps + 1) * step_s
    ncand = len(candidates)
    offsets: list[list[float]] = [[] for _ in candidates]
    today = np.zeros(ncand)
    joint = np.zeros(ncand)
    today_offsets: list[float] = []
    for run, bases in items:
        n = run.t.size
        keep = (np.unique(np.linspace(0, n - 1, max_samples).round().astype(np.intp))
                if n > max_samples else np.arange(n))
        t, y = run.t[keep], run.y[keep]
        cols = [run.y_sim[:, None]] + [np.asarray(b, dtype=float) for b in bases]
        bounds = np.cumsum([0] + [c.shape[1] for c in cols])
        series = ShiftedAverage(run.t_sim, np.hstack(cols), window_s=run.window_s,
                                stamp=run.stamp)
        del cols

        def scores(lag: float, which: Sequence[int]) -> list[float]:
            m = series.at(t, lag)
            e = y - m[:, 0]
            return [_sse(e, m[:, bounds[i + 1]:bounds[i + 2]]) for i in which]

        every = range(ncand)
        table = np.array([scores(run.offset_s + d, every) for d in grid]).reshape(
            grid.size, ncand)
        today_offsets.append(run.offset_s)
        for i in every:
            col = table[:, i]
            today[i] += col[steps]
            k = int(np.argmin(col))
            if k in (0, grid.size - 1):
                # the best lag is at the end of the range: no offset found within it
                offsets[i].append(run.offset_s)
                joint[i] += col[steps]
                continue
            lag = run.offset_s + (k + _vertex(col, k) - steps) * step_s
            exact = scores(lag, [i])[0]
            if exact > col[k]:
                lag, exact = run.offset_s + float(grid[k]), float(col[k])
            offsets[i].append(lag)
            joint[i] += exact
    fits = [JointFit(c.key, dict(c.shape), tuple(offsets[i]),
                     tuple(o - t0 for o, t0 in zip(offsets[i], today_offsets)),
                     float(today[i]), float(joint[i]))
            for i, c in enumerate(candidates)]
    return sorted(fits, key=lambda f: f.sse_joint)
