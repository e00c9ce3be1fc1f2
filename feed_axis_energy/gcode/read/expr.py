"""Values on a line: numbers, ``#`` parameters, ``[ ]`` expressions and functions.

The semantics are LinuxCNC 2.9's (``interp_read.cc``, ``interp_execute.cc``):

* A value is a number, ``#n`` / ``#<name>`` (the number itself may be a value: ``##1``,
  ``#[#1+2]``), an expression ``[ ... ]``, a function ``NAME[ ... ]``, or ``+``/``-``
  in front of any of these.
* Binary operators by precedence, highest first; operators of equal precedence are
  evaluated left to right (also ``**``): ``**`` | ``*`` ``/`` ``MOD`` | ``+`` ``-`` |
  ``EQ NE GT GE LT LE`` | ``AND OR XOR``. ``EQ``/``NE``/``GE``/``LE`` compare within
  1e-6 (LinuxCNC's ``TOLERANCE_EQUAL``); comparisons and logic give 1.0 or 0.0.
  ``MOD`` is always non-negative (``fmod`` plus ``|b|`` when negative).
* Functions: ``ABS ACOS ASIN COS EXP FIX`` (floor) ``FUP`` (ceiling) ``LN ROUND``
  (half away from zero) ``SIN SQRT TAN``, ``ATAN[y]/[x]`` (two arguments, ``atan2``) and
  ``EXISTS[#<name>]``. Angles are in degrees.
* Domain errors as LinuxCNC reports them: division by zero, ``SQRT`` of a negative
  number, ``LN`` of a number <= 0, ``ACOS``/``ASIN`` outside [-1, 1], a negative number
  to a non-integer power. In addition every intermediate result must be finite (LinuxCNC:
  "Calculation resulted in 'not a number'/'infinity'") and a value that reaches the
  interpreter (a word or an assignment) must not exceed :data:`MAX_MAGNITUDE`: a
  400-digit number is an error, never ``inf`` or NaN.

The reader works on the line *compacted*: comments blanked, upper case, every blank
removed (LinuxCNC removes blanks before reading); an error finds the column of the
offending character in the line as written.
"""
from __future__ import annotations

import math
import re

from .params import ParameterError, Parameters
from ...errors import GcodeError, shorten

__all__ = ['Reader', 'compact', 'MAX_MAGNITUDE', 'TOLERANCE_EQUAL', 'FUNCTIONS']

MAX_MAGNITUDE = 1e12
"""Largest magnitude of a value handed on (program units; 1e12 mm is 1e6 km)."""

TOLERANCE_EQUAL = 1e-6
"""``EQ``, ``NE``, ``GE`` and ``LE`` treat numbers closer than this as equal (LinuxCNC)."""

FUNCTIONS = ('ABS', 'ACOS', 'ASIN', 'ATAN', 'COS', 'EXISTS', 'EXP', 'FIX', 'FUP', 'LN',
             'ROUND', 'SIN', 'SQRT', 'TAN')

# Binary operators: text -> precedence (LinuxCNC's precedence(): 2 logic .. 6 power).
_PRECEDENCE = {'**': 6, '*': 5, '/': 5, 'MOD': 5, '+': 4, '-': 4,
               'EQ': 3, 'NE': 3, 'GT': 3, 'GE': 3, 'LT': 3, 'LE': 3,
               'AND': 2, 'OR': 2, 'XOR': 2}
# Operator spellings by first character, longest first.
_OPERATORS = {'*': ('**', '*'), '/': ('/',), '+': ('+',), '-': ('-',), 'M': ('MOD',),
              'E': ('EQ',), 'N': ('NE',), 'G': ('GT', 'GE'), 'L': ('LT', 'LE'),
              'A': ('AND',), 'O': ('OR',), 'X': ('XOR',)}
_NUMBER_SPAN = re.compile(r'[+-]*[0-9.]*')
_NUMBER = re.compile(r'[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)')
_DEG = math.pi / 180.0
_BLANKS = re.compile(r'\s+')
_DIGITS = frozenset('0123456789.')
_NUMBER_START = frozenset('0123456789.+-')


