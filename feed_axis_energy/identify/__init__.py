"""Identification from measured runs: what the declared model is missing.

The loss-function fit of section 2.1 (:mod:`.lossfit` on steady segments, :mod:`.samplefit` on
every sample, :mod:`.torquefit` on every sample of a current, torque or force trace,
:mod:`.frictionfit` the richer friction of such a trace: asymmetric Coulomb and viscous,
Stribeck, offset force), residual diagnostics, effect selection with held-out checks and
ambiguity (:mod:`.analyze` and its steps), and the virtual test rig that makes "measured"
campaigns from a truth model (:mod:`.rig`).
"""
from .ambiguity import found_text
from .frictionfit import fit_drive_friction, FrictionFit, machine_with_friction_fits
from .analyze import analyze_campaign
from .lossfit import fit_loss, fit_power_regression, LossFit, machine_with_losses
from .results import AnalysisResult, AnalyzeOptions, HOLDOUTS, STATE_NAMES
from .rig import (Instrument, make_campaign, OUTSIDE_KINDS, PAPER_FEEDS_MM_S, PAPER_LOADS_KG,
                  parse_effects, RigConfig)
from .samplefit import fit_loss_samples, machine_with_sample_fits, SampleFitOptions
from .torquefit import fit_drive_samples
from .steady import (range_uses, run_segments, steady_segments, SteadyOptions, SteadySegment,
                     VELOCITY_SOURCES)

__all__ = [
    'AnalysisResult', 'analyze_campaign', 'AnalyzeOptions', 'fit_drive_friction',
    'fit_drive_samples', 'fit_loss', 'FrictionFit', 'machine_with_friction_fits',
    'fit_loss_samples',
    'fit_power_regression', 'found_text', 'HOLDOUTS', 'Instrument', 'LossFit',
    'machine_with_losses', 'machine_with_sample_fits', 'make_campaign', 'OUTSIDE_KINDS',
    'PAPER_FEEDS_MM_S', 'PAPER_LOADS_KG', 'parse_effects', 'range_uses', 'RigConfig',
    'run_segments', 'SampleFitOptions', 'STATE_NAMES', 'steady_segments', 'SteadyOptions',
    'SteadySegment', 'VELOCITY_SOURCES',
]
