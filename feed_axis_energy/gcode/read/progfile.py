"""A program or subroutine file as the flow reads it: text, lines and its O-word index.

The text is kept whole (line ends made LF) and read line by line from an offset; the table
of line offsets (8 bytes a line) and the index of the file's O-word lines are built only
when a control structure first needs to jump, so a plain program costs nothing beyond its
text. O-word heads (``o<label> keyword``) are read as LinuxCNC's ``read_o`` reads them.
"""
from __future__ import annotations

from array import array
from bisect import bisect_left
import re
from typing import cast

from .expr import compact, Reader
from .lexer import blank_comments
from .params import Parameters
from ...errors import GcodeError, shorten

__all__ = ['ProgramFile', 'read_head', 'expect_end', 'shown', 'KEYWORDS', 'FANUC']

# A line that may be an O-word line: optional N number, then O (blanks allowed).
_OLINE_RE = re.compile(r'[ \t]*(?:[Nn][ \t]*[0-9][0-9. \t]*)?[Oo]')

KEYWORDS = ('SUB', 'ENDSUB', 'CALL', 'DO', 'WHILE', 'REPEAT', 'IF', 'ELSEIF', 'ELSE',
            'ENDIF', 'BREAK', 'CONTINUE', 'ENDWHILE', 'ENDREPEAT', 'RETURN')
"""O-word keywords in LinuxCNC's order of matching (``read_o``)."""

FANUC = ''
"""Keyword of a bare ``O1234`` line (a Fanuc program number)."""


class ProgramFile:
    """A loaded program or subroutine file.

    Parameters
    ----------
    name
        Name used in blocks and errors.
    text
        The decoded text (any of LF, CRLF, CR line ends).
    params
        The run's parameters (computed O-word labels such as ``o[#1]`` read them).
    fanuc
        Whether bare ``O1234`` lines define Fanuc subprograms.
    """

    __slots__ = ('name', 'text', 'ascii', 'params', 'fanuc', 'starts', 'olines',
                 'heads', 'defs')

    def __init__(self, name: str, text: str, *, params: Parameters, fanuc: bool = True):
        self.name = name
        if '\r' in text:
            text = text.replace('\r\n', '\n').replace('\r', '\n')
        self.text = text
        self.ascii = text.isascii()
        self.params = params
        self.fanuc = fanuc
        self.starts: array | None = None          # offset of each line's start (lazily)
        self.olines: list[int] | None = None      # indices of lines that may be O-lines
        self.heads: dict[int, tuple[str, str]] = {}  # index -> (label, keyword), literal labels
        self.defs: dict[str, tuple[str, int]] | None = None  # label -> (keyword, index)

    # -- lines -----------------------------------------------------------------------------
    def offset(self, idx: int) -> int:
        """Offset in ``text`` of the start of line ``idx`` (0-based; past the end: len + 1)."""
        starts = self.starts
        if starts is None:
            starts = array('q', [0])
            text = self.text
            find = text.find
            pos = find('\n')
            while pos != -1:
                starts.append(pos + 1)
                pos = find('\n', pos + 1)
            if starts[-1] == len(text):
                starts.pop()            # a final line end starts no line
            self.starts = starts
        return starts[idx] if idx < len(starts) else len(self.text) + 1

    def line(self, idx: int) -> str:
        """Line ``idx`` (0-based) without its line end."""
        start = self.offset(idx)
        end = self.text.find('\n', start)
        return self.text[start:] if end == -1 else self.text[start:end]

    def n_lines(self) -> int:
        """Number of lines."""
        self.offset(0)
        return len(cast(array, self.starts))    # offset() has built it

    # -- the O-line index ------------------------------------------------------------------
    def o_lines(self) -> list[int]:
        """Indices of the lines that may be O-word lines (built once, lazily)."""
        if self.olines is None:
            match = _OLINE_RE.match
            self.olines = [i for i in range(self.n_lines()) if match(self.line(i))]
        return self.olines

    def reader(self, idx: int) -> Reader:
        """A reader on line ``idx`` positioned after its N word (if any)."""
        raw = self.line(idx)
        code = blank_comments(raw, file=self.name, line=idx + 1)
        s, code = compact(code.upper())
        r = Reader(s, code, raw, file=self.name, line=idx + 1, params=self.params)
        if s.startswith('N'):
            r.pos = 1
            r.number()
        return r

    def head(self, idx: int) -> tuple[str, str]:
        """(label, keyword) of O-line ``idx``; literal labels are cached."""
        hit = self.heads.get(idx)
        if hit is not None:
            return hit
        r = self.reader(idx)
        if r.peek() != 'O':
            return ('', '?')
        after = r.s[r.pos + 1:r.pos + 2]
        literal = after == '<' or after.isdigit()   # not o[#1] or o#1
        head = read_head(r)
        if literal:
            self.heads[idx] = head
        return head

    def find(self, start: int, label: str, keywords: tuple[str, ...], r: Reader) -> int:
        """Index of the first O-line at or after line index ``start`` with ``label`` and one
        of ``keywords``; an error at ``r``'s line if there is none."""
        olines = self.o_lines()
        for k in range(bisect_left(olines, start), len(olines)):
            idx = olines[k]
            try:
                head = self.head(idx)
            except GcodeError:
                continue    # a label such as o#<local> that cannot be computed here
            if head[0] == label and head[1] in keywords:
                return idx
        want = ' or '.join(kw.lower() for kw in keywords)
        raise r.error(f'no matching o{shown(label)} {want} after this line', 0)

    def definitions(self) -> dict[str, tuple[str, int]]:
        """Subroutine definitions: label -> (keyword 'SUB' or :data:`FANUC`, line index)."""
        if self.defs is None:
            defs: dict[str, tuple[str, int]] = {}
            for idx in self.o_lines():
                try:
                    label, kw = self.head(idx)
                except GcodeError:
                    continue      # reported when (if ever) the line runs
                if kw == 'SUB' or (kw == FANUC and self.fanuc):
                    defs.setdefault(label, (kw, idx))
            self.defs = defs
        return self.defs


def read_head(r: Reader) -> tuple[str, str]:
    """Read ``O<label> keyword`` (``r`` at the ``O``); returns (label, keyword).

    A numbered label is the integer as text (``o0100`` and ``o100`` are ``'100'``), a named
    one the lower-case name.
    """
    r.pos += 1
    if r.peek() == '<':
        label = r.name()
        if not label:
            raise r.error('empty O-word name', r.pos - 2)
    else:
        label = str(r.integer())
    s = r.s
    for kw in KEYWORDS:
        if s.startswith(kw, r.pos):
            r.pos += len(kw)
            return label, kw
    if r.at_end():
        return label, FANUC
    raise r.error(f'unknown O-word keyword {shorten(s[r.pos:], limit=12)!r} (expected sub, '
                  'endsub, call, return, if, elseif, else, endif, while, endwhile, do, '
                  'repeat, endrepeat, break or continue)')


def expect_end(r: Reader) -> None:
    """Nothing but comments may follow an O-word's arguments."""
    if not r.at_end():
        raise r.error('unexpected text after the O-word')


def shown(label: str) -> str:
    """``100`` or ``<name>``, as the label was written."""
    return label if label.isdigit() else f'<{label}>'
