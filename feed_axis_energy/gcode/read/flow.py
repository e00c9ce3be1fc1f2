"""Program flow: lines -> executed :class:`~.block.Block` s (O-words, subprograms, loops).

:func:`read_blocks` is the reading half of the interpreter. It walks the program line by
line, executes what is not motion itself (parameter assignments, O-word control lines,
Fanuc ``M98``/``M99``) and yields every other line as a :class:`~.block.Block` with its
words evaluated. It is a generator pulled by the interpreter: a line's parameter
assignments are applied when the interpreter asks for the next block (RS274NGC: they take
effect after the line), and nothing is read ahead, so a parameter read always sees the
state after the previous line.

Control flow follows LinuxCNC 2.9 (``interp_o_word.cc``, manual "O Codes"):

* ``o<name> sub`` ... ``o<name> endsub [value]`` (or a number: ``o100 sub``) defines a
  subroutine; the definition is skipped where it stands. ``o<name> call [a] [b] ...``
  passes up to 30 arguments as ``#1..#30`` (local to the call, restored on return; the
  ones without an argument are 0); ``o<any label> return [value]`` leaves early; the
  value of ``return``/``endsub`` goes to ``#<_value>`` with ``#<_value_returned>`` = 1
  (without a value both are 0; both are also cleared before each call). A subroutine may be defined
  after its call in the same file (LinuxCNC requires it before; accepting more is harmless).
  A subroutine not in the program is looked for in the file ``<name>.ngc`` (lower case) in
  the program's directory and then the ``search_path`` directories (LinuxCNC's
  ``SUBROUTINE_PATH``).
* ``if``/``elseif``/``else``/``endif``, ``while``/``endwhile``, ``do``/``while``,
  ``repeat [n]``/``endrepeat``, ``break`` and ``continue`` with the loop's label. Labels of
  control structures are local to the subroutine they are in.
* Fanuc style (on by default, as in LinuxCNC): a bare ``O1234`` line labels a numbered
  (sub)program; ``M98 P1234 [L n]`` calls it ``n`` times (``L0``: not at all), ``#1..#30``
  stay global; ``M99`` returns. ``M99`` in the main program, an endless program in
  LinuxCNC (it restarts at the first line), ends the simulation after one pass with a
  warning.
* Limits, so that a runaway program ends with a clear error instead of running for ever:
  :data:`.control.MAX_LOOP_ITERATIONS` passes of one loop (also ``M98 ... L`` repeats),
  :data:`MAX_EXECUTED_LINES` executed lines in all, :data:`MAX_CALL_DEPTH` nested calls
  (LinuxCNC's own limit of subroutine levels).

Other line rules: a line whose first non-blank character is ``/`` is skipped (block delete
on); a ``%`` line before the first code line is ignored and one after code ends the
program (LinuxCNC's ``%`` delimiters; text after the ``%`` is allowed, as some CAM systems
write it); grbl ``$`` lines (``$H``, ``$X``, ``$$``) are skipped with a warning.

Memory: a file is held as its text (line ends made LF) and read line by line; nothing per
executed line is kept. Only when a control structure first needs to jump does the file get
a table of line start offsets (8 bytes a line) and an index of its O-word lines.
"""
from __future__ import annotations

from collections.abc import Callable
from os import PathLike
from pathlib import Path
from typing import Any, Iterator

from .block import Block
from .control import Frame, goto, run_structure
from .expr import compact, Reader
from .fanuc import END, fanuc_m, FanucCalls, MAX_CALL_DEPTH, SWITCH
from .lexer import blank_comments, LINE_RE, read_items, WORD_RE
from .macrob import is_macro_statement, run_macro
from .params import N_CALL_ARGUMENTS, Parameters
from .progfile import expect_end, FANUC, ProgramFile, read_head
from .source import find_subroutine_file, read_program
from ...errors import GcodeError, shorten

__all__ = ['read_blocks', 'BlockReader', 'MAX_EXECUTED_LINES']

MAX_EXECUTED_LINES = 50_000_000
"""Lines executed in one run (each loop pass counts its lines again) before it is stopped."""


