"""Lexical layer of the G-code parser: comments, words, code tables and error places.

Kept apart from :mod:`.gcode` (the interpreter) so each module stays small. Everything here
works on one source line at a time; columns are 1-based positions in the original line
(comments are blanked with spaces, never removed, so columns never shift).
"""
from __future__ import annotations

import re
from typing import Union

from .expr import Reader
from .params import ParameterError
from ..errors import GcodeError, shorten

__all__ = ['blank_comments', 'WORD_RE', 'LINE_RE', 'G_CODES', 'G_UNSUPPORTED', 'M_CODES',
           'ALLOWED_LETTERS', 'UNSUPPORTED_LETTERS', 'diagnose_line', 'locate_word',
           'read_items', 'Assignment']

# A number as LinuxCNC reads it: optional sign, digits and at most one point, and (like
# LinuxCNC) blanks anywhere inside; the value is validated by float() afterwards so that
# ``X1.2.3`` is reported as a bad number rather than as two words.
_NUM = r'[-+]?\s*[0-9.]+(?:\s+[0-9.]+)*'
WORD_RE = re.compile(r'([A-Z])\s*(' + _NUM + r')')
# The same language as a sequence of WORD_RE matches, written possessively: it only checks.
LINE_RE = re.compile(r'\s*+(?:[A-Z]\s*+[-+]?+\s*+[0-9.]++(?:\s++[0-9.]++)*+\s*+)*+')

# G codes keyed by round(10 * number): value is (modal group, argument).
G_CODES: dict[int, tuple[str, object]] = {
    0: ('motion', 0), 10: ('motion', 1), 20: ('motion', 2), 30: ('motion', 3),
    800: ('motion', None),
    40: ('nonmodal', 'dwell'), 90: ('nonmodal', 'exact'), 280: ('nonmodal', 'home'),
    170: ('plane', 17), 180: ('plane', 18), 190: ('plane', 19),
    200: ('units', 0.0254), 210: ('units', 0.001),
    900: ('distance', True), 910: ('distance', False),
    901: ('arc_distance', True), 911: ('arc_distance', False),
    930: ('feed_mode', True), 940: ('feed_mode', False),
    610: ('control', True), 611: ('control', True), 640: ('control', False),
    400: ('cutter', None), 430: ('tool_length', 'G43'), 490: ('tool_length', None),
    540: ('coord', 54), 550: ('coord', 55), 560: ('coord', 56), 570: ('coord', 57),
    580: ('coord', 58), 590: ('coord', 59),
    980: ('retract', None), 990: ('retract', None),
    960: ('spindle_mode', None), 970: ('spindle_mode', None),
    80: ('lathe', None),
}

# Codes we know and refuse, with the reason shown to the user.
G_UNSUPPORTED: dict[int, str] = {
    50: 'spline moves', 51: 'spline moves', 52: 'spline moves', 70: 'lathe diameter mode',
    100: 'G10 data setting', 281: 'setting the reference point',
    300: 'reference return', 301: 'reference return', 330: 'spindle-synchronised motion',
    331: 'rigid tapping', 382: 'probing', 383: 'probing', 384: 'probing', 385: 'probing',
    410: 'cutter radius compensation', 420: 'cutter radius compensation',
    411: 'cutter radius compensation', 421: 'cutter radius compensation',
    431: 'tool length offset from the tool table', 432: 'dynamic tool length offset',
    520: 'local coordinate offsets', 530: 'machine coordinate moves',
    730: 'canned cycles', 740: 'canned cycles', 760: 'canned cycles',
    **{c * 10: 'canned cycles' for c in range(81, 90)},
    920: 'coordinate offsets', 921: 'coordinate offsets', 922: 'coordinate offsets',
    923: 'coordinate offsets', 950: 'feed per revolution', 171: 'UVW planes',
    181: 'UVW planes', 191: 'UVW planes', 591: 'extra coordinate systems',
    592: 'extra coordinate systems', 593: 'extra coordinate systems',
}

