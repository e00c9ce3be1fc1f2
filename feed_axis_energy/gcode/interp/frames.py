"""Coordinate-system hooks of the interpreter: work offsets, G10/G92/G52, G43, G53, G28/G30.

A mixin of :class:`~.interp.Interpreter` (split off along this seam to keep modules small):
the interpreter notes a line's coordinate codes (:meth:`CoordsMixin.coord_codes`) and runs
them through :class:`~.coords.Coords` (:meth:`CoordsMixin.apply_coords`); the live values
``#5420..`` and the probe results come from there too.
"""
from __future__ import annotations

import math
from typing import cast, NoReturn, TYPE_CHECKING

from .coords import foreign_codes
from .tools import MAX_OFFSET_M
from .sysvars import fanuc_system_value
from ..program import Move, MoveKind

if TYPE_CHECKING:
    from .coordstate import Vec3
    from .state import InterpreterState
else:
    InterpreterState = object     # the declarations are for the type checker only

__all__ = ['CoordsMixin']

_INF = float('inf')
_AXIS_LETTERS = ('X', 'Y', 'Z')


class CoordsMixin(InterpreterState):
    """Coordinate-system codes and values for :class:`~.interp.Interpreter`."""

    __slots__ = ()

    def offset(self) -> tuple[float, float, float]:
        """``machine - program`` [m]: work offset, G92, G52 and tool length (canned cycles;
        they are refused in a rotated coordinate system, where this is no translation)."""
        if self.rotated:
            self.fail('canned cycles in a rotated coordinate system (G10 L2 R) are not '
                      'supported', 'G', value=float(cast(int, self.motion)))
        return self.coords.offset

    def coord_codes(self, group: str, arg: object, code: int) -> None:
        """Note a code of coords.py on this line; :meth:`apply_coords` runs them."""
        if self.coord_line != self.lineno:
            self.coord_line = self.lineno
            self.coord_todo = {}
        self.coord_todo[group] = arg
        self.coord_todo['_code_' + group] = code
        if arg in ('G43', 'G43.2'):
            self.g43_lineno = self.lineno       # its H word is legal here

    def apply_coords(self, d: dict[str, str | float], explicit_motion: bool = False) -> bool:
        """Run the line's coordinate codes; True if they used the axis words (or moved)."""
        todo = self.coord_todo
        self.coord_todo = {}
        coords = self.coords
        coords.selected_tool = self.tool_selected
        coords.loaded_tool = self.tool_loaded

        def value(letter: str) -> float | None:
            return self.num(letter, d[letter]) if letter in d else None

        def fail(msg: str, letter: str) -> NoReturn:
            if letter != 'G':
                self.fail(msg, letter)
            code = next(todo['_code_' + g] for g in ('nonmodal', 'tool_length', 'coord')
                        if '_code_' + g in todo)
            self.fail(msg, 'G', value=cast(int, code) / 10)

        rot = self.rotary
        if (rot is not None and rot.pending(self.lineno) and todo.get('nonmodal') in ('G92', 'G52')
                and not any(letter in d for letter in _AXIS_LETTERS)):
            # rotary words only: X, Y, Z keep their offsets
            rot.coords(todo, value, lineno=self.lineno, system=self.coord)
            return True
        control, foreign = foreign_codes(self.dialect.name, todo, value)
        for code in foreign:
            if code not in self.warned:
                self.warned.add(code)
                self.warnings.append(f'{self.file}:{self.lineno}: {code} is not a {control} '
                                     'code (the control would stop here); simulated as '
                                     'LinuxCNC runs it')
        effect = coords.execute(todo, value, position=self.pos, scale=self.scale,
                                motion=self.motion, absolute=self.absolute,
                                comp_active=self.comp.active,
                                explicit_motion=explicit_motion, fail=fail)
        self.frame = coords.offset
        self.rotated = coords.rotated
        self.coord = coords.system
        rotary_data = False
        if self.rotary is not None:
            rotary_data = (self.rotary.pending(self.lineno)
                           and todo.get('nonmodal') in ('G10', 'G92', 'G52'))
            self.rotary.coords(todo, value, lineno=self.lineno, system=self.coord)
        if effect.home is not None:
            self.home_return(d, effect.home)
            return True
        if todo.get('nonmodal') == 'G53':
            self.machine_words(d)
        return effect.axes_used or rotary_data

    def machine_words(self, d: dict[str, str | float]) -> None:
        """G53: this line's axis words are machine coordinates; give them as program ones
        (in a rotated system X and Y both, since each depends on the other)."""
        s = self.scale
        end = list(self.pos)
        given = [letter in d for letter in _AXIS_LETTERS]
        for i, letter in enumerate(_AXIS_LETTERS):
            if given[i]:
                v = self.num(letter, d[letter]) * s
                if not abs(v) <= MAX_OFFSET_M:
                    self.fail(f'G53 {letter}: not a machine position within '
                              f'{MAX_OFFSET_M:g} m of the machine origin', letter)
                end[i] = v
        if self.rotated and (given[0] or given[1]):
            given[0] = given[1] = True
        program = self.coords.to_program(cast('Vec3', tuple(end)))
        for i, letter in enumerate(_AXIS_LETTERS):
            if given[i]:
                d[letter] = program[i] / s

    def rotated_target(self, d: dict[str, str | float]) -> tuple[float, float, float]:
        """:meth:`target` in a rotated coordinate system: the point is turned as a whole; on
        an arc line the I/J words become machine-frame offsets (G17 only)."""
        coords = self.coords
        s = self.scale
        prog = list(coords.to_program(self.pos))
        for i, letter in enumerate(_AXIS_LETTERS):
            if letter in d:
                v = self.num(letter, d[letter]) * s
                prog[i] = v if self.absolute else prog[i] + v
        if (self.motion == 2 or self.motion == 3) and ('I' in d or 'J' in d or 'K' in d):
            if self.plane != 17:
                self.fail(f'G{self.plane} arcs in a rotated coordinate system (G10 L2 R) '
                          'are not supported', next(c for c in 'IJK' if c in d))
            i = self.num('I', d['I']) if 'I' in d else 0.0  # type: ignore[assignment]  # (a new i)
            j = self.num('J', d['J']) if 'J' in d else 0.0
            d['I'], d['J'] = coords.rotate(i, j)
        return coords.to_machine(cast('Vec3', tuple(prog)))

    def home_return(self, d: dict[str, str | float], code: str) -> None:
        """G28/G30: rapid to the intermediate point, then the named axes (all without axis
        words) to the stored position; both rapids stop at their end."""
        if self.home is None and code == 'G28' and not self.coords.home_used:
            self.warnings.append(f'{self.file}:{self.lineno}: G28 returns to the stored '
                                 'position #5161..#5163 (0 unless the program set it): the '
                                 'machine config has no home_m')
        if self.series:
            self.end_series()
        named = cast('tuple[bool, bool, bool]', tuple(letter in d for letter in _AXIS_LETTERS))
        rot = self.rotary
        rotary_only = not any(named) and rot is not None and rot.pending(self.lineno)
        rotary = None if rot is None else rot.home(self.lineno, any(named), system=self.coord,
                                                   absolute=self.absolute)
        path = self.coords.home_path(code, self.target(d), named,
                                     fail=lambda msg, letter: self.fail(msg, 'G', value=float(
                                         code[1:])))
        if rotary_only:
            path = [self.pos, self.pos]     # rotary words only: X, Y, Z stay
        for k, end in enumerate(path):
            # both rapids, even of zero length: LinuxCNC issues both (the planner drops them)
            move = Move(kind=MoveKind.RAPID, line=self.lineno, start=self.pos, end=end,
                        feed_m_s=_INF, exact_stop=True, length_m=math.dist(self.pos, end))
            if rot is not None and rotary is not None:
                move = rot.move(move, rotary[k], inverse_time=False, feed=None, scale=self.scale)
            self.emit(move)
            self.pos = end

    def system_value(self, key: int | str) -> float | None:
        """Live coordinate values for ``Parameters.provider`` (``#5420..#5428``, ``#5400``,
        ``#5401..#5410``, ``#<_x>``.., ``#<_abs_x>``.., ``#<_coord_system>``, tool numbers;
        in Macro B dialects Fanuc's ``#4001..``, ``#5001..``: :mod:`.sysvars`);
        ``None`` for any other key."""
        if self.dialect.fanuc_macro and isinstance(key, int) and 4000 < key < 5100:
            value = fanuc_system_value(self, key)
            if value is not None:
                return value
        if self.rotary is not None:
            value = self.rotary.system_value(key, self.coord)
            if value is not None:
                return value
        coords = self.coords
        coords.selected_tool = self.tool_selected
        coords.loaded_tool = self.tool_loaded
        return coords.system_value(key, self.pos, self.scale)

    def probe_result(self) -> None:
        """After a G38.x move: the probe parameters #5061.. (see Coords.probe_result)."""
        self.coords.probe_result(self.pos, self.scale)
