"""Rotary axes A, B, C of the interpreter: their words, positions, offsets and moves.

One :class:`RotaryAxes` per run of :class:`~.interp.Interpreter`, which hands it the modal
state it needs with each call. It exists only for the rotary axes the machine
declares (``rotary_axes``; the others stay refused, or dropped with ``--ignore-axes``), so
a program without rotary words costs one attribute test per unusual line.

The rules are LinuxCNC 2.9's (rs274ngc ``convert_straight``, ``inverse_time_rate_straight``,
``find_straight_length`` and ``convert_home``; the user manual's *Feed Rate* section):

* rotary words are degrees in G20 and G21 alike; G90 makes them absolute in the active
  coordinate system (work offset G54..G59.3 and G92/G52 offset of the axis, set with
  ``G10 L2``/``L20`` and ``G92``/``G52`` like X, Y, Z), G91 incremental; ``G53`` takes them
  as machine positions. Rotary axes are not wrapped (LinuxCNC's default): ``A370`` after
  ``A0`` turns 370 degrees.
* G94: when X, Y or Z move, F is the XYZ path speed and the rotary axes move in step
  (start and end together); a move of rotary axes alone runs at F degrees per minute along
  ``sqrt(dA**2 + dB**2 + dC**2)``. G93: the move takes ``1/F`` minutes either way.
* G0 moves rotary axes at their own limits, together with X, Y, Z.
* G2/G3 with a rotary word: the rotary axes turn linearly along the helix (F on its XYZ
  length).
* G28/G30 without axis words returns every axis, the rotary ones to 0 degrees (LinuxCNC's
  fresh parameter file, #5164..#5166 and #5184..#5186); with axis words only the named
  axes go through the intermediate point to the stored position.

The live position parameters ``#5423..#5425`` and ``#<_a>``.. (``#<_abs_a>``..) give the
rotary positions. Not handled (refused with the line, never skipped): rotary words in a
canned cycle, a spline, probing or rigid tapping, and while cutter radius compensation is on.
The stored rotary parameters (work offsets #5224.., G28 #5164..) are not written: reading
them gives what the parameter table holds (0), not the rotary offset in force.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
import math
from typing import Any, NoReturn

from ..program import Move, MoveKind, ROTARY_AXES

__all__ = ['RotaryAxes', 'DEG']

DEG = math.pi / 180.0
_TINY_M = 1e-12             # an XYZ length below this makes a pure rotary move
_MAX_DEG = 1.0e9            # rotary positions beyond this are no machine's

Fail = Callable[..., NoReturn]


def _zeros() -> list[float]:
    return [0.0, 0.0, 0.0]


@dataclass
class RotaryAxes:
    """Rotary state of a program run (degrees, machine coordinates).

    Attributes
    ----------
    axes
        The letters the machine declares (a subset of A, B, C).
    pos
        Position of A, B, C [deg]; an undeclared axis stays at 0.
    words
        The rotary words of the line ``line`` [deg, as written].
    g5x
        Work offset of A, B, C per coordinate system 1..9 [deg].
    g92, saved_g92
        G92/G52 offset of A, B, C [deg], and the one G92.2 suspended.
    g53_line
        Line that carries G53 (its rotary words are machine positions).
    """

    axes: frozenset[str]
    pos: list[float] = field(default_factory=_zeros)
    words: dict[str, float] = field(default_factory=dict)
    line: int = -1
    g5x: dict[int, list[float]] = field(default_factory=dict)
    g92: list[float] = field(default_factory=_zeros)
    saved_g92: list[float] = field(default_factory=_zeros)
    g53_line: int = -1

    def offset(self, system: int) -> list[float]:
        """``machine - program`` of A, B, C in ``system`` [deg]."""
        g5x = self.g5x.get(system, _zeros())
        return [g5x[i] + self.g92[i] for i in range(3)]

    def word(self, letter: str, value: float, lineno: int, fail: Fail) -> None:
        """Keep a rotary word [deg] of line ``lineno``."""
        if self.line != lineno:
            self.line = lineno
            self.words = {}
        if not abs(value) <= _MAX_DEG:
            fail(f'{letter}{value:g}: not a rotary position (at most {_MAX_DEG:g} degrees)',
                 letter)
        if letter in self.words:
            fail(f'{letter} word repeated on one line', letter, nth=1)
        self.words[letter] = value

    def pending(self, lineno: int) -> bool:
        """True when line ``lineno`` has rotary words not yet used."""
        return self.line == lineno and bool(self.words)

    def first_letter(self) -> str:
        """The first rotary letter of the pending words (for error places)."""
        return next(iter(self.words), 'G')

    def target(self, lineno: int, system: int, absolute: bool) -> list[float]:
        """End position of A, B, C [deg, machine] from the rotary words of ``lineno``."""
        end = list(self.pos)
        if self.line != lineno:
            return end
        off = self.offset(system)
        machine = self.g53_line == lineno
        for i, letter in enumerate(ROTARY_AXES):
            if letter in self.words:
                v = self.words[letter]
                if machine:
                    end[i] = v
                elif absolute:
                    end[i] = v + off[i]
                else:
                    end[i] = self.pos[i] + v
        return end

    def move(self, m: Move, end_deg: list[float], *, inverse_time: bool,
             feed: float | None, scale: float) -> Move:
        """``m`` (a G0/G1/G2/G3 move just built) with the rotary axes going to ``end_deg``.

        ``feed`` is the interpreter's (m/s under G94, 1/min under G93), ``scale`` metres per
        program unit; the feed of a pure rotary move becomes an angular speed [rad/s]
        (module docstring).
        """
        start_deg = self.pos
        self.pos = list(end_deg)
        self.words = {}
        if start_deg == end_deg:
            return m
        rs = (start_deg[0] * DEG, start_deg[1] * DEG, start_deg[2] * DEG)
        re_ = (end_deg[0] * DEG, end_deg[1] * DEG, end_deg[2] * DEG)
        rate = m.feed_m_s
        if m.kind == MoveKind.LINEAR and math.dist(m.start, m.end) < _TINY_M:
            angle = math.dist(rs, re_)                      # [rad]
            if inverse_time:
                rate = angle * float(feed or 0.0) / 60.0
            elif feed:
                # F is degrees per minute here: feed holds F * scale / 60
                rate = float(feed) / scale * DEG
        return replace(m, feed_m_s=rate, rot_start=rs, rot_end=re_)

    def coords(self, todo: Mapping[str, Any], value: Callable[[str], float | None], *,
               lineno: int, system: int) -> None:
        """The rotary part of a line's coordinate codes, after the X, Y, Z part ran (and
        checked L and P): G10 L2/L20, G92/G52 and their cancels, G53."""
        code = todo.get('nonmodal')
        if code == 'G53':
            self.g53_line = lineno
            return
        words = self.words if self.line == lineno else {}
        if code == 'G10':
            l_word, p_word = value('L'), value('P')
            if l_word in (2.0, 20.0) and p_word is not None and words:
                target = system if round(p_word) == 0 else int(round(p_word))
                g5x = list(self.g5x.get(target, _zeros()))
                for i, letter in enumerate(ROTARY_AXES):
                    if letter in words:
                        # L20: the current point reads as the given value
                        g5x[i] = (words[letter] if l_word == 2.0
                                  else self.pos[i] - self.g92[i] - words[letter])
                self.g5x[target] = g5x
        elif code in ('G92', 'G52'):
            g5x = self.g5x.get(system, _zeros())
            for i, letter in enumerate(ROTARY_AXES):
                if letter in words:
                    # G92: the current point reads as the given value; G52: a plain offset
                    self.g92[i] = (self.pos[i] - g5x[i] - words[letter] if code == 'G92'
                                   else words[letter])
        elif code in ('G92.1', 'G92.2'):
            if code == 'G92.2':
                self.saved_g92 = list(self.g92)
            self.g92 = _zeros()
        elif code == 'G92.3':
            self.g92 = list(self.saved_g92)
        if code in ('G10', 'G92', 'G52'):
            self.words = {}

    def system_value(self, key: int | str, system: int) -> float | None:
        """The rotary part of the live position parameters: ``#5423..#5425`` and
        ``#<_a>``, ``#<_b>``, ``#<_c>`` (program coordinates [deg]), ``#<_abs_a>``..
        (machine); ``None`` for any other key."""
        if isinstance(key, int):
            if 5423 <= key <= 5425:
                i = key - 5423
                return self.pos[i] - self.offset(system)[i]
            return None
        name = key.lower().lstrip('_')
        absolute = name.startswith('abs_')
        letter = name[4:] if absolute else name
        if letter not in ('a', 'b', 'c'):
            return None
        i = 'abc'.index(letter)
        return self.pos[i] if absolute else self.pos[i] - self.offset(system)[i]

    def home(self, lineno: int, named_xyz: bool, *, system: int,
             absolute: bool) -> list[list[float]]:
        """G28/G30: the rotary intermediate and end positions [deg]. Without any axis word
        every axis returns (the rotary ones to 0); else only the named ones."""
        words = self.words if self.line == lineno else {}
        via = self.target(lineno, system, absolute)
        if not words and not named_xyz:
            end = _zeros()
        else:
            end = [0.0 if letter in words else via[i] for i, letter in enumerate(ROTARY_AXES)]
        return [via, end]
