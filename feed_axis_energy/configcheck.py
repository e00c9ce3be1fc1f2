"""Validation helpers for configuration mappings read from YAML.

Shared by :mod:`.machine` and :mod:`feed_axis_energy.gcode.settings`; each raises
:class:`~.errors.ConfigError` naming the file and the dotted key.
"""
from __future__ import annotations

from collections.abc import Mapping
import math
from typing import Any

from .errors import ConfigError, describe, shorten

__all__ = ['REQUIRED', 'join_key', 'is_finite_number', 'check_mapping', 'check_float',
           'check_choice']

REQUIRED = object()
"""Default marking a value that must be present."""


def join_key(key: str, name: str) -> str:
    """Return the dotted key ``key.name`` (``name`` alone at the top level)."""
    return f'{key}.{name}' if key else name


def is_finite_number(value: Any) -> bool:
    """True for an int or float (not bool) that is a finite float."""
    if isinstance(value, bool):
        return False
    if isinstance(value, int):
        # math.isfinite(10**400) raises OverflowError instead of answering
        return value.bit_length() <= 1000
    return isinstance(value, float) and math.isfinite(value)


def check_mapping(value: Any, *, file: str, key: str,
                  allowed: tuple[str, ...] | None) -> Mapping[str, Any]:
    """Return ``value`` if it is a mapping whose keys are all ``allowed`` (None: any key).

    Raises
    ------
    ConfigError
        Not a mapping, or an unknown key (named with its dotted path).
    """
    if not isinstance(value, Mapping):
        msg = f'expected a mapping, got {describe(value)}'
        raise ConfigError(msg, file=file, key=key or '<top>')
    for name in value:
        if allowed is not None and name not in allowed:
            msg = f'unknown key {shorten(str(name))!r}; expected one of {", ".join(allowed)}'
            raise ConfigError(msg, file=file, key=join_key(key, shorten(str(name))))
    return value


def check_float(d: Mapping[str, Any], name: str, *, file: str, key: str,
                default: Any = REQUIRED, minimum: float | None = None, strict: bool = True,
                maximum: float | None = None) -> float:
    """Return ``d[name]`` as a finite float within the bounds, or ``default`` if absent.

    Raises
    ------
    ConfigError
        Missing (without a default), not a finite number, or out of range.
    """
    where = join_key(key, name)
    if name not in d:
        if default is REQUIRED:
            msg = 'missing required value; expected a number'
            raise ConfigError(msg, file=file, key=where)
        return default
    value = d[name]
    if not is_finite_number(value):
        msg = f'expected a finite number, got {describe(value)}'
        raise ConfigError(msg, file=file, key=where)
    if minimum is not None and (value <= minimum if strict else value < minimum):
        msg = f'expected a number {">" if strict else ">="} {minimum}, got {describe(value)}'
        raise ConfigError(msg, file=file, key=where)
    if maximum is not None and value > maximum:
        msg = f'expected a number <= {maximum}, got {describe(value)}'
        raise ConfigError(msg, file=file, key=where)
    return float(value)


def check_choice(d: Mapping[str, Any], name: str, choices: tuple[Any, ...], *, file: str,
                 key: str, default: Any = REQUIRED) -> Any:
    """Return ``d[name]`` if it is one of ``choices``, or ``default`` if absent.

    Raises
    ------
    ConfigError
        Missing (without a default) or not one of the choices.
    """
    where = join_key(key, name)
    if name not in d:
        if default is REQUIRED:
            msg = f'missing required value; expected one of {", ".join(map(str, choices))}'
            raise ConfigError(msg, file=file, key=where)
        return default
    value = d[name]
    if value not in choices:
        shown = ', '.join('null' if c is None else str(c) for c in choices)
        msg = f'expected one of {shown}, got {describe(value)}'
        raise ConfigError(msg, file=file, key=where)
    return value
