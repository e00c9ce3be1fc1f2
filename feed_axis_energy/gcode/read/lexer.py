"""Lexical layer of the G-code reader: comments, words and error places.

Everything here works on one source line at a time; columns are 1-based positions in the
original line (comments are blanked with spaces, never removed, so columns never shift).
``LINE_RE``/``WORD_RE`` are the fast path for plain lines (letters and numbers only), and
``CONTOUR_RE`` splits the most common of them (a motion in the usual word order) at once;
:func:`read_items` reads any other line through :mod:`.expr`. The G/M code tables live in
:mod:`.codes` (the interpreter's).
"""
from __future__ import annotations

import re
from typing import Union

from .expr import Reader
from .params import ParameterError
from ...errors import GcodeError, shorten

__all__ = ['blank_comments', 'WORD_RE', 'LINE_RE', 'CONTOUR_RE', 'locate_word', 'read_items',
           'Assignment']

# A number as LinuxCNC reads it: optional sign, digits and at most one point, and (like
# LinuxCNC) blanks anywhere inside; the value is validated by float() afterwards so that
# ``X1.2.3`` is reported as a bad number rather than as two words.
_NUM = r'[-+]?\s*[0-9.]+(?:\s+[0-9.]+)*'
WORD_RE = re.compile(r'([A-Z])\s*(' + _NUM + r')')
# The plain lines the fast paths take (:mod:`.run`, :mod:`.flow`), written possessively: it
# only checks. Words of a letter and a number with at most one point, at most 12 integer
# digits and no blanks inside, so every value is below expr.MAX_MAGNITUDE (1e12) and finite.
# Anything else (a longer number, a bad one such as ``1.2.3``, LinuxCNC's blanks inside a
# number) goes to the full reader, which reads it or reports it at its column.
LINE_RE = re.compile(
    r'\s*+(?:[A-Z]\s*+[-+]?+\s*+(?:[0-9]{1,12}+(?:\.[0-9]*+)?+|\.[0-9]++)\s*+)*+')
# The usual CAM line, tokenised by the expression itself: an optional N word, an optional
# G0..G3 (or G00..G03), then X Y Z I J K R F, each at most once and in this order, with no
# blank between a letter and its number (``N10 G1 X1.5 Y-2 F300``, ``G2X1Y2I3J-4``). Every
# such line is a LINE_RE line and its groups are the texts WORD_RE reads (checked by
# test_lexer_contour): (G, X, Y, Z, I, J, K, R, F), ``None`` for a word not given. run.py
# gives a match to Interpreter.contour_line and any other line to the word reader.
_PLAIN_NUM = r'[-+]?+(?:[0-9]{1,12}+(?:\.[0-9]*+)?+|\.[0-9]++)'
CONTOUR_RE = re.compile(r'\s*+(?:N[0-9]{1,12}+\s*+)?+(?:G(0?[0-3])\s*+)?+' + ''.join(
    rf'(?:{letter}({_PLAIN_NUM})\s*+)?+' for letter in 'XYZIJKRF'))


def blank_comments(text: str, *, file: str, line: int) -> str:
    """Return ``text`` with comments replaced by blanks (same length up to a ``;`` comment).

    Parameters
    ----------
    text
        One source line.
    file, line
        The place, for errors.

    Returns
    -------
    str
        The code part; ``( ... )`` comments become spaces, a ``;`` comment is cut off.

    Raises
    ------
    GcodeError
        For an unclosed comment or a ``(`` inside a comment (LinuxCNC refuses nesting).
    """
    parts = []
    i = 0
    while True:
        p = text.find('(', i)
        q = text.find(';', i)
        if q != -1 and (p == -1 or q < p):
            parts.append(text[i:q])
            break
        if p == -1:
            parts.append(text[i:])
            break
        close = text.find(')', p + 1)
        if close == -1:
            msg = 'unclosed comment: "(" without ")" on the same line'
            raise GcodeError(msg, file=file, line=line, column=p + 1, text=text[p:p + 20])
        nested = text.find('(', p + 1, close)
        if nested != -1:
            msg = 'nested comment: "(" inside a comment'
            raise GcodeError(msg, file=file, line=line, column=nested + 1,
                             text=shorten(text[p:close + 1]))
        parts.append(text[i:p])
        parts.append(' ' * (close + 1 - p))
        i = close + 1
    return ''.join(parts)


def locate_word(code: str, letter: str, *, value: float | None = None,
                nth: int = 0) -> tuple[int, str]:
    """Find the 1-based column and text of a word, for error messages.

    Parameters
    ----------
    code
        The line with comments blanked.
    letter
        Upper-case letter of the word.
    value
        If given, only words whose number equals it count (to pick ``G91`` out of
        ``G90 G91``).
    nth
        Which of the matching words (0 = first).

    Returns
    -------
    tuple[int, str]
        Column (1 if not found) and the word's text (cut to about 60 characters).
    """
    k = 0
    for m in WORD_RE.finditer(code.upper()):
        if m.group(1) != letter:
            continue
        if value is not None:
            try:
                if float(re.sub(r'\s', '', m.group(2))) != value:
                    continue
            except ValueError:
                continue
        if k == nth:
            return m.start() + 1, shorten(code[m.start():m.end()])
        k += 1
    return 1, shorten(code.strip())


Assignment = tuple[Union[int, str], float]
"""A parameter assignment read from a line: ``(number or lower-case name, value)``."""


def read_items(r: Reader, *, open_assign: bool = False
               ) -> tuple[list[tuple[str, float]], list[Assignment]]:
    """Read the words and parameter assignments of a compacted line (not an O-word line).

    Parameters
    ----------
    r
        A reader positioned where the items start (see :mod:`.expr`).
    open_assign
        Fanuc macro B: the value of an assignment is an expression without brackets that
        runs to the end of the line (``#1 = #2 / 2 + 1``).

    Returns
    -------
    tuple[list[tuple[str, float]], list[Assignment]]
        The words ``(letter, value)`` in order (letters A-Z, and ``@``/``^``, LinuxCNC's
        polar radius and angle), and the assignments, which the caller
        applies after the line (RS274NGC: assignments on a line take effect after it).

    Raises
    ------
    GcodeError
        At the column of anything that is neither a word nor an assignment.
    """
    words: list[tuple[str, float]] = []
    assigns: list[Assignment] = []
    s = r.s
    n = len(s)
    while r.pos < n:
        at = r.pos
        c = s[at]
        if 'A' <= c <= 'Z' or c == '@' or c == '^':
            # '@' and '^' are LinuxCNC's polar words (radius, angle in degrees).
            r.pos += 1
            words.append((c, r.checked(r.value(), at)))
        elif c == '#':
            ref = r.parameter_ref()
            try:
                if isinstance(ref, int):
                    r.params.check_settable(ref)
                else:
                    r.params.check_settable_named(ref)
            except ParameterError as err:
                raise r.error(str(err), at) from None
            if r.peek() != '=':
                raise r.error('expected "=" after the parameter (an assignment such as '
                              '#1=2)')
            r.pos += 1
            value = r.expression(open_end=True) if open_assign else r.value()
            assigns.append((ref, r.checked(value, at)))
        elif c == ')':
            raise r.error('")" without an opening "("', at)
        elif c.isdigit() or c in '+-.':
            raise r.error('number without a letter in front of it', at)
        else:
            raise r.error(f'unexpected character {c!r}; expected a letter (G, X, F, ...) '
                          'or a parameter assignment', at)
    return words, assigns
