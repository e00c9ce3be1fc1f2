"""Is a program written for a Sinumerik control? What the file itself says.

A program is taken as Sinumerik when its name ends in ``.MPF`` or ``.SPF`` (either case: the
control's main program and subprogram types), when a line before the first motion is a
``%_N_NAME_MPF`` / ``%_N_NAME_SPF`` header (the control's archive format), or when one of its
first lines sets ``G710`` or ``G700`` (units that only Siemens controls have).
"""
from __future__ import annotations

from os import PathLike
from pathlib import Path
import re

__all__ = ['siemens_evidence', 'SNIFF_LINES']

SNIFF_LINES = 50
"""Lines at the top of a program that are looked at."""

_HEADER_RE = re.compile(r'\s*%_N_\w+_(MPF|SPF)\b', re.IGNORECASE)
_UNITS_RE = re.compile(r'(?<![A-Z0-9.])G7[01]0(?![0-9.])', re.IGNORECASE)


def siemens_evidence(name: str | PathLike[str], head: str) -> str | None:
    """Why the program looks like a Sinumerik program, or ``None``.

    Parameters
    ----------
    name
        The program's file name (only its suffix is used).
    head
        Its first lines (at most :data:`SNIFF_LINES` are looked at).

    Returns
    -------
    str or None
        For example ``'the file suffix .MPF'`` or ``'G710 on line 9'``.
    """
    suffix = Path(str(name)).suffix
    if suffix.upper() in ('.MPF', '.SPF'):
        return f'the file suffix {suffix}'
    for number, line in enumerate(head.splitlines()[:SNIFF_LINES], 1):
        code = line.split(';', 1)[0]
        if _HEADER_RE.match(code):
            return f'the header {code.strip()[:40]} on line {number}'
        m = _UNITS_RE.search(code)
        if m is not None and '(' not in code[:m.start()]:
            return f'{m.group(0).upper()} on line {number}'
    return None
