"""Canned cycles and cutter compensation as the interpreter runs them.

A mixin of :class:`~.interp.Interpreter` (split off along this seam to keep modules small):
the glue between the modal state and the pure :mod:`.cycles` and :mod:`.cutter` modules,
and the one place where every move leaves the interpreter (:meth:`CompMixin.emit`).
"""
from __future__ import annotations

from collections.abc import Mapping
import math
from typing import cast, NoReturn, TYPE_CHECKING

from .codes import COMP_FORBIDDEN
from .tools import missing_tool_message
from ..expand.cutter import LEFT, RIGHT
from ..expand.cycles import CycleSpec, expand_cycle
from ..program import Move, MoveKind

if TYPE_CHECKING:
    from .state import InterpreterState
else:
    InterpreterState = object     # the declarations are for the type checker only

__all__ = ['CompMixin']

_INF = float('inf')
# Words of a canned-cycle line (cycles.py checks which the cycle needs).
_CYCLE_LENGTH_WORDS = ('X', 'Y', 'Z', 'R', 'I', 'J', 'K', 'Q')


class CompMixin(InterpreterState):
    """Canned cycles, cutter compensation and the move output of the interpreter."""

    __slots__ = ()

    def comp_forbidden(self, group: str, arg: object, code: int) -> None:
        """Refuse what LinuxCNC refuses while cutter compensation is on (a plane or
        coordinate-system change, any G61/G64, G98/G99)."""
        if group == 'plane' and arg == self.plane:
            return
        if group == 'coord' and arg == self.coord:
            return
        self.fail(COMP_FORBIDDEN[group], 'G', value=code / 10)

    def emit(self, move: Move) -> None:
        """Append a move, through the cutter compensation while it is engaged."""
        if self.routing:
            self.route(move)
        else:
            self.moves.append(move)

    def route(self, move: Move) -> None:
        """Feed a programmed move to the cutter compensation; keep what it hands back."""
        comp = self.comp
        self.moves += comp.feed(move, fail=self.fail)
        self.routing = comp.engaged

    def close(self) -> None:
        """End of the program text: release the moves the compensation still holds; drop
        (with a warning) a G5.2 curve no G5.3 ended."""
        self.nurbs_close()
        comp = self.comp
        if comp.active or self.routing:
            self.moves += comp.finish(fail=self.fail, line=self.lineno)
            self.routing = False

    def end_series(self) -> None:
        """A motion that is not a canned cycle ends the series (LinuxCNC forgets R, Z)."""
        self.cycle_memory = self.cycle_memory.end_series()
        self.series = False

    def select_tool(self, text: str | float) -> None:
        """T word: select a tool (it is loaded by M6)."""
        t = self.num('T', text)
        if t != int(t) or t < 0:
            self.fail('T (tool number) must be a whole number >= 0', 'T')
        self.coords.check_tool_number(int(t), letter='T', fail=self.fail)
        self.tool_selected = int(t)

    def before_motion(self, d: dict[str, str | float]) -> None:
        """Work that LinuxCNC does after the modes and before the motion: M6, G40/G41/G42,
        G5.3."""
        if self.tool_change:
            self.tool_change = False
            if self.io_lineno == self.lineno:      # M61 Q
                if 'Q' not in d:
                    self.fail('M61 needs a Q word (the tool number)', 'M', value=61.0)
                q = self.num('Q', d['Q'])
                if q != int(q) or q < 0:
                    self.fail('M61 Q must be a whole number >= 0', 'Q')
                self.coords.check_tool_number(int(q), letter='Q', fail=self.fail)
                self.tool_loaded = self.tool_selected = int(q)
            else:
                self.tool_loaded = self.tool_selected
            if self.on_tool is not None:
                self.on_tool(self.tool_loaded)
        code = self.comp_code
        if code is not None:
            self.comp_code = None
            comp = self.comp
            if code == 40:
                self.moves += comp.finish(fail=self.fail, line=self.lineno)
            else:
                comp.units_m = self.scale
                side = LEFT if code in (41, 411) else RIGHT
                comp.start(side, self.comp_radius(d, code), self.plane, fail=self.fail,
                           line=self.lineno)
            self.routing = comp.engaged
        if self.nurbs.end_line == self.lineno:
            self.nurbs_end(d)           # G5.3 (LinuxCNC's modal group 0, after G40..G42)

    def d_number(self, text: str | float) -> int:
        """The tool number of a D word (for G41/G42)."""
        t = self.num('D', text)
        if t != int(t) or t < 0:
            self.fail('D (tool number for G41/G42) must be a whole number >= 0', 'D')
        return int(t)

    def comp_radius(self, d: dict[str, str | float], code: int) -> float:
        """Tool radius [m] for G41/G42 (tool table via D, the D of an earlier line in the
        Fanuc/Haas dialects, or the loaded tool), G41.1/G42.1."""
        if code > 100:
            if 'D' not in d:
                self.fail(f'G{code / 10:g} needs a D word (the tool diameter)', 'G',
                          value=code / 10)
            return 0.5 * self.num('D', d['D']) * self.scale
        if 'D' in d:
            number, letter = self.d_number(d['D']), 'D'
            if self.dialect.modal_d:
                self.d_selected = number
        elif self.dialect.modal_d and self.d_selected is not None:
            number, letter = self.d_selected, 'G'    # the D of an earlier line (Fanuc, Haas)
        else:
            number, letter = self.tool_loaded, 'G'
        if number == 0:
            return 0.0          # no tool: zero diameter, as LinuxCNC's empty pocket 0
        if number not in self.tools:
            if self.coords.strict_tools:
                self.fail(missing_tool_message(number), letter,
                          value=None if letter == 'D' else code)
            self.missing_tool(number)
            return 0.0
        return _tool_radius(self.tools[number])

    def cycle(self, d: dict[str, str | float], code: int) -> None:
        """Expand a canned-cycle line (cycles.py) into moves."""
        s = self.scale
        num = self.num
        words = {letter: num(letter, d[letter]) * s for letter in _CYCLE_LENGTH_WORDS
                 if letter in d}
        if 'P' in d:
            words['P'] = num('P', d['P']) * self.p_unit
        if 'L' in d:
            words['L'] = num('L', d['L'])
        polar = None
        if self.polar_line == self.lineno and not self.absolute:
            polar = self.polar_inc          # the X/Y made of them are not increments here
            del words['X'], words['Y']
        spec = CycleSpec(code, self.plane, self.pos, words, offset=self.offset(),
                         incremental=not self.absolute, retract=self.retract,
                         feed_m_s=None if self.inverse_time else self.feed,
                         inverse_time=self.inverse_time, cutter_comp=self.comp.active,
                         spindle=self.spindle, polar=polar)
        res = expand_cycle(spec, self.cycle_memory, fail=self.cycle_fail)
        line = self.lineno
        pos = self.pos
        emit = self.emit
        feed = cast(float, self.feed)      # expand_cycle refuses a cycle without a feed
        for prim in res.primitives:
            kind = prim[0]
            if kind == 'rapid' or kind == 'feed':
                end = prim[1]
                rapid = kind == 'rapid'
                emit(Move(kind=MoveKind.RAPID if rapid else MoveKind.LINEAR, line=line,
                          start=pos, end=end, feed_m_s=_INF if rapid else feed,
                          exact_stop=True, length_m=math.dist(pos, end)))
                pos = end
            elif kind == 'dwell':
                emit(Move(kind=MoveKind.DWELL, line=line, start=pos, end=pos,
                          dwell_s=prim[1]))
            else:
                emit(Move(kind=MoveKind.STOP, line=line, start=pos, end=pos))
        self.pos = res.end
        self.cycle_memory = res.memory
        self.series = True

    def cycle_fail(self, msg: str, letter: str) -> NoReturn:
        """Fail at a word of a cycle line (``G`` means the cycle's own G word)."""
        if letter == 'G' and self.motion is not None:
            self.fail(msg, 'G', value=float(self.motion))
        self.fail(msg, letter)


def _tool_radius(entry: object) -> float:
    """Radius [m] of a tool-table entry: a number, ``(radius_m, length_m)``, a mapping or an
    object with ``radius_m``."""
    if isinstance(entry, Mapping):
        value = entry.get('radius_m', 0.0)
    elif hasattr(entry, 'radius_m'):
        value = entry.radius_m
    elif isinstance(entry, (tuple, list)):
        value = entry[0]            # (radius_m, length_m)
    else:
        value = entry
    return float(value)