def compact(code: str) -> tuple[str, str]:
    """Remove blanks from a comment-free, upper-cased line.

    Parameters
    ----------
    code
        The line, comments already blanked.

    Returns
    -------
    tuple[str, str]
        The compacted text, and ``code`` itself (from which :class:`Reader` finds the
        original column of a character only when it reports an error).
    """
    return _BLANKS.sub('', code), code


class Reader:
    """Reads values from one compacted line (see :func:`compact`).

    Parameters
    ----------
    s
        The compacted line (upper case, no blanks, no comments).
    code
        The line ``s`` was compacted from (comments blanked; for error columns).
    raw
        The line as written (for the text shown in errors).
    file, line
        The place.
    params
        The parameter table values are read from.
    """

    __slots__ = ('s', 'code', 'raw', 'file', 'line', 'params', 'pos')

    def __init__(self, s: str, code: str, raw: str, *, file: str, line: int,
                 params: Parameters):
        self.s = s
        self.code = code
        self.raw = raw
        self.file = file
        self.line = line
        self.params = params
        self.pos = 0

    # -- errors -----------------------------------------------------------------------------
    def error(self, msg: str, at: int | None = None) -> GcodeError:
        """A :class:`GcodeError` at compact position ``at`` (default: the current one)."""
        at = self.pos if at is None else at
        cols = [i for i, ch in enumerate(self.code, 1) if not ch.isspace()]
        if at < len(cols):
            column = cols[at]
        else:
            column = (cols[-1] + 1) if cols else 1
        shown = shorten(self.raw[column - 1:].strip(), limit=20) if self.raw else ''
        return GcodeError(msg, file=self.file, line=self.line, column=column,
                          text=shown or shorten(self.raw.strip()))

    def peek(self) -> str:
        """The current character ('' at the end of the line)."""
        return self.s[self.pos:self.pos + 1]

    def at_end(self) -> bool:
        """Whether the whole line has been read."""
        return self.pos >= len(self.s)

    def checked(self, value: float, at: int) -> float:
        """``value`` if it may be handed on; error if non-finite or too large."""
        if not math.isfinite(value):
            raise self.error('calculation resulted in infinity or not a number', at)
        if abs(value) > MAX_MAGNITUDE:
            raise self.error(f'value {value:.6g} is too large (limit {MAX_MAGNITUDE:g})', at)
        return value

    # -- values -----------------------------------------------------------------------------
    def value(self) -> float:
        """Read one value (LinuxCNC ``read_real_value``) starting at the current position."""
        start = self.pos
        s = self.s
        if start < len(s) and s[start] in _NUMBER_START:
            m = _NUMBER.match(s, start)   # the common case: a plain number
            if m is not None and s[m.end():m.end() + 1] not in _DIGITS:
                self.pos = m.end()
                v = float(m.group(0))
                if -MAX_MAGNITUDE <= v <= MAX_MAGNITUDE:
                    return v
                self.pos = start
        c = self.peek()
        if c == '':
            raise self.error('expected a value at the end of the line')
        if c == '[':
            v = self.expression()
        elif c == '#':
            v = self.parameter()
        elif c in '+-' and self.s[self.pos + 1:self.pos + 2] not in ('', '.') and \
                not self.s[self.pos + 1].isdigit():
            self.pos += 1
            v = self.value()
            if c == '-':
                v = -v
        elif 'A' <= c <= 'Z':
            v = self.function()
        else:
            v = self.number()
        if not math.isfinite(v):
            if v != v:
                raise self.error("calculation resulted in 'not a number'", start)
            raise self.error("calculation resulted in 'infinity' (number too large)", start)
        return v

    def number(self) -> float:
        """Read a literal number (sign, digits and at most one point)."""
        start = self.pos
        m = _NUMBER_SPAN.match(self.s, start)
        text = m.group(0)  # type: ignore[union-attr]  # the span may be empty: always a match
        if not _NUMBER.fullmatch(text):
            if not text:
                if start >= len(self.s):
                    raise self.error('expected a number at the end of the line', start)
                raise self.error(f'expected a number, found {self.s[start]!r}', start)
            raise self.error(f'bad number {shorten(text, limit=20)!r}', start)
        self.pos = m.end()  # type: ignore[union-attr]  # (as above)
        v = float(text)
        if not math.isfinite(v):
            raise self.error(f'number with {len(text)} characters is too large', start)
        return v

    def integer(self) -> int:
        """Read a value that must be an integer (within 1e-4, as LinuxCNC)."""
        start = self.pos
        v = self.value()
        if abs(v) > MAX_MAGNITUDE:
            raise self.error(f'value {v:.6g} is too large for an integer', start)
        n = math.floor(v)
        if v - n > 0.9999:
            n = math.ceil(v)
        elif v - n > 0.0001:
            raise self.error(f'integer expected, found {v:.6g}', start)
        return int(n)

    def name(self) -> str:
        """Read ``<name>`` (the current character is ``<``); returns it lower case."""
        start = self.pos
        end = self.s.find('>', start + 1)
        if end == -1:
            raise self.error('named parameter or O-word name without closing ">"', start)
        self.pos = end + 1
        return self.s[start + 1:end].lower()

    def parameter_ref(self) -> int | str:
        """Read the reference after ``#`` (the current character is ``#``).

        Returns
        -------
        int or str
            The parameter number, or the lower-case name of a named parameter.
        """
        self.pos += 1
        if self.peek() == '<':
            name = self.name()
            if not name:
                raise self.error('empty parameter name', self.pos - 2)
            return name
        return self.integer()

    def parameter(self) -> float:
        """Read ``#n``, ``#<name>``, ``##n`` or ``#[expr]`` and return its value."""
        start = self.pos
        ref = self.parameter_ref()
        try:
            if isinstance(ref, str):
                return self.params.get_named(ref)
            return self.params.get(ref)
        except ParameterError as err:
            raise self.error(str(err), start) from None

    def expression(self, *, open_end: bool = False) -> float:
        """Read ``[ ... ]`` (the current character is ``[``) and evaluate it.

        With ``open_end`` the expression has no brackets and runs to the end of the line
        (Fanuc macro B assignments, ``#1 = #2 / 2 + 1``); the current character is its
        first value.
        """
        if not open_end:
            self.pos += 1
        values = [self.value()]
        ops: list[tuple[str, int]] = []
        while True:
            at = self.pos
            if open_end and self.pos >= len(self.s):
                break
            op = self.operator()
            if op == ']':
                if open_end:
                    raise self.error('"]" without an opening "["', at)
                break
            prec = _PRECEDENCE[op]
            while ops and _PRECEDENCE[ops[-1][0]] >= prec:
                self.reduce(values, ops)
            ops.append((op, at))
            values.append(self.value())
        while ops:
            self.reduce(values, ops)
        return values[0]

    def operator(self) -> str:
        """Read a binary operator or the closing ``]``."""
        c = self.peek()
        if c == ']':
            self.pos += 1
            return ']'
        if c == '':
            raise self.error('"[" without a closing "]"')
        for op in _OPERATORS.get(c, ()):
            if self.s.startswith(op, self.pos):
                self.pos += len(op)
                return op
        raise self.error(f'unknown operator at {shorten(self.s[self.pos:], limit=12)!r}')

    def reduce(self, values: list[float], ops: list[tuple[str, int]]) -> None:
        """Apply the last operator to the last two values."""
        op, at = ops.pop()
        b = values.pop()
        a = values[-1]
        try:
            r = _binary(op, a, b)
        except ArithmeticError as err:
            raise self.error(str(err), at) from None
        if not math.isfinite(r):
            raise self.error(f"calculation resulted in 'infinity' or 'not a number' ({op})",
                             at)
        values[-1] = r

    def function(self) -> float:
        """Read ``NAME[...]`` (``ATAN[y]/[x]``, ``EXISTS[#<name>]``)."""
        start = self.pos
        for fname in FUNCTIONS:
            if self.s.startswith(fname, start):
                break
        else:
            raise self.error('unknown function or word where a value was expected', start)
        self.pos += len(fname)
        if self.peek() != '[':
            raise self.error(f'"[" missing after {fname}')
        if fname == 'EXISTS':
            return self.exists()
        arg = self.expression()
        if fname == 'ATAN':
            if self.peek() != '/':
                raise self.error('"/" missing after the first argument of ATAN')
            self.pos += 1
            if self.peek() != '[':
                raise self.error('"[" missing after "/" of ATAN')
            return math.atan2(arg, self.expression()) / _DEG
        try:
            return _unary(fname, arg)
        except (ArithmeticError, ValueError) as err:
            raise self.error(str(err), start) from None

    def exists(self) -> float:
        """``EXISTS[#<name>]`` (current character ``[``): 1.0 if the parameter is set."""
        self.pos += 1
        if self.peek() != '#':
            raise self.error('expected # in EXISTS[...]')
        ref = self.parameter_ref()
        if self.peek() != ']':
            raise self.error('expected "]" after the parameter in EXISTS[...]')
        self.pos += 1
        if isinstance(ref, str):
            return 1.0 if self.params.exists_named(ref) else 0.0
        try:
            self.params.get(ref)
        except ParameterError:
            return 0.0
        return 1.0


