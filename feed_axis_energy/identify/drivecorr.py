"""Catalog effects as corrections of a declared drive (``docs/electrical.md``).

When the campaign's meter measures the power at the motor terminals
(``instrument.measures: motor``) and the axis declares its motor and drive, the catalog's
``copper`` (``k·M²``) and ``iron`` (``k_h·|omega| + k_e·omega²``) effects have the form of
losses the model already holds. There they are fitted as signed **changes** of the declared
coefficients, bounded so that the corrected loss stays >= 0 (lower bound ``-declared``), and
the augmented machine takes the corrected data-sheet values (winding resistance, iron
coefficients) instead of an added effect. At the motor terminals the two are the same power
at every sample, so ``analyze``'s "after" and ``compare --machine AUG`` agree.

At the supply side the converter scales the drive's losses (``1/eta_c`` motoring), so an
added effect and a changed data-sheet value differ there; effects stay additions (>= 0) for
``measures: supply`` and ``shaft``, as for ``standby`` everywhere.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import replace
from typing import Any, cast

import numpy as np

from ..machine import COPPER_FACTOR, DriveSpec, IronSpec, Machine

__all__ = ['CORRECTABLE', 'common_measures', 'declared_values', 'correction_bounds',
           'fold_corrections', 'describe_correction']

CORRECTABLE = ('copper', 'iron')


def common_measures(values: Iterable[str]) -> str | None:
    """What every run's meter measures, or ``None`` when the runs differ."""
    found = set(values)
    return found.pop() if len(found) == 1 else None


def declared_values(machine: Machine, axis: str, effect_id: str,
                    measures: str | None) -> dict[str, float] | None:
    """The declared value of each linear parameter of ``effect_id`` on ``axis`` when the
    effect acts as a correction (see the module docstring), else ``None``."""
    if measures != 'motor' or effect_id not in CORRECTABLE or axis not in machine.axis_names:
        return None
    drive = machine.axis(axis).drive
    if drive is None:
        return None
    if effect_id == 'copper':
        return {'k_w_nm2': drive.copper_k_w_nm2}
    return {'k_h_w_s_rad': drive.iron.k_h_w_s_rad, 'k_e_w_s2_rad2': drive.iron.k_e_w_s2_rad2}


def correction_bounds(names: Iterable[str], bounds: tuple[np.ndarray, np.ndarray],
                      declared: Mapping[str, float] | None) -> tuple[np.ndarray, np.ndarray]:
    """``bounds`` with the lower bound of each corrected parameter set to ``-declared``."""
    if declared is None:
        return bounds
    lo = np.array(bounds[0], dtype=float)
    for i, name in enumerate(names):
        if name in declared:
            lo[i] = -declared[name]
    return lo, bounds[1]


def _corrected_drive(drive: DriveSpec, effect_id: str, change: Mapping[str, float]) -> DriveSpec:
    if effect_id == 'copper':
        k = max(drive.copper_k_w_nm2 + change.get('k_w_nm2', 0.0), 0.0)
        factor = COPPER_FACTOR[drive.resistance_between]
        return replace(drive, resistance_ohm=k * drive.kt_nm_a ** 2 / factor)
    iron = IronSpec(
        k_h_w_s_rad=max(drive.iron.k_h_w_s_rad + change.get('k_h_w_s_rad', 0.0), 0.0),
        k_e_w_s2_rad2=max(drive.iron.k_e_w_s2_rad2 + change.get('k_e_w_s2_rad2', 0.0), 0.0))
    return replace(drive, iron=iron)


def fold_corrections(machine: Machine,
                     corrections: Iterable[tuple[str, str, Mapping[str, float]]]) -> Machine:
    """``machine`` with each ``(effect_id, axis, change)`` folded into the axis's drive."""
    axes = {a.name: a for a in machine.axes}
    changed = False
    for effect_id, axis, change in corrections:
        spec = axes[axis]
        drive = cast(DriveSpec, spec.drive)     # a correction is made for a drive only
        axes[axis] = replace(spec, drive=_corrected_drive(drive, effect_id, change))
        changed = True
    if not changed:
        return machine
    return replace(machine, axes=tuple(axes[a.name] for a in machine.axes))


def describe_correction(machine: Machine, effect_id: str, axis: str,
                        change: Mapping[str, float]) -> dict[str, Any]:
    """``{'declared', 'change', 'corrected'}`` of the parameters, and for ``copper`` the
    winding resistance ``resistance_ohm: {'declared', 'corrected'}`` [ohm] (``kt`` kept)."""
    drive = cast(DriveSpec, machine.axis(axis).drive)   # a correction is made for a drive only
    declared = declared_values(machine, axis, effect_id, 'motor') or {}
    out: dict[str, Any] = {
        'declared': dict(declared),
        'change': {n: float(change.get(n, 0.0)) for n in declared},
        'corrected': {n: max(v + float(change.get(n, 0.0)), 0.0) for n, v in declared.items()}}
    if effect_id == 'copper':
        out['resistance_ohm'] = {
            'declared': drive.resistance_ohm,
            'corrected': _corrected_drive(drive, effect_id, change).resistance_ohm,
            'between': drive.resistance_between}
    return out
