"""Rotary feed axes (A, B, C) in a machine file: read, check, write.

A rotary table or swivel head is declared under its letter::

    axes:
      B:
        rides_on: X                    # optional: the linear axis that carries the unit
        mass_kg: 85.0                  # what that axis moves with it [kg]
        table_inertia_kg_m2: 0.40      # table (or head) about its axis [kg m^2]
        load_inertia_kg_m2: 0.05       # workpiece and fixture about the axis [kg m^2]
        gear_ratio: 90.0               # motor revolutions per table revolution (1: direct)
        efficiency: 0.75               # gear (worm) efficiency, 0 < eta <= 1
        inertias: {motor_kg_m2: 2.6e-4, coupling_kg_m2: 2.0e-5}   # motor side
        limits: {velocity_deg_s: 1800.0, acceleration_deg_s2: 3600.0, jerk_deg_s3: 36000.0}
        friction: {coulomb_nm: 8.0, viscous_nm_s_rad: 4.0}        # at the table
        travel_deg: [-120.0, 120.0]    # optional (a swivel); endless when left out
        drive: {...}                   # optional, as for a linear axis (docs/electrical.md)

Required: ``table_inertia_kg_m2``, ``gear_ratio``, ``inertias``, ``limits``. The axis
becomes an :class:`~.spec.AxisSpec` with a :class:`~.spec.RotarySpec`, whose linear fields
hold the equivalent feed axis (rad for m, N·m for N, kg·m^2 for kg), so planner, dynamics,
power, energy and every output treat it as they treat a ball-screw axis:
``omega_motor = gear_ratio · omega_table``,
``M_motor = J_motor · alpha_motor + M_table / (gear_ratio · eta)`` (``· eta`` when the table
drives the motor back), ``M_table = (J_table + J_load) · alpha_table + M_friction`` with
``M_friction = coulomb_nm · sign(omega) + viscous_nm_s_rad · omega``. A rotary axis feels no
gravity (its load is taken as balanced about the axis) and carries no other axis; a linear
axis that carries it moves its ``mass_kg`` (and the workpiece mass ``--load`` when the
machine's ``load_axis`` is the rotary one, whose inertia about the axis is
``load_inertia_kg_m2``).
"""
from __future__ import annotations

import math
from typing import Any

from ..configcheck import check_float as _float, check_mapping as _mapping, join_key as _join
from .drives import drive_from_value, drive_to_dict
from ..errors import ConfigError, describe
from .losses import CoulombViscousLoss
from .spec import AxisSpec, InertiaSpec, LimitSpec, RotarySpec, ScrewSpec

__all__ = ['rotary_axis_from_value', 'rotary_axis_to_dict', 'check_rotary_stacking',
           'ROTARY_KEYS']

ROTARY_KEYS = ('rides_on', 'mass_kg', 'table_inertia_kg_m2', 'load_inertia_kg_m2',
               'gear_ratio', 'efficiency', 'inertias', 'limits', 'friction', 'travel_deg',
               'drive')
_LIMIT_NAMES = ('velocity_deg_s', 'acceleration_deg_s2', 'jerk_deg_s3')
# Accepted ranges [deg/s, deg/s^2, deg/s^3]: far outside any rotary table, and narrow
# enough that nothing simulated overflows (as machine/file.py's ranges for linear axes).
_LIMIT_RANGES = ((1.0e-2, 1.0e6), (1.0e-2, 1.0e8), (1.0e-2, 1.0e10))