def _binary(op: str, a: float, b: float) -> float:
    """One binary operation with LinuxCNC's rules; errors as ``ArithmeticError``."""
    if op == '+':
        return a + b
    if op == '-':
        return a - b
    if op == '*':
        return a * b
    if op == '/':
        if b == 0.0:
            raise ZeroDivisionError('attempt to divide by zero')
        return a / b
    if op == 'MOD':
        if b == 0.0:
            raise ZeroDivisionError('MOD by zero')
        r = math.fmod(a, b)
        return r + abs(b) if r < 0.0 else r
    if op == '**':
        if a < 0.0 and math.floor(b) != b:
            raise ArithmeticError('attempt to raise a negative number to a non-integer power')
        if a == 0.0 and b < 0.0:
            raise ZeroDivisionError('attempt to raise zero to a negative power')
        try:
            return math.pow(a, b)
        except OverflowError:
            raise ArithmeticError('power too large') from None
    if op == 'EQ':
        return 1.0 if abs(a - b) < TOLERANCE_EQUAL else 0.0
    if op == 'NE':
        return 1.0 if abs(a - b) >= TOLERANCE_EQUAL else 0.0
    if op == 'GT':
        return 1.0 if a > b else 0.0
    if op == 'GE':
        return 1.0 if abs(a - b) < TOLERANCE_EQUAL or a >= b else 0.0
    if op == 'LT':
        return 1.0 if a < b else 0.0
    if op == 'LE':
        return 1.0 if abs(a - b) < TOLERANCE_EQUAL or a <= b else 0.0
    if op == 'AND':
        return 0.0 if a == 0.0 or b == 0.0 else 1.0
    if op == 'OR':
        return 1.0 if a != 0.0 or b != 0.0 else 0.0
    # XOR
    return 1.0 if (a == 0.0) != (b == 0.0) else 0.0


