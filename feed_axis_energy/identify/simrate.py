"""The rate the analysis simulates at: finer than the planner's where the data resolve its
sampling.

A simulation sampled at the planner's ``rate_hz`` and read through the meter's windows differs
from the continuous motion by a sampling error (each comparison's ``step_error``). On precise
data (a drive trace at 1 kHz, a smooth controller output) that error can be larger than the
noise, and a candidate effect would then be fitted to the simulation's own numerics.
:func:`sim_rate` says by which power of two ``analyze`` raises the rate so that it cannot;
:func:`rate_with_effects` asks it again with the effects an analysis found in the model (their
own power may need a finer rate, and without the missing effect in the residual the noise
level is the meter's own).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
import math

from ..machine import Machine
from ..measured import Campaign, compare_campaign, MeasuredRun, RunComparison
from .diagnostics import noise_level
from .results import AnalysisResult
from .timing import with_filter

__all__ = ['at_rate', 'MAX_OVERSAMPLING', 'MAX_SIM_SAMPLES', 'rate_with_effects',
           'sampling_left', 'sim_rate', 'STEP_MAX_CHI2']

STEP_MAX_CHI2 = 4.0
"""The most the simulation's sampling may put into the campaign's residual, as a sum of
squares over the noise variance (:func:`sim_rate`): below the one-parameter tests' limits,
so that no candidate can be fitted to the simulation's own numerics."""
MAX_OVERSAMPLING = 8
"""Largest factor by which the analysis raises the planner's ``rate_hz``."""
MAX_SIM_SAMPLES = 1_000_000
"""Largest number of simulated samples per run the raised rate may give (memory and time
stay those of a drive trace at the planner's rate)."""


def sim_rate(runs: Sequence[RunComparison], machine: Machine) -> tuple[int, float]:
    """The factor by which the analysis raises the planner's rate, and the residual sum of
    squares over the noise variance that the declared rate's sampling gives.

    Each run's comparison estimates what the sampling puts into the meter's readings
    (``step_error``, falling with the square of the step); against each axis's white noise
    (:func:`.diagnostics.noise_level` of its baseline residual) it adds
    ``n·(step_error/sigma)²``. The factor is the smallest power of two that brings the sum
    to :data:`STEP_MAX_CHI2` (the sum falls with its fourth power), at most
    :data:`MAX_OVERSAMPLING` and :data:`MAX_SIM_SAMPLES` per run.
    """
    chi2 = 0.0
    for r in runs:
        meas = r.power_meas_w if r.signal_meas is None else r.signal_meas
        sim = r.power_sim_w if r.signal_sim is None else r.signal_sim
        for j, axis in enumerate(r.axes):
            err = float(r.step_error.get(axis, 0.0))
            if not (err > 0.0 and math.isfinite(err)):
                continue
            sigma = noise_level([meas[:, j] - sim[:, j]]).white_w
            if not math.isfinite(sigma):
                continue
            chi2 += meas.shape[0] * (err / max(sigma, 1e-12 * err)) ** 2
    rate = machine.planner.rate_hz
    longest = max((r.sim_duration_s for r in runs), default=0.0)
    factor = 1
    while (sampling_left(chi2, factor) and 2 * factor <= MAX_OVERSAMPLING
           and 2 * factor * rate * longest <= MAX_SIM_SAMPLES):
        factor *= 2
    return factor, chi2


def sampling_left(chi2: float, factor: int) -> float:
    """What a sampling that puts ``chi2`` noise variances into the residual still puts
    there with the rate raised ``factor`` times (it falls with the fourth power), when that
    exceeds :data:`STEP_MAX_CHI2` (the rate could not be raised far enough); else 0."""
    left = chi2 / factor ** 4
    return left if math.isfinite(left) and left > STEP_MAX_CHI2 else 0.0


def at_rate(machine: Machine, factor: int) -> Machine:
    """``machine`` with its planner's rate raised ``factor`` times."""
    return replace(machine, planner=replace(machine.planner,
                                            rate_hz=factor * machine.planner.rate_hz))


def rate_with_effects(campaign: Campaign, result: AnalysisResult, machine: Machine,
                      loaded: Mapping[str, MeasuredRun]) -> tuple[int, float]:
    """:func:`sim_rate` of the campaign compared with the effects ``result`` found
    (and offered) in ``machine``, at its rate and through its meter filter: by what further
    factor the rate must rise so that the found effects' own sampling cannot be fitted, and
    the sum of squares over the noise variance it gives at this rate. ``(1, 0)`` when
    nothing was found (the model is the one whose rate was chosen)."""
    if not (result.effects or result.offered):
        return 1, 0.0
    model = replace(replace(result, machine=machine).augmented_machine(),
                    planner=machine.planner)
    filtered = (with_filter(campaign, result.meter_filter_s) if result.meter_filter_s
                else campaign)
    fcmp = compare_campaign(filtered, machine=model, runs=[r.name for r in result.runs],
                            loaded=loaded)
    return sim_rate(fcmp.runs, model)
