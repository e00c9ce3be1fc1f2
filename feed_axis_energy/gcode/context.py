"""Which operation, subroutine and tool each move belongs to (for energy roll-ups).

The interpreter keeps a small table of contexts ``(operation, subroutine, tool)`` and, each
time the context changes, a mark ``(number of moves emitted so far, context index)``: the
moves themselves carry nothing, and the cost is one mark per change, none per move.
A move's context is the one of the last mark at or before its ordinal
(:meth:`OperationContext.index_at`).

What is recognised (``docs/breakdown.md``, "Roll-ups"):

* **tool**: the tool loaded by ``M6`` (``T`` selects, ``M6`` loads; ``M61 Q``), as LinuxCNC;
* **subroutine**: the innermost ``o<name> call`` / ``M98 P`` / ``M97`` / ``G65`` being run
  (``o<name>``, ``O1234``);
* **operation**: a comment alone on its line, after the program's first line of code
  (the header's comments describe the program, not an operation):

  - ``(begin operation: NAME)`` (FreeCAD's posts), ``(Toolpath: NAME)`` and Vectric's
    ``(Toolpath:- NAME)`` (a trailing `` Tool: ...`` is cut), ``; Operation: N`` (jscut:
    "operation N"), Estlcam's ``(No. N: NAME)`` name NAME;
  - until the program uses one of those forms, any other short comment line (at most
    60 characters) without a ``key: value`` colon
    or ``=``, as Fusion 360 (``(2D ADAPTIVE1)``), CamBam (``( holes )``) and CAMotics
    scripts write their operation names, is an operation name;
  - not names: LinuxCNC's active comments (``MSG``, ``DEBUG``, ``PRINT``, ``LOG*``,
    ``PROBE*``), tool descriptions (``T2 D=3.175 ...``), FreeCAD's ``finish operation`` /
    ``end operation`` / ``begin preamble``/``postamble`` and other ``key: value`` lines;
    Mastercam's header (``PROGRAM NAME - ...``, ``MATERIAL - ...``, ``MCX FILE - ...``,
    ``NC FILE``, ``POST DEV``, ``DATE``, ``TIME``), its tool lines (``... TOOL - 1 DIA.
    OFF. - 1 LEN. - 1 DIA. - .5``, ``TOOL - 1 OFFSET - 1``, ``T1|.25 SPOT|H1|...``) and
    ``MACHINE GROUP-1``. Mastercam writes each operation's comment as a plain comment line
    (``(CONTOUR)``), which the rule above takes.
"""
from __future__ import annotations

import bisect
import re

__all__ = ['OperationContext', 'operation_name', 'NO_OPERATION']

NO_OPERATION = ''
_MAX_NAME = 60
# FreeCAD "begin operation: NAME"; Estlcam's default operation start text "No. N: NAME"
_NAMED = re.compile(r'^(?:begin\s+operation\s*:|no\.\s*\d+\s*:)\s*(?P<name>.+)$',
                    re.IGNORECASE)
# "Toolpath: NAME" and Vectric's "Toolpath:- NAME", some posts adding " Tool: TOOLNAME"
_TOOLPATH = re.compile(r'^toolpath\s*:-?\s*(?P<name>.+?)(?:\s+tool\s*:.*)?$', re.IGNORECASE)
_JSCUT = re.compile(r'^operation\s*:\s*(?P<n>\d+)\s*$', re.IGNORECASE)
_NOT_NAMES = re.compile(
    r'^(?:msg\b|debug\b|print\b|log|probe|abs\b|end\s+operation|finish\s+operation|'
    r'begin\s+(?:preamble|postamble)|end\s+(?:preamble|postamble)|'
    r't\s*\d+\b.*(?:d\s*=|dia)|tool\s+change|'
    # Mastercam: header lines "KEY - value", tool table "T1|...", "MACHINE GROUP-1"
    r'(?:program\s+name|mcx\s+file|nc\s+file|material|post\s+dev|date|time)\s*[-=]|'
    r't\d+\s*\||machine\s+group\b)', re.IGNORECASE)