def _unary(name: str, x: float) -> float:
    """One function of LinuxCNC's list (not ATAN/EXISTS); domain errors as ``ValueError``."""
    if name == 'ABS':
        return abs(x)
    if name in ('ACOS', 'ASIN'):
        if not -1.0 <= x <= 1.0:
            raise ValueError(f'argument to {name} out of range [-1, 1]: {x:.6g}')
        return (math.acos(x) if name == 'ACOS' else math.asin(x)) / _DEG
    if name == 'COS':
        return math.cos(x * _DEG)
    if name == 'SIN':
        return math.sin(x * _DEG)
    if name == 'TAN':
        return math.tan(x * _DEG)
    if name == 'EXP':
        try:
            return math.exp(x)
        except OverflowError:
            raise ArithmeticError(f'EXP[{x:.6g}] is too large') from None
    if name == 'FIX':
        return float(math.floor(x))
    if name == 'FUP':
        return float(math.ceil(x))
    if name == 'LN':
        if x <= 0.0:
            raise ValueError(f'zero or negative argument to LN: {x:.6g}')
        return math.log(x)
    if name == 'ROUND':
        return float(math.trunc(x + (-0.5 if x < 0.0 else 0.5)))
    # SQRT
    if x < 0.0:
        raise ValueError(f'negative argument to SQRT: {x:.6g}')
    return math.sqrt(x)
