"""Fanuc-style subprogram calls of the block reader: ``M98``/``M99``, Haas ``M97``, ``G65``.

A mixin of :class:`.flow.BlockReader` (it uses the reader's frames, parameters and
``_call``/``_leave``). LinuxCNC 2.9 semantics for ``M98 P.. L..``/``M99`` (manual "O Codes",
"Fanuc-Style Numbered Programs"): the subprogram ``O<P>`` runs ``L`` times (``L0``: not at
all) with ``#1..#30`` global; ``M99`` in the main program ends the simulation after one
pass with a warning (LinuxCNC restarts it for ever; its preview runs one pass). ``M97`` and
``G65`` only where Fanuc macros are on (:mod:`.macrob`).
"""
from __future__ import annotations

from typing import Any, TYPE_CHECKING

from . import control
from .control import Frame, goto
from .expr import Reader
from .lexer import blank_comments, locate_word
from .macrob import find_sequence, g65_arguments
from ...errors import GcodeError

if TYPE_CHECKING:
    from collections.abc import Callable

    from .params import Parameters
    from .progfile import ProgramFile

__all__ = ['FanucCalls', 'fanuc_m', 'END', 'SWITCH', 'MAX_CALL_DEPTH']

MAX_CALL_DEPTH = 10
"""Deepest nesting of calls (``call``, ``M98``, ``M97``, ``G65``; LinuxCNC's limit)."""

SWITCH = object()   # the frame stack changed
END = object()      # the program ends here


class FanucCalls:
    """``M98``/``M99``/``M97``/``G65`` handling, mixed into the block reader."""

    # what this mixin uses of the block reader (flow.BlockReader); declarations only
    macro: bool
    warnings: list[str]
    frames: list[Frame]
    params: Parameters
    main: ProgramFile
    _apply: Callable[[list], None]
    _call: Callable[..., Any]
    _leave: Callable[[Frame], Any]

    def _fanuc(self, fr: Frame, r: Reader, words: list[tuple[str, float]],
               assigns: list, lineno: int) -> Any:
        """``M98 P.. L..`` (call) and ``M99`` (return, or the end of the main program);
        Haas ``M97 P.. L..`` where Fanuc macros are on (else M97 goes to the interpreter)."""
        d = dict(words)
        fname = fr.file.name
        if ('M', 97.0) in words:
            if not self.macro:
                return words, assigns
            return self._m97(fr, r, d, assigns, lineno)
        if ('M', 98.0) in words:
            if 'P' not in d:
                raise _err("'M98' with no P word (the subprogram number)", fname, lineno,
                           r.raw, 'M')
            p = d['P']
            if abs(p - round(p)) > 1e-4:
                raise _err(f'M98 P{p:g}: subprogram number must be an integer', fname,
                           lineno, r.raw, 'P')
            count = _run_count('M98', d, fname, lineno, r.raw)
            self._apply(assigns)
            if count == 0:
                return None
            return self._call(fr, str(int(round(p))), None, lineno, kind='m98',
                              repeats=count - 1, raw=r.raw)
        # M99
        if fr.kind == 'm98':
            self._apply(assigns)
            return self._return_m98(fr, lineno)
        if fr.kind == 'sub':
            raise _err(f"'M99' cannot end subroutine o<{fr.name}> sub (use o<{fr.name}> "
                       'endsub)', fname, lineno, r.raw, 'M')
        self.warnings.append(f'{fname}:{lineno}: M99 in the main program restarts it for '
                             'ever on LinuxCNC (an endless program); simulated once')
        return END

    def _m97(self, fr: Frame, r: Reader, d: dict[str, float], assigns: list,
             lineno: int) -> Any:
        """Haas local subprogram call ``M97 P<sequence number> [L<repeats>]``."""
        fname = fr.file.name
        p = d.get('P')
        if p is None or abs(p - round(p)) > 1e-4:
            raise _err('M97 needs P<sequence number> (an integer)', fname, lineno, r.raw, 'M')
        count = _run_count('M97', d, fname, lineno, r.raw)
        self._apply(assigns)
        if count == 0:
            return None
        if len(self.frames) > MAX_CALL_DEPTH:
            raise _err(f'calls nested more than {MAX_CALL_DEPTH} deep', fname, lineno,
                       r.raw, 'M')
        target = int(round(p))
        idx = find_sequence(fr.file, target, r, f'M97 P{target}')
        saved = self.params.enter_call(None)
        ml = lineno if fr.file is self.main else fr.main_line
        new = Frame(fr.file, idx, kind='m98', name=f'N{target}', saved=saved,
                    repeats=count - 1,
                    main_line=None if fr.file is self.main else ml, call_line=lineno)
        self.frames.append(new)
        return SWITCH

    def _g65(self, fr: Frame, r: Reader, words: list[tuple[str, float]], assigns: list,
             lineno: int) -> Any:
        """Fanuc macro call ``G65 P<program> [L<repeats>] <arguments>``."""
        d = dict(words)
        fname = fr.file.name
        p = d.get('P')
        if p is None or abs(p - round(p)) > 1e-4:
            raise _err('G65 needs P<program number> (an integer)', fname, lineno, r.raw, 'G')
        count = _run_count('G65', d, fname, lineno, r.raw)
        args = g65_arguments(words, r)
        self._apply(assigns)
        if count == 0:
            return None
        return self._call(fr, str(int(round(p))), args, lineno, kind='m98',
                          repeats=count - 1, raw=r.raw)

    def _return_m98(self, fr: Frame, lineno: int) -> Any:
        """M99 in a subprogram: run it again for ``L`` repeats, else return."""
        if fr.repeats > 0:
            fr.repeats -= 1
            fr.iterations += 1
            if fr.iterations > control.MAX_LOOP_ITERATIONS:
                msg = f'M98 repeats of O{fr.name} exceed {control.MAX_LOOP_ITERATIONS}'
                raise GcodeError(msg, file=fr.file.name, line=lineno, column=1)
            goto(fr, fr.start)
            return None
        return self._leave(fr)


def fanuc_m(words: list[tuple[str, float]]) -> bool:
    """Whether a line holds M97, M98 or M99."""
    return any(letter == 'M' and (v == 98.0 or v == 99.0 or v == 97.0) for letter, v in words)


def _run_count(code: str, d: dict[str, float], file: str, line: int, raw: str) -> int:
    """How many times an M98/M97/G65 call runs its subprogram: its L word (1 without)."""
    repeat = d.get('L', 1.0)
    if repeat < 0 or abs(repeat - round(repeat)) > 1e-4:
        raise _err(f'{code} L{repeat:g}: repeat count must be a whole number >= 0', file,
                   line, raw, 'L')
    return int(round(repeat))


def _err(msg: str, file: str, line: int, raw: str, letter: str) -> GcodeError:
    """A :class:`GcodeError` at the first ``letter`` word of ``raw``."""
    code = blank_comments(raw, file=file, line=line)
    column, text = locate_word(code, letter)
    return GcodeError(msg, file=file, line=line, column=column, text=text)
