"""A meter that smooths: its first-order filter, estimated with the effects in the model.

A power meter that averages over a window may also smooth (a first-order lag of time constant
``tau``). Read as a pure delay, such a lag leaves the rounded edges of every move to the
effects (an inertia, a friction term); ``analyze`` also tries it as a filter
(:func:`may_filter`), estimates the time constant anew after each round with the effects in
the model (:func:`filter_step`, one Gauss-Newton step) and extrapolates steps that converge
by turns (:func:`filter_next`). :func:`with_filter` reads a campaign through such meters.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import replace

import numpy as np

from ...measured import Campaign, first_order_lag, RunComparison
from .pinning import lag_tolerance_s

__all__ = ['MIN_FILTER_PERIODS', 'FILTER_TOLERANCE', 'FILTER_EXTRA_ROUNDS', 'FILTER_MAX_RATIO',
           'may_filter', 'filter_step', 'filter_next', 'with_filter', 'runs_differ']

MIN_FILTER_PERIODS = 0.05
"""A common lag behind the motion of at least this many sampling periods is also tried as a
meter's first-order smoothing."""
FILTER_TOLERANCE = 0.1
"""A meter filter's time constant is estimated anew after a round when its step
(:func:`filter_step`) exceeds this share of a run's offset tolerance
(:func:`.pinning.lag_tolerance_s`: a thousandth of a sampling period): a filter a few
microseconds off leaves the derivative of the found effects' power, the shape of a moved
mass on a large speed-dependent loss."""
FILTER_EXTRA_ROUNDS = 2
"""Rounds a start with a meter filter may take beyond :data:`.pinning.MAX_PIN_ROUNDS` while
the filter still moves: the filter and the effects fitted with it converge by turns (each
round's step leaves some fifth of the filter's error, with alternating sign)."""
FILTER_MAX_RATIO = 0.5
"""Largest ratio of two successive filter steps (:func:`filter_next`) that is taken as the
rate of that convergence and extrapolated; above it (or of a step that was itself
extrapolated) the plain step is taken."""


def may_filter(campaign: Campaign, runs: Sequence[RunComparison], lag: float) -> bool:
    """Whether the power's common lag behind the measured motion may be a meter's
    first-order smoothing: no run declares a filter, the lag is positive (a filter only
    delays) and at least :data:`MIN_FILTER_PERIODS` of a sampling period (a shorter one
    hardly changes what a window of one period reads)."""
    if any(campaign.run(r.name).instrument.filter_s for r in runs):
        return False
    periods = [float(np.median(np.diff(r.t))) for r in runs
               if r.offset.anchor == 'motion' and r.t.size > 1]
    return bool(periods) and lag >= MIN_FILTER_PERIODS * float(np.median(periods))


def filter_step(runs: Iterable[RunComparison], filter_s: float) -> float | None:
    """The change of a meter filter's time constant [s] that the comparisons' residuals ask
    for: one Gauss-Newton step, least squares over the motion-anchored runs (each run's mean
    free) on the derivative of what the meter reads with respect to the time constant.

    The meter reads ``A[F_tau P]`` (window ``A``, first-order filter ``F_tau``); since
    ``dF_tau/dtau = -s·F_tau²``, that derivative is ``-d/dt F_tau[A F_tau P]``: the aligned
    simulated trace through the filter once more, differentiated on the stamps. ``None``
    without a motion-anchored run of three stamps or with a flat trace."""
    num = den = 0.0
    for r in runs:
        if r.offset.anchor != 'motion' or r.t.size < 3:
            continue
        y = r.total_sim_w
        basis = -np.gradient(first_order_lag(r.t, y, filter_s), r.t)
        res = r.total_meas_w - y
        basis = basis - basis.mean()
        res = res - res.mean()
        num += float(basis @ res)
        den += float(basis @ basis)
    return num / den if den > 0.0 else None


def filter_next(delta: float, last: float | None) -> tuple[float, float | None]:
    """The filter's change [s] from this round's step ``delta`` and the previous plain step
    ``last``, and the plain step to remember.

    Two plain steps whose ratio ``rho`` lies within (-1, :data:`FILTER_MAX_RATIO`] are taken
    as a linear convergence (each round leaves ``rho`` of the error): the limit is
    ``delta / (1 - rho)`` away (Aitken's extrapolation). An extrapolated step is not a
    plain one: the next step is taken as it is, and the one after may be extrapolated
    again."""
    if last is not None and last != 0.0:
        rho = delta / last
        if -1.0 < rho <= FILTER_MAX_RATIO:
            return delta / (1.0 - rho), None
    return delta, delta


def with_filter(campaign: Campaign, filter_s: float) -> Campaign:
    """The campaign read through meters that smooth with a first-order ``filter_s`` [s]."""
    return replace(campaign, runs=tuple(
        replace(spec, instrument=replace(spec.instrument, filter_s=float(filter_s)))
        for spec in campaign.runs))


def runs_differ(runs: Sequence[RunComparison], lag: float) -> bool:
    """Whether a motion-anchored run's offset at ``lag`` differs from its motion's offset."""
    return any(r.offset.anchor == 'motion' and abs(lag) > lag_tolerance_s(r) for r in runs)