def read_blocks(text: str, *, file: str = '<string>', params: Parameters | None = None,
                dialect: Any = None, search_path: tuple[str | PathLike[str], ...] = (),
                program_dir: str | PathLike[str] | None = None) -> 'BlockReader':
    """Read a program as a stream of executed blocks.

    Parameters
    ----------
    text
        The program text (any of LF, CRLF, CR line ends).
    file
        Name used in blocks, errors and warnings.
    params
        The parameter table (a new one if ``None``); the interpreter installs its
        ``provider`` and writes its persistent values there.
    dialect
        A dialect profile; ``fanuc_subprograms`` (default true) says whether bare
        ``O1234`` lines and ``M98``/``M99`` are Fanuc subprograms; ``fanuc_macro`` (default:
        true for the ``fanuc`` and ``haas`` profiles) turns on Fanuc Custom Macro B
        (:mod:`.macrob`: ``WHILE``/``DO``/``END``, ``IF``/``GOTO``/``THEN``, ``G65``,
        assignments without brackets).
    search_path
        Directories searched for subroutine files after ``program_dir``.
    program_dir
        Directory of the program (searched first for subroutine files); by default the
        directory of ``file`` when ``file`` names an existing file.

    Returns
    -------
    BlockReader
        Iterate over it for the :class:`~.block.Block` s; its ``warnings`` list fills while
        it is read.
    """
    return BlockReader(text, file=file, params=params, dialect=dialect,
                       search_path=search_path, program_dir=program_dir)


