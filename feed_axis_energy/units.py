"""Conversion of user-typed units (mm/min, kW, ...) to SI, done once at the edge.

Every unit here is a pure scale factor to the SI unit of its quantity (no offsets, so no
temperatures). Spelling variants are normalised first: spaces are ignored, ``²`` and a
trailing ``2`` after ``s`` mean ``^2``, ``mm/s/s`` means ``mm/s^2``, ``·`` and ``*`` in
``N*m`` are optional.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .errors import ConfigError, DataError, shorten

__all__ = ['GRAVITY_M_S2', 'QUANTITIES', 'MAX_ABS_SI', 'check_si_values', 'known_units',
           'quantity_of', 'rate_from_interval', 'si_unit_of', 'to_si', 'ROTARY_AXIS_LETTERS',
           'axis_units']

_INCH_M = 0.0254

GRAVITY_M_S2 = 9.80665   # standard gravity [m/s^2] (CGPM 1901)
ROTARY_AXIS_LETTERS = ('A', 'B', 'C')
"""Axis names that are rotary (positions in rad): machine/rotary.py."""


def axis_units(axis: str) -> tuple[str, str, str]:
    """SI units of an axis's position, velocity and acceleration: ``('m', 'm/s', 'm/s^2')``
    for a linear axis, ``('rad', 'rad/s', 'rad/s^2')`` for a rotary one (A, B, C)."""
    if axis in ROTARY_AXIS_LETTERS:
        return 'rad', 'rad/s', 'rad/s^2'
    return 'm', 'm/s', 'm/s^2'


MAX_ABS_SI = 1.0e12
"""Largest magnitude a measured value may have in SI (1 TW, 10^12 m, m/s, A, V, s).

