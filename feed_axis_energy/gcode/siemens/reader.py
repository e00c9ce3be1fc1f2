"""The Sinumerik front: program text -> executed :class:`~..read.block.Block` s.

:class:`SiemensReader` runs the Siemens language itself - variables, control flow,
subprogram calls, frames, cycles - and hands every block that moves or sets a machine
function to the RS274NGC interpreter as ordinary words in machine coordinates
(:mod:`.geometry`). It is pulled block by block, as the RS274NGC front (:mod:`..read.flow`).

Language (Siemens "Fundamentals" and "Job planning" programming manuals, as far as milling
programs use it):

* Lines ``[/][N10] [LABEL:] block ; comment``; ``%_N_NAME_MPF`` / ``;$PATH=`` header lines.
* R parameters ``R1=...`` (global, 0 until set) and ``DEF REAL|INT|BOOL|CHAR|STRING`` local
  variables (local to their program level), with expressions (:mod:`.text`); several
  assignments in one block run left to right.
* ``IF cond GOTOF|GOTOB|GOTO|GOTOC label``, ``GOTOF``/``GOTOB`` alone; labels ``NAME:`` and
  block numbers ``N100`` as targets; ``IF``/``ELSE``/``ENDIF``, ``WHILE``/``ENDWHILE``,
  ``FOR var=a TO b``/``ENDFOR``, ``REPEAT``/``UNTIL``, ``LOOP``/``ENDLOOP``; section
  repeats ``REPEAT label [label] [P=n]`` and ``REPEATB label [P=n]``.
* Subprograms by name: ``L100``, ``NAME`` alone, ``NAME(args)``, ``CALL "NAME"``,
  ``EXTCALL "NAME"``, with ``P=n`` / ``Pn`` repeats; ``PROC NAME(REAL A, INT B)`` binds the
  arguments by value (missing ones are 0; ``VAR`` parameters, by reference, are
  refused); ``RET``, ``M17``, ``M2``/``M30`` or the end of the file return. Found as a
  ``PROC`` or ``%_N_NAME_SPF`` section of a file already read, else as ``NAME.SPF``
  (``.spf``, ``.MPF``, ``.mpf``; the name as written, in upper and in lower case) beside
  the main program, then in the ``search_path`` directories. Calls nest at most
  :data:`MAX_CALL_DEPTH` deep (the control's limit of program levels).
* ``MCALL NAME(args)`` calls ``NAME`` after every later block that moves, until ``MCALL``
  alone; drilling cycles and ``HOLES1``/``HOLES2`` (:mod:`.cycles`).
* Accepted without effect on the path: ``MSG()``, ``STOPRE``, ``GROUP_BEGIN()``/
  ``GROUP_END()``, ``WORKPIECE()`` (SinuTrain), ``SOFT``/``BRISK``, ``FFWON``/``FFWOF``,
  ``CFC``/``CFTCP``/``CFIN``, ``ADIS=``/``ADISPOS=``, ``SPOS=``; ``CYCLE832()`` with a warning
  (it sets the control's own smoothing and tolerance, which the machine config stands for).
* Refused with the name, file, line and column (``check`` lists each place): cycles and
  calls that cannot be simulated (pockets ``POCKET*``, slots, ``CYCLE800`` swivelling,
  thread and tapping cycles, ...), contour definitions (``ANG=``, ``RND=``, ``CHR=``), and
  anything unknown.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from os import PathLike
from pathlib import Path
import re
from typing import Any

from .cycles import DRILLING, drill, PATTERNS, pattern_points
from .frames import plane_axes, Vec3
from .geometry import Geometry, Word, Words
from .progfile import line_head, SiemensFile
from .text import code_part, Scanner
from ..read.block import Block
from ..read.source import read_program_bytes
from ...errors import GcodeError, shorten

__all__ = ['SiemensReader', 'read_siemens_blocks', 'decode_siemens', 'read_siemens_program',
           'MAX_CALL_DEPTH',
           'MAX_EXECUTED_LINES', 'MAX_LOOP_PASSES']

MAX_CALL_DEPTH = 16
"""Program levels (calls nested) before a call is refused as a recursion without end."""
MAX_LOOP_PASSES = 1_000_000
"""Passes of one loop (or jumps back from one line) before the run is stopped."""
MAX_EXECUTED_LINES = 50_000_000
"""Lines executed in one run (each loop pass counts again) before it is stopped."""

_CYCLE_RE = re.compile(r'(CYCLE\d+|POCKET\d*|SLOT\d*|LONGHOLE|HOLES\d|E_[A-Z_]+|F_[A-Z_]+|'
                       r'CONTPRON|CONTDCON)$')
_NAME_RE = re.compile(r'[A-Z_][A-Z0-9_]*$')
_NUMBER = r'[-+]?(?:\d+\.?\d*|\.\d+)'
_PLAIN_RE = re.compile(r' *(?:N\d+ *)?((?:[ABCDFGHIJKMSTXYZUVW] *' + _NUMBER + r' *)+)')
_PLAIN_WORD_RE = re.compile(r'([A-Z]) *(' + _NUMBER + ')')
_FILE_RE = re.compile(r'[^/\\\x00]+$')
_ADDRESS = frozenset('ABCDFGHIJKMPSTXYZUVW')
_EQ_ADDRESSES = frozenset({'CR', 'AP', 'RP', 'I1', 'J1', 'K1', 'TURN', 'RPL'})
_IGNORED_EQ = frozenset({'ADIS', 'ADISPOS', 'SPOS', 'SPOSA', 'SF', 'FB'})
_CONTOUR_EQ = frozenset({'ANG', 'RND', 'RNDM', 'CHR', 'CHF', 'OFFN', 'FRC', 'FRCM'})
_KEYWORDS = frozenset({'CIP', 'CT', 'SUPA'})
_QUIET_KEYWORDS = frozenset({'SOFT', 'BRISK', 'DRIVE', 'FFWON', 'FFWOF', 'CFC', 'CFTCP',
                             'CFIN', 'STOPRE', 'TRAFOOF', 'ORIWKS', 'ORIMKS', 'UPATH', 'SPATH',
                             'CPRECON', 'CPRECOF', 'DISPLON', 'DISPLOF', 'SBLON', 'SBLOF',
                             'WAITM', 'FTOCOF', 'G_', 'DIAMOF', 'TOFFOF', 'COMPOF', 'COMPCAD',
                             'COMPCURV', 'KONT', 'NORM'})
_NOOP_CALLS = frozenset({'MSG', 'GROUP_BEGIN', 'GROUP_END', 'WORKPIECE', 'SETAL', 'SETPIECE',
                         'WRTPR', 'DISPLON', 'DISPLOF', 'TRAFOOF', 'FGROUP'})
_STATEMENT_WORDS = frozenset({
    'IF', 'ELSE', 'ENDIF', 'WHILE', 'ENDWHILE', 'LOOP', 'ENDLOOP', 'FOR', 'ENDFOR', 'REPEAT',
    'REPEATB', 'UNTIL', 'GOTOF', 'GOTOB', 'GOTO', 'GOTOC', 'DEF', 'PROC', 'RET', 'CALL',
    'EXTCALL', 'MCALL', 'TRANS', 'ATRANS', 'ROT', 'AROT', 'SCALE', 'ASCALE', 'MIRROR',
    'AMIRROR'})
_TYPES = {'REAL': 'REAL', 'INT': 'INT', 'BOOL': 'BOOL', 'CHAR': 'INT', 'STRING': 'STRING',
          'AXIS': 'STRING', 'FRAME': 'FRAME'}
_END_M = (2.0, 30.0, 17.0)


def _reserved(name: str) -> bool:
    """Names a ``DEF`` may not take: addresses (``X``, ``I1``, ``CR``), keywords."""
    if len(name) == 1 or (name[0] in _ADDRESS | {'L', 'N', 'R', 'E', 'O', 'Q'}
                          and name[1:].isdigit()):
        return True
    return name in _EQ_ADDRESSES or name in _KEYWORDS or name in _QUIET_KEYWORDS or \
        name in _STATEMENT_WORDS or name in _CONTOUR_EQ or name in _IGNORED_EQ or \
        name in ('AC', 'IC', 'TO', 'TRUE', 'FALSE', 'NOT', 'AND', 'OR', 'XOR', 'DIV', 'MOD')


def _is_count(name: str) -> bool:
    """``P`` or ``P3``: the repetition count of a call or section repeat."""
    return name == 'P' or (name[:1] == 'P' and name[1:].isdigit())


def decode_siemens(data: bytes) -> str:
    """Program bytes as text: UTF-8 (a BOM dropped), else Latin-1 (controls and SinuTrain
    write umlauts in comments either way)."""
    try:
        return data.decode('utf-8-sig')
    except UnicodeDecodeError:
        return data.decode('latin-1')


def read_siemens_program(path: str | PathLike[str], *, file: str | None = None) -> str:
    """Read a Sinumerik program file (:func:`decode_siemens`; errors as ``read_program``)."""
    return _read(Path(path), str(path) if file is None else file)


def _read(path: Path, name: str) -> str:
    return decode_siemens(read_program_bytes(path, file=name))


class _Level:
    """One program level: a running (sub)program or a section repeat."""

    __slots__ = ('file', 'pc', 'local', 'types', 'kind', 'name', 'main_line', 'entry',
                 'repeats', 'stop', 'for_vars', 'passes', 'args', 'modal', 'saved')

    def __init__(self, file: SiemensFile, pc: int, *, kind: str, name: str = '',
                 main_line: int | None = None, repeats: int = 1, stop: int = -1,
                 local: dict[str, float] | None = None, types: dict[str, str] | None = None):
        self.file = file
        self.pc = pc
        self.entry = pc
        self.kind = kind
        self.name = name
        self.main_line = main_line
        self.repeats = repeats
        self.stop = stop
        self.local: dict[str, float] = {} if local is None else local
        self.types: dict[str, str] = {} if types is None else types
        self.for_vars: dict[int, tuple[str, float]] = {}
        self.passes: dict[int, int] = {}
        self.args: list[Any] = []
        self.modal = False          # entered by MCALL: its own moves call nothing
        self.saved: tuple[object, ...] | None = None   # PROC ... SAVE: the state to restore


def read_siemens_blocks(text: str, *, file: str = '<string>',
                        search_path: tuple[str | PathLike[str], ...] = (),
                        program_dir: str | PathLike[str] | None = None,
                        start_mm: Vec3 = (0.0, 0.0, 0.0),
                        offsets_mm: Mapping[int, Vec3] | None = None) -> 'SiemensReader':
    """The executed blocks of a Sinumerik program (see :class:`SiemensReader`)."""
    return SiemensReader(text, file=file, search_path=search_path, program_dir=program_dir,
                         start_mm=start_mm, offsets_mm=offsets_mm)


class SiemensReader:
    """Iterate over the executed blocks of a Sinumerik program.

    Parameters
    ----------
    text
        The main program.
    file
        Its name (subprograms are looked for in its directory first).
    search_path
        Further directories for subprogram files.
    program_dir
        The main program's directory (default: that of ``file`` if it exists).
    start_mm
        Tool position [mm] in machine coordinates before the first block.
    offsets_mm
        Values of the settable work offsets by number (``57`` for ``G57``) [mm]: the
        control's data (a machine's ``gcode.work_offsets_m``); one not given is 0, with a
        warning when the program selects it.

    Attributes
    ----------
    warnings
        ``file:line: message`` texts.
    frames
        The program levels (``kind`` ``'main'``, ``'sub'`` or ``'repeat'``, ``name``).
    on_error
        ``None``: an error ends the run. Else called with the error of a block that cannot
        be simulated (it raises to stop), and the block is skipped; errors of the program's
        structure (labels, calls, loops) always end the run.
    """

    def __init__(self, text: str, *, file: str = '<string>',
                 search_path: tuple[str | PathLike[str], ...] = (),
                 program_dir: str | PathLike[str] | None = None,
                 start_mm: Vec3 = (0.0, 0.0, 0.0),
                 offsets_mm: Mapping[int, Vec3] | None = None):
        self.warnings: list[str] = []
        self.on_error: Callable[[GcodeError], None] | None = None
        self.main = SiemensFile(file, text)
        if program_dir is None and file and not file.startswith('<'):
            parent = Path(file).parent
            program_dir = parent if parent.is_dir() else None
        self.dirs = ([] if program_dir is None else [Path(program_dir)]) + [
            Path(d) for d in search_path]
        self.files: dict[str, SiemensFile] = {}
        self.frames: list[_Level] = [_Level(self.main, 0, kind='main')]
        self.rparams: dict[str, float] = {}
        self.geo = Geometry(start_mm, self._warn_once)
        self.geo.offsets.update(offsets_mm or {})
        self.mcall: tuple[str, list[Any], int] | None = None
        self.executed = 0
        self._warned: set[str] = set()
        self._reported: set[tuple[str, int, int, str]] = set()
        self._after: list[Words] = []       # blocks a return hands on (PROC ... SAVE)
        self._place = (file, 0)

    # -- helpers ---------------------------------------------------------------------------
    def _warn_once(self, key: str, msg: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.warnings.append(f'{self._place[0]}:{self._place[1]}: {msg}')

    def _report(self, err: GcodeError) -> None:
        """Hand an error of a block to :attr:`on_error` (once per place and message: a
        repeated section does not repeat it), or raise it."""
        if self.on_error is None:
            raise err
        key = (err.file, err.line, err.column, err.reason)
        if key not in self._reported:
            self._reported.add(key)
            self.on_error(err)

    def _lookup(self, name: str) -> float | None:
        local = self.frames[-1].local
        if name in local:
            return local[name]
        if name[0] == 'R' and name[1:].isdigit():
            return self.rparams.get(f'R{int(name[1:])}', 0.0)
        return None

    def _assign(self, name: str, value: float, s: Scanner, at: int) -> None:
        lv = self.frames[-1]
        if name in lv.local:
            kind = lv.types.get(name, 'REAL')
            if kind == 'INT':
                value = float(round(value))
            elif kind == 'BOOL':
                value = float(bool(value))
            elif kind in ('STRING', 'FRAME'):
                s.fail(f'{kind} variable {name} cannot take a number', at)
            lv.local[name] = value
        elif name[0] == 'R' and name[1:].isdigit():
            self.rparams[f'R{int(name[1:])}'] = value
        else:
            s.fail(f'unknown variable {name!r} (define it with DEF, or use an R parameter)', at)

    def _is_variable(self, name: str) -> bool:
        return name in self.frames[-1].local or (name[0] == 'R' and name[1:].isdigit())

    # -- the main loop ---------------------------------------------------------------------
    def __iter__(self) -> Iterator[Block]:
        """Run the program, yielding blocks."""
        return self._run()

    def _run(self) -> Iterator[Block]:
        frames = self.frames
        while frames:
            lv = frames[-1]
            f = lv.file
            if lv.kind == 'repeat' and lv.pc > lv.stop:
                lv.repeats -= 1
                if lv.repeats > 0:
                    lv.pc = lv.entry
                else:
                    frames.pop()
                continue
            if lv.pc >= len(f.lines):
                if lv.kind == 'main':
                    return
                self._return()
                yield from self._restored(f.name, len(f.lines), lv.main_line)
                continue
            idx = lv.pc
            lv.pc += 1
            raw = f.lines[idx]
            if not raw.strip() or raw.lstrip().startswith(';'):
                continue
            self._place = (f.name, idx + 1)
            main_line = lv.main_line if lv.main_line is not None else idx + 1
            code = code_part(raw)
            text = re.sub(r'[()"=,]', ' ', code)
            for words in self._line(lv, idx, raw, code):
                yield Block(idx + 1, words, f.name, text, main_line)
            if self._after:
                yield from self._restored(f.name, idx + 1, main_line)

    def _restored(self, name: str, line: int, main_line: int | None) -> Iterator[Block]:
        """The blocks a return handed on (the plane a ``PROC ... SAVE`` restores)."""
        for words in self._after:
            yield Block(line, words, name, '', main_line or line)
        self._after = []

    def _line(self, lv: _Level, idx: int, raw: str, code: str) -> list[Words]:
        self.executed += 1
        f = lv.file
        if self.executed > MAX_EXECUTED_LINES:
            msg = (f'more than {MAX_EXECUTED_LINES} lines executed: a loop or subprogram '
                   'that never ends?')
            raise GcodeError(msg, file=f.name, line=idx + 1, column=1, text=shorten(raw.strip()))
        plain = _PLAIN_RE.fullmatch(code)
        if plain is not None:              # address words with plain numbers: the usual line
            s = Scanner(code, raw, file=f.name, line=idx + 1, lookup=self._lookup)
            try:
                words = [Word(m.group(1), float(m.group(2)), '', m.start())
                         for m in _PLAIN_WORD_RE.finditer(code, plain.start(1))]
                return self._block(lv, words, s)
            except GcodeError as err:
                self._report(err)
                return []
        at, skip, _, _ = line_head(code)
        if code.lstrip().startswith('%'):
            if idx > lv.entry and lv.kind != 'repeat' and '_N_' in code:
                self._return()                  # the next program of the file begins
            return []
        if skip:
            return []
        s = Scanner(code, raw, file=f.name, line=idx + 1, lookup=self._lookup)
        s.pos = at
        if s.at_end():
            return []
        word = s.peek_ident()
        handler = self._STATEMENTS.get(word)
        if handler is not None:
            return handler(self, lv, idx, s)
        try:
            return self._ordinary(lv, idx, s)
        except GcodeError as err:
            self._report(err)
            return []

    # -- control flow ----------------------------------------------------------------------
    def _count_pass(self, lv: _Level, idx: int, s: Scanner) -> None:
        n = lv.passes.get(idx, 0) + 1
        if n > MAX_LOOP_PASSES:
            s.fail(f'loop ran more than {MAX_LOOP_PASSES} times (no end?)', 0)
        lv.passes[idx] = n

    def _st_if(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        s.ident()
        cond = s.expression()
        jump = s.peek_ident()
        if jump in ('GOTOF', 'GOTOB', 'GOTO', 'GOTOC'):
            if cond:
                self._st_goto(lv, idx, s)
            return []
        self._end(s)
        if not cond:
            f = lv.file
            other = f.else_of.get(idx)
            lv.pc = (other if other is not None else f.partners[idx]) + 1
        return []

    def _st_else(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        lv.pc = lv.file.partners[idx] + 1          # the IF branch ran: on after ENDIF
        return []

    def _st_nothing(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        s.ident()
        self._end(s)
        return []

    def _st_while(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        s.ident()
        cond = s.expression()
        self._end(s)
        if not cond:
            lv.pc = lv.file.partners[idx] + 1
            lv.passes.pop(idx, None)        # the limit is per run of the loop
        else:
            self._count_pass(lv, idx, s)
        return []

    def _st_back(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        """ENDWHILE (back to the WHILE test) and ENDLOOP (back into the loop)."""
        word = s.ident()
        self._end(s)
        target = lv.file.partners[idx]
        if word == 'ENDLOOP':
            self._count_pass(lv, idx, s)
            target += 1
        lv.pc = target
        return []

    def _st_for(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        s.ident()
        at = s.pos
        name = s.ident()
        if not name or not self._is_variable(name):
            s.fail('FOR needs a defined variable (DEF INT) or an R parameter', at)
        s.expect('=')
        first = s.expression()
        if s.ident() != 'TO':
            s.fail('expected TO')
        last = s.expression()
        self._end(s)
        self._assign(name, first, s, at)
        lv.for_vars[idx] = (name, last)
        if first > last:
            lv.pc = lv.file.partners[idx] + 1
        return []

    def _st_endfor(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        s.ident()
        self._end(s)
        head = lv.file.partners[idx]
        if head not in lv.for_vars:
            s.fail(f'ENDFOR reached without its FOR of line {head + 1} having run (a jump '
                   'into the loop?)', 0)
        name, last = lv.for_vars[head]
        value = self._lookup(name)
        assert value is not None
        self._assign(name, value + 1.0, s, 0)
        if value + 1.0 <= last:
            self._count_pass(lv, idx, s)
            lv.pc = head + 1
        else:
            lv.passes.pop(idx, None)
        return []

    def _st_repeat(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        s.ident()
        if s.at_end():
            return []                            # REPEAT ... UNTIL
        return self._section(lv, idx, s, single=False)

    def _st_repeatb(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        s.ident()
        return self._section(lv, idx, s, single=True)

    def _section(self, lv: _Level, idx: int, s: Scanner, *, single: bool) -> list[Words]:
        at = s.pos
        first = s.ident()
        if not first:
            s.fail('expected a label')
        second = ''
        nxt = s.peek_ident()
        if not single and nxt and not _is_count(nxt):
            second = s.ident()
        count = self._repeat_count(s)
        self._end(s)
        f = lv.file
        start = f.label_target(first, idx, 'B')
        if start is None:
            start = f.label_target(first, idx, 'F')
        if start is None:
            s.fail(f'label {first} not found for the repetition', at)
        stop = start if single else idx - 1
        if second:
            end = f.label_target(second, start, 'F')
            if end is None or end >= idx:
                s.fail(f'end label {second} not found between {first} and the REPEAT', at)
            stop = end
        if stop < start:
            s.fail(f'the section from {first} to the REPEAT is empty', at)
        if len(self.frames) > 4 * MAX_CALL_DEPTH:
            s.fail('section repetitions nested too deep', at)
        self.frames.append(_Level(f, start, kind='repeat', name=first, stop=stop,
                                  repeats=count, main_line=lv.main_line,
                                  local=lv.local, types=lv.types))
        return []

    def _st_until(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        s.ident()
        cond = s.expression()
        self._end(s)
        if not cond:
            self._count_pass(lv, idx, s)
            lv.pc = lv.file.partners[idx] + 1
        else:
            lv.passes.pop(idx, None)
        return []

    def _st_goto(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        word = s.ident()
        at = s.pos
        s.skip()
        at = s.pos
        label = s.ident()
        if label == 'N' or (not label and s.peek().isdigit()):
            label = 'N' + str(int(s.number()))
        elif label and label[0] == 'N' and label[1:].isdigit():
            label = f'N{int(label[1:])}'
        if not label:
            s.fail(f'{word} needs a label')
        self._end(s)
        direction = {'GOTOF': 'F', 'GOTOB': 'B'}.get(word, '')
        target = lv.file.label_target(label, idx, direction)
        if target is None:
            if word == 'GOTOC':
                return []
            where = {'F': 'after', 'B': 'before'}.get(direction, 'in')
            s.fail(f'{word} {label}: no label {label} {where} this line in '
                   f'{Path(lv.file.name).name}', at)
        if target <= idx:
            self._count_pass(lv, idx, s)    # only a jump back can loop
        lv.pc = target
        return []

    def _end(self, s: Scanner) -> None:
        if not s.at_end():
            s.fail('unexpected text')

    # -- declarations ----------------------------------------------------------------------
    def _st_def(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        s.ident()
        at = s.pos
        kind = s.ident()
        if kind not in _TYPES:
            s.fail(f'DEF type {kind or "?"}: REAL, INT, BOOL, CHAR or STRING', at)
        vtype = _TYPES[kind]
        if kind == 'STRING' and s.take('['):
            s.expression()
            s.expect(']')
        while True:
            s.skip()
            at = s.pos
            name = s.ident()
            if not name:
                s.fail('expected a variable name')
            if name[0] == 'R' and name[1:].isdigit():
                s.fail(f'{name} is an R parameter', at)
            if _reserved(name):
                s.fail(f'{name} is an address or keyword of the NC language, not a free '
                       'variable name', at)
            if s.peek() == '[':
                s.fail(f'arrays ({name}[...]) are not supported', at)
            lv.types[name] = vtype
            lv.local[name] = 0.0
            if s.take('='):
                if vtype in ('STRING', 'FRAME'):
                    if s.peek() == '"':
                        s.string()
                    else:
                        s.fail(f'{kind} {name} is not simulated', at)
                else:
                    self._assign(name, s.expression(), s, at)
            if not s.take(','):
                break
        self._end(s)
        return []

    def _st_proc(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        if lv.kind == 'sub' and idx in (lv.entry - 1, lv.entry):
            return []                           # the header of the running subprogram
        if lv.kind == 'main' and idx == 0:
            return []                           # a main program written as a PROC
        self._return()                          # the next program of the file begins
        return []

    # -- calls -----------------------------------------------------------------------------
    def _find(self, name: str, s: Scanner, at: int, *, file_name: str = '') -> tuple[
            SiemensFile, int]:
        for f in (self.frames[-1].file, self.main, *self.files.values()):
            if name in f.procs:
                return f, f.procs[name]
        if file_name:
            if not _FILE_RE.fullmatch(file_name) or file_name in ('.', '..'):
                s.fail(f'subprogram file name {file_name!r} must be a plain name', at)
            candidates = [file_name]
        else:
            candidates = []
            for stem in dict.fromkeys((name, name.lower())):
                candidates += [stem + ext for ext in ('.SPF', '.spf', '.MPF', '.mpf')]
        for directory in self.dirs:
            for cand in candidates:
                path = directory / cand
                if path.is_file():
                    key = str(path)
                    loaded = self.files.get(key)
                    if loaded is None:
                        loaded = SiemensFile(key, _read(path, key))
                        self.files[key] = loaded
                    return loaded, loaded.procs.get(name, -1)
        if _CYCLE_RE.match(name):
            s.fail(f'cycle {name} cannot be simulated (it is not one of the drilling cycles '
                   f'{", ".join(sorted(DRILLING))} or the patterns HOLES1/HOLES2)', at)
        where = ', '.join(str(d) for d in self.dirs) or 'no directory (a program from text)'
        if file_name:
            s.fail(f'subprogram file {file_name!r} not found (looked in {where})', at)
        s.fail(f'unknown keyword or subprogram {name!r} (no PROC {name} and no file '
               f'{name}.SPF in {where})', at)

    def _arguments(self, s: Scanner) -> list[Any]:
        args: list[Any] = []
        if not s.take('('):
            return args
        if s.take(')'):
            return args
        while True:
            ch = s.peek()
            if ch in (',', ')'):
                args.append(None)
            elif ch == '"':
                args.append(s.string())
            else:
                args.append(s.expression())
            if s.take(')'):
                return args
            s.expect(',')

    def _repeat_count(self, s: Scanner) -> int:
        count = 1.0
        if _is_count(s.peek_ident()):
            s.skip()
            s.pos += 1
            count = s.expression() if s.take('=') else s.number()
        if count != int(count) or count < 1 or count > 1_000_000:
            s.fail(f'P{count:g}: the number of passes must be a whole number >= 1')
        return int(count)

    def _call(self, lv: _Level, name: str, args: list[Any], s: Scanner, at: int, *,
              repeats: int = 1, file_name: str = '') -> list[Words]:
        """Run a cycle, or enter subprogram ``name``."""
        if name in DRILLING:
            s.pos = at                      # errors of the cycle name the call
            return drill(name, args, self.geo, s)
        if name in PATTERNS:
            s.pos = at
            return self._pattern(name, args, s)
        if name == 'CYCLE832':
            self._warn_once('CYCLE832', 'CYCLE832 (high-speed settings: tolerance and '
                            'smoothing of the control) accepted; the planner follows the '
                            'machine config instead')
            return []
        if len(self.frames) >= MAX_CALL_DEPTH:
            msg = (f'subprogram {name} called {MAX_CALL_DEPTH} levels deep (a recursion '
                   'without end?)')
            raise GcodeError(msg, file=s.file, line=s.line, column=at + 1,
                             text=shorten(s.raw.strip()))
        f, start = self._find(name, s, at, file_name=file_name)
        main_line = lv.main_line if lv.main_line is not None else s.line
        new = _Level(f, start + 1 if start >= 0 else 0, kind='sub', name=name,
                     main_line=main_line, repeats=repeats)
        new.args = args
        self._bind(new, f, start, args, s, at)
        self.frames.append(new)
        return []

    def _bind(self, new: _Level, f: SiemensFile, start: int, args: list[Any], s: Scanner,
              at: int) -> None:
        """Bind a PROC's parameters (by value; missing ones are 0)."""
        if start < 0 or not f.lines[start].lstrip().upper().startswith('PROC'):
            if args:
                s.fail(f'{new.name} takes no arguments (no PROC line with parameters)', at)
            return
        code = code_part(f.lines[start])
        p = Scanner(code, f.lines[start], file=f.name, line=start + 1, lookup=lambda n: None)
        p.ident()
        p.ident()
        params: list[tuple[str, str]] = []
        if p.take('('):
            while not p.take(')'):
                kind = p.ident()
                if kind == 'VAR':
                    # by reference: the subprogram may write the caller's variable, which
                    # taking the value would silently lose
                    p.fail(f'VAR parameters (call by reference) of {new.name} are not '
                           'simulated', p.pos - 3)
                if kind not in _TYPES:
                    p.fail(f'parameter type {kind or "?"} (REAL, INT, BOOL, CHAR, STRING)')
                if kind == 'STRING' and p.take('['):
                    p.expression()
                    p.expect(']')
                pname = p.ident()
                if not pname:
                    p.fail('expected a parameter name')
                if p.peek() == '[':
                    p.fail(f'array parameter {pname}[...] is not supported')
                params.append((pname, _TYPES[kind]))
                p.take(',')
        while not p.at_end():
            attribute = p.ident()
            if not attribute:
                break
            if attribute == 'SAVE' and new.saved is None:
                new.saved = self.geo.snapshot()
        if len(args) > len(params):
            s.fail(f'{new.name} takes {len(params)} argument{"s" if len(params) != 1 else ""},'
                   f' got {len(args)}', at)
        for k, (pname, vtype) in enumerate(params):
            value = args[k] if k < len(args) else None
            if isinstance(value, str):
                if vtype != 'STRING':
                    s.fail(f'argument {k + 1} of {new.name} is a text, {pname} a number', at)
                value = 0.0
            v = 0.0 if value is None else float(value)
            if vtype == 'INT':
                v = float(round(v))
            elif vtype == 'BOOL':
                v = float(bool(v))
            new.types[pname] = vtype
            new.local[pname] = v

    def _return(self) -> None:
        lv = self.frames[-1]
        if lv.kind == 'main':
            self.frames.clear()
            return
        while lv.kind == 'repeat':
            self.frames.pop()
            lv = self.frames[-1]
        if lv.kind == 'main':
            self.frames.clear()
            return
        lv.repeats -= 1
        if lv.repeats > 0:
            lv.pc = lv.entry
            args = lv.args
            lv.local.clear()
            lv.types.clear()
            lv.for_vars.clear()
            f = lv.file
            start = lv.entry - 1
            s = Scanner('', '', file=f.name, line=start + 1, lookup=self._lookup)
            self._bind(lv, f, start if lv.entry > 0 else -1, args, s, 0)
            return
        self.frames.pop()
        if lv.saved is not None:
            words = self.geo.restore(lv.saved)
            if words:
                self._after.append(words)

    def _st_ret(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        s.ident()
        self._end(s)
        if lv.kind == 'main' and len(self.frames) == 1:
            return [[('M', 2.0)]]
        self._return()
        return []

    def _st_call(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        word = s.ident()
        at = s.pos
        s.skip()
        at = s.pos
        if s.peek() == '"':
            text = s.string()
            name = Path(text).stem.upper() if word == 'EXTCALL' else text.upper()
            file_name = text if word == 'EXTCALL' and '.' in text else ''
        else:
            name = s.ident()
            file_name = ''
        if not name:
            s.fail(f'{word} needs a program name')
        args = self._arguments(s)
        self._end(s)
        try:
            return self._call(lv, name, args, s, at, file_name=file_name)
        except GcodeError as err:
            if 'levels deep' in err.reason:
                raise
            self._report(err)
            return []

    def _st_mcall(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        s.ident()
        at = s.pos
        s.skip()
        at = s.pos
        if s.at_end():
            self.mcall = None
            return []
        name = s.ident()
        args = self._arguments(s)
        self._end(s)
        if name in PATTERNS:
            s.fail(f'MCALL {name}: a pattern is not a modal cycle', at)
        if name not in DRILLING:
            try:
                self._find(name, s, at)
            except GcodeError as err:
                self._report(err)
                self.mcall = None
                return []
        self.mcall = (name, args, at)
        return []

    def _modal_call(self, lv: _Level, s: Scanner) -> list[Words]:
        """The modal call after a block that moved."""
        assert self.mcall is not None
        name, args, at = self.mcall
        depth = len(self.frames)
        out = self._call(lv, name, args, s, at)
        if len(self.frames) > depth:
            self.frames[-1].modal = True
        return out

    def _pattern(self, name: str, args: list[Any], s: Scanner) -> list[Words]:
        g = self.geo
        a, b, _ = plane_axes(g.plane)
        out: list[Words] = []
        for pa, pb in pattern_points(name, args, g, s):
            here = list(g.program_position())
            here[a], here[b] = pa, pb
            out.append(g.move_words(0, (here[0], here[1], here[2])))
            if self.mcall is not None:
                cname = self.mcall[0]
                if cname not in DRILLING:
                    s.fail(f'{name} with the modal subprogram {cname}: only the drilling '
                           'cycles run at pattern positions')
                out += drill(cname, self.mcall[1], g, s)
        return out

    # -- other statements ------------------------------------------------------------------
    def _st_frame(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        kind = s.ident()
        words = self._words(s, frame=True)
        try:
            self.geo.frame_statement(kind, words, s)
        except GcodeError as err:
            self._report(err)
        return []

    # -- ordinary blocks -------------------------------------------------------------------
    def _words(self, s: Scanner, *, frame: bool = False) -> list[Word]:
        """The addresses of a block; assignments run as they come."""
        out: list[Word] = []
        while not s.at_end():
            ch = s.peek()
            at = s.pos
            if ch == '$':
                s.pos += 1
                s.fail(f'system variable ${s.ident()} is not simulated (its value lives in the '
                       'control: machine data, settable frames, tool data)', at)
            name = s.ident()
            if not name:
                s.fail(f'unexpected {ch!r}', at)
            eq = s.peek() == '=' and not s.code.startswith('==', s.pos)
            if eq and self._is_variable(name) and not frame:
                s.pos += 1
                self._assign(name, s.expression(), s, at)
                continue
            if eq and (name in _EQ_ADDRESSES or name in _ADDRESS):
                s.pos += 1
                out.append(self._value(name, s, at))
                continue
            if eq and name in _IGNORED_EQ:
                s.pos += 1
                if s.peek_ident() in ('AC', 'IC', 'DC', 'ACN', 'ACP'):
                    s.ident()
                s.expression()
                continue
            if eq and name in _CONTOUR_EQ:
                s.fail(f'{name}= (contour definition: angle, rounding or chamfer) is not '
                       'simulated', at)
            if name in _KEYWORDS:
                out.append(Word(name, 0.0, 'KW', at))
                continue
            if name in _QUIET_KEYWORDS:
                continue
            if name in _NOOP_CALLS and s.peek() == '(':
                self._arguments(s)
                continue
            if name[0] in _ADDRESS and (len(name) == 1 or name[1].isdigit()):
                s.pos = at + 1
                if name[0] == 'L' or name[0] == 'P':
                    s.fail(f'{name}: a subprogram call (L..) or repetition (P) shares its '
                           'block with other words', at)
                out.append(Word(name[0], s.signed_number(), '', at))
                continue
            if name[0] == 'L' and name[1:].isdigit():
                s.fail(f'{name}: a subprogram call (L..) shares its block with other words',
                       at)
            if eq:
                s.fail(f'unknown variable or address {name!r}', at)
            s.fail(f'unknown keyword or address {name!r}', at)
        return out

    def _value(self, name: str, s: Scanner, at: int) -> Word:
        """The value after ``NAME=``: an expression, ``AC(..)``/``IC(..)``, or a text."""
        if s.peek() == '"':
            if name != 'T':
                s.fail(f'{name}= takes a number, not a text', at)
            return Word(name, s.string(), '', at)
        mode = ''
        kind = s.peek_ident()
        if kind in ('AC', 'IC') and s.code[s.pos:].replace(' ', '')[2:3] == '(':
            s.ident()
            s.expect('(')
            value = s.expression()
            s.expect(')')
            mode = kind
        else:
            value = s.expression()
        return Word(name, value, mode, at)

    def _ordinary(self, lv: _Level, idx: int, s: Scanner) -> list[Words]:
        at = s.pos
        name = s.peek_ident()
        # a call: NAME(...), NAME alone (perhaps with P), L<number>
        call = ''
        if name and name not in _QUIET_KEYWORDS and name not in _KEYWORDS and not (
                name[0] in _ADDRESS and (len(name) == 1 or name[1].isdigit())):
            s.ident()
            nxt = s.peek()
            if nxt == '(' and name not in _NOOP_CALLS:
                call = name
            elif (nxt == '' or nxt == 'P') and not self._is_variable(name) and \
                    name not in _EQ_ADDRESSES:
                call = name
            else:
                s.pos = at
        elif name[:1] == 'L' and name[1:].isdigit():
            s.ident()
            call = f'L{int(name[1:])}' if name[1:] != '' else name
        if call:
            args = self._arguments(s) if s.peek() == '(' else []
            repeats = self._repeat_count(s)
            self._end(s)
            return self._call(lv, call, args, s, at, repeats=repeats)
        return self._block(lv, self._words(s), s)

    def _block(self, lv: _Level, words: list[Word], s: Scanner) -> list[Words]:
        """The interpreter blocks of a block's words (the end of a subprogram, the modal
        call after a move)."""
        if not words:
            return []
        ends = [w for w in words if w.name == 'M' and w.value in _END_M]
        if ends and (lv.kind != 'main' or ends[0].value == 17.0 or len(self.frames) > 1):
            words = [w for w in words if w not in ends]
            out = self.geo.block(words, s)
            if lv.kind == 'main' and len(self.frames) == 1:
                out.append([('M', 2.0)])      # M17 in the main program: its end
            else:
                self._return()
            return out
        out = self.geo.block(words, s)
        if self.mcall is not None and any(o[:1] and o[0][0] == 'G' and o[0][1] <= 3
                                          and len(o) > 1 for o in out) and not any(
                                              x.modal for x in self.frames):
            out += self._modal_call(lv, s)
        return out

    _STATEMENTS: dict[str, Callable[['SiemensReader', _Level, int, Scanner], list[Words]]] = {
        'IF': _st_if, 'ELSE': _st_else, 'ENDIF': _st_nothing, 'WHILE': _st_while,
        'ENDWHILE': _st_back, 'LOOP': _st_nothing, 'ENDLOOP': _st_back, 'FOR': _st_for,
        'ENDFOR': _st_endfor, 'REPEAT': _st_repeat, 'REPEATB': _st_repeatb,
        'UNTIL': _st_until, 'GOTOF': _st_goto, 'GOTOB': _st_goto, 'GOTO': _st_goto,
        'GOTOC': _st_goto, 'DEF': _st_def, 'PROC': _st_proc, 'RET': _st_ret,
        'CALL': _st_call, 'EXTCALL': _st_call, 'MCALL': _st_mcall,
        'TRANS': _st_frame, 'ATRANS': _st_frame, 'ROT': _st_frame, 'AROT': _st_frame,
        'SCALE': _st_frame, 'ASCALE': _st_frame, 'MIRROR': _st_frame, 'AMIRROR': _st_frame,
    }