# Mastercam's tool lines anywhere in the comment: "TOOL - 1 DIA. OFF. ...", "TOOL - 1 OFFSET"
_MASTERCAM_TOOL = re.compile(r'\btool\s*-\s*\d+\s+(?:.*\bdia\.\s*off\b|offset\b)',
                             re.IGNORECASE)
_COMMENTS = re.compile(r'\(([^()]*)\)|;(.*)$')


def operation_name(line: str, *, explicit_only: bool = False) -> str | None:
    """The operation a comment-only source line names, or ``None`` (see the module doc).

    Parameters
    ----------
    line
        A raw source line whose code part is empty (only comments and blanks).
    explicit_only
        Only the explicit forms (``begin operation:``, ``Toolpath:``, ``Operation: N``,
        ``No. N:``), not a plain section comment.

    Returns
    -------
    str or None
        The name (stripped, at most 60 characters), or ``None`` when the comment is not an
        operation name.
    """
    texts = [(a or b).strip() for a, b in _COMMENTS.findall(line)]
    text = ' '.join(t for t in texts if t)
    if not text:
        return None
    m = _NAMED.match(text) or _TOOLPATH.match(text)
    if m:
        return m.group('name').strip()[:_MAX_NAME]
    m = _JSCUT.match(text)
    if m:
        return f'operation {m.group("n")}'
    if explicit_only or len(text) > _MAX_NAME or ':' in text or '=' in text:
        return None
    if _NOT_NAMES.match(text) or _MASTERCAM_TOOL.search(text):
        return None
    return text


class OperationContext:
    """The table of ``(operation, subroutine, tool)`` contexts and the change marks.

    Attributes
    ----------
    table
        Contexts in order of first use; index 0 is the start (no operation, no
        subroutine, tool 0 = none loaded).
    marks
        ``(move ordinal, context index)``, ordinals increasing: from that move on, that
        context.
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Back to the start: one context, no marks after it (the lists are cleared in
        place: a reader may hold them)."""
        start = (NO_OPERATION, '', 0)
        if not hasattr(self, 'table'):
            self.table: list[tuple[str, str, int]] = []
            self.marks: list[tuple[int, int]] = []
        self.table[:] = [start]
        self._index = {start: 0}
        self.marks[:] = [(0, 0)]
        self.operation = NO_OPERATION
        self.subroutine = ''
        self.tool = 0
        self.explicit = False                 # an explicit operation form was seen

    def _change(self, ordinal: int) -> None:
        key = (self.operation, self.subroutine, self.tool)
        index = self._index.get(key)
        if index is None:
            index = self._index[key] = len(self.table)
            self.table.append(key)
        if self.marks[-1][1] == index:
            return
        if self.marks[-1][0] == ordinal:
            self.marks[-1] = (ordinal, index)      # no move in between: replace
        else:
            self.marks.append((ordinal, index))

    def comment(self, line: str, ordinal: int) -> None:
        """A comment-only source line before move ``ordinal``.

        Once a program has named an operation in an explicit form, its plain comment lines
        are notes within operations (jscut's ``; plunge``), not names.
        """
        name = operation_name(line, explicit_only=self.explicit)
        if name is None:
            return
        if not self.explicit and operation_name(line, explicit_only=True) is not None:
            self.explicit = True
        if name != self.operation:
            self.operation = name
            self._change(ordinal)

    def set_tool(self, tool: int, ordinal: int) -> None:
        """Tool ``tool`` loaded before move ``ordinal``."""
        if tool != self.tool:
            self.tool = int(tool)
            self._change(ordinal)

    def set_subroutine(self, name: str, ordinal: int) -> None:
        """Subroutine ``name`` ('' for the main program) runs from move ``ordinal`` on."""
        if name != self.subroutine:
            self.subroutine = name
            self._change(ordinal)

    def index_at(self, ordinal: int) -> int:
        """The context index of move ``ordinal``."""
        pos = bisect.bisect_right(self.marks, (ordinal, len(self.table))) - 1
        return self.marks[max(pos, 0)][1]
