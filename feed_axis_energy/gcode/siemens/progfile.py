"""A Sinumerik program file: its lines, labels, control structures and program headers.

Built once per file (main program or subprogram) before it runs: a pass over the lines finds
jump labels (``NAME:``, also block numbers ``N100``), ``PROC`` definitions and ``%_N_NAME_SPF``
headers, and pairs the structure keywords (``IF``/``ELSE``/``ENDIF``, ``WHILE``/``ENDWHILE``,
``FOR``/``ENDFOR``, ``REPEAT``/``UNTIL``, ``LOOP``/``ENDLOOP``); an unbalanced one is an
error naming its line and column before any line runs.
"""
from __future__ import annotations

import re

from .text import code_part
from ...errors import GcodeError, shorten

__all__ = ['SiemensFile', 'line_head', 'STRUCTURE_OPEN', 'STRUCTURE_CLOSE']

STRUCTURE_OPEN = {'IF': ('ELSE', 'ENDIF'), 'WHILE': ('ENDWHILE',), 'FOR': ('ENDFOR',),
                  'REPEAT': ('UNTIL',), 'LOOP': ('ENDLOOP',)}
"""Opening keyword -> the keywords that close (or continue) it."""
STRUCTURE_CLOSE = {'ELSE': 'IF', 'ENDIF': 'IF', 'ENDWHILE': 'WHILE', 'ENDFOR': 'FOR',
                   'UNTIL': 'REPEAT', 'ENDLOOP': 'LOOP'}

_HEAD_RE = re.compile(r' *(?:(/)\d? *)?(?:(?:N|:)(\d+) *)?(?:([A-Z_][A-Z0-9_]*) *:(?!:) *)?')
_WORD_RE = re.compile(r'[A-Z_][A-Z0-9_]*')
_HEADER_RE = re.compile(r'\s*%_N_([A-Za-z0-9_]+?)_(MPF|SPF)\s*$')
_PATH_RE = re.compile(r'\s*;\s*\$PATH=')


def line_head(code: str) -> tuple[int, bool, str | None, str | None]:
    """Split the head of a line's code.

    Returns
    -------
    tuple
        (index after the head, block skip ``/``, block number or None, label or None).
    """
    m = _HEAD_RE.match(code)
    assert m is not None        # every part is optional
    return m.end(), m.group(1) is not None, m.group(2), m.group(3)


class SiemensFile:
    """One program file, indexed (see the module docstring).

    Attributes
    ----------
    name
        The file's name in messages.
    lines
        The raw lines.
    labels
        Label (upper case) -> 0-based line indices where it stands (block numbers as
        ``N<number>``).
    partners
        Line index of a structure keyword -> the index it jumps to (see :meth:`partner`).
    procs
        Subprogram name -> index of its ``PROC`` line or ``%_N_`` header.
    """

    def __init__(self, name: str, text: str):
        self.name = name
        if '\r' in text:
            text = text.replace('\r\n', '\n').replace('\r', '\n')
        self.lines = text.split('\n')
        if self.lines and self.lines[-1] == '':
            self.lines.pop()
        self.labels: dict[str, list[int]] = {}
        self.partners: dict[int, int] = {}
        self.else_of: dict[int, int] = {}       # IF line -> its ELSE line
        self.procs: dict[str, int] = {}
        self._index()

    def _index(self) -> None:
        stack: list[tuple[str, int, int]] = []   # (keyword, line index, column)
        for idx, raw in enumerate(self.lines):
            header = _HEADER_RE.match(raw)
            if header is not None:
                self.procs.setdefault(header.group(1).upper(), idx)
                continue
            if ';' not in raw and not raw.strip():
                continue
            code = code_part(raw)
            at, skip, number, label = line_head(code)
            if number is not None:
                self.labels.setdefault(f'N{int(number)}', []).append(idx)
            if label is not None:
                self.labels.setdefault(label, []).append(idx)
            m = _WORD_RE.match(code, at)
            if m is None:
                continue
            word = m.group(0)
            rest = code[m.end():].strip()
            if word == 'PROC':
                name = _WORD_RE.match(rest)
                if name is not None:
                    self.procs[name.group(0)] = idx     # after a %_N_ header: the PROC
                if stack:
                    self._unbalanced(stack[-1])
                continue
            if word == 'IF' and re.search(r'\bGOTO[FBC]?\b', rest):
                continue                         # IF cond GOTOF label: one line
            if word == 'REPEAT' and rest:
                continue                         # REPEAT label P=n: a section repeat
            if word in STRUCTURE_OPEN:
                stack.append((word, idx, m.start()))
            elif word in STRUCTURE_CLOSE:
                opener = STRUCTURE_CLOSE[word]
                if not stack or stack[-1][0] != opener:
                    want = f'{opener} before it' if not stack else \
                        f'{"/".join(STRUCTURE_OPEN[stack[-1][0]])} for the {stack[-1][0]} ' \
                        f'of line {stack[-1][1] + 1} first'
                    msg = f'{word} without a matching {opener} (expected {want})'
                    raise GcodeError(msg, file=self.name, line=idx + 1, column=m.start() + 1,
                                     text=shorten(raw.strip()))
                open_idx = stack[-1][1]
                if word == 'ELSE':
                    if open_idx in self.else_of:
                        msg = 'a second ELSE for one IF'
                        raise GcodeError(msg, file=self.name, line=idx + 1,
                                         column=m.start() + 1, text=shorten(raw.strip()))
                    self.else_of[open_idx] = idx
                    continue
                stack.pop()
                self.partners[open_idx] = idx
                self.partners[idx] = open_idx
                if word == 'ENDIF' and open_idx in self.else_of:
                    self.partners[self.else_of[open_idx]] = idx
        if stack:
            self._unbalanced(stack[-1])

    def _unbalanced(self, entry: tuple[str, int, int]) -> None:
        word, idx, col = entry
        closers = '/'.join(STRUCTURE_OPEN[word])
        msg = f'{word} without {STRUCTURE_OPEN[word][-1]} (unbalanced: no {closers} follows)'
        raise GcodeError(msg, file=self.name, line=idx + 1, column=col + 1,
                         text=shorten(self.lines[idx].strip()))

    def label_target(self, label: str, here: int, direction: str) -> int | None:
        """The line index of ``label`` from line ``here``: ``'F'`` forwards (towards the
        end), ``'B'`` backwards, ``''`` forwards then backwards; ``None`` if none."""
        spots = self.labels.get(label, [])
        after = [i for i in spots if i > here]
        before = [i for i in spots if i < here]
        if direction == 'F':
            return after[0] if after else None
        if direction == 'B':
            return before[-1] if before else None
        if after:
            return after[0]
        return before[-1] if before else (here if here in spots else None)
