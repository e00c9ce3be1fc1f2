"""The unit the reading half of the interpreter hands to the modal half: one :class:`Block`.

A block is one executed source line with its words evaluated (parameters substituted,
expressions computed). Control lines (O-words, ``M98``/``M99``) and parameter assignments
never become blocks: :mod:`.flow` executes them itself.
"""
from __future__ import annotations

from typing import NamedTuple

__all__ = ['Block']


class Block(NamedTuple):
    """One executed line of a program.

    Attributes
    ----------
    line
        1-based line number in ``file``.
    words
        ``(letter, value)`` pairs in the order written; letters upper case, values
        evaluated floats (finite, magnitude at most :data:`.expr.MAX_MAGNITUDE`).
    file
        The file the line comes from (a subroutine file may differ from the program).
    text
        The raw source line, for locating a word's column in an error message.
    main_line
        The line of the main program this block is attributed to: its own line when it is in
        the main program file, otherwise the line of the outermost ``call``/``M98``.
    """

    line: int
    words: list[tuple[str, float]]
    file: str
    text: str
    main_line: int