# M codes keyed by integer: (group, action); ``None`` action means ignored for the feed axes.
M_CODES: dict[int, tuple[str, str | None]] = {
    0: ('stop', 'pause'), 1: ('stop', 'pause'), 2: ('stop', 'end'), 30: ('stop', 'end'),
    3: ('spindle', None), 4: ('spindle', None), 5: ('spindle', None),
    6: ('tool', None), 7: ('coolant', None), 8: ('coolant', None), 9: ('coolant', None),
}

# Letters the interpreter understands (D/H/L/Q and the extra axes are refused with a reason).
ALLOWED_LETTERS = frozenset('GMXYZIJKRFPSTNOQH')
UNSUPPORTED_LETTERS: dict[str, str] = {
    **{a: f'axis {a} is not supported (only X, Y, Z are simulated)' for a in 'ABCUVW'},
    'D': 'D words (cutter compensation) are not supported',
    'L': 'L words (G10, canned cycle repeats) are not supported',
}


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


_DIAG_WORD_RE = re.compile(r'\s*([A-Za-z])\s*(' + _NUM + r')?')


def diagnose_line(code: str, *, file: str, line: int) -> GcodeError:
    """Explain why a comment-free line is not a sequence of ``letter number`` words.

    Parameters
    ----------
    code
        The line with comments blanked (see :func:`blank_comments`).
    file, line
        The place.

    Returns
    -------
    GcodeError
        The error to raise, pointing at the first offending character.
    """
    stripped = code.lstrip()
    if stripped[:1] in ('O', 'o') and not re.fullmatch(r'[Oo]\s*\d+\s*', stripped):
        col = len(code) - len(stripped) + 1
        msg = 'O-word subroutines and control flow are not supported'
        return GcodeError(msg, file=file, line=line, column=col,
                          text=shorten(stripped.strip()))
    pos = 0
    n = len(code)
    while pos < n:
        m = _DIAG_WORD_RE.match(code, pos)
        if m is None or not m.group(0).strip():
            ws = len(code[pos:]) - len(code[pos:].lstrip())
            col = pos + ws
            if col >= n:
                break
            ch = code[col]
            if ch in '#[]':
                msg = 'parameters and expressions (#, [...]) are not supported'
            elif ch == ')':
                msg = '")" without an opening "("'
            elif ch.isdigit() or ch in '+-.':
                msg = 'number without a letter in front of it'
            else:
                msg = f'unexpected character {ch!r}; expected a letter (G, X, F, ...)'
            return GcodeError(msg, file=file, line=line, column=col + 1, text=code[col:col + 12])
        if m.group(2) is None:
            after = code[m.end():].lstrip()
            if after[:1] in ('#', '['):
                col = len(code) - len(after) + 1
                msg = 'parameters and expressions (#, [...]) are not supported'
                return GcodeError(msg, file=file, line=line, column=col, text=after[:12])
            col = m.start(1) + 1
            letter = m.group(1).upper()
            msg = f'expected a number after {letter!r}'
            return GcodeError(msg, file=file, line=line, column=col,
                              text=code[m.start(1):m.start(1) + 12].strip())
        pos = m.end()
    msg = 'cannot read this line'
    return GcodeError(msg, file=file, line=line, column=1, text=shorten(code.strip()))


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


def read_items(r: Reader) -> tuple[list[tuple[str, float]], list[Assignment]]:
    """Read the words and parameter assignments of a compacted line (not an O-word line).

    Parameters
    ----------
    r
        A reader positioned where the items start (see :mod:`.expr`).

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
            assigns.append((ref, r.checked(r.value(), at)))
        elif c == ')':
            raise r.error('")" without an opening "("', at)
        elif c.isdigit() or c in '+-.':
            raise r.error('number without a letter in front of it', at)
        else:
            raise r.error(f'unexpected character {c!r}; expected a letter (G, X, F, ...) '
                          'or a parameter assignment', at)
    return words, assigns