class BlockReader(FanucCalls):
    """The executed blocks of a program (see :func:`read_blocks`).

    Attributes
    ----------
    params
        The parameter table.
    warnings
        ``file:line: message`` texts about lines that were read but changed nothing (grbl
        ``$`` lines, an ``M99`` ending the main program, code after the closing ``%``).
    """

    def __init__(self, text: str, *, file: str = '<string>', params: Parameters | None = None,
                 dialect: Any = None, search_path: tuple[str | PathLike[str], ...] = (),
                 program_dir: str | PathLike[str] | None = None):
        self.params = Parameters() if params is None else params
        self.warnings: list[str] = []
        self.fanuc = bool(getattr(dialect, 'fanuc_subprograms', True))
        macro = getattr(dialect, 'fanuc_macro', None)
        if macro is None:
            macro = getattr(dialect, 'name', '') in ('fanuc', 'haas')
        self.macro = bool(macro)
        self.main = ProgramFile(file, text, params=self.params, fanuc=self.fanuc)
        if program_dir is None and file and not file.startswith('<'):
            parent = Path(file).parent
            program_dir = parent if parent.is_dir() else None
        self.program_dir = program_dir
        self.search_path = tuple(search_path)
        self.sub_files: dict[str, ProgramFile] = {}
        self.subs: dict[str, tuple[ProgramFile, str, int]] = {}
        self.frames = [Frame(self.main, 0, kind='main')]
        self.executed = 0
        self.seen_code = False
        self._warned_dollar = False
        # Set by GcodeRun(max_errors=...): called with an error in an ordinary line (not an
        # O-word, macro or subprogram line), which is then skipped; it raises to stop.
        self.on_error: Callable[[GcodeError], None] | None = None

    def __iter__(self) -> Iterator[Block]:
        """Run the program, yielding blocks."""
        return self._run()

    # -- the main loop ---------------------------------------------------------------------
    def _run(self) -> Iterator[Block]:
        """Generator over the executed blocks; the fast path for plain lines is inline."""
        frames = self.frames
        params = self.params
        line_re = LINE_RE.fullmatch
        findall = WORD_RE.findall
        new_tuple = tuple.__new__
        macro = self.macro
        fast = 0      # plain lines since the last slow one (added to self.executed there)
        while frames:
            fr = frames[-1]
            f = fr.file
            text = f.text
            find = text.find
            end = len(text)
            fname = f.name
            ascii_file = f.ascii
            main_line = fr.main_line
            pc = fr.pc
            off = fr.off
            switched = False
            while off < end:
                nl = find('\n', off)
                if nl == -1:
                    nl = end
                raw = text[off:nl]
                off = nl + 1
                pc += 1
                code = raw.upper()
                if '(' in code or ';' in code:
                    code = blank_comments(code, file=fname, line=pc)
                if line_re(code) is not None and 'O' not in code and (ascii_file or
                                                                      raw.isascii()):
                    words = findall(code)
                    if not words:
                        continue
                    try:
                        vals = [(letter, float(t)) for letter, t in words]
                    except ValueError:
                        vals = None   # blanks inside a number, or a bad one: slow path
                    if vals is not None and (
                            'M9' not in code or not fanuc_m(vals)) and (
                            not macro or ('G', 65.0) not in vals):
                        fast += 1
                        # tuple.__new__ skips NamedTuple's Python-level __new__ (3x faster).
                        yield new_tuple(Block, (pc, vals, fname, raw, main_line or pc))
                        continue
                fr.pc = pc
                fr.off = off
                if fast:
                    self.executed += fast
                    self.seen_code = True
                    fast = 0
                out = self._slow(fr, raw, pc)
                if out is SWITCH:
                    switched = True
                    break
                if out is END:
                    frames.clear()
                    return
                if out is not None:
                    vals, assigns = out
                    if vals:
                        self.seen_code = True
                        yield Block(pc, vals, fname, raw, main_line or pc)
                    for ref, value in assigns:
                        if isinstance(ref, int):
                            params.set(ref, value)
                        else:
                            params.set_named(ref, value)
                pc = fr.pc
                off = fr.off
            if switched:
                continue
            if fr.kind == 'main':
                return
            what = 'o<%s> endsub' % fr.name if fr.kind == 'sub' else 'M99'
            msg = f'end of file inside subroutine {fr.name!r}: {what} missing'
            raise GcodeError(msg, file=fname, line=pc, column=1)

    # -- lines that are not plain words ----------------------------------------------------
    def _slow(self, fr: Frame, raw: str, lineno: int) -> Any:
        """Execute a line off the fast path.

        Returns
        -------
        None (nothing to hand on), ``(words, assignments)``, ``SWITCH`` (the frame stack
        changed) or ``END``.
        """
        fname = fr.file.name
        self.executed += 1
        if self.executed > MAX_EXECUTED_LINES:
            msg = (f'more than {MAX_EXECUTED_LINES} lines executed: a loop or subprogram '
                   'that never ends?')
            raise GcodeError(msg, file=fname, line=lineno, column=1,
                             text=shorten(raw.strip()))
        code = blank_comments(raw, file=fname, line=lineno)
        stripped = code.strip()
        if not stripped or stripped[0] == '/':
            return None
        if stripped[0] == '%':
            return self._percent(fr, lineno)
        if stripped[0] == '$':
            if not self._warned_dollar:
                self._warned_dollar = True
                self.warnings.append(f'{fname}:{lineno}: grbl "$" lines are controller '
                                     'settings/commands and are skipped')
            return None
        if not code.isascii():
            col = next(i for i, ch in enumerate(code, 1) if not ch.isascii())
            msg = f'unexpected character {code[col - 1]!r} (not part of G-code)'
            return self._line_error(GcodeError(msg, file=fname, line=lineno, column=col,
                                               text=shorten(raw[col - 1:].strip(), limit=20)))
        s, cols = compact(code.upper())
        r = Reader(s, cols, raw, file=fname, line=lineno, params=self.params)
        if s[0] == 'N':
            r.pos = 1
            r.number()
        if r.peek() == 'O':
            return self._oline(fr, r, lineno)
        if self.macro and is_macro_statement(s, r.pos):
            return run_macro(fr, r, lineno)
        r.pos = 0
        try:
            words, assigns = read_items(r, open_assign=self.macro)
        except GcodeError as err:
            return self._line_error(err)
        self.seen_code = self.seen_code or bool(words)
        if self.fanuc and fanuc_m(words):
            return self._fanuc(fr, r, words, assigns, lineno)
        if self.macro and ('G', 65.0) in words:
            return self._g65(fr, r, words, assigns, lineno)
        return words, assigns

    def _line_error(self, err: GcodeError) -> None:
        """An error in an ordinary line: raised, or handed to :attr:`on_error` and the line
        skipped."""
        if self.on_error is None:
            raise err
        self.on_error(err)

    def _percent(self, fr: Frame, lineno: int) -> Any:
        """A ``%`` line: ignored before the first code, the end of the program after it."""
        if fr.kind != 'main' or not self.seen_code:
            return None
        text = fr.file.text
        off = fr.off
        k = lineno
        while off < len(text):
            nl = text.find('\n', off)
            rest = (text[off:] if nl == -1 else text[off:nl]).strip()
            k += 1
            if rest and rest[0] not in '%(;':
                self.warnings.append(f'{fr.file.name}:{k}: lines after the closing "%" '
                                     f'(line {lineno}) are ignored')
                break
            off = len(text) if nl == -1 else nl + 1
        return END

    def _apply(self, assigns: list) -> None:
        """Apply a control line's assignments (before the jump)."""
        for ref, value in assigns:
            if isinstance(ref, int):
                self.params.set(ref, value)
            else:
                self.params.set_named(ref, value)

    # -- calls -----------------------------------------------------------------------------
    def _call(self, fr: Frame, label: str, args: list[float] | None, lineno: int, *,
              kind: str, repeats: int = 0, raw: str = '') -> Any:
        """Enter subroutine ``label`` (``kind`` 'sub' for ``o.. call``, 'm98' for M98)."""
        fname = fr.file.name
        shown = f'o<{label}>' if kind == 'sub' else f'O{label}'
        if len(self.frames) > MAX_CALL_DEPTH:
            msg = (f'calls nested more than {MAX_CALL_DEPTH} deep at {shown} (recursion '
                   'without end?)')
            raise GcodeError(msg, file=fname, line=lineno, column=1, text=shorten(raw.strip()))
        target = self._find_sub(fr, label, kind == 'sub', lineno, raw)
        tfile, tkind, idx = target
        if kind == 'sub' and tkind != 'SUB':
            msg = f'O{label} is a Fanuc subprogram: call it with M98 P{label}'
            raise GcodeError(msg, file=fname, line=lineno, column=1, text=shorten(raw.strip()))
        if kind == 'm98' and tkind != FANUC:
            msg = f"o{label} sub must be called with 'o{label} call', not M98"
            raise GcodeError(msg, file=fname, line=lineno, column=1, text=shorten(raw.strip()))
        saved = self.params.enter_call(args)
        ml = lineno if fr.file is self.main else fr.main_line
        self.frames.append(Frame(tfile, idx + 1, kind=kind, name=label, saved=saved,
                                 repeats=repeats,
                                 main_line=None if tfile is self.main else ml,
                                 call_line=lineno))
        return SWITCH

    def _find_sub(self, fr: Frame, label: str, may_load: bool, lineno: int,
                  raw: str) -> tuple[ProgramFile, str, int]:
        """Where subroutine ``label`` starts: (file, keyword, index of its first line)."""
        hit = self.subs.get(label)
        if hit is not None:
            return hit
        f: ProgramFile | None
        for f in (fr.file, self.main):
            kind_idx = f.definitions().get(label)
            if kind_idx is not None:
                hit = (f, kind_idx[0], kind_idx[1])
                self.subs[label] = hit
                return hit
        path = find_subroutine_file(label, program_dir=self.program_dir,
                                    search_path=self.search_path) if may_load else None
        if path is not None:
            key = str(path)
            f = self.sub_files.get(key)
            if f is None:
                f = ProgramFile(key, read_program(path), params=self.params,
                                fanuc=self.fanuc)
                self.sub_files[key] = f
            kind_idx = f.definitions().get(label)
            if kind_idx is None or kind_idx[0] != 'SUB':
                msg = f'subroutine file {path.name} does not define o<{label}> sub'
                raise GcodeError(msg, file=key, line=1, column=1)
            hit = (f, kind_idx[0], kind_idx[1])
            self.subs[label] = hit
            return hit
        if may_load:
            where = (f'not in the program and no file {label.lower()}.ngc on the '
                     'subroutine search path')
        else:
            where = f'no line O{label} in the program'
        msg = f'subroutine {label!r} is not defined: {where}'
        raise GcodeError(msg, file=fr.file.name, line=lineno, column=1,
                         text=shorten(raw.strip()))

    def _leave(self, fr: Frame) -> Any:
        """Return from the innermost call."""
        self.params.leave_call(fr.saved)
        self.frames.pop()
        return SWITCH

    # -- O-word lines ----------------------------------------------------------------------
    def _oline(self, fr: Frame, r: Reader, lineno: int) -> Any:
        """Execute an O-word line (``r`` positioned at the ``O``)."""
        label, keyword = read_head(r)
        f = fr.file
        idx = lineno - 1
        if keyword == FANUC:
            if not self.fanuc:
                raise r.error('bare O-number (Fanuc program number) with Fanuc subprograms '
                              'off in this dialect', 0)
            return None
        if keyword == 'SUB':
            if fr.kind != 'main':
                raise r.error(f'subroutine definition o<{label}> sub inside a running '
                              f'subroutine (o<{fr.name}>): definitions cannot be nested', 0)
            f.definitions().setdefault(label, ('SUB', idx))
            end = f.find(lineno, label, ('ENDSUB',), r)
            goto(fr, end + 1)
            return None
        if keyword in ('ENDSUB', 'RETURN'):
            value = r.checked(r.expression(), r.pos) if r.peek() == '[' else None
            expect_end(r)
            if fr.kind != 'sub':
                what = 'M99 ends an M98 subprogram' if fr.kind == 'm98' else \
                    'not in a subroutine'
                raise r.error(f'o<{label}> {keyword.lower()}: {what}', 0)
            # LinuxCNC checks no label here: 'o1010 return' leaves the running subroutine.
            self.params.set_named('_value', 0.0 if value is None else value)
            self.params.set_named('_value_returned', 0.0 if value is None else 1.0)
            return self._leave(fr)
        if keyword == 'CALL':
            args: list[float] = []
            while r.peek() == '[':
                at = r.pos
                args.append(r.checked(r.expression(), at))
            expect_end(r)
            if len(args) > N_CALL_ARGUMENTS:
                raise r.error(f'more than {N_CALL_ARGUMENTS} call arguments', 0)
            self.params.set_named('_value', 0.0)
            self.params.set_named('_value_returned', 0.0)
            return self._call(fr, label, args, lineno, kind='sub', raw=r.raw)
        run_structure(fr, r, label, keyword, lineno, self.params)
        return None