Far above anything a machine tool measures, and far enough below the float range that
squares, sums and integrals of such values stay finite."""

# quantity -> (SI unit, {unit: factor to SI})
QUANTITIES: dict[str, tuple[str, dict[str, float]]] = {
    'length': ('m', {'m': 1.0, 'cm': 1e-2, 'mm': 1e-3, 'um': 1e-6, 'in': _INCH_M}),
    'velocity': ('m/s', {
        'm/s': 1.0, 'mm/s': 1e-3, 'mm/min': 1e-3 / 60.0, 'm/min': 1.0 / 60.0,
        'in/min': _INCH_M / 60.0, 'in/s': _INCH_M,
    }),
    'acceleration': ('m/s^2', {'m/s^2': 1.0, 'mm/s^2': 1e-3}),
    'power': ('W', {'W': 1.0, 'kW': 1e3, 'mW': 1e-3}),
    'energy': ('J', {'J': 1.0, 'kJ': 1e3, 'Wh': 3600.0, 'kWh': 3.6e6}),
    'current': ('A', {'A': 1.0, 'mA': 1e-3}),
    'voltage': ('V', {'V': 1.0, 'kV': 1e3}),
    'time': ('s', {'s': 1.0, 'ms': 1e-3, 'us': 1e-6, 'ns': 1e-9, 'min': 60.0}),
    'mass': ('kg', {'kg': 1.0, 'g': 1e-3}),
    'force': ('N', {'N': 1.0, 'kN': 1e3}),
    'torque': ('N*m', {'N*m': 1.0, 'Nm': 1.0, 'kN*m': 1e3}),
}

_FACTOR: dict[str, tuple[str, float]] = {
    unit: (quantity, factor)
    for quantity, (_, table) in QUANTITIES.items()
    for unit, factor in table.items()
}


def _normalise(unit: str) -> str:
    text = str(unit).replace(' ', '').replace('\u00b2', '^2').replace('\u00b7', '*')
    text = text.replace('\u00b5', 'u').replace('\u03bc', 'u')
    if text.endswith('/s/s'):
        text = text[:-4] + '/s^2'
    elif text.endswith('/s2') or text.endswith('/sec2'):
        text = text[:text.rindex('/')] + '/s^2'
    elif text.endswith('/sec'):
        text = text[:-4] + '/s'
    return text


def known_units(quantity: str | None = None) -> tuple[str, ...]:
    """Units accepted for one quantity (or for all of them).

    Parameters
    ----------
    quantity
        A key of :data:`QUANTITIES` such as ``'power'``; ``None`` for every unit.

    Returns
    -------
    tuple of str
        Canonical unit spellings.
    """
    if quantity is None:
        return tuple(_FACTOR)
    _check_quantity(quantity)
    return tuple(QUANTITIES[quantity][1])


def _check_quantity(quantity: str) -> None:
    if quantity not in QUANTITIES:
        msg = f'unknown quantity {quantity!r}; expected one of {", ".join(QUANTITIES)}'
        raise ConfigError(msg, file='<units>')


def _lookup(unit: str, quantity: str | None) -> tuple[str, float]:
    if quantity is not None:
        _check_quantity(quantity)
    found = _FACTOR.get(_normalise(unit))
    if found is None or (quantity is not None and found[0] != quantity):
        if quantity is None:
            listing = '; '.join(f'{q}: {", ".join(t)}' for q, (_, t) in QUANTITIES.items())
            msg = f'unknown unit {shorten(str(unit))!r}; known units are {listing}'
        else:
            listing = ', '.join(QUANTITIES[quantity][1])
            msg = f'unknown {quantity} unit {shorten(str(unit))!r}; expected one of {listing}'
        raise ConfigError(msg, file='<units>')
    return found


def quantity_of(unit: str) -> str:
    """Name the quantity a unit measures (``'mm/min'`` -> ``'velocity'``).

    Parameters
    ----------
    unit
        A unit string.

    Returns
    -------
    str
        A key of :data:`QUANTITIES`.

    Raises
    ------
    ConfigError
        If the unit is unknown.
    """
    return _lookup(unit, None)[0]


def si_unit_of(unit: str, *, quantity: str | None = None) -> str:
    """The SI unit a value in ``unit`` is converted to (``'kW'`` -> ``'W'``).

    Parameters
    ----------
    unit
        A unit string.
    quantity
        If given, the unit must measure this quantity.

    Returns
    -------
    str
        The SI unit.

    Raises
    ------
    ConfigError
        If the unit is unknown or measures another quantity (the message lists the known
        units of the quantity).
    """
    return QUANTITIES[_lookup(unit, quantity)[0]][0]


def to_si(values: ArrayLike, unit: str, *, quantity: str | None = None) -> np.ndarray:
    """Convert values given in ``unit`` to SI.

    Parameters
    ----------
    values
        Scalar or array of numbers.
    unit
        Their unit, e.g. ``'mm/min'``, ``'kW'``, ``'mm/s/s'``.
    quantity
        If given, the unit must measure this quantity (``'power'``, ``'velocity'``, ...).

    Returns
    -------
    numpy.ndarray
        ``float64`` array of the same shape, in the SI unit (:func:`si_unit_of`).

    Raises
    ------
    ConfigError
        If the unit is unknown or of another quantity.
    """
    factor = _lookup(unit, quantity)[1]
    arr = np.asarray(values, dtype=np.float64)
    if factor == 1.0:
        return arr.copy()
    # overflow to inf is not warned about here: callers check the converted values
    with np.errstate(over='ignore'):
        return arr * factor


def check_si_values(values: np.ndarray, *, file: str, column: str,
                    rows: np.ndarray | None = None, topic: str = '') -> np.ndarray:
    """Check converted (SI) measured values: finite and within :data:`MAX_ABS_SI`.

    Done after the unit conversion, because a finite number in the file can become
    infinite on conversion (``1e307`` kW is ``inf`` W).

    Parameters
    ----------
    values
        SI values, shape ``(n,)``.
    file, column, topic
        Where they came from, for the error.
    rows
        1-based data row of each value (CSV) or ``None`` (sample numbers, counted from 1).

    Returns
    -------
    numpy.ndarray
        ``values`` unchanged.

    Raises
    ------
    DataError
        Naming file, column (or topic) and row of the first bad value.
    """
    bad = ~(np.abs(values) <= MAX_ABS_SI)  # NaN compares False: counted as bad
    if not bad.any():
        return values
    i = int(np.flatnonzero(bad)[0])
    row = int(rows[i]) if rows is not None else i + 1
    v = float(values[i])
    what = 'is not finite' if not np.isfinite(v) else f'is {v:.6g}'
    msg = (f'the value {what} after conversion to SI units; expected a finite magnitude of '
           f'at most {MAX_ABS_SI:g}')
    if topic:
        msg = f'sample {row}: {msg}'
        raise DataError(msg, file=file, topic=topic)
    raise DataError(msg, file=file, column=column, row=row)


def rate_from_interval(interval_s: float) -> float:
    """Sample rate [Hz] of a sample interval [s], without the float noise of ``1/dt``.

    Intervals are differences of float time stamps, so ``1 / 0.001`` may come out as
    ``1000.0000000001102``. The rate is rounded to 10 significant digits, far finer than any
    clock a machine or a meter keeps. Returns 0.0 for an interval that is not finite and
    positive (no rate to report).
    """
    interval = float(interval_s)
    if not (interval > 0.0) or interval == float('inf'):
        return 0.0
    return float(f'{1.0 / interval:.10g}')
