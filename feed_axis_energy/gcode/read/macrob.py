"""Fanuc Custom Macro B statements, for the dialects of controls that have them.

Read only where the dialect says so (``fanuc`` and ``haas``; LinuxCNC refuses these
lines). Semantics as in the Fanuc Series 0i-MF operator's manual, "Custom Macro":

* ``WHILE [condition] DOm`` ... ``ENDm``: the loop runs while the condition holds;
  ``m`` is the loop's identifier (1 to 3 on a Fanuc; any integer here).
* ``IF [condition] GOTO n`` and ``GOTO n``: continue at the block with sequence number
  ``N n`` (the first one in the file).
* ``IF [condition] THEN #i = expression``: the assignment runs only if the condition holds.
* Assignments take an expression without brackets (``#1 = #2 / 2 + 1``, read by
  :func:`.lexer.read_items`).
* ``G65 P<program> [L<repeats>] <arguments>``: a macro call of a numbered subprogram
  (``O<program>`` ... ``M99``) with the letter arguments in ``#1..#26`` (argument
  specification I: A #1, B #2, C #3, I #4, J #5, K #6, D #7, E #8, F #9, H #11, M #13,
  Q #17, R #18, S #19, T #20, U #21, V #22, W #23, X #24, Y #25, Z #26), local to the call.
* Haas ``M97 P<n> [L<repeats>]``: a local subprogram call to the block ``N<n>`` of the same
  file, back at ``M99`` (Haas mill operator's manual, "M97 Local Sub-Program Call").

A ``WHILE`` loop and the target of a ``GOTO`` may each be passed at most
:data:`.control.MAX_LOOP_ITERATIONS` times.
"""
from __future__ import annotations

import re

from . import control
from .control import Frame, goto, Loop
from .expr import Reader
from .lexer import Assignment, read_items
from .progfile import expect_end, ProgramFile
from ...errors import GcodeError, shorten

__all__ = ['is_macro_statement', 'run_macro', 'g65_arguments', 'find_sequence',
           'G65_ARGUMENTS']

G65_ARGUMENTS = {'A': 1, 'B': 2, 'C': 3, 'I': 4, 'J': 5, 'K': 6, 'D': 7, 'E': 8, 'F': 9,
                 'H': 11, 'M': 13, 'Q': 17, 'R': 18, 'S': 19, 'T': 20, 'U': 21, 'V': 22,
                 'W': 23, 'X': 24, 'Y': 25, 'Z': 26}
"""Fanuc argument specification I: letter of a G65 argument -> local variable number."""

_STATEMENTS = ('WHILE', 'IF', 'GOTO', 'END')
_END_RE = re.compile(r'[ \t]*(?:[Nn][ \t]*[0-9.]+[ \t]*)?[Ee][ \t]*[Nn][ \t]*[Dd][ \t]*'
                     r'([0-9]+)[ \t]*(?:[(;].*)?$')
_WHILE_RE = re.compile(r'[ \t]*(?:[Nn][ \t]*[0-9.]+[ \t]*)?[Ww][ \t]*[Hh][ \t]*[Ii][ \t]*'
                       r'[Ll][ \t]*[Ee].*[Dd][ \t]*[Oo][ \t]*([0-9]+)')
_SEQ_RE = re.compile(r'[ \t]*/?[ \t]*[Nn][ \t]*([0-9]+)')


def is_macro_statement(s: str, pos: int) -> bool:
    """Whether the compacted line ``s`` holds a macro statement at ``pos``."""
    return s.startswith(_STATEMENTS, pos) and not s.startswith('ENDSUB', pos)


