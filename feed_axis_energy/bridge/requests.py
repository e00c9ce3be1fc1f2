"""Checks of what a cell client sends before it reaches the job service.

A program's path is the job service's to check (it knows the program root); what the bridge
refuses by itself is what no service should ever see: job ids that are empty, over-long or
carry control characters, program texts of that kind, loads that are not a finite mass in a
sensible range. Each check raises :class:`~feed_axis_energy.errors.RequestError` naming the
request and the argument; the bridges turn it into ``Accepted = false`` and its message.
"""
from __future__ import annotations

import math
from typing import Any

from ..errors import describe, RequestError, shorten

__all__ = ['check_job_id', 'check_load_kg', 'check_program', 'MAX_JOB_ID_CHARS',
           'MAX_LOAD_KG', 'MAX_PROGRAM_CHARS']

MAX_JOB_ID_CHARS = 64
"""Longest job id accepted [characters]."""

MAX_PROGRAM_CHARS = 4096
"""Longest program path accepted [characters] (PATH_MAX on Linux)."""

MAX_LOAD_KG = 10000.0
"""Default upper bound of a job's load [kg]; a bridge may be given a lower one."""


def _printable_text(value: Any, *, request: str, field: str, limit: int) -> str:
    if not isinstance(value, str):
        msg = f'expected text, got {describe(value)}'
        raise RequestError(msg, request=request, field=field)
    if not value:
        raise RequestError('must not be empty', request=request, field=field)
    if len(value) > limit:
        msg = f'has {len(value)} characters, at most {limit} are accepted'
        raise RequestError(msg, request=request, field=field)
    if not value.isprintable():
        bad = next(c for c in value if not c.isprintable())
        msg = (f'contains the non-printable character U+{ord(bad):04X} '
               f'in {shorten(ascii(value))}')
        raise RequestError(msg, request=request, field=field)
    if value != value.strip():
        msg = f'starts or ends with white space: {shorten(repr(value))}'
        raise RequestError(msg, request=request, field=field)
    return value


def check_job_id(value: Any, *, request: str) -> str:
    """Return ``value`` if it is a job id: text of 1 to 64 printable characters.

    Parameters
    ----------
    value
        What the client sent.
    request
        The request's name for the message (``StartJob``).

    Raises
    ------
    RequestError
        Not text, empty, too long, a control character, white space at either end.
    """
    return _printable_text(value, request=request, field='JobId', limit=MAX_JOB_ID_CHARS)


def check_program(value: Any, *, request: str) -> str:
    """Return ``value`` if it can be a program path (the service checks where it points).

    Raises
    ------
    RequestError
        Not text, empty, longer than :data:`MAX_PROGRAM_CHARS`, a control character.
    """
    return _printable_text(value, request=request, field='Program', limit=MAX_PROGRAM_CHARS)


def check_load_kg(value: Any, *, request: str, max_kg: float = MAX_LOAD_KG) -> float:
    """Return ``value`` as a load [kg] if it is a finite number in ``[0, max_kg]``.

    Parameters
    ----------
    value
        What the client sent.
    request
        The request's name for the message.
    max_kg
        Largest load accepted [kg].

    Raises
    ------
    RequestError
        Not a number, NaN or infinite, negative, above ``max_kg``.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        msg = f'expected a load in kg (a number), got {describe(value)}'
        raise RequestError(msg, request=request, field='LoadKg')
    load = float(value)
    if not math.isfinite(load):
        msg = f'expected a finite load in kg, got {load!r}'
        raise RequestError(msg, request=request, field='LoadKg')
    if load < 0.0:
        msg = f'a load cannot be negative: {load:g} kg'
        raise RequestError(msg, request=request, field='LoadKg')
    if load > max_kg:
        msg = f'{load:g} kg is above the largest load accepted, {max_kg:g} kg'
        raise RequestError(msg, request=request, field='LoadKg')
    return load
