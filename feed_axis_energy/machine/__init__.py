"""The machine: its data (:mod:`.spec`) and its YAML file (:mod:`.file`).

Owns what a machine file declares: ball screws, masses and inertias, kinematic limits and
planner settings (:mod:`.limits`), the loss function (:mod:`.losses`) with its covariance
(:mod:`.covariance`) and calibrated range (:mod:`.calibrated`), motors, drives and supply
(:mod:`.drives`), declared catalog effects (:mod:`.declared`), and the moved mass of stacked
axes (:mod:`.mass`). Nothing here simulates; everything is a frozen value.
"""
from .calibrated import CalibratedRange, machine_warnings, observed_range, range_warnings, RangeUse
from .covariance import LossCovariance
from .declared import DeclaredEffect
from .drives import COPPER_FACTOR, DriveSpec, IronSpec
from .file import load_machine, machine_from_dict, machine_to_dict
from .limits import AxisLimits, PlannerOptions
from .losses import CoulombViscousLoss, PowerRegressionLoss
from .mass import moved_mass_kg
from .spec import BRAKING_MODES, Machine

__all__ = [
    'AxisLimits', 'BRAKING_MODES', 'CalibratedRange', 'COPPER_FACTOR', 'CoulombViscousLoss',
    'DeclaredEffect', 'DriveSpec', 'IronSpec', 'load_machine', 'LossCovariance', 'Machine',
    'machine_from_dict', 'machine_to_dict', 'machine_warnings', 'moved_mass_kg', 'observed_range',
    'PlannerOptions', 'PowerRegressionLoss', 'range_warnings', 'RangeUse',
]
