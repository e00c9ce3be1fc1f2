"""What :func:`.analyze.analyze_campaign` returns: options, fitted effects with their
uncertainties, per-run before/after outcomes and the whole result (``to_dict`` gives the
JSON of ``docs/analyze.md``).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
from typing import Any

import numpy as np

from ..machine import CalibratedRange, DeclaredEffect, Machine
from ..effects import get_effect
from ..errors import ConfigError
from ..measured import group_metrics, json_clean, Metrics
from .ambiguity import AmbiguousGroup
from .consistency import Fate
from .diagnostics import Diagnostic, NoiseLevel
from .design import ANALYSIS_PERIOD_S, STATE_MEMORY_BYTES
from .timing import LeftOut
from .drivecorr import fold_corrections
from .selection import Step

__all__ = ['AnalyzeOptions', 'AnalysisResult', 'FittedEffect', 'ParamEstimate', 'RunOutcome',
           'HOLDOUTS', 'STATE_NAMES']

HOLDOUTS = ('loro', 'roles')
STATE_NAMES = ('velocity', 'position', 'acceleration', 'kinetic_power', 'time')
"""States the residual is binned against. ``kinetic_power`` is ``a·v`` [W/kg], the rate of
change of the kinetic energy per kilogram: an error of a moved mass or of braking is odd in
the velocity at a given acceleration (starts forward and stops backward share ``a > 0``),
so bins of the acceleration alone average it away."""


@dataclass(frozen=True)
class AnalyzeOptions:
    """Settings of :func:`analyze_campaign`.

    Attributes
    ----------
    holdout
        ``'loro'`` (leave one run out) or ``'roles'`` (fit on ``calibrate`` runs, score on
        ``validate`` runs of the manifest).
    effects
        Catalog ids to consider (default: all).
    se_factor, alpha
        Acceptance, by statistics only: mean relative held-out gain above ``se_factor``
        standard errors, and the drop of the residual above the chi-square limit at family
        level ``alpha`` over the candidates of a round (see
        :func:`.selection.forward_select`).
    min_bic_drop
        ... and the BIC must drop by more than this (default 2: positive evidence on the
        scale of Kass & Raftery 1995; ``0``: any drop).
    sampling_chi2
        Set by the analysis itself, not a user's setting: what the simulation's sampling still
        puts into the residual at the finest rate it simulates at [noise variances]
        (:mod:`.simrate`; 0 when the rate brings it below ``STEP_MAX_CHI2``). Every
        chi-square limit of the selection and the pruning is raised by it: a drop that small
        may be the simulation's own numerics.
    max_effects
        Most effects added.
    max_tries, pair_pool
        A round tries its ``max_tries`` best candidates one by one, then the pairs of its
        ``pair_pool`` best, until one passes.
    max_heterogeneity, heterogeneity_alpha
        An effect is inconsistent across runs when per-run refits add more than
        ``max_heterogeneity`` of what it explains and that improvement is significant
        against the noise (chi-square probability below ``heterogeneity_alpha``).
    min_share
        Share of the measured energy at which an effect *matters* in the report (default
        1 %): an effect below it is reported as "detected, below ... of the energy". It
        decides how effects are ranked and marked, never whether they exist.
    min_explained
        The selected effects together must explain at least this share of the structured
        baseline residual to be named, unless what they leave is within the noise's own
        scatter (:func:`.consistency.noise_floor_ss`); otherwise they are *offered* as a
        loss of their shape (``offered``, in the augmented machine), not attributed.
    noise_w
        A noise level declared by the user [W, per sample] for every test instead of the
        estimate (:func:`.diagnostics.noise_level`; the estimate is still reported).
    analysis_period_s
        Effects are selected on bins of the measured samples no longer than this [s]
        (:mod:`.design.grid`): each bin the exact mean of the whole number of sample periods that
        fit in it; data sampled at this period or slower are used sample by sample. Noise
        levels, diagnostics and the series of :class:`RunOutcome` are on these bins.
    shape_grid_points
        Grid size of each shape parameter before the refinement.
    max_rounds
        Cap of the consistency loop (selection redone without inconsistent effects); when
        reached, the effects consistent in the last round are kept and the result says so.
    realign
        ``False`` skips the re-aligned before/after comparisons (:mod:`.realign`): *after*
        and ``augmented`` are then the baseline comparison, unchanged. The findings are the
        same; for studies that need only them (``bench/detection_power.py``), a third less
        work.
    state_memory_bytes
        Budget [bytes] of the runs' simulations held in memory during a round; the states
        beyond it are written to a private temporary directory and memory-mapped when used
        (:mod:`.design.statestore`; the same results, bit for bit). ``0`` maps every state. The
        same budget again holds the runs' measured records for the whole analysis (their
        stamps, traces and file rows: those beyond it memory-mapped, :meth:`.design.statestore.
        StateStore.hold`).
    """

    holdout: str = 'loro'
    effects: tuple[str, ...] | None = None
    se_factor: float = 2.0
    alpha: float = 0.05
    min_bic_drop: float = 2.0
    sampling_chi2: float = 0.0
    max_effects: int = 4
    max_tries: int = 8
    pair_pool: int = 4
    max_heterogeneity: float = 0.05
    heterogeneity_alpha: float = 1e-3
    min_share: float = 0.01
    min_explained: float = 0.5
    shape_grid_points: int = 8
    max_rounds: int = 6
    realign: bool = True
    noise_w: float | None = None
    analysis_period_s: float = ANALYSIS_PERIOD_S
    state_memory_bytes: int = STATE_MEMORY_BYTES

    def __post_init__(self) -> None:
        if not (isinstance(self.state_memory_bytes, int) and self.state_memory_bytes >= 0):
            msg = f'state_memory_bytes must be an integer >= 0, got {self.state_memory_bytes!r}'
            raise ConfigError(msg, key='state_memory_bytes')
        if not (math.isfinite(self.analysis_period_s) and self.analysis_period_s > 0.0):
            msg = (f'analysis_period_s must be a finite number > 0 s, got '
                   f'{self.analysis_period_s!r}')
            raise ConfigError(msg, key='analysis_period_s')
        if not 0.0 <= self.min_share < 1.0:
            msg = f'min_share must lie in [0, 1), got {self.min_share!r}'
            raise ConfigError(msg, key='min_share')
        if self.noise_w is not None and not (math.isfinite(self.noise_w)
                                             and self.noise_w > 0.0):
            msg = f'noise_w must be a finite number > 0 W, got {self.noise_w!r}'
            raise ConfigError(msg, key='noise_w')
        if not 0.0 < self.alpha < 1.0:
            msg = f'alpha must lie in (0, 1), got {self.alpha!r}'
            raise ConfigError(msg, key='alpha')
        if not (math.isfinite(self.min_bic_drop) and self.min_bic_drop >= 0.0):
            msg = f'min_bic_drop must be a finite number >= 0, got {self.min_bic_drop!r}'
            raise ConfigError(msg, key='min_bic_drop')


@dataclass(frozen=True)
class ParamEstimate:
    """A fitted effect parameter: value, unit and standard uncertainty (``None``: none).

    ``at_bound`` is ``'lower'`` or ``'upper'`` when the bounded fit put the value on that
    physical bound (the data would push it further: an impossible value, not a finding).
    """

    name: str
    value: float
    unit: str
    uncertainty: float | None
    method: str
    at_bound: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain dict."""
        return {'name': self.name, 'value': self.value, 'unit': self.unit,
                'uncertainty': self.uncertainty, 'method': self.method,
                'at_bound': self.at_bound}


