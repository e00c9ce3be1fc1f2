"""Non-motion words of the interpreter: G-code lookup, F, G4, M codes, stops.

A mixin of :class:`~.interp.Interpreter` (split off along this seam to keep modules small).
"""
from __future__ import annotations

from collections.abc import Sequence
import math
from typing import Any, cast, NoReturn, TYPE_CHECKING

from .codes import ALLOWED_LETTERS, G_CODES, G_UNSUPPORTED, M_CODES, UNSUPPORTED_LETTERS
from ..dialect import CONTROL_MODE_CODES, USER_M_CODES
from ..read.lexer import blank_comments, locate_word
from ...errors import GcodeError
from ..program import Move, MoveKind

if TYPE_CHECKING:
    from .state import InterpreterState, Lines
else:
    InterpreterState = object     # the declarations are for the type checker only

__all__ = ['ModesMixin']

_SPINDLE = {'cw': 1, 'ccw': -1, 'off': 0}


class ModesMixin(InterpreterState):
    """F, G4, M codes and the G-code table lookup for :class:`~.interp.Interpreter`."""

    __slots__ = ()

    def set_feed(self, text: str | float) -> None:
        """Read F: m/s under G94 (in the units now in force), 1/min under G93; under G95 F
        is per spindle revolution and the feed follows the spindle speed S."""
        f = self.num('F', text)
        if f < 0.0:
            self.fail('negative feed rate', 'F')
        if self.feed_per_rev is not None:
            self.feed_per_rev = f * self.scale
            self.feed = self.feed_per_rev * self.rpm / 60.0 or None
            return
        # Under G93 the raw number (1/min) is kept; it is used only on this line.
        self.feed = f if self.inverse_time else f * self.scale / 60.0

    def dwell(self, d: dict[str, str | float]) -> None:
        """Emit the G4 dwell of P (the dialect's unit; see :mod:`.dialect`)."""
        if 'P' not in d:
            self.fail('G4 dwell needs a P word (seconds)', 'G', value=4.0)
        seconds = self.num('P', d['P']) * self.p_unit
        if self.dialect.dwell_p == 'haas' and not self.word_has_point('P'):
            seconds *= 0.001                # Haas: P without a decimal point is ms
        if seconds < 0.0:
            self.fail('negative dwell time', 'P')
        p = self.pos
        self.emit(Move(kind=MoveKind.DWELL, line=self.lineno, start=p, end=p,
                       dwell_s=seconds))

    def dwell_x(self, d: dict[str, str | float]) -> None:
        """Fanuc ``G4 X``: the dwell in seconds (X is then no axis word)."""
        x = self.num('X', d.pop('X'))
        if 'P' in d:
            self.fail('G4 with both X and P (Fanuc: give one dwell time)', 'P')
        d['P'] = x / self.p_unit

    def word_has_point(self, letter: str) -> bool:
        """True if the line's ``letter`` word was written with a decimal point."""
        src = self.src
        raw = cast('Lines', self.lines)[self.lineno - 1] if src is None else src.text
        code = blank_comments(raw, file=self.file, line=self.lineno)
        return '.' in locate_word(code, letter)[1]

    def m_words(self, ml) -> list[str]:
        """Check the M words of a line; return the stop actions (run after the motion)."""
        groups: dict[str, int] = {}
        actions = []
        for text in ml:
            value = self.num('M', text)
            code = int(value)
            if code != value or code not in M_CODES:
                self.harmless_m(value)
                continue
            group, action = M_CODES[code]
            if group in groups and {groups[group], code} != {7, 8}:
                self.fail(f'M{groups[group]} and M{code} are in the same modal group on one '
                          'line', 'M', value=value)
            groups[group] = code
            if action is None:
                continue
            if group == 'stop':
                actions.append(action)
            elif group == 'spindle':
                self.spindle = _SPINDLE[action]
            else:
                self.tool_change = True
                self.pending_lineno = self.lineno
        return actions

    def harmless_m(self, value: float) -> None:
        """An M code outside M_CODES: accepted if the dialect calls it harmless I/O."""
        code = int(value)
        if code == value and USER_M_CODES[0] <= code <= USER_M_CODES[1] \
                and self.dialect.user_m:
            self.user_m(code)
            return
        if code != value or code not in self.dialect.harmless_m:
            self.fail(f'M{value:g} is not supported (not a machine function the '
                      f'{self.dialect.name} dialect lets pass; see --dialect)', 'M',
                      value=value)
        self.io_lineno = self.lineno       # its P, Q, E, L words belong to it
        self.pending_lineno = self.lineno
        if code == 61:
            self.tool_change = True        # M61 Q: the tool in the spindle is Q
        elif 62 <= code <= 68 and self.comp.active:
            self.fail('Cannot set motion output with cutter radius compensation on', 'M',
                      value=value)

    def user_m(self, code: int) -> None:
        """M100-M199 (``Dialect.user_m``): LinuxCNC runs the user's program ``M1nn`` from
        its ``USER_M_PATH`` with the line's P and Q as arguments and waits for it; it moves
        no axis the interpreter knows of, so it is no motion here, with one warning per
        code."""
        self.user_m_lineno = self.lineno   # its P and Q words are the program's arguments
        key = f'M{code}'
        if key not in self.warned:
            self.warned.add(key)
            self.warnings.append(f'{self.file}:{self.lineno}: M{code} is a user M code '
                                 f'(LinuxCNC runs the program M{code} from USER_M_PATH): '
                                 'no motion is simulated for it, and its run time is not '
                                 'counted')

    def stop(self, actions: list[str]) -> None:
        """STOP moves for M0/M1/M2/M30; M2/M30 end the program."""
        for action in actions:
            p = self.pos
            if action == 'end' and (self.comp.active or self.routing):
                self.moves += self.comp.finish(fail=self.fail)
                self.routing = self.comp.engaged
            self.emit(Move(kind=MoveKind.STOP, line=self.lineno, start=p, end=p))
            if action == 'end':
                self.ended = True

    def unknown_letter(self, d: dict[str, str | float]) -> None:
        """Words off the common path: polar ``@``/``^`` (made X/Y), axes the user chose to
        ignore (dropped, one warning each); fail at any other letter the interpreter does
        not accept."""
        if '@' in d or '^' in d:
            self.polar(d)
        for letter in list(d):
            if letter in ALLOWED_LETTERS:
                continue
            if self.rotary is not None and letter in self.rotary.axes:
                self.rotary.word(letter, self.num(letter, d.pop(letter)), self.lineno,
                                 self.fail)
                continue
            if letter in self.ignore_axes:
                del d[letter]
                if letter not in self.warned:
                    self.warned.add(letter)
                    self.warnings.append(f'{self.file}:{self.lineno}: axis {letter} words are '
                                         'ignored (--ignore-axes): its motion is not '
                                         'simulated')
                continue
            if letter in UNSUPPORTED_LETTERS:
                self.fail(f'{UNSUPPORTED_LETTERS[letter]}: a machine with that axis cannot '
                          f'be simulated; --ignore-axes {letter} drops its words', letter)
            self.fail(f'unknown word letter {letter!r}', letter)

    def fail_at_char(self, msg: str, char: str) -> NoReturn:
        """Fail at the first ``char`` of the line outside comments (for ``@`` and ``^``,
        which are no letters for the lexer's word finder)."""
        src = self.src
        if src is None:
            file, line, raw = self.file, self.lineno, cast('Lines', self.lines)[self.lineno - 1]
        else:
            file, line, raw = src.file, src.line, src.text
        code = blank_comments(raw, file=file, line=line)
        col = code.find(char) + 1
        raise GcodeError(msg, file=file, line=line, column=max(col, 1),
                         text=code[max(col - 1, 0):][:20].strip())

    def polar(self, d: dict[str, str | float]) -> None:
        """LinuxCNC's polar words in the XY plane: ``@`` distance, ``^`` angle [degrees]
        from the program origin (G90), or added to the current point's (G91)."""
        if 'X' in d or 'Y' in d:
            self.fail_at_char('polar coordinates (@, ^) cannot be combined with X or Y on '
                              'one line', '@' if '@' in d else '^')
        x, y, _ = self.coords.to_program(self.pos)
        r = math.hypot(x, y) / self.scale
        a = math.degrees(math.atan2(y, x))
        if self.absolute:
            r = self.num('@', d.pop('@')) if '@' in d else r
            a = self.num('^', d.pop('^')) if '^' in d else a
        else:
            dr = self.num('@', d.pop('@')) if '@' in d else 0.0
            da = self.num('^', d.pop('^')) if '^' in d else 0.0
            # A G91 canned cycle repeats polar increments itself (cycles.py).
            self.polar_inc = (dr * self.scale, math.radians(da))
            self.polar_line = self.lineno
            r += dr
            a += da
        px = r * math.cos(math.radians(a))
        py = r * math.sin(math.radians(a))
        if not self.absolute:       # target() adds increments to the current point
            px -= x / self.scale
            py -= y / self.scale
        d['X'] = px
        d['Y'] = py

    def split_repeated(self, words: Sequence[tuple[str, str | float]],
                       d: dict[str, str | float]) -> tuple[list[str | float], list[str | float]]:
        """G and M words of a line with several of them; other letters must not repeat."""
        gl: list[str | float] = []
        ml: list[str | float] = []
        seen: set[str] = set()
        for letter, text in words:
            if letter == 'G':
                gl.append(text)
            elif letter == 'M':
                ml.append(text)
            elif letter in seen:
                self.fail(f'{letter} word repeated on one line', letter, nth=1)
            else:
                seen.add(letter)
        d.pop('G', None)
        d.pop('M', None)
        return gl, ml

    def control_mode(self, code: int) -> None:
        """A G code selecting the control's own contouring mode (``Dialect.control_modes``):
        one warning per code; the line's P/Q/E/L words are its settings."""
        self.io_lineno = self.lineno
        key = f'G{code}'
        if key not in self.warned:
            self.warned.add(key)
            self.warnings.append(
                f'{self.file}:{self.lineno}: {CONTROL_MODE_CODES[code]} changes how the '
                'control smooths and accelerates; it is not modelled (the planner uses the '
                'machine config\'s limits) and its words are ignored')

    def g_lookup(self, text: str | float) -> tuple[str, Any, int]:
        """(group, argument, 10 x code) of a G word, or fail naming why it is refused."""
        value = self.num('G', text)
        code = round(value * 10.0)
        whole = abs(value * 10.0 - code) <= 1e-6
        if whole and code in self.dialect.control_modes:
            return 'control_mode', None, code
        if whole and code in G_CODES:
            group, arg = G_CODES[code]
            return group, arg, code
        if whole and code in G_UNSUPPORTED:
            self.fail(f'G{value:g} is not supported ({G_UNSUPPORTED[code]})', 'G', value=value)
        self.fail(f'unknown G code G{value:g}', 'G', value=value)
