"""One run of a program through the interpreter, as a stream of moves.

Plain lines (``letter number`` words only: most CAM output) are read here, line by line
with precompiled regular expressions, and handed straight to the interpreter: a motion line
in the usual word order as :data:`.lexer.CONTOUR_RE`'s groups (``Interpreter.contour_line``),
any other plain line as its words (``Interpreter.line``). At the
first line that needs more (parameters, expressions, O-words, ``M98``/``M99``, ``$`` lines,
anything to diagnose) the rest of the program goes to the front's reader
(:func:`.flow.read_blocks`) with the same interpreter and parameter table: the lines
already run are blanked for it, so its line numbers stay those of the file. Nothing is read
twice and memory is bounded by the batch size (plus the program text itself).

A program in the ``sinumerik`` dialect goes to the Siemens front
(:func:`.siemens.read_siemens_blocks`) from its first line: its blocks are the same
:class:`~.read.block.Block` s, in machine coordinates, for the same interpreter.
"""
from __future__ import annotations

from collections.abc import Callable, Generator, Iterator, Mapping, Sequence
from os import PathLike
from typing import Any, cast, TextIO, TYPE_CHECKING

from .context import OperationContext
from .dialect import Dialect
from .interp.sysvars import READ_ONLY as FANUC_READ_ONLY
from .read.flow import read_blocks
from .siemens import read_siemens_blocks
from .interp.interpreter import Interpreter
from .read.lexer import blank_comments, CONTOUR_RE, LINE_RE, WORD_RE
from .read.params import Parameters
from ..errors import GcodeError
from .program import Move

if TYPE_CHECKING:
    from .interp.state import Lines

__all__ = ['GcodeRun']

Vec3 = tuple[float, float, float]


class _Recent:
    """Stands in for the interpreter's list of lines on the streaming path: whatever line
    is asked for, it is the one being interpreted (errors are raised at that line)."""

    __slots__ = ('raw',)

    def __init__(self) -> None:
        self.raw = ''

    def __getitem__(self, index: int) -> str:
        return self.raw