def run_macro(fr: Frame, r: Reader, lineno: int
              ) -> tuple[list[tuple[str, float]], list[Assignment]] | None:
    """Execute the macro statement at ``r`` (line ``lineno`` of frame ``fr``).

    Returns
    -------
    tuple or None
        The words and assignments of a ``THEN`` statement whose condition holds, else
        ``None``; jumps move ``fr``.
    """
    s = r.s
    if s.startswith('WHILE', r.pos):
        r.pos += 5
        cond = _condition(r, 'WHILE')
        if not s.startswith('DO', r.pos):
            raise r.error('expected DOm after WHILE [condition]')
        r.pos += 2
        ident = r.integer()
        expect_end(r)
        key = f'DO{ident}'
        loop = fr.loops.get(key)
        if cond:
            if loop is None or loop.start != lineno - 1:
                fr.loops[key] = Loop('FWHILE', lineno - 1)
        else:
            fr.loops.pop(key, None)
            goto(fr, _find_end(fr, lineno, ident, r) + 1)
        return None
    if s.startswith('END', r.pos):
        r.pos += 3
        ident = r.integer()
        expect_end(r)
        loop = fr.loops.get(f'DO{ident}')
        if loop is None:
            raise r.error(f'END{ident} without a WHILE [...] DO{ident} before it', 0)
        _count(loop, fr, f'WHILE ... DO{ident}')
        goto(fr, loop.start)
        return None
    if s.startswith('GOTO', r.pos):
        r.pos += 4
        target = r.integer()
        expect_end(r)
        _goto_sequence(fr, target, r)
        return None
    # IF
    r.pos += 2
    cond = _condition(r, 'IF')
    if s.startswith('GOTO', r.pos):
        r.pos += 4
        target = r.integer()
        expect_end(r)
        if cond:
            _goto_sequence(fr, target, r)
        return None
    if s.startswith('THEN', r.pos):
        r.pos += 4
        if not cond:
            return None
        return read_items(r, open_assign=True)
    raise r.error('expected GOTO n or THEN after IF [condition]')


def g65_arguments(words: list[tuple[str, float]], r: Reader) -> list[float]:
    """``#1..#26`` of a G65 call from its letter words (other than G, P, L, N)."""
    args = [0.0] * 26
    for letter, value in words:
        if letter in 'GPLN':
            continue
        n = G65_ARGUMENTS.get(letter)
        if n is None:
            raise r.error(f'{letter} is not a G65 argument letter', 0)
        args[n - 1] = value
    return args


def _condition(r: Reader, what: str) -> bool:
    """Read ``[condition]``."""
    if r.peek() != '[':
        raise r.error(f'expected [condition] after {what}')
    at = r.pos
    return r.checked(r.expression(), at) != 0.0


def _count(loop: Loop, fr: Frame, what: str) -> None:
    """One more pass of a WHILE loop or GOTO target; stop a runaway one."""
    loop.iterations += 1
    if loop.iterations > control.MAX_LOOP_ITERATIONS:
        msg = (f'{what} ran {control.MAX_LOOP_ITERATIONS} times without ending '
               '(limit MAX_LOOP_ITERATIONS)')
        raise GcodeError(msg, file=fr.file.name, line=loop.start + 1, column=1,
                         text=shorten(fr.file.line(loop.start).strip()))


def _find_end(fr: Frame, lineno: int, ident: int, r: Reader) -> int:
    """Index of the ``END<ident>`` closing the WHILE on line ``lineno`` (nesting counted)."""
    f = fr.file
    depth = 0
    for idx in range(lineno, f.n_lines()):
        line = f.line(idx)
        m = _WHILE_RE.match(line)
        if m is not None and int(m.group(1)) == ident:
            depth += 1
            continue
        m = _END_RE.match(line)
        if m is not None and int(m.group(1)) == ident:
            if depth == 0:
                return idx
            depth -= 1
    raise r.error(f'no END{ident} after this WHILE [...] DO{ident}', 0)


def find_sequence(f: ProgramFile, target: int, r: Reader, what: str) -> int:
    """Index of the first line of ``f`` numbered ``N<target>``; an error at ``r`` if none."""
    for idx in range(f.n_lines()):
        m = _SEQ_RE.match(f.line(idx))
        if m is not None and int(m.group(1)) == target:
            return idx
    raise r.error(f'{what}: no block N{target} in {f.name}', 0)


def _goto_sequence(fr: Frame, target: int, r: Reader) -> None:
    """Continue at the first line numbered ``N<target>``."""
    key = f'N{target}'
    loop = fr.loops.get(key)
    if loop is None:
        idx = find_sequence(fr.file, target, r, f'GOTO {target}')
        loop = fr.loops[key] = Loop('GOTO', idx)
    _count(loop, fr, f'GOTO {target}')
    goto(fr, loop.start)
