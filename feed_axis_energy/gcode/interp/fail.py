"""How the interpreter's state classes fail when their caller gives no place.

:class:`.coords.Coords`, its parameter side (:mod:`.stored`) and its tool table
(:mod:`.tools`) take a ``fail`` callable, ``fail(message, letter)``, that raises the
:class:`~feed_axis_energy.errors.GcodeError` at the word ``letter`` of the line being run.
Used on their own (tests, a tool table read outside a program) they fail with
:func:`raise_unplaced`.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import NoReturn

from ...errors import GcodeError

__all__ = ['Fail', 'raise_unplaced']

Fail = Callable[[str, str], NoReturn]
"""``fail(message, letter)``: raise the error of ``message`` at the word ``letter``."""


def raise_unplaced(message: str, letter: str) -> NoReturn:
    """The default ``fail``: a :class:`GcodeError` without a place (``<program>``, line 0).

    ``letter`` is accepted for the :data:`Fail` signature and not used.
    """
    raise GcodeError(message, file='<program>', line=0, column=0)
