"""The electrical side of a machine config: motor and drive per axis, the supply.

A machine file may declare, from data-sheet values (all optional; ``docs/electrical.md``)::

    supply:                        # machine level; needs a drive on every axis
      standby_w: 40.0              # cabinet: control, fans, line module at idle [W]
      measured_at: motor           # the meter's point: motor (terminals) or supply (grid)
    axes:
      X:
        drive:
          kt_nm_a: 1.1             # torque constant [N·m/A] per rms phase current
          resistance_ohm: 2.6      # winding resistance [ohm] ...
          resistance_between: terminals   # ... between two terminals (or: phase)
          iron: {no_load_w: 20.0, speed_rpm: 3000.0, eddy_share: 0.5}
          # or: iron: {k_h_w_s_rad: 0.03, k_e_w_s2_rad2: 1.0e-4}
          standby_w: 12.0          # the drive's own electronics [W]
          converter_efficiency: 0.95
          regeneration_limit_w: 300.0   # braking power the drive returns at most [W]

Copper loss of a three-phase winding with sinusoidal currents of rms value ``I = |M|/kt``:
``P_cu = 3·R_phase·I²``, or ``1.5·R_terminals·I²`` with the resistance measured between two
terminals (IEC 60034-2-1, stator I²R loss ``P_s = 1.5·I²·R``; the same for star and delta
connection). Servo data sheets list the resistance between terminals (phase-to-phase); a
per-phase value is marked ``resistance_between: phase``.

Iron loss ``P_fe = k_h·|omega| + k_e·omega²`` (hysteresis, eddy currents; the catalog's
``iron`` effect). Given as a no-load power ``P0`` at a speed ``n0``, the split between the
two is ``eddy_share``: ``k_e·omega0² = eddy_share·P0``, ``k_h·omega0 = (1 - eddy_share)·P0``.

This module parses and holds the values (:class:`DriveSpec`, :class:`SupplySpec`); the
power model is :mod:`.electrical`. Errors are :class:`~.errors.ConfigError` naming the file
and the dotted key.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any

from ..configcheck import check_choice, check_float, check_mapping, join_key
from ..errors import ConfigError

__all__ = ['DriveSpec', 'IronSpec', 'SupplySpec', 'RESISTANCE_BETWEEN', 'MEASURED_AT',
           'COPPER_FACTOR', 'drive_from_value', 'drive_to_dict', 'supply_from_value',
           'supply_to_dict', 'check_drives']

RESISTANCE_BETWEEN = ('terminals', 'phase')
COPPER_FACTOR = {'terminals': 1.5, 'phase': 3.0}
"""``P_cu = factor·R·I²`` for a three-phase winding (IEC 60034-2-1: ``1.5·I²·R`` with ``R``
between terminals; ``3·I²·R_phase`` per phase)."""
MEASURED_AT = ('motor', 'supply')
_BIG = 1.0e6          # upper bound of powers [W] and coefficients: far beyond a feed drive


@dataclass(frozen=True)
class IronSpec:
    """Iron loss ``k_h·|omega| + k_e·omega²`` and, when given so, the no-load figure.

    Attributes
    ----------
    k_h_w_s_rad, k_e_w_s2_rad2
        Hysteresis [W·s/rad] and eddy-current [W·s²/rad²] coefficients.
    no_load
        ``(no_load_w, speed_rpm, eddy_share)`` when the file gave a no-load power, else
        ``None`` (kept to write the file back as it was given).
    """

    k_h_w_s_rad: float = 0.0
    k_e_w_s2_rad2: float = 0.0
    no_load: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class DriveSpec:
    """Motor and drive (servo amplifier) of one axis, from data-sheet values.

    Attributes
    ----------
    kt_nm_a
        Torque constant [N·m/A], torque per rms phase current.
    resistance_ohm
        Winding resistance [ohm], measured as ``resistance_between`` says.
    resistance_between
        ``'terminals'`` (phase-to-phase, as data sheets give it) or ``'phase'``.
    iron
        Iron loss (:class:`IronSpec`).
    standby_w
        The drive's own consumption whatever the motion [W].
    converter_efficiency
        Efficiency of the drive's converter, ``0.01 <= eta_c <= 1``: motoring it takes
        ``P/eta_c`` for ``P`` at the motor, braking it returns ``P·eta_c``.
    regeneration_limit_w
        Largest braking power the drive returns [W] (beyond it the brake chopper burns it);
        ``None``: no limit. Applies with ``braking: regenerative``; ``dissipated`` returns
        nothing.
    """

    kt_nm_a: float
    resistance_ohm: float
    resistance_between: str
    iron: IronSpec = IronSpec()
    standby_w: float = 0.0
    converter_efficiency: float = 1.0
    regeneration_limit_w: float | None = None

    @property
    def copper_k_w_nm2(self) -> float:
        """``P_cu / M²`` [W/(N·m)²]: ``factor·R/kt²`` (:data:`COPPER_FACTOR`)."""
        return COPPER_FACTOR[self.resistance_between] * self.resistance_ohm / self.kt_nm_a ** 2


@dataclass(frozen=True)
class SupplySpec:
    """What the axes' drives share: the cabinet's standby and where the meter sits.

    Attributes
    ----------
    standby_w
        Cabinet standby (control, fans, line module at idle) [W], not tied to an axis.
    measured_at
        ``'motor'``: between converter and motor, as the paper measured; ``'supply'``: the
        grid side of the drives (converter losses, standby, braking rule included).
    """

    standby_w: float = 0.0
    measured_at: str = 'motor'


def _iron(value: Any, *, file: str, key: str) -> IronSpec:
    if value is None:
        return IronSpec()
    coeffs = ('k_h_w_s_rad', 'k_e_w_s2_rad2')
    no_load = ('no_load_w', 'speed_rpm', 'eddy_share')
    d = check_mapping(value, file=file, key=key, allowed=coeffs + no_load)
    if any(n in d for n in coeffs) and any(n in d for n in no_load):
        msg = ('give the iron loss either as coefficients (k_h_w_s_rad, k_e_w_s2_rad2) or as '
               'a no-load power (no_load_w, speed_rpm, eddy_share), not both')
        raise ConfigError(msg, file=file, key=key)
    if any(n in d for n in no_load):
        p0 = check_float(d, 'no_load_w', file=file, key=key, minimum=0.0, strict=False,
                         maximum=_BIG)
        rpm = check_float(d, 'speed_rpm', file=file, key=key, minimum=1.0, strict=False,
                          maximum=_BIG)
        share = check_float(d, 'eddy_share', file=file, key=key, default=0.5, minimum=0.0,
                            strict=False, maximum=1.0)
        w0 = rpm * 2.0 * math.pi / 60.0
        return IronSpec(k_h_w_s_rad=(1.0 - share) * p0 / w0,
                        k_e_w_s2_rad2=share * p0 / (w0 * w0), no_load=(p0, rpm, share))
    k_h, k_e = (check_float(d, n, file=file, key=key, default=0.0, minimum=0.0,
                            strict=False, maximum=_BIG) for n in coeffs)
    return IronSpec(k_h, k_e)


def drive_from_value(value: Any, *, file: str, key: str) -> DriveSpec | None:
    """The ``axes.<A>.drive`` block (``None`` when absent).

    Raises
    ------
    ConfigError
        A missing or unknown key, a value out of its physical bounds (no negative
        resistance or loss, efficiency in [0.01, 1]); the message names the dotted key.
    """
    if value is None:
        return None
    d = check_mapping(value, file=file, key=key,
                      allowed=('kt_nm_a', 'resistance_ohm', 'resistance_between', 'iron',
                               'standby_w', 'converter_efficiency', 'regeneration_limit_w'))
    limit = None
    if d.get('regeneration_limit_w') is not None:
        limit = check_float(d, 'regeneration_limit_w', file=file, key=key, minimum=0.0,
                            strict=False, maximum=_BIG)
    return DriveSpec(
        kt_nm_a=check_float(d, 'kt_nm_a', file=file, key=key, minimum=1.0e-4, strict=False,
                            maximum=1.0e3),
        resistance_ohm=check_float(d, 'resistance_ohm', file=file, key=key, minimum=0.0,
                                   strict=False, maximum=1.0e4),
        resistance_between=check_choice(d, 'resistance_between', RESISTANCE_BETWEEN,
                                        file=file, key=key),
        iron=_iron(d.get('iron'), file=file, key=join_key(key, 'iron')),
        standby_w=check_float(d, 'standby_w', file=file, key=key, default=0.0, minimum=0.0,
                              strict=False, maximum=_BIG),
        converter_efficiency=check_float(d, 'converter_efficiency', file=file, key=key,
                                         default=1.0, minimum=0.01, strict=False,
                                         maximum=1.0),
        regeneration_limit_w=limit)


def supply_from_value(value: Any, *, file: str) -> SupplySpec | None:
    """The machine-level ``supply`` block (``None`` when absent).

    Raises
    ------
    ConfigError
        An unknown key, a negative standby, an unknown ``measured_at``.
    """
    if value is None:
        return None
    d = check_mapping(value, file=file, key='supply', allowed=('standby_w', 'measured_at'))
    return SupplySpec(
        standby_w=check_float(d, 'standby_w', file=file, key='supply', default=0.0,
                              minimum=0.0, strict=False, maximum=_BIG),
        measured_at=check_choice(d, 'measured_at', MEASURED_AT, file=file, key='supply',
                                 default='motor'))


def check_drives(drives: dict[str, DriveSpec | None], supply: SupplySpec | None, *,
                 file: str) -> None:
    """All axes or none: the electrical model needs a drive on every axis once one is given.

    Raises
    ------
    ConfigError
        Naming the first axis without ``drive``.
    """
    if supply is None and not any(d is not None for d in drives.values()):
        return
    for name, drive in drives.items():
        if drive is None:
            why = 'a supply block' if supply is not None else 'another axis'
            msg = (f'missing: {why} declares the electrical side, which needs a drive on '
                   'every axis')
            raise ConfigError(msg, file=file, key=f'axes.{name}.drive')


def drive_to_dict(drive: DriveSpec) -> dict[str, Any]:
    """The YAML form of ``drive`` (:func:`drive_from_value` of it gives it back)."""
    iron = drive.iron
    if iron.no_load is not None:
        p0, rpm, share = iron.no_load
        iron_d = {'no_load_w': p0, 'speed_rpm': rpm, 'eddy_share': share}
    else:
        iron_d = {'k_h_w_s_rad': iron.k_h_w_s_rad, 'k_e_w_s2_rad2': iron.k_e_w_s2_rad2}
    out: dict[str, Any] = {'kt_nm_a': drive.kt_nm_a, 'resistance_ohm': drive.resistance_ohm,
                           'resistance_between': drive.resistance_between, 'iron': iron_d,
                           'standby_w': drive.standby_w,
                           'converter_efficiency': drive.converter_efficiency}
    if drive.regeneration_limit_w is not None:
        out['regeneration_limit_w'] = drive.regeneration_limit_w
    return out


def supply_to_dict(supply: SupplySpec) -> dict[str, Any]:
    """The YAML form of ``supply``."""
    return {'standby_w': supply.standby_w, 'measured_at': supply.measured_at}
