"""O-word control structures of one frame: if, while, do, repeat, break and continue.

LinuxCNC 2.9 semantics (``interp_o_word.cc``, manual "O Codes"): ``if``/``elseif``/
``else``/``endif``, ``while``/``endwhile``, ``do``/``while``, ``repeat [n]``/``endrepeat``
(``n`` rounded, <= 0 runs nothing), ``break`` and ``continue`` with the loop's label. Labels
are local to the frame (the main program or one call) they run in. A loop that passes
:data:`MAX_LOOP_ITERATIONS` times ends with a :class:`~..errors.GcodeError` at its first line.
"""
from __future__ import annotations

from .expr import Reader
from .params import Parameters
from .progfile import expect_end, ProgramFile, read_head, shown
from ...errors import GcodeError, shorten

__all__ = ['Frame', 'Loop', 'goto', 'run_structure', 'MAX_LOOP_ITERATIONS']

MAX_LOOP_ITERATIONS = 1_000_000
"""Passes of any one loop (``while``, ``do``, ``repeat``, ``M98 L``) before it is stopped."""


class Loop:
    """An open loop of a frame."""

    __slots__ = ('kind', 'start', 'left', 'iterations')

    def __init__(self, kind: str, start: int, left: int = 0):
        self.kind = kind          # 'WHILE', 'DO' or 'REPEAT'
        self.start = start        # index of the loop's first line (while/do/repeat)
        self.left = left          # repeats still to run (REPEAT)
        self.iterations = 0


class Frame:
    """The main program or one active call, and where it reads next."""

    __slots__ = ('file', 'pc', 'off', 'kind', 'name', 'saved', 'start', 'repeats',
                 'main_line', 'loops', 'call_line', 'iterations')

    def __init__(self, file: ProgramFile, pc: int, *, kind: str, name: str = '',
                 saved: list[float] | None = None, repeats: int = 0,
                 main_line: int | None = None, call_line: int = 0):
        self.file = file
        self.pc = pc                  # index of the next line to read
        self.off = 0 if pc == 0 else file.offset(pc)   # its offset in file.text
        self.kind = kind              # 'main', 'sub' (o-call) or 'm98'
        self.name = name
        self.saved = saved or []
        self.start = pc
        self.repeats = repeats        # M98 L repeats still to run
        self.main_line = main_line    # None: blocks are attributed to their own line
        self.loops: dict[str, Loop] = {}
        self.call_line = call_line
        self.iterations = 0


def goto(fr: Frame, idx: int) -> None:
    """Continue ``fr`` at line index ``idx``."""
    fr.pc = idx
    fr.off = fr.file.offset(idx)


def run_structure(fr: Frame, r: Reader, label: str, keyword: str, lineno: int,
                  params: Parameters) -> None:
    """Execute an if/elseif/else/endif, while/endwhile, do/while, repeat/endrepeat, break
    or continue line (``r`` positioned after the keyword); jumps move ``fr``."""
    f = fr.file
    idx = lineno - 1
    loops = fr.loops
    if keyword == 'IF':
        if not _condition(r):
            _skip_branch(fr, label, lineno, r)
        return
    if keyword in ('ELSEIF', 'ELSE'):
        # Reached by running the branch before it: the if is done.
        goto(fr, f.find(lineno, label, ('ENDIF',), r) + 1)
        return
    if keyword == 'ENDIF':
        expect_end(r)
        return
    if keyword == 'DO':
        expect_end(r)
        loops[label] = Loop('DO', idx)
        return
    if keyword == 'WHILE':
        loop = loops.get(label)
        if loop is not None and loop.kind == 'DO' and loop.start != idx:
            if _condition(r):
                _iterate(loop, label, fr)
                goto(fr, loop.start + 1)
            else:
                del loops[label]
            return
        if _condition(r):
            if loop is None or loop.start != idx:
                loops[label] = Loop('WHILE', idx)
        else:
            loops.pop(label, None)
            goto(fr, f.find(lineno, label, ('ENDWHILE',), r) + 1)
        return
    if keyword == 'ENDWHILE':
        expect_end(r)
        loop = loops.get(label)
        if loop is None or loop.kind != 'WHILE':
            raise r.error(f'o{shown(label)} endwhile without a matching while', 0)
        _iterate(loop, label, fr)
        goto(fr, loop.start)
        return
    if keyword == 'REPEAT':
        if r.peek() != '[':
            raise r.error('expected [count] after repeat')
        at = r.pos
        count = r.checked(r.expression(), at)
        expect_end(r)
        times = int(count + (0.5 if count >= 0 else -0.5))
        if times <= 0:
            loops.pop(label, None)
            goto(fr, f.find(lineno, label, ('ENDREPEAT',), r) + 1)
        else:
            loops[label] = Loop('REPEAT', idx, times - 1)
        return
    if keyword == 'ENDREPEAT':
        expect_end(r)
        loop = loops.get(label)
        if loop is None or loop.kind != 'REPEAT':
            raise r.error(f'o{shown(label)} endrepeat without a matching repeat', 0)
        if loop.left > 0:
            loop.left -= 1
            _iterate(loop, label, fr)
            goto(fr, loop.start + 1)
        else:
            del loops[label]
        return
    # BREAK / CONTINUE
    expect_end(r)
    loop = loops.get(label)
    if loop is None:
        raise r.error(f'o{shown(label)} {keyword.lower()} outside a loop with that label', 0)
    end_kw = {'WHILE': 'ENDWHILE', 'REPEAT': 'ENDREPEAT', 'DO': 'WHILE'}[loop.kind]
    end = f.find(lineno, label, (end_kw,), r)
    if keyword == 'BREAK':
        del loops[label]
        goto(fr, end + 1)
    elif loop.kind == 'WHILE':
        _iterate(loop, label, fr)
        goto(fr, loop.start)
    else:
        goto(fr, end)      # the do's while / the endrepeat decides


def _condition(r: Reader) -> bool:
    """Read ``[condition]`` at the end of an O-word line."""
    if r.peek() != '[':
        raise r.error('expected [condition]')
    at = r.pos
    value = r.checked(r.expression(), at)
    expect_end(r)
    return value != 0.0


def _iterate(loop: Loop, label: str, fr: Frame) -> None:
    """Count one more pass of ``loop``; stop a runaway loop."""
    loop.iterations += 1
    if loop.iterations > MAX_LOOP_ITERATIONS:
        msg = (f'loop o{shown(label)} ran {MAX_LOOP_ITERATIONS} times without ending '
               f'(limit MAX_LOOP_ITERATIONS)')
        raise GcodeError(msg, file=fr.file.name, line=loop.start + 1, column=1,
                         text=shorten(fr.file.line(loop.start).strip()))


def _skip_branch(fr: Frame, label: str, lineno: int, r: Reader) -> None:
    """After a false if/elseif: go to the next branch whose condition holds."""
    f = fr.file
    start = lineno
    while True:
        j = f.find(start, label, ('ELSEIF', 'ELSE', 'ENDIF'), r)
        if f.head(j)[1] != 'ELSEIF':
            goto(fr, j + 1)
            return
        r2 = f.reader(j)
        read_head(r2)
        if _condition(r2):
            goto(fr, j + 1)
            return
        start = j + 1
