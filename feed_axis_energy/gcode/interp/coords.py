"""Coordinate systems, offsets and the tool table: program coordinates <-> machine coordinates.

LinuxCNC 2.9 semantics (``interp_convert.cc``: ``convert_coordinate_system``,
``convert_setup``, ``convert_axis_offsets``, ``convert_home``, ``convert_savehome``,
``convert_tool_length_offset``; ``interp_find.cc``: ``find_ends``, ``find_relative``). For
the X, Y and Z axes::

    machine = R (program + G92/G52 offset) + G5x offset + tool length offset

where R turns X and Y by the active system's rotation (G10 L2 R, #5230 + 20 (k - 1); a pure
translation without it).

* G54..G59, G59.1..G59.3 select coordinate system 1..9; its origin is read from the stored
  parameters ``#5221 + 20 (n - 1)`` (X, Y, Z) when it is selected, as LinuxCNC does.
* G10 L2 P.. sets a system's origin to the given values; G10 L20 P.. sets it so that the
  current point has the given coordinates; P0 = the active system. G10 L1 P.. writes the
  tool table (R = radius, Z = length offset), L10/L11 from the current point.
* G92 shifts the origin so that the current point has the given coordinates; G52 sets the
  same offset to the given values (LinuxCNC treats G52 as a G92 with absolute values);
  G92.1 clears it and its parameters #5211..#5213, G92.2 clears it and keeps them, G92.3
  restores it from them.
* G53: the axis words of this line are machine coordinates (no offset at all).
* G28/G30: a rapid to the line's intermediate point, then the named axes (all without axis
  words) to the stored position ``#5161..#5163`` / ``#5181..#5183`` (machine coordinates);
  G28.1/G30.1 store the current machine position there.
* G43 H.. (H absent: the loaded tool) applies the tool table's length to Z; G43.1 X/Y/Z
  sets the offset directly, G43.2 adds to it; G49 cancels it. A tool the table lacks runs
  with length and radius 0 (one warning per tool), or is an error with ``strict_tools``
  (:mod:`.tools`).

Stored parameters hold lengths in millimetres (LinuxCNC with a millimetre machine
configuration); the live values (``#5420..`` position, ``#<_x>`` ...) are in program units.
The state is pure: no I/O.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
import math
from typing import Any, cast, NamedTuple, TYPE_CHECKING

from .fail import Fail, raise_unplaced
from .stored import G28_PARAM, ParamReadback
from .tools import MAX_OFFSET_M, tool_spec, ToolTable
from ..settings import ToolSpec

if TYPE_CHECKING:
    from .coordstate import ParamStore

__all__ = ['Coords', 'LineEffect', 'ParamTable', 'COORD_G_CODES', 'SYSTEM_NAMES', 'system_param',
           'foreign_codes']

Vec3 = tuple[float, float, float]
Value = Callable[[str], 'float | None']

_AXES = ('X', 'Y', 'Z')
_MM = 1000.0
# G codes this module executes, keyed by round(10 x number): (modal group, argument).
COORD_G_CODES: dict[int, tuple[str, object]] = {
    100: ('nonmodal', 'G10'), 280: ('nonmodal', 'G28'), 281: ('nonmodal', 'G28.1'),
    300: ('nonmodal', 'G30'), 301: ('nonmodal', 'G30.1'), 520: ('nonmodal', 'G52'),
    530: ('nonmodal', 'G53'), 920: ('nonmodal', 'G92'), 921: ('nonmodal', 'G92.1'),
    922: ('nonmodal', 'G92.2'), 923: ('nonmodal', 'G92.3'),
    430: ('tool_length', 'G43'), 431: ('tool_length', 'G43.1'),
    432: ('tool_length', 'G43.2'), 490: ('tool_length', 'G49'),
    540: ('coord', 1), 550: ('coord', 2), 560: ('coord', 3), 570: ('coord', 4),
    580: ('coord', 5), 590: ('coord', 6), 591: ('coord', 7), 592: ('coord', 8),
    593: ('coord', 9),
}
SYSTEM_NAMES = ('G54', 'G55', 'G56', 'G57', 'G58', 'G59', 'G59.1', 'G59.2', 'G59.3')
G92_APPLIED = 5210
G92_PARAM = 5211
SYSTEM_PARAM = 5220


# Coordinate codes a dialect's control lacks (grbl 1.1's G-code list: G10 L2/L20, G28/G30
# (+ .1), G43.1/G49, G53, G54..G59, G92/G92.1 only). The program is simulated as LinuxCNC
# runs it, with a warning, since the control itself would stop at the line.
_FOREIGN = {
    'grbl': ('grbl 1.1', frozenset({'G52', 'G92.2', 'G92.3', 'G43', 'G43.2', 'G59.1', 'G59.2',
                                    'G59.3', 'G10 L1', 'G10 L10', 'G10 L11'})),
}


def foreign_codes(dialect: str, codes: Mapping[str, Any],
                  value: Callable[[str], 'float | None']) -> tuple[str, list[str]]:
    """The codes of a line (as :meth:`Coords.execute` takes them) that ``dialect``'s
    control does not have: ``(control name, [code, ...])``; empty for the others."""
    control, missing = _FOREIGN.get(dialect, ('', frozenset()))
    if not missing:
        return control, []
    names = [c for c in (codes.get('nonmodal'), codes.get('tool_length')) if c is not None]
    system = codes.get('coord')
    if system is not None:
        names.append(SYSTEM_NAMES[system - 1])
    if codes.get('nonmodal') == 'G10' and value('L') is not None:
        names.append(f'G10 L{value("L"):g}')
    return control, [n for n in names if n in missing]


def system_param(system: int, axis: int = 0) -> int:
    """Number of the stored parameter of ``axis`` (0 = X) of coordinate system 1..9."""
    return 5201 + 20 * system + axis


# LinuxCNC 2.9's messages for what it refuses while cutter radius compensation is on.
_COMP_MESSAGES = {
    'G92': 'Cannot change axis offsets with cutter radius compensation',
    'G28': 'Cannot use G28 or G30 with cutter radius compensation',
    'G28.1': 'Cannot set reference point with cutter compensation in effect',
    'G10': 'Cannot change the active coordinate system with cutter radius compensation on',
    'G43': 'Cannot change tool offset with cutter radius compensation on',
}
_COMP_KEY = {'G52': 'G92', 'G92.1': 'G92', 'G92.2': 'G92', 'G92.3': 'G92', 'G30': 'G28',
             'G30.1': 'G28.1', 'G43.1': 'G43', 'G43.2': 'G43', 'G49': 'G43'}
# Codes whose line's axis words are data, not a motion.
_AXIS_DATA = frozenset({'G10', 'G52', 'G92', 'G28.1', 'G30.1', 'G43.1', 'G43.2'})


class LineEffect(NamedTuple):
    """What the coordinate codes of a line mean for its motion.

    Attributes
    ----------
    axes_used
        The axis words were data of G10/G92/G52/G43.1/G43.2/G28.1/G30.1: no motion.
    frame
        ``machine - program`` [m] for this line's absolute axis words (zero under G53).
    home
        ``'G28'`` or ``'G30'`` when the line returns to a stored position
        (:meth:`Coords.home_path`), else ``None``.
    """

    axes_used: bool
    frame: Vec3
    home: str | None


class ParamTable:
    """Numbered parameters as a plain table (stand-in for ``gcode.params.Parameters``).

    Only :meth:`get` and :meth:`set` are used here, so the front end's ``Parameters``
    object can be passed instead. Unset parameters read 0 (LinuxCNC's fresh parameter file).
    """

    __slots__ = ('values',)

    def __init__(self) -> None:
        self.values: dict[int, float] = {}

    def get(self, number: int) -> float:
        """Value of ``#number`` (0 if never set)."""
        return self.values.get(number, 0.0)

    def set(self, number: int, value: float) -> None:
        """Set ``#number``."""
        self.values[number] = float(value)


class Coords(ToolTable, ParamReadback):
    """The coordinate state of a program being interpreted (all lengths in metres).

    Parameters
    ----------
    tools
        The tool table ``{T: ToolSpec}`` (a machine's ``gcode.tools``); copied, since G10 L1
        may change it.
    home_m
        Initial G28 position (machine coordinates [m]) stored in #5161..#5163; ``None``
        leaves them at 0, LinuxCNC's fresh parameter file.
    params
        The numbered parameter table (``get``/``set``); a fresh :class:`ParamTable` if
        ``None``.
    strict_tools
        A tool the table lacks is an error at the word that names it (LinuxCNC with its
        own table); otherwise it has length and radius 0 and ``on_missing_tool`` (if set)
        is called with its number.
    work_offsets_m
        Stored origins of coordinate systems by name (``'G54'``..``'G59.3'``) [m], written
        to their parameters #5221.. before the first line; the others stay 0.
    """

    __slots__ = ('params', 'tools', 'system', 'g5x', 'g92', 'tlo', 'offset', 'rotation_deg',
                 'cos', 'sin', 'selected_tool',
                 'loaded_tool', 'home_used', 'strict_tools', 'on_missing_tool')

    def __init__(self, *, tools: Mapping[int, object] | None = None,
                 home_m: Vec3 | None = None, params: ParamStore | None = None,
                 strict_tools: bool = False,
                 work_offsets_m: Mapping[str, Vec3] | None = None):
        self.params = ParamTable() if params is None else params
        self.tools: dict[int, ToolSpec] = {int(t): tool_spec(e)
                                           for t, e in (tools or {}).items()}
        self.system = 1
        self.g5x: Vec3 = (0.0, 0.0, 0.0)
        self.g92: Vec3 = (0.0, 0.0, 0.0)
        self.tlo: Vec3 = (0.0, 0.0, 0.0)
        self.offset: Vec3 = (0.0, 0.0, 0.0)
        self.rotation_deg = 0.0
        self.cos = 1.0
        self.sin = 0.0
        self.selected_tool = 0
        self.loaded_tool = 0
        self.home_used = False
        self.strict_tools = bool(strict_tools)
        self.on_missing_tool: Callable[[int], None] | None = None
        if home_m is not None:
            for i in range(3):
                self.params.set(G28_PARAM + i, home_m[i] * _MM)
        for name, origin in (work_offsets_m or {}).items():
            # the control's stored origins of G54..G59 (LinuxCNC's var file)
            system = SYSTEM_NAMES.index(name) + 1
            for i in range(3):
                self.params.set(system_param(system, i), origin[i] * _MM)
        self.params.set(SYSTEM_PARAM, 1.0)
        self._load_system(1)

    # -- one line -------------------------------------------------------------------------
    def execute(self, codes: Mapping[str, Any], value: Value, *, position: Vec3,
                scale: float, motion: int | None, absolute: bool, comp_active: bool = False,
                explicit_motion: bool = False, fail: Fail = raise_unplaced) -> LineEffect:
        """Execute the coordinate codes of one line, in LinuxCNC's order.

        Tool length (G43/G49) first, then the coordinate system (G54..), then the
        non-modal code (G10, G28.1/G30.1, G92.., G52; G28/G30 and G53 only mark the line).

        Parameters
        ----------
        codes
            ``{group: argument}`` of the line's entries of :data:`COORD_G_CODES` (groups
            ``'tool_length'``, ``'coord'``, ``'nonmodal'``).
        value
            ``value(letter)``: the number of the line's word ``letter`` as written, or
            ``None`` if the line has none.
        position
            Current machine position [m].
        scale
            Metres per program unit.
        motion
            The motion mode the line runs in (0, 1, 2, 3, a cycle code or ``None``).
        absolute
            G90 in force.
        comp_active
            Cutter radius compensation G41/G42 is on (LinuxCNC then refuses most of these).
        explicit_motion
            The line has its own G0..G3 or cycle code (LinuxCNC refuses it beside G10, G28,
            G30, G52 or G92: both would use the axis words).
        fail
            ``fail(message, letter)`` raising the error at a word.

        Returns
        -------
        LineEffect
            Whether the axis words were used, the frame of the line's axis words and the
            G28/G30 return, if any.
        """
        axes = {a: v * scale for a in _AXES if (v := value(a)) is not None}
        code = codes.get('nonmodal')
        if explicit_motion and code in ('G10', 'G28', 'G30', 'G52', 'G92'):
            fail('Cannot use two g codes that both use axis values', 'G')
        if code in ('G52', 'G92') and not axes:
            fail(f'All axes missing with G52 or G92 ({code} needs X, Y or Z)', 'G')
        if code in _AXIS_DATA or codes.get('tool_length') in _AXIS_DATA:
            for a, v in axes.items():
                if not abs(v) <= MAX_OFFSET_M:
                    shown = f'{v:.6g} m' if math.isfinite(v) else 'beyond any float'
                    fail(f'{a} value ({shown}) is not a plausible offset (at most '
                         f'{MAX_OFFSET_M:g} m)', a)
        if comp_active:
            refused: Any
            for refused in (codes.get('tool_length'), code):
                key = _COMP_KEY.get(refused, refused)
                if key in _COMP_MESSAGES and not (
                        key == 'G10' and not self._g10_hits_active(value)):
                    fail(_COMP_MESSAGES[key], 'G')
        length = codes.get('tool_length')
        if length is not None:
            h = value('H')
            self.tool_length(length, h, axes if length in _AXIS_DATA else {}, fail=fail)
        system = codes.get('coord')
        if system is not None:
            self.select_system(system, fail=fail)
        if code == 'G10':
            data = dict(axes)
            r = value('R')
            if r is not None:
                data['R'] = r * scale if value('L') in (1.0, 10.0, 11.0) else r
            self.g10(value('L'), value('P'), data, position, fail=fail)
        elif code in ('G92', 'G52', 'G92.1', 'G92.2', 'G92.3'):
            self.axis_offsets(code, axes, position)
        elif code in ('G28.1', 'G30.1'):
            self.save_home(code, position)
        elif code == 'G53':
            if motion not in (0, 1):
                fail('Must use G0 or G1 with G53', 'G')
            if not absolute:
                fail('Cannot use G53 incremental', 'G')
        if not all(abs(v) <= MAX_OFFSET_M for v in self.offset):
            fail('the offsets of this line move the program origin more than '
                 f'{MAX_OFFSET_M:g} m from the machine origin', 'G')
        return LineEffect(axes_used=bool(axes) and (code in _AXIS_DATA or length in _AXIS_DATA),
                          frame=(0.0, 0.0, 0.0) if code == 'G53' else self.offset,
                          home=code if code in ('G28', 'G30') else None)

    def _g10_hits_active(self, value: Value) -> bool:
        l_word, p_word = value('L'), value('P')
        if l_word not in (2.0, 20.0) or p_word is None or not abs(p_word) <= 1e9:
            return False        # not a coordinate system G10 (g10() names what is wrong)
        p = round(p_word)
        return p == 0 or p == self.system

    # -- frames ---------------------------------------------------------------------------
    def _update(self) -> None:
        # offset = the machine position of the program origin = R (G92) + G5x + TLO
        g5x, g92, tlo = self.g5x, self.g92, self.tlo
        gx, gy = self.rotate(g92[0], g92[1])
        self.offset = (g5x[0] + gx + tlo[0], g5x[1] + gy + tlo[1], g5x[2] + g92[2] + tlo[2])

    @property
    def rotated(self) -> bool:
        """True if the active coordinate system is rotated about Z (G10 L2 R)."""
        return self.sin != 0.0 or self.cos != 1.0

    def rotate(self, x: float, y: float) -> tuple[float, float]:
        """An XY vector turned by the active system's rotation (program -> machine)."""
        c, s = self.cos, self.sin
        return (x * c - y * s, x * s + y * c)

    def to_machine(self, program: Vec3) -> Vec3:
        """Machine coordinates [m] of a point given in program coordinates [m].

        ``machine = R (program + G92) + G5x + TLO`` in XY (R: the system's rotation about Z,
        as LinuxCNC applies it), a plain sum in Z.
        """
        o = self.offset
        x, y = self.rotate(program[0], program[1])
        return (x + o[0], y + o[1], program[2] + o[2])

    def to_program(self, machine: Vec3) -> Vec3:
        """Program coordinates [m] of a point given in machine coordinates [m]."""
        o = self.offset
        dx, dy = machine[0] - o[0], machine[1] - o[1]
        c, s = self.cos, self.sin
        return (dx * c + dy * s, -dx * s + dy * c, machine[2] - o[2])

    def _set_rotation(self, degrees: float) -> None:
        self.rotation_deg = degrees
        if degrees == 0.0:
            self.cos, self.sin = 1.0, 0.0
        else:
            t = math.radians(degrees)
            self.cos, self.sin = math.cos(t), math.sin(t)

    def _load_system(self, system: int) -> None:
        get = self.params.get
        self.g5x = cast(Vec3, tuple(get(system_param(system, i)) / _MM for i in range(3)))
        self._set_rotation(self._system_rotation(system, None))
        self._update()

    def _system_rotation(self, system: int, fail: Fail | None) -> float:
        r = self.params.get(system_param(system, 9))
        if not abs(r) <= 1.0e6:
            (fail or raise_unplaced)(f'rotation of {SYSTEM_NAMES[system - 1]} (#'
                                     f'{system_param(system, 9)}) is not a plausible angle', 'G')
        return r

    # -- G54 .. G59.3 ---------------------------------------------------------------------
    def select_system(self, system: int, *, fail: Fail = raise_unplaced) -> None:
        """G54..G59.3: make coordinate system ``system`` (1..9) active."""
        if system == self.system:
            return
        self._system_rotation(system, fail)
        self.system = system
        self.params.set(SYSTEM_PARAM, float(system))
        self._load_system(system)

    # -- G10 ------------------------------------------------------------------------------
    def g10(self, l_word: float | None, p_word: float | None, values: Mapping[str, float],
            position: Vec3, *, fail: Fail = raise_unplaced) -> None:
        """G10 L1/L10/L11 (tool table) or L2/L20 (coordinate system) with the line's words.

        Parameters
        ----------
        l_word, p_word
            The L and P words as read (``None`` if absent).
        values
            ``{'X': m, 'Y': m, 'Z': m}`` for the axis words on the line (program units
            converted to metres, not made absolute), ``'R'`` as written (L1/L10/L11: radius
            [m]; L2: rotation [deg]).
        position
            Current machine position [m] (for L10, L11, L20).
        fail
            ``fail(message, letter)`` raising the error at a word.
        """
        if l_word is None:
            fail('G10 needs an L word (L1, L10, L11 tool table; L2, L20 coordinate system)',
                 'G')
        if l_word not in (1.0, 2.0, 10.0, 11.0, 20.0):
            fail(f'G10 L{l_word:g} is not supported (L1, L2, L10, L11 and L20 are)', 'L')
        if p_word is None:
            fail(f'G10 L{l_word:g} needs a P word', 'G')
        if not abs(p_word) <= 1e9:
            fail('P value out of range with G10', 'P')
        p = int(math.floor(p_word + 0.5)) if p_word >= 0 else int(math.ceil(p_word - 0.5))
        if abs(p_word - p) > 0.0002:
            fail('P value not an integer with G10', 'P')
        if l_word in (1.0, 10.0, 11.0):
            self._g10_tool(int(l_word), p, values, position, fail=fail)
            return
        if not 0 <= p <= 9:
            fail(f'P value out of range (0-9) with G10 L{l_word:g}', 'P')
        system = p or self.system
        get = self.params.get
        rotation = get(system_param(system, 9))
        if 'R' in values:
            if l_word == 20.0:
                fail('R not allowed in G10 L20', 'R')
            rotation = values['R']
            if not abs(rotation) <= 1.0e6:
                fail('R (rotation in degrees) is not a plausible angle', 'R')
            self.params.set(system_param(system, 9), rotation)
        origin = [get(system_param(system, i)) / _MM for i in range(3)]
        if l_word == 2.0:
            for i, axis in enumerate(_AXES):
                if axis in values:
                    origin[i] = values[axis]
        else:
            # the current point, seen in `system`, gets the given coordinates (LinuxCNC:
            # the XY difference is turned by the system's rotation; parameters unrotated)
            here = self._in_system(system, position)
            want = [values.get(axis, here[i]) for i, axis in enumerate(_AXES)]
            t = math.radians(rotation)
            c, s = math.cos(t), math.sin(t)
            dx, dy = here[0] - want[0], here[1] - want[1]
            if 'X' in values or 'Y' in values:
                origin[0] += dx * c - dy * s
                origin[1] += dx * s + dy * c
            origin[2] += here[2] - want[2]
        for i in range(3):
            self.params.set(system_param(system, i), origin[i] * _MM)
        if system == self.system:
            self.g5x = cast(Vec3, tuple(origin))
            self._set_rotation(rotation)
            self._update()

    def _in_system(self, system: int, position: Vec3) -> Vec3:
        """Program coordinates of machine ``position`` if ``system`` were active (LinuxCNC's
        find_current_in_system: the G92 offset applies if #5210 says so)."""
        get = self.params.get
        t = math.radians(get(system_param(system, 9)))
        c, s = math.cos(t), math.sin(t)
        g92 = self.g92 if get(G92_APPLIED) else (0.0, 0.0, 0.0)
        dx, dy, dz = (position[i] - self.tlo[i] - get(system_param(system, i)) / _MM
                      for i in range(3))
        return (dx * c + dy * s - g92[0], -dx * s + dy * c - g92[1], dz - g92[2])

    # -- G92, G52 -------------------------------------------------------------------------
    def axis_offsets(self, code: str, values: Mapping[str, float], position: Vec3) -> None:
        """G92 / G52 / G92.1 / G92.2 / G92.3.

        Parameters
        ----------
        code
            ``'G92'``, ``'G52'``, ``'G92.1'``, ``'G92.2'`` or ``'G92.3'``.
        values
            ``{'X': m, ...}`` for the axis words on the line (G92, G52).
        position
            Current machine position [m].
        """
        g92 = list(self.g92)
        set_param = self.params.set
        here = self.to_program(position)
        if code in ('G92', 'G52'):
            set_param(G92_APPLIED, 1.0)
            for i, axis in enumerate(_AXES):
                if axis in values:
                    if code == 'G52':
                        g92[i] = values[axis]
                    else:
                        # the current point reads the value (LinuxCNC: current + offset - v)
                        g92[i] = here[i] + self.g92[i] - values[axis]
            for i in range(3):
                set_param(G92_PARAM + i, g92[i] * _MM)
        elif code in ('G92.1', 'G92.2'):
            set_param(G92_APPLIED, 0.0)
            g92 = [0.0, 0.0, 0.0]
            if code == 'G92.1':
                for i in range(3):
                    set_param(G92_PARAM + i, 0.0)
        elif code == 'G92.3':
            set_param(G92_APPLIED, 1.0)
            g92 = [self.params.get(G92_PARAM + i) / _MM for i in range(3)]
        else:
            raise ValueError(f'not a G92 code: {code!r}')
        self.g92 = cast(Vec3, tuple(g92))
        self._update()
