"""Fitting the loss model to measured runs (``fit-loss``): the paper's section 2.1 and its
sample-wise forms.

:mod:`.lossfit` fits the power regression on steady-motion segments (:mod:`.steady` finds
them), :mod:`.samplefit` Coulomb + viscous loss and motor inertia on every moving sample of a
power trace, :mod:`.torquefit` the same on a current, torque or force trace (the torque
constant fitted where not declared), :mod:`.frictionfit` the richer friction of such a trace
(asymmetric Coulomb and viscous, Stribeck, offset force). Effect selection (``analyze``) is
the rest of :mod:`feed_axis_energy.identify`.
"""
from .frictionfit import fit_drive_friction, FrictionFit, machine_with_friction_fits
from .lossfit import fit_loss, fit_power_regression, LossFit, machine_with_losses
from .samplefit import (fit_loss_samples, machine_with_sample_fits, nonnegative_lsq, SampleFit,
                        SampleFitOptions)
from .steady import (kinematics, range_uses, run_segments, steady_segments, SteadyOptions,
                     SteadySegment, VELOCITY_SOURCES)
from .torquefit import fit_drive_samples

__all__ = [
    'fit_drive_friction', 'fit_drive_samples', 'fit_loss', 'fit_loss_samples',
    'fit_power_regression', 'FrictionFit', 'kinematics', 'LossFit', 'machine_with_friction_fits',
    'machine_with_losses', 'machine_with_sample_fits', 'nonnegative_lsq', 'range_uses',
    'run_segments', 'SampleFit', 'SampleFitOptions', 'steady_segments', 'SteadyOptions',
    'SteadySegment', 'VELOCITY_SOURCES',
]
