"""Reading one Sinumerik line: the code part, a scanner over it, and expressions.

A Siemens line is ``[/][N<n>|:<n>] [LABEL:] statement ; comment``. Unlike RS274NGC,
parentheses are part of expressions and calls (``X=(R1+2)*3``, ``CYCLE81(10,0,2,-5)``)
and ``;`` starts the only comment. Letters are read in upper case outside strings; only
ASCII letters are upper-cased, so every column of the code equals the column in the file.

Expressions (Sinumerik's NC language, "Job planning" manual): numbers (``1.5``, ``.5``,
``2EX3``), R parameters ``R1`` / ``R[2]``, the program's ``DEF`` variables, ``TRUE`` /
``FALSE``, ``+ - * /``, ``DIV`` (integer quotient), ``MOD``, comparisons ``== <> < > <= >=``,
``NOT AND OR XOR``, ``B_AND B_OR B_XOR B_NOT``, and the functions ``SIN COS TAN ASIN ACOS
ATAN2 SQRT POT ABS TRUNC ROUND ROUNDUP LN EXP MINVAL MAXVAL`` (angles in degrees).
"""
from __future__ import annotations

import math
from typing import Callable, NoReturn

from ...errors import GcodeError, shorten

__all__ = ['Scanner', 'code_part', 'MAX_MAGNITUDE', 'MAX_NESTING', 'FUNCTIONS']

MAX_MAGNITUDE = 1.0e12
"""Largest magnitude of a value in an expression (as the RS274NGC front's bound)."""
MAX_NESTING = 32
"""Parentheses, function calls and signs nested in one expression (a bound of the reader)."""

_UPPER = {c: c - 32 for c in range(ord('a'), ord('z') + 1)}
_UPPER_TAB = {**_UPPER, ord('\t'): ord(' ')}
_IDENT_START = frozenset('ABCDEFGHIJKLMNOPQRSTUVWXYZ_')
_IDENT = frozenset('ABCDEFGHIJKLMNOPQRSTUVWXYZ_0123456789')
_DIGITS = frozenset('0123456789')


def code_part(raw: str) -> str:
    """The code of a line: the ``;`` comment cut off (a ``;`` inside a string stays), ASCII
    letters upper-cased outside strings, tabs made blanks; columns unchanged."""
    if '"' not in raw:
        return raw.split(';', 1)[0].translate(_UPPER_TAB)
    out = []
    in_string = False
    for ch in raw:
        if ch == '"':
            in_string = not in_string
        elif ch == ';' and not in_string:
            break
        elif not in_string:
            ch = ch.translate(_UPPER) if ch != '\t' else ' '
        out.append(ch)
    return ''.join(out)


def _sin(a: float) -> float:
    return math.sin(math.radians(a))


def _cos(a: float) -> float:
    return math.cos(math.radians(a))


def _tan(a: float) -> float:
    return math.tan(math.radians(a))


def _asin(a: float) -> float:
    return math.degrees(math.asin(a))


def _acos(a: float) -> float:
    return math.degrees(math.acos(a))


def _atan2(y: float, x: float) -> float:
    return math.degrees(math.atan2(y, x))


def _round(a: float) -> float:
    return float(math.floor(a + 0.5)) if a >= 0 else -float(math.floor(-a + 0.5))


FUNCTIONS: dict[str, tuple[int, Callable[..., float]]] = {
    'SIN': (1, _sin), 'COS': (1, _cos), 'TAN': (1, _tan), 'ASIN': (1, _asin),
    'ACOS': (1, _acos), 'ATAN2': (2, _atan2), 'SQRT': (1, math.sqrt),
    'POT': (1, lambda a: a * a), 'ABS': (1, abs), 'TRUNC': (1, lambda a: float(math.trunc(a))),
    'ROUND': (1, _round), 'ROUNDUP': (1, lambda a: float(math.ceil(a)) if a >= 0
                                      else float(math.floor(a))),
    'LN': (1, math.log), 'EXP': (1, math.exp), 'MINVAL': (2, min), 'MAXVAL': (2, max),
}
"""Arithmetic functions: name -> (number of arguments, function of degrees where angles)."""

# Binary operators by precedence level (low to high); word operators need a word border.
_LEVELS: tuple[tuple[str, ...], ...] = (
    ('OR',), ('XOR',), ('AND',), ('B_OR',), ('B_XOR',), ('B_AND',),
    ('==', '<>', '>=', '<=', '>', '<'), ('+', '-'), ('*', '/', 'DIV', 'MOD'),
)


