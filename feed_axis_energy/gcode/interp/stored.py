"""The parameter side of :class:`.coords.Coords`: the G28/G30 stored positions, the G38 probe
result and the read-only system parameters (current position, tool, coordinate system).

LinuxCNC 2.9 semantics (``interp_convert.cc``: ``convert_home``, ``convert_savehome``,
``convert_probe``; ``interp_read.cc``: the read-only parameters and named ``#<_...>``
values). Stored parameters hold millimetres; live values are in program units.
"""
from __future__ import annotations

from typing import cast, TYPE_CHECKING

from ..settings import ToolSpec
from .fail import Fail, raise_unplaced
from .tools import MAX_OFFSET_M

if TYPE_CHECKING:
    from .coordstate import CoordsState
else:
    CoordsState = object        # the declarations are for the type checker only

__all__ = ['ParamReadback', 'G28_PARAM', 'G30_PARAM', 'PROBE_PARAM', 'TOOL_PARAM',
           'POSITION_PARAM', 'MAX_PASSES']

Vec3 = tuple[float, float, float]

_MM = 1000.0
# #<_coord_system> as LinuxCNC reports it (540 ... 593).
_SYSTEM_CODES = (540.0, 550.0, 560.0, 570.0, 580.0, 590.0, 591.0, 592.0, 593.0)
G28_PARAM = 5161
G30_PARAM = 5181
PROBE_PARAM = 5061      # G38 result X Y Z A B C U V W, then #5070 tripped
TOOL_PARAM = 5400
POSITION_PARAM = 5420
MAX_PASSES = 9          # axes X Y Z A B C U V W of every parameter block


class ParamReadback(CoordsState):
    """Stored homes, probe result and read-only parameters of :class:`.coords.Coords` (a mixin:
    the state lives there).

    Uses ``params``, ``tools``, ``loaded_tool``, ``selected_tool``, ``system``, ``tlo``,
    ``home_used`` and ``to_program()`` of the class it is mixed into.
    """

    __slots__ = ()

    # -- G28 / G30 ------------------------------------------------------------------------
    def stored_home(self, code: str, *, fail: Fail = raise_unplaced) -> Vec3:
        """The stored G28 or G30 position, machine coordinates [m]."""
        base = G28_PARAM if code == 'G28' else G30_PARAM
        self.home_used = True
        home = cast(Vec3, tuple(self.params.get(base + i) / _MM for i in range(3)))
        if not all(abs(v) <= MAX_OFFSET_M for v in home):
            fail(f'the stored {code} position (#{base}..#{base + 2}) is more than '
                 f'{MAX_OFFSET_M:g} m from the machine origin', 'G')
        return home

    def home_path(self, code: str, via: Vec3, named: tuple[bool, bool, bool], *,
                  fail: Fail = raise_unplaced) -> list[Vec3]:
        """G28/G30: the intermediate point and the end point, machine coordinates [m].

        Parameters
        ----------
        code
            ``'G28'`` or ``'G30'``.
        via
            Intermediate point [m] (machine coordinates; the current point where the line
            has no axis words).
        named
            Which of X, Y, Z the line names; those go to the stored position (all of them
            when none is named).
        """
        home = self.stored_home(code, fail=fail)
        if not any(named):
            named = (True, True, True)
        end = cast(Vec3, tuple(home[i] if named[i] else via[i] for i in range(3)))
        return [via, end]

    def save_home(self, code: str, position: Vec3) -> None:
        """G28.1 / G30.1: store the current machine position [m]."""
        base = G28_PARAM if code == 'G28.1' else G30_PARAM
        for i in range(3):
            self.params.set(base + i, position[i] * _MM)

    # -- probing ------------------------------------------------------------------------
    def probe_result(self, position: Vec3, scale: float) -> None:
        """After a G38.x move: #5061..#5063 = where it ended, in the program coordinates of
        the active system and program units; #5064..#5069 and #5070 (tripped) = 0.

        No contact is simulated, so the probe point is the end of the move -- what LinuxCNC's
        interpreter records when nothing trips (its preview and the reference set-up).
        """
        program = self.to_program(position)
        for i in range(3):
            self.params.set(PROBE_PARAM + i, program[i] / scale)
        for n in range(PROBE_PARAM + 3, PROBE_PARAM + 10):
            self.params.set(n, 0.0)

    # -- live values ----------------------------------------------------------------------
    def system_value(self, key: int | str, position: Vec3, scale: float) -> float | None:
        """Read-only system parameter ``key`` (number or lower-case name), or ``None``.

        Parameters
        ----------
        key
            ``5420``..``5428`` (current position), ``5400`` (loaded tool), ``5401``..``5403``
            (its tool length offset, mm), ``5410`` (its diameter, mm), or a name
            ``'_x'``, ``'_y'``, ``'_z'``, ``'_a'``..``'_w'``, ``'_coord_system'``,
            ``'_current_tool'``, ``'_selected_tool'``, ``'_abs_x'``..``'_abs_z'``.
        position
            Current machine position [m].
        scale
            Metres per program unit (G20: 0.0254, G21: 0.001).
        """
        if isinstance(key, str):
            return self._named_value(key, position, scale)
        if POSITION_PARAM <= key < POSITION_PARAM + MAX_PASSES:
            i = key - POSITION_PARAM
            return self.to_program(position)[i] / scale if i < 3 else 0.0
        if key == TOOL_PARAM:
            return float(self.loaded_tool)
        spec = self.tools.get(self.loaded_tool, ToolSpec())
        if TOOL_PARAM + 1 <= key <= TOOL_PARAM + MAX_PASSES:
            return spec.length_m * _MM if key == TOOL_PARAM + 3 else 0.0
        if key == 5410:
            return 2.0 * spec.radius_m * _MM
        return None

    def _named_value(self, name: str, position: Vec3, scale: float) -> float | None:
        if len(name) == 2 and name[0] == '_' and name[1] in 'xyzabcuvw':
            return self.system_value(POSITION_PARAM + 'xyzabcuvw'.index(name[1]), position,
                                     scale)
        if name in ('_abs_x', '_abs_y', '_abs_z'):
            return position['xyz'.index(name[-1])] / scale
        if name == '_coord_system':
            return _SYSTEM_CODES[self.system - 1]
        if name == '_tool_offset':
            return float(any(self.tlo))
        if name == '_current_tool':
            return float(self.loaded_tool)
        if name == '_selected_tool':
            return float(self.selected_tool)
        return None