@dataclass(frozen=True)
class FittedEffect:
    """A selected effect.

    Attributes
    ----------
    id, axis
        Catalog id and measured axis.
    params
        Linear parameters (jackknife uncertainty) then shape parameters.
    share_of_residual
        Drop in the in-sample residual sum of squares when the effect is added last,
        relative to the baseline residual sum of squares.
    share_of_structured
        The same relative to the structured part of the baseline residual
        (``SSE - N sigma²``), clipped to [0, 1].
    heldout_gain_w2, heldout_gain_rel
        Mean over held-out runs of ``mse(without it) - mse(with it)`` [W²] and of the same
        relative to ``mse(without it)``.
    heterogeneity
        Share of its explained variance per-run refits would add (0: same on every run).
    aliases
        Candidates that fit nearly as well in its place (``id@axis``).
    correction
        When the effect corrects a declared drive (:mod:`.drivecorr`): the declared value,
        the change (the fitted parameters) and the corrected value, else ``None``.
    energy_j, energy_share
        Energy of its fitted power over every run of the campaign [J] (fitted on all runs,
        beside the other effects) and its magnitude relative to the measured energy [-].
    matters
        ``energy_share >= AnalyzeOptions.min_share``: how the report marks it ("detected,
        below ... of the energy" otherwise); it was added either way.
    attributed
        ``False`` for an *offered* effect: it improves the held-out error, but the data do
        not attribute the loss to it (``AnalysisResult.offered``).
    """

    id: str
    axis: str
    params: tuple[ParamEstimate, ...]
    share_of_residual: float
    share_of_structured: float
    heldout_gain_w2: float
    heldout_gain_rel: float
    heterogeneity: float
    aliases: tuple[str, ...] = ()
    correction: dict[str, Any] | None = None
    energy_j: float = math.nan
    energy_share: float = math.nan
    matters: bool = True
    attributed: bool = True

    def values(self) -> dict[str, float]:
        """Parameter values by name."""
        return {p.name: p.value for p in self.params}

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (keys in docs/analyze.md)."""
        return {'id': self.id, 'axis': self.axis,
                'parameters': [p.to_dict() for p in self.params],
                'share_of_residual': self.share_of_residual,
                'share_of_structured_residual': self.share_of_structured,
                'heldout_gain_w2': self.heldout_gain_w2,
                'heldout_gain_rel': self.heldout_gain_rel,
                'heterogeneity': self.heterogeneity,
                'aliases': list(self.aliases), 'energy_j': self.energy_j,
                'energy_share': self.energy_share, 'matters': self.matters,
                'attributed': self.attributed} | (
                    {} if self.correction is None else {'correction': self.correction})


@dataclass(frozen=True)
class RunOutcome:
    """One run before and after (series on the analysis grid of :mod:`.design.grid`: the measured
    stamps, or bins of them for data sampled faster than the analysis period; sums of
    measured axes).

    ``heldout`` is ``False`` for ``calibrate`` runs with ``holdout='roles'``: their
    ``after`` is in-sample and they are left out of the overall before/after.
    ``offset_before`` / ``offset_after``: the offset estimates (``compare --json``'s
    ``offset`` objects) of the baseline and of the re-aligned *after* comparison.
    """

    name: str
    load_kg: float
    role: str | None
    heldout: bool
    before: Metrics
    after: Metrics
    t: np.ndarray = field(repr=False)
    meas_w: np.ndarray = field(repr=False)
    sim_w: np.ndarray = field(repr=False)
    after_w: np.ndarray = field(repr=False)
    residual_before_w: np.ndarray = field(repr=False)
    residual_after_w: np.ndarray = field(repr=False)
    states: dict[str, np.ndarray] = field(repr=False, default_factory=dict)
    offset_before: dict[str, Any] | None = None
    offset_after: dict[str, Any] | None = None


@dataclass(frozen=True)
class AnalysisResult:
    """Outcome of :func:`analyze_campaign`; a poor fit or no finding is a result.

    Attributes
    ----------
    status
        ``'effects'`` (effects found, no structure left), ``'partial'`` (effects found,
        structure left), ``'unexplained'`` (structure, no catalog effect explains it),
        ``'clean'`` (no effect, no structure; a ``time_offset`` alone, which corrects the
        records' alignment, is clean too), ``'too_few_runs'``.
    message
        One sentence.
    alignment_warnings
        The baseline comparison's offset and instrument warnings (``compare``'s).
    candidates
        The fate of every candidate ``(effect, axis)`` (:class:`.consistency.Fate`).
    warnings
        Loss functions applied outside the speeds/loads they were calibrated on
        (:func:`..calibrated.range_warnings`).
    calibrated
        Axis -> the steady speeds, loads and positions of the campaign: written with each
        added effect into the augmented machine (``calibrated``).
    rounds, cap_reached
        Rounds of the consistency loop and whether its cap was reached.
    ambiguous
        Findings the data cannot attribute to one effect (:mod:`.ambiguity`): selected
        effects whose power other candidates reproduce within the noise, with their forms.
    left_out
        Runs not fitted because their time offset could not be pinned down, not even with
        the effects found (:mod:`.timing.pinning`).
    residual_unit
        Unit of the residual the effects were selected on, of the noise levels
        (``noise_sigma_w``) and of the diagnostics: ``'W'``, or ``'A'`` on current traces
        (:mod:`.driveforms`).
    pin_rounds
        Analysis rounds with offsets estimated anew after the effects found (1: none moved).
    analysis_period_s, samples_per_bin
        The analysis grid (:mod:`.design.grid`): the period asked for [s] and, per run name, how
        many measured samples each bin averages (1: the samples themselves). Noise levels,
        diagnostics and the series of ``runs`` are on these bins.
    noise
        Axis -> the noise level every test used and how it was found
        (:class:`.diagnostics.NoiseLevel`); ``noise_sigma_w`` holds its ``sigma_w``.
    offered
        Effects that improve the held-out error but that the data do not attribute (too
        little of the structured residual explained, or an alternative outside the catalog
        fits as well): a loss of their shape, fitted beside the named effects, written into
        the augmented machine; never counted as a finding of that effect.
    offered_gain_rel
        Mean relative drop of the held-out mean squared error the offered effects give
        together, beside the named ones (NaN: none offered).
    min_share
        Share of the measured energy at which an effect matters in the report.
    meter_filter_s
        Time constant [s] of a first-order smoothing of the meter that ``analyze`` estimated
        and fitted with (0: none estimated; a filter the manifest declares is the runs'
        instrument, ``instrument.filter_s``).
    aligned_with
        When the analysis started from the offsets the runs have with one candidate effect
        in the model (records of the power alone, :mod:`.timing.jointalign`): ``{'effect', 'axis',
        'median_move_s', 'largest_move_s'}`` (the median and the largest distance [s] from
        the power's own lags); else ``None``.
    sim_rate_hz
        The rate [Hz] the analysis simulated at: the planner's ``rate_hz``, or a multiple of
        it when the data resolve what the simulation's sampling changes in the meter's
        readings (:func:`.simrate.sim_rate`); 0 when not set.
    """

    status: str
    message: str
    campaign: str
    manifest: str
    machine: Machine
    machine_file: str
    holdout: str
    axes: tuple[str, ...]
    noise_sigma_w: dict[str, float]
    runs: tuple[RunOutcome, ...]
    effects: tuple[FittedEffect, ...]
    unexplained: tuple[dict[str, Any], ...]
    diagnostics_before: tuple[Diagnostic, ...]
    diagnostics_after: tuple[Diagnostic, ...]
    steps: tuple[Step, ...]
    spectra: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(
        repr=False, default_factory=dict)
    augmented: tuple[dict[str, Any], ...] = ()
    alignment_warnings: tuple[str, ...] = ()
    candidates: tuple[Fate, ...] = ()
    warnings: tuple[str, ...] = ()
    calibrated: dict[str, CalibratedRange | None] = field(default_factory=dict)
    rounds: int = 0
    cap_reached: bool = False
    ambiguous: tuple[AmbiguousGroup, ...] = ()
    left_out: tuple[LeftOut, ...] = ()
    pin_rounds: int = 1
    meter_filter_s: float = 0.0
    aligned_with: dict[str, Any] | None = None
    sim_rate_hz: float = 0.0
    residual_unit: str = 'W'
    analysis_period_s: float = ANALYSIS_PERIOD_S
    samples_per_bin: dict[str, int] = field(default_factory=dict)
    noise: dict[str, NoiseLevel] = field(default_factory=dict)
    offered: tuple[FittedEffect, ...] = ()
    offered_gain_rel: float = math.nan
    min_share: float = 0.01

    @property
    def heldout_runs(self) -> tuple[RunOutcome, ...]:
        """Runs scored by a fit without them."""
        return tuple(r for r in self.runs if r.heldout)

    @property
    def before(self) -> Metrics:
        """Pooled baseline metrics of the held-out runs."""
        return group_metrics([r.before for r in self.heldout_runs])

    @property
    def after(self) -> Metrics:
        """Pooled held-out metrics with the selected effects."""
        return group_metrics([r.after for r in self.heldout_runs])

    def by_load(self) -> list[tuple[float, Metrics, Metrics]]:
        """``[(load_kg, before, after), ...]`` of held-out runs, by increasing load."""
        loads = sorted({r.load_kg for r in self.heldout_runs})
        return [(load, group_metrics([r.before for r in self.heldout_runs
                                      if r.load_kg == load]),
                 group_metrics([r.after for r in self.heldout_runs if r.load_kg == load]))
                for load in loads]

    def augmented_machine(self) -> Machine:
        """The declared machine plus the selected effects with their fitted parameters.

        Effects that describe the comparison rather than the machine (``time_offset``: how
        the two records line up, which ``compare`` estimates anew for every run) are left out.
        Offered effects (a loss of their shape, not attributed) are in: they are what
        improves the prediction.
        """
        every = self.effects + self.offered
        added = tuple(DeclaredEffect(id=e.id, axis=e.axis,
                                     params=tuple((p.name, float(p.value)) for p in e.params),
                                     calibrated=self.calibrated.get(e.axis))
                      for e in every
                      if get_effect(e.id).machine_property and e.correction is None)
        # corrections of a declared drive change its data-sheet values (.drivecorr)
        machine = fold_corrections(self.machine, [(e.id, e.axis, e.values())
                                                  for e in every
                                                  if e.correction is not None])
        return replace(machine, effects=machine.effects + added)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able summary (keys in docs/analyze.md); NaN becomes ``None``."""
        def metrics(which: str) -> dict[str, Any]:
            held = self.heldout_runs
            return {
                'total': (self.before if which == 'before' else self.after).to_dict(),
                'loads': [{'load_kg': load, 'metrics': (b if which == 'before' else a).to_dict()}
                          for load, b, a in self.by_load()],
                'runs': [{'name': r.name, 'load_kg': r.load_kg, 'role': r.role,
                          'metrics': getattr(r, which).to_dict(),
                          'offset': getattr(r, f'offset_{which}')} for r in held],
            }
        return json_clean({
            'campaign': self.campaign,
            'manifest': self.manifest,
            'machine': self.machine.name,
            'machine_file': self.machine_file,
            'holdout': self.holdout,
            'status': self.status,
            'message': self.message,
            'noise_sigma_w': self.noise_sigma_w,
            'noise': {a: n.to_dict() for a, n in self.noise.items()},
            'min_share': self.min_share,
            'before': metrics('before'),
            'after': metrics('after'),
            'effects': [e.to_dict() for e in self.effects],
            'offered': [e.to_dict() for e in self.offered],
            'offered_gain_rel': self.offered_gain_rel,
            'ambiguous': [g.to_dict() for g in self.ambiguous],
            'augmented': list(self.augmented),
            'alignment_warnings': list(self.alignment_warnings),
            'unexplained': [dict(u) for u in self.unexplained],
            'diagnostics': {'before': [d.to_dict() for d in self.diagnostics_before],
                            'after': [d.to_dict() for d in self.diagnostics_after]},
            'selection': [{'effect': s.key[0], 'axis': s.key[1],
                           'shape': {k: float(v) for k, v in s.shape.items()},
                           'heldout_gain_rel': s.mean_gain, 'heldout_gain_se': s.se_gain,
                           'bic_before': s.bic_before, 'bic_after': s.bic_after,
                           'accepted': s.accepted, 'reason': s.reason, 'round': s.round,
                           'with': None if s.with_key is None else
                           {'effect': s.with_key[0], 'axis': s.with_key[1]},
                           'chi2': s.chi2, 'chi2_limit': s.chi2_limit}
                          for s in self.steps],
            'candidates': [f.to_dict() for f in self.candidates],
            'consistency': {'rounds': self.rounds, 'cap_reached': self.cap_reached},
            'left_out': [lo.to_dict() for lo in self.left_out],
            'pin_rounds': self.pin_rounds,
            'meter_filter_s': self.meter_filter_s,
            'aligned_with': None if self.aligned_with is None else dict(self.aligned_with),
            'sim_rate_hz': self.sim_rate_hz,
            'analysis_grid': {'period_s': self.analysis_period_s,
                              'samples_per_bin': dict(self.samples_per_bin)},
            'residual_unit': self.residual_unit,
            'warnings': list(self.warnings),
        })