class GcodeRun:
    """Iterate over the moves of one program in batches (lists of :class:`Move`).

    Parameters
    ----------
    text
        The program text (LF, CRLF or CR line ends), or ``None`` with ``stream``.
    stream
        A text file opened with universal newlines, read line by line (bounded memory on
        the fast path; the front's reader gets the rest of the text if it is needed).
    file, start, arc_tolerance_m, home, tools, dialect, search_path, ignore_axes
    strict_tools, allow_no_feed, rotary_axes
        As for :func:`~.parse_gcode` (``dialect`` already a :class:`Dialect`, the axes
        checked).
    batch
        Hand on the moves whenever this many have gathered (``None``: once, at the end).
    max_errors
        0 (the default): the first error ends the run (raised). ``N > 0``: an error in the
        interpretation of a line is kept in :attr:`errors`, the rest of that line is dropped
        and the run goes on with the next line; the ``N``-th error is raised.
        An error the front's reader finds in an ordinary line (a bad number or expression)
        is kept the same way; errors in O-word, macro and subprogram lines end the run.
        For ``check``: later errors may follow from an earlier one.
    context
        Where to note the operation, subroutine and tool of the moves (``None``: not
        noted); see :mod:`.context`.

    Attributes
    ----------
    warnings
        ``file:line: message`` texts so far; complete once the iteration has ended.
    errors
        The errors kept under ``max_errors`` (:class:`~..errors.GcodeError`), in order.
    n_lines
        Number of lines of the program file (complete once the iteration has ended).
    """

    def __init__(self, text: str | None = None, *, stream: TextIO | None = None, file: str,
                 start: Vec3, arc_tolerance_m: float | None, home: Vec3 | None,
                 tools: Mapping[int, object] | None, dialect: Dialect,
                 search_path: Sequence[str | PathLike[str]] = (), batch: int | None = None,
                 ignore_axes: Sequence[str] = (), max_errors: int = 0,
                 context: OperationContext | None = None, strict_tools: bool = False,
                 allow_no_feed: bool = False, rotary_axes: Sequence[str] = (),
                 work_offsets: Mapping[str, Vec3] | None = None):
        self.recent = _Recent()
        self.work_offsets = dict(work_offsets or {})
        self.rotary_axes = frozenset(rotary_axes)
        if text is not None:
            if '\r' in text:
                text = text.replace('\r\n', '\n').replace('\r', '\n')
            lines = text.split('\n')
            if lines and lines[-1] == '':
                lines.pop()
            self.source: Iterator[str] = iter(lines)
            self.stream = None
            ref_lines: Lines = lines
        else:
            self.source = _file_lines(cast(TextIO, stream))     # given when text is not
            self.stream = stream
            ref_lines = self.recent
        self.n_lines = 0
        self.file = file
        self.dialect = dialect
        self.search_path = tuple(search_path)
        self.batch = batch
        self.max_errors = max(0, int(max_errors))
        self.errors: list[GcodeError] = []
        self._warnings: list[str] | None = None     # all of them, once the run has ended
        self._reader_warnings: list[str] = []        # the front's reader's, while it runs
        self.params = Parameters()
        self.interp = Interpreter(file, start, arc_tolerance_m, lines=ref_lines, home=home,
                                  tools=tools, dialect=dialect, params=self.params,
                                  ignore_axes=ignore_axes, strict_tools=strict_tools,
                                  allow_no_feed=allow_no_feed, rotary_axes=rotary_axes,
                                  # the Siemens front applies its own (G54..G57) and
                                  # hands on machine coordinates
                                  work_offsets=None if dialect.siemens else self.work_offsets)
        self.params.provider = self.interp.system_value
        self.context = context
        self.emitted = 0                             # moves handed on so far
        self.seen_code_blocks = False
        if context is not None:
            self.interp.on_tool = self._tool_loaded
        if self.dialect.fanuc_macro:
            self.params.read_only = FANUC_READ_ONLY     # #4001.., #5001..: gcode.interp.sysvars

    @property
    def warnings(self) -> list[str]:
        """``file:line: message`` texts so far (all of them once the run has ended)."""
        if self._warnings is not None:
            return self._warnings
        return self._reader_warnings + self.interp.warnings

    def _guarded(self, method: Callable[..., bool | None]) -> Callable[..., bool | None]:
        """An interpreter method that runs one line (``line``, ``contour_line``); under
        ``max_errors``, one that keeps an error, drops the rest of the line and reports the
        line as done."""
        if not self.max_errors:
            return method
        p = self.interp
        keep = self._keep

        def tolerant(*args: object) -> bool | None:
            try:
                return method(*args)
            except GcodeError as err:
                keep(err)
                p.abandon_line()
                return True
        return tolerant

    def _keep(self, err: GcodeError) -> None:
        """Keep an error and go on, or raise it when it is the ``max_errors``-th."""
        if len(self.errors) + 1 >= self.max_errors:
            raise err
        self.errors.append(err)

    def __iter__(self) -> Iterator[list[Move]]:
        """Run the program; yield the moves in batches."""
        p = self.interp
        if self.dialect.siemens:        # Siemens' language: all of it through its front
            first: tuple[int, str] | None = (1, next(self.source, ''))
        else:
            first = yield from self._plain()
        reader_warnings: list[str] = []
        if first is not None:
            reader_warnings = yield from self._blocks(first)
        p.close()
        self._warnings = reader_warnings + p.warnings
        if p.moves:
            self.emitted += len(p.moves)
            yield p.moves
            p.moves = []

    def _take(self) -> list[Move]:
        p = self.interp
        out = p.moves
        p.moves = []
        self.emitted += len(out)
        return out

    def _ordinal(self) -> int:
        """The ordinal of the next move the interpreter emits."""
        return self.emitted + len(self.interp.moves)

    def _tool_loaded(self, tool: int) -> None:
        cast(OperationContext, self.context).set_tool(tool, self._ordinal())  # on_tool: set

    def _comment_lines(self, lines: list[str], lo: int, hi: int) -> None:
        """Note the operation names of the comment-only lines ``lo`` .. ``hi - 1``
        (1-based) of the main file, skipped by the front's reader."""
        for number in range(max(lo, 1), min(hi, len(lines) + 1)):
            raw = lines[number - 1]
            if '(' in raw or ';' in raw:
                try:
                    code = blank_comments(raw, file=self.file, line=number)
                except GcodeError:
                    continue
                if not code.strip():
                    cast(OperationContext, self.context).comment(raw, self._ordinal())

    def _rest(self) -> str:
        """The text after the lines read so far."""
        if self.stream is not None:
            return self.stream.read()
        return '\n'.join(self.source)

    def _plain(self) -> Generator[list[Move], None, tuple[int, str] | None]:
        """The fast path; returns the first line (1-based number, raw text) it cannot take,
        or ``None`` when the program ended."""
        p = self.interp
        file = self.file
        recent = self.recent
        line_re = LINE_RE.fullmatch
        contour = CONTOUR_RE.fullmatch
        findall = WORD_RE.findall
        interpret = self._guarded(p.line)
        contour_line = self._guarded(p.contour_line)
        fanuc = self.dialect.fanuc_subprograms
        macro = self.dialect.fanuc_macro
        batch = self.batch or 0
        seen_code = False
        end_at = 0
        lineno = 0
        context = self.context
        for lineno, raw in enumerate(self.source, 1):
            recent.raw = raw
            code = raw.upper()
            if '(' in code:
                code = blank_comments(code, file=file, line=lineno)
            elif ';' in code:
                code = code.partition(';')[0]     # blank_comments without a '(' before it
            m = contour(code)
            if m is not None and m.lastindex and raw.isascii():
                # The usual motion line, split by the expression: no word list, no dict.
                p.lineno = lineno
                if contour_line(*m.groups()):
                    seen_code = True
                    if batch and len(p.moves) >= batch:
                        yield self._take()
                    continue
            if line_re(code) is None or not raw.isascii():
                # Not plain words: block delete, a % marker, or a line for the front.
                code = blank_comments(raw, file=file, line=lineno)
                stripped = code.strip()
                if stripped[:1] == '/':
                    continue
                if stripped == '%':
                    if seen_code:
                        end_at = lineno
                        break
                    continue
                if not code.isascii() or line_re(code.upper()) is None:
                    self.n_lines = lineno - 1
                    self.seen_code_blocks = seen_code
                    return lineno, raw
                code = code.upper()
            words = findall(code)
            if not words:
                if context is not None and seen_code and not code.strip():
                    context.comment(raw, self._ordinal())     # a comment-only line
                continue
            if ((fanuc and 'M9' in code) or (macro and 'G65' in code)) and _fanuc_call(words):
                self.n_lines = lineno - 1
                self.seen_code_blocks = seen_code
                return lineno, raw
            seen_code = True
            p.lineno = lineno
            interpret(words)
            if p.ended:
                end_at = lineno
                break
            if batch and len(p.moves) >= batch:
                yield self._take()
        self.n_lines = lineno
        if end_at:
            self.n_lines += _warn_trailing(p, self.source, end_at)
        return None

    def _blocks(self, first: tuple[int, str]) -> Generator[list[Move], None, list[str]]:
        """The front's reader from line ``first`` on; returns its warnings."""
        p = self.interp
        file = self.file
        lineno, raw = first
        rest = self._rest()
        text = '\n' * (lineno - 1) + raw + '\n' + rest
        lines = text.split('\n')
        if lines and lines[-1] == '':
            lines.pop()
        self.n_lines = len(lines)
        p.lines = lines
        siemens = self.dialect.siemens
        reader: Any
        if siemens:
            reader = read_siemens_blocks(text, file=file, search_path=self.search_path,
                                         start_mm=_mm(p.pos), offsets_mm={
                                             int(name[1:]): _mm(v)
                                             for name, v in self.work_offsets.items()
                                             if name in ('G54', 'G55', 'G56', 'G57')})
        else:
            reader = read_blocks(text, file=file, params=self.params, dialect=self.dialect,
                                 search_path=self.search_path)
        self._reader_warnings = reader.warnings
        if siemens:
            reader.geo.rotary = self.rotary_axes
        if self.max_errors:
            reader.on_error = self._keep
        interpret = self._guarded(p.line)
        batch = self.batch or 0
        end_at = 0
        context = self.context
        frames = reader.frames
        after = lineno - 1                  # the last main-file line run (comment scan)
        for block in reader:
            if context is not None:
                fr = frames[-1] if frames else None
                if siemens:
                    sub = next((x.name for x in reversed(frames) if x.kind == 'sub'), '')
                else:
                    sub = '' if fr is None or fr.kind == 'main' else (
                        f'o<{fr.name}>' if fr.kind == 'sub' else f'O{fr.name}')
                if sub != context.subroutine:
                    context.set_subroutine(sub, self._ordinal())
                if block.file == file:
                    if block.line > after + 1 and self.seen_code_blocks:
                        self._comment_lines(lines, after + 1, block.line)
                    after = block.line
                    self.seen_code_blocks = True
            p.src = block
            p.lineno = block.main_line
            interpret(block.words)
            p.end_block()
            if p.ended:
                if block.file == file and block.line == block.main_line:
                    end_at = block.line
                break
            if batch and len(p.moves) >= batch:
                yield self._take()
        p.src = None
        if end_at:
            _warn_trailing(p, iter(lines[end_at:]), end_at)
        return list(reader.warnings)


