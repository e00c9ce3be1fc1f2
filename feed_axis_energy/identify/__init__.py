"""Identification from measured runs: what the declared model is missing.

The loss-function fit of section 2.1 and its sample-wise forms (:mod:`.fit`: on steady
segments, on every sample of a power, current, torque or force trace, the richer friction of
a drive trace), residual diagnostics, effect selection with held-out checks and
ambiguity (:mod:`.analyze` and its steps), and the virtual test rig that makes "measured"
campaigns from a truth model (:mod:`.rig`).
"""
from .ambiguity import found_text
from .analyze import analyze_campaign
from .fit import (fit_drive_friction, fit_drive_samples, fit_loss, fit_loss_samples,
                  fit_power_regression, FrictionFit, LossFit, machine_with_friction_fits,
                  machine_with_losses, machine_with_sample_fits, range_uses, run_segments,
                  SampleFitOptions, steady_segments, SteadyOptions, SteadySegment,
                  VELOCITY_SOURCES)
from .results import AnalysisResult, AnalyzeOptions, HOLDOUTS, STATE_NAMES
from .rig import (Instrument, make_campaign, OUTSIDE_KINDS, PAPER_FEEDS_MM_S, PAPER_LOADS_KG,
                  parse_effects, RigConfig)

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