def rotary_axis_from_value(name: str, d: Any, *, file: str,
                           rides_on: str | None) -> AxisSpec:
    """Read and check the rotary axis ``name`` (``axes.<name>`` of a machine file).

    Parameters
    ----------
    name
        ``'A'``, ``'B'`` or ``'C'``.
    d
        Its mapping.
    file
        The machine file, for messages.
    rides_on
        The checked ``rides_on`` value.

    Returns
    -------
    AxisSpec
        The equivalent feed axis with its :class:`~.spec.RotarySpec`.

    Raises
    ------
    ConfigError
        A missing, invalid or unknown value, named by its dotted key.
    """
    key = f'axes.{name}'
    d = _mapping(d, file=file, key=key, allowed=ROTARY_KEYS)
    for part in ('table_inertia_kg_m2', 'gear_ratio', 'inertias', 'limits'):
        if part not in d:
            msg = 'missing required value of a rotary axis'
            raise ConfigError(msg, file=file, key=f'{key}.{part}')
    table = _float(d, 'table_inertia_kg_m2', file=file, key=key, minimum=0.0, strict=False,
                   maximum=1.0e6)
    load = _float(d, 'load_inertia_kg_m2', file=file, key=key, default=0.0, minimum=0.0,
                  strict=False, maximum=1.0e6)
    ratio = _float(d, 'gear_ratio', file=file, key=key, minimum=1.0e-3, strict=False,
                   maximum=1.0e5)
    eta = _float(d, 'efficiency', file=file, key=key, default=1.0, minimum=0.01,
                 strict=False, maximum=1.0)
    rotary = RotarySpec(
        gear_ratio=ratio, table_inertia_kg_m2=table, load_inertia_kg_m2=load,
        mass_kg=_float(d, 'mass_kg', file=file, key=key, default=0.0, minimum=0.0,
                       strict=False, maximum=1.0e6),
        travel_deg=_travel(d.get('travel_deg'), file=file, key=f'{key}.travel_deg'),
        limits_deg=_limits_deg(d['limits'], file=file, key=f'{key}.limits'))
    inertias_d = _mapping(d['inertias'], file=file, key=f'{key}.inertias',
                          allowed=('motor_kg_m2', 'coupling_kg_m2'))
    ikey = f'{key}.inertias'
    inertias = InertiaSpec(
        motor_kg_m2=_float(inertias_d, 'motor_kg_m2', file=file, key=ikey, minimum=0.0,
                           strict=False, maximum=1.0e3),
        coupling_kg_m2=_float(inertias_d, 'coupling_kg_m2', file=file, key=ikey, default=0.0,
                              minimum=0.0, strict=False, maximum=1.0e3),
        screw_kg_m2=0.0)
    rad = [math.radians(v) for v in rotary.limits_deg]
    fkey = f'{key}.friction'
    friction_d = _mapping(d.get('friction', {}), file=file, key=fkey,
                          allowed=('coulomb_nm', 'viscous_nm_s_rad'))
    loss = CoulombViscousLoss(
        coulomb_n=_float(friction_d, 'coulomb_nm', file=file, key=fkey, default=0.0,
                         minimum=0.0, strict=False, maximum=1.0e6),
        viscous_n_s_m=_float(friction_d, 'viscous_nm_s_rad', file=file, key=fkey,
                             default=0.0, minimum=0.0, strict=False, maximum=1.0e6))
    return AxisSpec(
        name=name, table_mass_kg=table,
        screw=ScrewSpec(diameter_m=0.0, lead_m=2.0 * math.pi / ratio, length_m=0.0,
                        efficiency=eta),
        inertias=inertias, limits=LimitSpec(*rad), loss=loss, rides_on=rides_on,
        inclination_deg=0.0, travel_m=None if rotary.travel_deg is None else (
            math.radians(rotary.travel_deg[0]), math.radians(rotary.travel_deg[1])),
        drive=drive_from_value(d.get('drive'), file=file, key=f'{key}.drive'),
        rotary=rotary)


def _limits_deg(value: Any, *, file: str, key: str) -> tuple[float, float, float]:
    limits_d = _mapping(value, file=file, key=key, allowed=_LIMIT_NAMES)
    v, a, j = (_float(limits_d, n, file=file, key=key, minimum=low, strict=False, maximum=high)
               for n, (low, high) in zip(_LIMIT_NAMES, _LIMIT_RANGES))
    return v, a, j


def _travel(value: Any, *, file: str, key: str) -> tuple[float, float] | None:
    if value is None:
        return None
    if (not isinstance(value, (list, tuple)) or len(value) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                       and math.isfinite(v) for v in value) or not value[0] < value[1]):
        msg = f'expected [min, max] in degrees with min < max, got {describe(value)}'
        raise ConfigError(msg, file=file, key=key)
    return float(value[0]), float(value[1])


def rotary_axis_to_dict(axis: AxisSpec) -> dict[str, Any]:
    """The machine-file form of a rotary axis (``rotary_axis_from_value`` reads it back)."""
    rot = axis.rotary
    if rot is None:
        msg = f'axis {axis.name} is not a rotary axis'
        raise ValueError(msg)
    loss = axis.loss
    assert isinstance(loss, CoulombViscousLoss)
    out: dict[str, Any] = {
        'rides_on': axis.rides_on,
        'mass_kg': rot.mass_kg,
        'table_inertia_kg_m2': rot.table_inertia_kg_m2,
        'load_inertia_kg_m2': rot.load_inertia_kg_m2,
        'gear_ratio': rot.gear_ratio,
        'efficiency': axis.screw.efficiency,
        'inertias': {'motor_kg_m2': axis.inertias.motor_kg_m2,
                     'coupling_kg_m2': axis.inertias.coupling_kg_m2},
        'limits': dict(zip(_LIMIT_NAMES, rot.limits_deg)),
        'friction': {'coulomb_nm': loss.coulomb_n, 'viscous_nm_s_rad': loss.viscous_n_s_m},
    }
    if rot.travel_deg is not None:
        out['travel_deg'] = [rot.travel_deg[0], rot.travel_deg[1]]
    if axis.drive is not None:
        out['drive'] = drive_to_dict(axis.drive)
    return out


def check_rotary_stacking(axes: tuple[AxisSpec, ...], *, file: str) -> None:
    """A rotary axis carries no other axis (its inertia about the axis would change with
    the carried axis's position); give a trunnion's inertia with the table it carries."""
    rotary = {a.name for a in axes if a.rotary is not None}
    for spec in axes:
        if spec.rides_on in rotary:
            msg = (f'axis {spec.name} rides on the rotary axis {spec.rides_on}: a rotary axis '
                   'carries no other axis (give its table_inertia_kg_m2 with what it carries)')
            raise ConfigError(msg, file=file, key=_join(f'axes.{spec.name}', 'rides_on'))
