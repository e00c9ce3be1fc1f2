"""Machine model: ball-screw feed axes as frozen dataclasses, loaded and validated from YAML.

The dataclasses themselves are in :mod:`.spec`; this module reads and writes them.

A machine file looks like (see ``config/demonstrator.yaml``)::

    name: demonstrator
    braking: regenerative        # or dissipated
    load_axis: X                 # the axis whose table carries the clamped workpiece
    planner: {profile: jerk, corner_tolerance_m: 1.0e-4, rate_hz: 1000.0}
    axes:
      X:
        table_mass_kg: 12.0
        rides_on: null           # the axis that carries this one
        inclination_deg: 0.0     # 90: vertical, positive direction upward
        screw: {diameter_m: 0.02, lead_m: 0.01, length_m: 0.6, starts: 1, efficiency: 1.0}
        inertias: {motor_kg_m2: 1.1e-4, coupling_kg_m2: 1.0e-5}
        limits: {velocity_m_s: 0.6, acceleration_m_s2: 2.5, jerk_m_s3: 50.0}
        loss: {model: power_regression, a: 0.2505, b: 0.3471}
    effects:                     # optional: catalog effects added on top of the power
      - {id: load_friction, axis: X, params: {mu: 0.012}}
    gcode:                       # optional: dialect and tool table (see .machine_gcode)
      dialect: linuxcnc
      tools: {1: {radius_m: 0.003, length_m: 0.045}}

Axes ``A``, ``B``, ``C`` are rotary (a rotary table or swivel head, :mod:`.rotary`): moment
of inertia of table and load, gear ratio, efficiency, friction torque, limits in degrees.

Each axis may declare its motor and drive (``drive:``) and the machine its cabinet standby
and meter point (``supply:``), from data-sheet values (:mod:`.drives`,
``docs/electrical.md``).

Each axis may also give ``travel_m: [min, max]``, its travel in machine coordinates [m],
and ``loss_calibrated: {feed_mm_s: [low, high], load_kg: [low, high]}``, the speeds and loads
its loss function was fitted on (written by ``fit-loss``; :mod:`.calibrated`), and
``loss_covariance: {params, units, matrix}``, the covariance of the loss parameters
(written by ``fit-loss``; :mod:`.covariance`; simulations then give the energy's uncertainty).

``effects`` lists effects of the catalog (:mod:`.effects`, ``docs/effects.md``) that the
model declares in addition to the loss function, usually written by ``feed-axis-energy
analyze --out-machine``; each adds its extra power to the named axis (every axis when
``axis`` is left out) after the braking rule. Parameters left out take the catalog default.

Every missing or invalid value raises :class:`~.errors.ConfigError` naming the file and the
dotted key (``axes.X.screw.lead_m``); unknown keys are rejected so that typos do not pass.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from .calibrated import calibrated_from_value
from ..configcheck import (check_choice as _choice, check_float as _float,
                           check_mapping as _mapping, join_key as _join)
from .drives import (check_drives, drive_from_value, drive_to_dict, supply_from_value,
                     supply_to_dict)
from ..errors import ConfigError, describe, shorten
from .covariance import covariance_from_value
from .losses import loss_from_dict
from .declared import effects_from_value, effects_to_list
from ..gcode import gcode_from_dict, gcode_to_dict, travel_from_value
from .rotary import check_rotary_stacking, rotary_axis_from_value, rotary_axis_to_dict
from .spec import (AXIS_NAMES, AxisSpec, BRAKING_MODES, DIRECT_SCREW, InertiaSpec, LimitSpec,
                   Machine, PlannerSettings, PROFILES, ROTARY_AXIS_NAMES, ScrewSpec,
                   STEEL_DENSITY_KG_M3, TRANSMISSIONS)
from ..safeyaml import load_yaml_file

__all__ = ['load_machine', 'machine_from_dict', 'machine_to_dict']


# Accepted ranges of values that the dynamics divide by or raise to powers: far outside any
# machine tool, and narrow enough that no simulated quantity can overflow (docs/measured.md).
_LIMIT_RANGES = ((1.0e-3, 1.0e3), (1.0e-3, 1.0e5), (1.0e-3, 1.0e8))


def _screw(d: Any, *, file: str, key: str) -> ScrewSpec:
    d = _mapping(d, file=file, key=key, allowed=('diameter_m', 'lead_m', 'length_m', 'starts',
                                                 'efficiency', 'density_kg_m3'))
    starts = d.get('starts', 1)
    if isinstance(starts, bool) or not isinstance(starts, int) or starts < 1:
        msg = f'expected a whole number >= 1, got {describe(starts)}'
        raise ConfigError(msg, file=file, key=_join(key, 'starts'))
    return ScrewSpec(
        diameter_m=_float(d, 'diameter_m', file=file, key=key, minimum=0.0, maximum=10.0),
        lead_m=_float(d, 'lead_m', file=file, key=key, minimum=1.0e-6, strict=False,
                      maximum=10.0),
        length_m=_float(d, 'length_m', file=file, key=key, minimum=0.0, maximum=1.0e3),
        starts=starts,
        efficiency=_float(d, 'efficiency', file=file, key=key, default=1.0, minimum=0.01,
                          strict=False, maximum=1.0),
        density_kg_m3=_float(d, 'density_kg_m3', file=file, key=key,
                             default=STEEL_DENSITY_KG_M3, minimum=0.0, maximum=1.0e5))


def _inertias(d: Any, *, file: str, key: str) -> InertiaSpec:
    d = _mapping(d, file=file, key=key,
                 allowed=('motor_kg_m2', 'coupling_kg_m2', 'screw_kg_m2'))
    screw = None
    if d.get('screw_kg_m2') is not None:
        screw = _float(d, 'screw_kg_m2', file=file, key=key, minimum=0.0, strict=False,
                       maximum=1.0e3)
    return InertiaSpec(
        motor_kg_m2=_float(d, 'motor_kg_m2', file=file, key=key, minimum=0.0, strict=False,
                           maximum=1.0e3),
        coupling_kg_m2=_float(d, 'coupling_kg_m2', file=file, key=key, default=0.0,
                              minimum=0.0, strict=False, maximum=1.0e3),
        screw_kg_m2=screw)


def _limits(d: Any, *, file: str, key: str) -> LimitSpec:
    names = ('velocity_m_s', 'acceleration_m_s2', 'jerk_m_s3')
    d = _mapping(d, file=file, key=key, allowed=names)
    return LimitSpec(*(_float(d, n, file=file, key=key, minimum=low, strict=False, maximum=high)
                       for n, (low, high) in zip(names, _LIMIT_RANGES)))


def _axis(name: Any, d: Any, *, file: str) -> AxisSpec:
    key = f'axes.{shorten(str(name))}'
    if name not in AXIS_NAMES:
        msg = f'unknown axis name {shorten(str(name))!r}; expected one of {", ".join(AXIS_NAMES)}'
        raise ConfigError(msg, file=file, key=key)
    if name in ROTARY_AXIS_NAMES:
        rides = _choice(_mapping(d, file=file, key=key, allowed=None), 'rides_on',
                        AXIS_NAMES + (None,), file=file, key=key, default=None)
        return rotary_axis_from_value(name, d, file=file, rides_on=rides)
    allowed = ('table_mass_kg', 'rides_on', 'inclination_deg', 'screw', 'inertias', 'limits',
               'loss', 'travel_m', 'loss_calibrated', 'loss_covariance', 'drive',
               'standstill_hold_n', 'transmission', 'counterbalance_n')
    d = _mapping(d, file=file, key=key, allowed=allowed)
    direct = _choice(d, 'transmission', TRANSMISSIONS, file=file, key=key,
                     default='screw') == 'direct'
    if direct:
        # a linear motor or force-measuring stand: no screw, no rotating inertia
        for part in ('screw', 'inertias'):
            if part in d:
                msg = (f'a direct axis (transmission: direct) has no {part}; remove the '
                       'section (the moving part of a linear motor belongs in table_mass_kg)')
                raise ConfigError(msg, file=file, key=f'{key}.{part}')
    for part in (('limits', 'loss') if direct else ('screw', 'inertias', 'limits', 'loss')):
        if part not in d:
            msg = 'missing required section'
            if part == 'screw':
                msg += ' (or transmission: direct for an axis without a screw)'
            raise ConfigError(msg, file=file, key=f'{key}.{part}')
    rides_on = _choice(d, 'rides_on', AXIS_NAMES + (None,), file=file, key=key, default=None)
    loss = loss_from_dict(d['loss'], file=file, key=f'{key}.loss')
    return AxisSpec(
        name=name,
        table_mass_kg=_float(d, 'table_mass_kg', file=file, key=key, minimum=0.0, strict=False,
                             maximum=1.0e6),
        screw=DIRECT_SCREW if direct else _screw(d['screw'], file=file, key=f'{key}.screw'),
        inertias=(InertiaSpec(motor_kg_m2=0.0, coupling_kg_m2=0.0, screw_kg_m2=0.0) if direct
                  else _inertias(d['inertias'], file=file, key=f'{key}.inertias')),
        direct=direct,
        limits=_limits(d['limits'], file=file, key=f'{key}.limits'),
        loss=loss, rides_on=rides_on,
        inclination_deg=_float(d, 'inclination_deg', file=file, key=key, default=0.0,
                               minimum=-90.0, strict=False, maximum=90.0),
        travel_m=travel_from_value(d.get('travel_m'), file=file, key=f'{key}.travel_m'),
        loss_calibrated=calibrated_from_value(d.get('loss_calibrated'), file=file,
                                              key=f'{key}.loss_calibrated'),
        loss_covariance=covariance_from_value(d.get('loss_covariance'), loss=loss, file=file,
                                              key=f'{key}.loss_covariance'),
        drive=drive_from_value(d.get('drive'), file=file, key=f'{key}.drive'),
        standstill_hold_n=_float(d, 'standstill_hold_n', file=file, key=key, default=0.0,
                                 minimum=0.0, strict=False, maximum=1.0e6),
        counterbalance_n=_counterbalance(d, file=file, key=key))


def _counterbalance(d: dict, *, file: str, key: str) -> float:
    value = _float(d, 'counterbalance_n', file=file, key=key, default=0.0, minimum=0.0,
                   strict=False, maximum=1.0e7)
    incl = d.get('inclination_deg', 0.0)
    if value > 0.0 and isinstance(incl, (int, float)) and float(incl) == 0.0:
        msg = ('a counterbalance acts against the weight along an inclined axis; this axis '
               'is horizontal (inclination_deg 0)')
        raise ConfigError(msg, file=file, key=f'{key}.counterbalance_n')
    return value


def _check_stacking(axes: tuple[AxisSpec, ...], *, file: str) -> None:
    names = {a.name: a for a in axes}
    for spec in axes:
        key = f'axes.{spec.name}.rides_on'
        if spec.rides_on is None:
            continue
        if spec.rides_on not in names:
            msg = f'axis {spec.rides_on!r} is not defined in axes'
            raise ConfigError(msg, file=file, key=key)
        chain = [spec.name]
        current: str | None = spec.rides_on
        while current is not None:
            if current in chain:
                msg = f'axes ride on each other in a loop: {" -> ".join(chain + [current])}'
                raise ConfigError(msg, file=file, key=key)
            chain.append(current)
            current = names[current].rides_on


def machine_from_dict(d: Any, *, file: str = '<dict>') -> Machine:
    """Build and validate a :class:`Machine` from its YAML form.

    Parameters
    ----------
    d
        The mapping read from a machine file.
    file
        Where it came from, for error messages.

    Returns
    -------
    Machine
        The validated machine.

    Raises
    ------
    ConfigError
        A missing, invalid or unknown value; the message names ``file`` and the dotted key.
    """
    d = _mapping(d, file=file, key='',
                 allowed=('name', 'braking', 'load_axis', 'planner', 'axes', 'effects',
                          'home_m', 'gcode', 'supply'))
    name = d.get('name', Path(file).stem)
    if not isinstance(name, str) or not name:
        msg = f'expected a non-empty string, got {describe(name)}'
        raise ConfigError(msg, file=file, key='name')
    # axis names are checked one by one in _axis, with a message naming the axis
    axes_d = _mapping(d.get('axes'), file=file, key='axes', allowed=None)
    if not axes_d:
        msg = 'expected at least one axis'
        raise ConfigError(msg, file=file, key='axes')
    axes = tuple(_axis(n, v, file=file) for n, v in axes_d.items())
    _check_stacking(axes, file=file)
    check_rotary_stacking(axes, file=file)
    supply = supply_from_value(d.get('supply'), file=file)
    check_drives({a.name: a.drive for a in axes}, supply, file=file)
    planner_d = _mapping(d.get('planner', {}), file=file, key='planner',
                         allowed=('profile', 'corner_tolerance_m', 'rate_hz', 'cycle_s'))
    planner = PlannerSettings(
        profile=_choice(planner_d, 'profile', PROFILES, file=file, key='planner',
                        default='jerk'),
        corner_tolerance_m=_float(planner_d, 'corner_tolerance_m', file=file, key='planner',
                                  default=1.0e-4, minimum=0.0, strict=False, maximum=1.0),
        rate_hz=_float(planner_d, 'rate_hz', file=file, key='planner', default=1000.0,
                       minimum=0.0, maximum=1.0e6),
        cycle_s=_float(planner_d, 'cycle_s', file=file, key='planner', default=1.0e-3,
                       minimum=0.0, maximum=10.0))
    return Machine(
        name=name,
        axes=axes,
        braking=_choice(d, 'braking', BRAKING_MODES, file=file, key=''),
        load_axis=_choice(d, 'load_axis', tuple(a.name for a in axes), file=file, key=''),
        planner=planner,
        effects=effects_from_value(d.get('effects'), tuple(a.name for a in axes), file=file),
        home_m=_home(d.get('home_m'), tuple(a.name for a in axes if a.rotary is None),
                     file=file),
        gcode=gcode_from_dict(d.get('gcode'), file=file),
        supply=supply)


def _home(value: Any, axis_names: tuple[str, ...], *,
          file: str) -> tuple[tuple[str, float], ...]:
    if value is None:
        return ()
    home_d = _mapping(value, file=file, key='home_m', allowed=axis_names)
    return tuple((a, _float(home_d, a, file=file, key='home_m', strict=False,
                            minimum=-1.0e3, maximum=1.0e3))
                 for a in axis_names if a in home_d)


def load_machine(path: str | Path) -> Machine:
    """Read and validate a machine YAML file.

    Parameters
    ----------
    path
        The file.

    Returns
    -------
    Machine
        The validated machine.

    Raises
    ------
    ConfigError
        Unreadable file, YAML syntax error, or any invalid value (named by dotted key).
    """
    file = str(path)
    data = load_yaml_file(path, error=ConfigError, what='machine file')
    return machine_from_dict(data, file=file)


def machine_to_dict(machine: Machine) -> dict[str, Any]:
    """Return the YAML form of ``machine`` (``machine_from_dict`` of it gives it back).

    Parameters
    ----------
    machine
        The machine.

    Returns
    -------
    dict
        Plain Python types only, ready for ``yaml.safe_dump``.
    """
    axes: dict[str, Any] = {}
    for a in machine.axes:
        if a.rotary is not None:
            axes[a.name] = rotary_axis_to_dict(a)
            continue
        inertias: dict[str, Any] = {'motor_kg_m2': a.inertias.motor_kg_m2,
                                    'coupling_kg_m2': a.inertias.coupling_kg_m2}
        if a.inertias.screw_kg_m2 is not None:
            inertias['screw_kg_m2'] = a.inertias.screw_kg_m2
        transmission: dict[str, Any] = {'transmission': 'direct'} if a.direct else {
            'screw': {'diameter_m': a.screw.diameter_m, 'lead_m': a.screw.lead_m,
                      'length_m': a.screw.length_m, 'starts': a.screw.starts,
                      'efficiency': a.screw.efficiency,
                      'density_kg_m3': a.screw.density_kg_m3},
            'inertias': inertias}
        axes[a.name] = {
            'table_mass_kg': a.table_mass_kg,
            'rides_on': a.rides_on,
            'inclination_deg': a.inclination_deg,
            **transmission,
            'limits': {'velocity_m_s': a.limits.velocity_m_s,
                       'acceleration_m_s2': a.limits.acceleration_m_s2,
                       'jerk_m_s3': a.limits.jerk_m_s3},
            'loss': dict(a.loss.to_dict()),
        }
        if a.travel_m is not None:
            axes[a.name]['travel_m'] = [float(v) for v in a.travel_m]
        if a.standstill_hold_n:
            axes[a.name]['standstill_hold_n'] = float(a.standstill_hold_n)
        if a.counterbalance_n:
            axes[a.name]['counterbalance_n'] = float(a.counterbalance_n)
        if a.loss_calibrated is not None:
            axes[a.name]['loss_calibrated'] = a.loss_calibrated.to_dict()
        if a.drive is not None:
            axes[a.name]['drive'] = drive_to_dict(a.drive)
        if a.loss_covariance is not None:
            axes[a.name]['loss_covariance'] = a.loss_covariance.to_dict()
    out: dict[str, Any] = {
        'name': machine.name,
        'braking': machine.braking,
        'load_axis': machine.load_axis,
        'planner': {'profile': machine.planner.profile,
                    'corner_tolerance_m': machine.planner.corner_tolerance_m,
                    'rate_hz': machine.planner.rate_hz,
                    'cycle_s': machine.planner.cycle_s},
        'axes': axes,
    }
    if machine.home_m:
        out['home_m'] = {a: float(v) for a, v in machine.home_m}
    gcode = gcode_to_dict(machine.gcode)
    if gcode is not None:
        out['gcode'] = gcode
    if machine.supply is not None:
        out['supply'] = supply_to_dict(machine.supply)
    if machine.effects:
        # only when present, so that the paper's model keeps its plain form
        out['effects'] = effects_to_list(machine.effects)
    return out