def _mm(pos_m: Vec3) -> Vec3:
    """A position [m] in millimetres (the Sinumerik front works in mm)."""
    return (pos_m[0] * 1e3, pos_m[1] * 1e3, pos_m[2] * 1e3)


def _file_lines(stream: TextIO) -> Iterator[str]:
    """Lines of a text file opened with universal newlines, without their line ends (a
    ``UnicodeDecodeError`` passes: the caller finds its place in the file)."""
    for line in stream:
        yield line[:-1] if line.endswith('\n') else line


def _fanuc_call(words: list[tuple[str, str]]) -> bool:
    """True if the line has M97, M98, M99 or G65 (subprograms and macro calls: the front's
    reader runs them)."""
    for letter, value in words:
        if letter == 'M' or letter == 'G':
            try:
                number = float(''.join(value.split()))
            except ValueError:
                return True
            if (letter == 'M' and number in (97.0, 98.0, 99.0)) or (letter == 'G'
                                                                    and number == 65.0):
                return True
    return False


def _warn_trailing(p: Interpreter, rest: Iterator[str], end_at: int) -> int:
    """Warn once if code follows the end of the program (line ``end_at``); return the number
    of lines after it (all of them are read, none kept)."""
    warned = False
    count = 0
    for count, raw in enumerate(rest, 1):
        if warned:
            continue
        lineno = end_at + count
        try:
            code = blank_comments(raw, file=p.file, line=lineno).strip()
        except GcodeError:
            code = raw.strip()
        if code and code != '%':
            p.warnings.append(f'{p.file}:{lineno}: lines after the end of the program '
                              f'(line {end_at}) are ignored')
            warned = True
    return count
