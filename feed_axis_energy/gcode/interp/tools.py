"""The tool table part of :class:`.coords.Coords`: tool selection, G10 L1/L10/L11, tool
length offsets G43/G43.1/G43.2/G49 and the cutter radius for G41/G42.

LinuxCNC 2.9 semantics (``interp_convert.cc``: ``convert_setup_tool``,
``convert_tool_length_offset``); T0/H0 is "no tool" (length and radius 0).

A tool the table lacks (the machine's table is rarely at hand when a program is planned):

* by default it has length and radius 0 and the interpreter warns once per tool number
  (``on_missing_tool``), where its data are used: G43/G43.2 H (or the loaded tool),
  G41/G42 D (or the loaded tool). G10 L1/L10/L11 on such a tool adds it to the table,
  starting from length and radius 0. A T word, M6 and M61 Q use no data and do not warn.
* with ``strict_tools`` (``--strict-tools``, ``gcode.strict_tools``) it is an error, as in
  LinuxCNC with its tool table: at the T word (LinuxCNC: "Requested tool N not found in
  the tool table"), at M61's Q, at the H or D word (at the G word when the loaded tool is
  meant) and at G10's P.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import cast, TYPE_CHECKING

from ..settings import MAX_TOOL_NUMBER, ToolSpec
from .fail import Fail, raise_unplaced

if TYPE_CHECKING:
    from .coordstate import CoordsState
else:
    CoordsState = object        # the declarations are for the type checker only

__all__ = ['ToolTable', 'tool_spec', 'MAX_OFFSET_M', 'missing_tool_message']

Vec3 = tuple[float, float, float]

_AXES = ('X', 'Y', 'Z')
_MM = 1000.0
MAX_OFFSET_M = 1.0e3
"""Largest offset, stored position or tool length [m] accepted (an absurd value would plan
an endless move or overflow to inf); :mod:`.coords` uses it for every offset."""
G59_3_Z_PARAM = 5383
"""Z of coordinate system 9 (G59.3), the fixture G10 L11 measures against."""


def missing_tool_message(number: int) -> str:
    """The error of a tool the table lacks under ``strict_tools``."""
    return (f'tool {number} is not in the tool table (add it under gcode.tools of the machine '
            'config or with --tool; without --strict-tools it would run with length and '
            'radius 0)')


def tool_spec(entry: object) -> ToolSpec:
    """A tool table entry as ToolSpec.

    Accepted: a ToolSpec, a number (the radius [m]), a ``(radius_m, length_m)`` pair, a
    mapping or an object with ``radius_m`` (and optionally ``length_m``).
    """
    if isinstance(entry, ToolSpec):
        return entry
    if isinstance(entry, (int, float)) and not isinstance(entry, bool):
        return ToolSpec(radius_m=float(entry))
    if isinstance(entry, Mapping):
        return ToolSpec(radius_m=float(entry.get('radius_m', 0.0)),
                        length_m=float(entry.get('length_m', 0.0)))
    if hasattr(entry, 'radius_m'):
        return ToolSpec(radius_m=float(entry.radius_m),
                        length_m=float(getattr(entry, 'length_m', 0.0)))
    radius, length = cast('tuple[float, float]', entry)     # a pair (or the error)
    return ToolSpec(radius_m=float(radius), length_m=float(length))


class ToolTable(CoordsState):
    """Tool table methods of :class:`.coords.Coords` (a mixin: the state lives there).

    Uses ``tools`` ({T: ToolSpec}), ``tlo``, ``selected_tool``, ``loaded_tool``, ``g5x``,
    ``g92``, ``params`` and ``_update()`` of the class it is mixed into.
    """

    __slots__ = ()

    def _g10_tool(self, l_word: int, number: int, values: Mapping[str, float],
                  position: Vec3, *, fail: Fail) -> None:
        """G10 L1 (values), L10 (the current point reads Z in the active system with the new
        length), L11 (the same in G59.3, without G92) -- LinuxCNC's convert_setup_tool."""
        if not 1 <= number <= MAX_TOOL_NUMBER:
            fail(f'P value out of range with G10 L{l_word} (a tool number 1 ... '
                 f'{MAX_TOOL_NUMBER})', 'P')
        old = self.tools.get(number)
        if old is None:
            old = self.missing_tool(number, letter='P', fail=fail)
        for axis in ('X', 'Y'):
            if axis in values:
                fail(f'tool {axis} offsets (lathe tools) are not supported', axis)
        if 'Z' not in values and 'R' not in values:
            fail(f'G10 L{l_word} without offsets has no effect', 'G')
        radius = values.get('R', old.radius_m)
        if not 0.0 <= radius <= 1.0:
            fail(f'tool radius {radius:.6g} m: expected 0 ... 1 m', 'R')
        length = old.length_m
        if 'Z' in values:
            length = values['Z']
            if l_word == 10:
                # the machine Z seen in the active system with no tool length offset
                length = position[2] - self.g5x[2] - self.g92[2] - values['Z']
            elif l_word == 11:
                length = position[2] - self.params.get(G59_3_Z_PARAM) / _MM - values['Z']
            if not abs(length) <= MAX_OFFSET_M:
                fail(f'tool length beyond {MAX_OFFSET_M:g} m', 'Z')
        self.tools[number] = ToolSpec(radius_m=radius, length_m=length)

    # -- tools ----------------------------------------------------------------------------
    def select_tool(self, number: int) -> None:
        """T word: the tool the next M6 loads (not checked against the table here)."""
        self.selected_tool = number

    def change_tool(self) -> None:
        """M6: the selected tool becomes the loaded one (the offset stays until G43/G49)."""
        self.loaded_tool = self.selected_tool

    def set_loaded_tool(self, number: int) -> None:
        """M61 Q..: declare the loaded tool without a change."""
        self.selected_tool = self.loaded_tool = number

    def tool(self, number: int | None, *, letter: str, fail: Fail = raise_unplaced) -> ToolSpec:
        """The table entry of tool ``number`` (``None``: the loaded tool); T0 = no tool.

        Raises through ``fail`` at ``letter`` when the table lacks the tool.
        """
        if number is None:
            number = self.loaded_tool
        if number == 0:
            return ToolSpec()
        spec = self.tools.get(number)
        if spec is None:
            return self.missing_tool(number, letter=letter, fail=fail)
        return spec

    def missing_tool(self, number: int, *, letter: str, fail: Fail = raise_unplaced) -> ToolSpec:
        """Tool ``number``, which the table lacks: length and radius 0 (``on_missing_tool``
        is told), or with ``strict_tools`` the error at ``letter``."""
        if self.strict_tools:
            fail(missing_tool_message(number), letter)
        if self.on_missing_tool is not None:
            self.on_missing_tool(number)
        return ToolSpec()

    def check_tool_number(self, number: int, *, letter: str,
                          fail: Fail = raise_unplaced) -> None:
        """A T word or M61 Q: with ``strict_tools`` a tool the table lacks is an error (as
        LinuxCNC refuses to select it); otherwise nothing (no data of it are used yet)."""
        if self.strict_tools and number != 0 and number not in self.tools:
            fail(missing_tool_message(number), letter)

    def cutter_radius(self, d_word: float | None, *, fail: Fail = raise_unplaced) -> float:
        """Radius [m] for G41/G42 with the line's D word (absent: the loaded tool)."""
        number = None
        if d_word is not None:
            number = int(d_word)
            if number != d_word or number < 0:
                fail('D word must be a tool number (a whole number >= 0)', 'D')
        return self.tool(number, letter='D' if d_word is not None else 'G', fail=fail).radius_m

    def tool_length(self, code: str, h_word: float | None, values: Mapping[str, float], *,
                    fail: Fail = raise_unplaced) -> None:
        """G43 [H..] / G43.1 axes / G43.2 H.. or axes / G49."""
        tlo = list(self.tlo)
        if code == 'G49':
            tlo = [0.0, 0.0, 0.0]
        elif code == 'G43' or (code == 'G43.2' and h_word is not None):
            number = None
            if h_word is not None:
                number = int(h_word)
                if number != h_word or number < 0:
                    fail('H word must be a tool number (a whole number >= 0)', 'H')
            spec = self.tool(number, letter='H' if h_word is not None else 'G', fail=fail)
            if code == 'G43':
                tlo = [0.0, 0.0, spec.length_m]
            else:
                if values:
                    fail('G43.2: Can not have both H and axis words', 'H')
                tlo[2] += spec.length_m
        elif code in ('G43.1', 'G43.2'):
            if not values and code == 'G43.2':
                fail('G43.2: No axes specified and H word missing', 'G')
            for i, axis in enumerate(_AXES):
                if axis in values:
                    tlo[i] = values[axis] + (tlo[i] if code == 'G43.2' else 0.0)
        else:
            raise ValueError(f'not a tool length code: {code!r}')
        self.tlo = cast(Vec3, tuple(tlo))
        self._update()