class Scanner:
    """A cursor over the code of one line, with the place for errors.

    Parameters
    ----------
    code
        The code part (:func:`code_part`).
    raw
        The line as in the file (for the text shown in errors).
    file, line
        The place.
    lookup
        Value of a variable name (upper case) or ``None`` if there is none by that name.
    """

    __slots__ = ('code', 'raw', 'file', 'line', 'pos', 'lookup', 'depth')

    def __init__(self, code: str, raw: str, *, file: str, line: int,
                 lookup: Callable[[str], float | None]):
        self.code = code
        self.raw = raw
        self.file = file
        self.line = line
        self.pos = 0
        self.lookup = lookup
        self.depth = 0

    # -- places and errors -----------------------------------------------------------------
    def error(self, msg: str, at: int | None = None) -> GcodeError:
        """A :class:`GcodeError` at column ``at`` (0-based; default: here) naming the text."""
        at = self.pos if at is None else at
        at = max(0, min(at, len(self.code)))
        text = self.code[at:].strip().split(' ')[0] or self.code.strip()
        return GcodeError(msg, file=self.file, line=self.line, column=at + 1,
                          text=shorten(text, limit=40))

    def fail(self, msg: str, at: int | None = None) -> NoReturn:
        """Raise :meth:`error`."""
        raise self.error(msg, at)

    # -- characters ------------------------------------------------------------------------
    def skip(self) -> None:
        """Skip blanks."""
        code = self.code
        n = len(code)
        while self.pos < n and code[self.pos] == ' ':
            self.pos += 1

    def peek(self) -> str:
        """The next non-blank character ('' at the end)."""
        self.skip()
        return self.code[self.pos] if self.pos < len(self.code) else ''

    def at_end(self) -> bool:
        """Only blanks left."""
        return self.peek() == ''

    def take(self, text: str) -> bool:
        """Consume ``text`` if it comes next (after blanks)."""
        self.skip()
        if self.code.startswith(text, self.pos):
            self.pos += len(text)
            return True
        return False

    def expect(self, text: str) -> None:
        """Consume ``text`` or fail naming it."""
        if not self.take(text):
            self.fail(f'expected {text!r}')

    def ident(self) -> str:
        """The identifier that comes next ('' if none; the cursor stays then)."""
        self.skip()
        code = self.code
        i = self.pos
        if i >= len(code) or code[i] not in _IDENT_START:
            return ''
        j = i + 1
        while j < len(code) and code[j] in _IDENT:
            j += 1
        self.pos = j
        return code[i:j]

    def peek_ident(self) -> str:
        """The identifier that comes next, without consuming it."""
        at = self.pos
        name = self.ident()
        self.pos = at
        return name

    def string(self) -> str:
        """A ``"..."`` string (the cursor at its opening quote)."""
        self.skip()
        if not self.code.startswith('"', self.pos):
            self.fail('expected a "text" in double quotes')
        end = self.code.find('"', self.pos + 1)
        if end == -1:
            self.fail('text in double quotes not closed')
        text = self.code[self.pos + 1:end]
        self.pos = end + 1
        return text

    def number(self) -> float:
        """An unsigned number literal (``12``, ``1.5``, ``.5``, ``2EX3``)."""
        self.skip()
        code = self.code
        i = self.pos
        j = i
        while j < len(code) and code[j] in _DIGITS:
            j += 1
        if j < len(code) and code[j] == '.':
            j += 1
            while j < len(code) and code[j] in _DIGITS:
                j += 1
        if j == i or code[i:j] == '.':
            self.fail('expected a number')
        text = code[i:j]
        if code.startswith('EX', j):
            k = j + 2
            if k < len(code) and code[k] in '+-':
                k += 1
            m = k
            while m < len(code) and code[m] in _DIGITS:
                m += 1
            if m > k:
                text = f'{text}e{code[j + 2:m]}'
                j = m
        self.pos = j
        return self.checked(float(text), i)

    def signed_number(self) -> float:
        """A number literal with an optional sign (an address value: ``X-5.5``)."""
        self.skip()
        sign = 1.0
        if self.take('-'):
            sign = -1.0
        else:
            self.take('+')
        return sign * self.number()

    def checked(self, value: float, at: int) -> float:
        """``value`` if finite and not absurd, else an error at ``at``."""
        if not math.isfinite(value) or abs(value) > MAX_MAGNITUDE:
            self.fail(f'value {value!r} out of range (at most {MAX_MAGNITUDE:g})', at)
        return value

    # -- expressions -----------------------------------------------------------------------
    def expression(self) -> float:
        """An arithmetic or logical expression (see the module docstring)."""
        at = self.pos
        return self.checked(self._level(0), at)

    def _operator(self, ops: tuple[str, ...]) -> str:
        self.skip()
        code = self.code
        for op in ops:
            if code.startswith(op, self.pos):
                end = self.pos + len(op)
                if op[0].isalpha() and end < len(code) and code[end] in _IDENT:
                    continue
                if op in ('<', '>') and code.startswith('<<', self.pos):
                    continue
                self.pos = end
                return op
        return ''

    def _level(self, k: int) -> float:
        if k == len(_LEVELS):
            return self._unary()
        left = self._level(k + 1)
        while True:
            at = self.pos
            op = self._operator(_LEVELS[k])
            if not op:
                return left
            right = self._level(k + 1)
            left = self._apply(op, left, right, at)

    def _apply(self, op: str, a: float, b: float, at: int) -> float:
        if op == '+':
            return a + b
        if op == '-':
            return a - b
        if op == '*':
            return a * b
        if op in ('/', 'DIV', 'MOD'):
            if b == 0:
                self.fail('division by zero', at)
            if op == '/':
                return a / b
            if op == 'DIV':
                return float(math.trunc(a / b))
            return math.fmod(a, b)
        if op == '==':
            return float(a == b)
        if op == '<>':
            return float(a != b)
        if op == '<':
            return float(a < b)
        if op == '>':
            return float(a > b)
        if op == '<=':
            return float(a <= b)
        if op == '>=':
            return float(a >= b)
        if op == 'AND':
            return float(bool(a) and bool(b))
        if op == 'OR':
            return float(bool(a) or bool(b))
        if op == 'XOR':
            return float(bool(a) != bool(b))
        ia, ib = int(a), int(b)
        if op == 'B_AND':
            return float(ia & ib)
        if op == 'B_OR':
            return float(ia | ib)
        return float(ia ^ ib)

    def _unary(self) -> float:
        self.depth += 1
        try:
            if self.depth > MAX_NESTING:
                self.fail(f'expression nested more than {MAX_NESTING} deep')
            return self._signed()
        finally:
            self.depth -= 1

    def _signed(self) -> float:
        if self.take('-'):
            return -self._unary()
        if self.take('+'):
            return self._unary()
        at = self.pos
        name = self.peek_ident()
        if name in ('NOT', 'B_NOT'):
            self.ident()
            value = self._unary()
            return float(not value) if name == 'NOT' else float(~int(value))
        return self._primary(at)

    def _primary(self, at: int) -> float:
        ch = self.peek()
        at = self.pos
        if ch == '(':
            self.pos += 1
            value = self._level(0)
            self.expect(')')
            return value
        if ch.isdigit() or ch == '.':
            return self.number()
        if ch == '$':
            self.pos += 1
            name = self.ident()
            self.fail(f'system variable ${name} is not simulated (its value lives in the '
                      'control)', at)
        if ch == '"':
            self.fail('a text where a number is expected', at)
        name = self.ident()
        if not name:
            self.fail('expected a number, a variable or "("' if ch else
                      'expression ends too early', at)
        if name in ('TRUE', 'FALSE'):
            return 1.0 if name == 'TRUE' else 0.0
        if name == 'R' and self.peek() == '[':
            self.pos += 1
            index = self._level(0)
            self.expect(']')
            if index != int(index) or index < 0:
                self.fail(f'R[{index:g}]: the index must be a whole number >= 0', at)
            name = f'R{int(index)}'
        if name in FUNCTIONS:
            return self._function(name, at)
        found = self.lookup(name)
        if found is None:
            if self.peek() == '[':
                self.fail(f'array {name}[...] is not supported', at)
            self.fail(f'unknown variable {name!r} (define it with DEF, or use an R '
                      'parameter)', at)
        return found

    def _function(self, name: str, at: int) -> float:
        n_args, fn = FUNCTIONS[name]
        self.expect('(')
        args = [self._level(0)]
        while self.take(','):
            args.append(self._level(0))
        self.expect(')')
        if len(args) != n_args:
            self.fail(f'{name} takes {n_args} argument{"s" if n_args > 1 else ""}, '
                      f'got {len(args)}', at)
        try:
            return float(fn(*args))
        except (ValueError, OverflowError):
            self.fail(f'{name}({", ".join(f"{a:g}" for a in args)}) is not defined', at)
