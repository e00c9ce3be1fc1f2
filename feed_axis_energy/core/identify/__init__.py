"""Identification from measured runs: the loss-function fit of section 2.1 (power regression).

Typical use::

    runs = [load_run(spec) for spec in campaign.runs_with_role('calibrate')]
    fits = fit_loss(runs, machine=machine)
    if all(f.ok for f in fits.values()):
        fitted = machine_with_losses(machine, fits)
"""
from .lossfit import (fit_loss, fit_power_regression, LossFit, machine_with_losses,
                      run_segments, steady_segments, SteadyOptions, SteadySegment)

__all__ = ['LossFit', 'SteadyOptions', 'SteadySegment', 'fit_loss', 'fit_power_regression',
           'machine_with_losses', 'run_segments', 'steady_segments']
