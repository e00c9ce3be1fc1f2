"""Fanuc / Haas read-only system variables from the interpreter's modal state.

In the dialects with Custom Macro B (``fanuc``, ``haas``: ``Dialect.fanuc_macro``) a macro
reads the control's state through system variables; LinuxCNC has no such variables (there
``#4001`` or ``#5001`` are ordinary parameters, 0 until set). A CAM or probing macro saves a
mode with ``#1 = #4003`` and restores it with ``G#1``, or reads where the tool is: reading
0 there would simulate a different program without a word, so each variable is either
given from the modal state or refused with an error naming it.

Values (Fanuc Series 0i/30i Custom Macro B and Haas mill manuals: the same numbers):

==========================  ===============================================================
``#4001``                   motion group 01: 0, 1, 2, 3 (G0..G3 in force; refused under a
                            canned cycle, G5.x or G80, where this interpreter keeps
                            LinuxCNC's motion mode and no G0..G3 beneath it)
``#4002``                   plane: 17, 18, 19
``#4003``                   distance mode: 90, 91
``#4005``                   feed mode: 93, 94
``#4006``                   units: 20, 21
``#4007``                   cutter compensation: 40, 41, 42 (the side in effect)
``#4008``                   tool length offset: 43 if an offset is in force, else 49
``#4009``                   canned cycle: 80, 73, 81..89
``#4010``                   cycle return: 98, 99
``#4011``                   scaling: 50 (G51 is not simulated, so it is never on)
``#4012``                   macro modal call: 67 (G66 is not simulated)
``#4014``                   work system: 54..59, 59.1..59.3
``#4015``                   path mode: 61 (G61/G61.1 exact stop), 64
``#4016``                   coordinate rotation: 69 (G68 is not simulated)
``#4017``                   polar coordinates: 15 (G16 is not simulated)
``#4109``                   F in force (program units per minute; under G93 the last F)
``#4119``                   S (rev/min)
``#4120``                   T (the selected tool)
``#5001..#5003``            end point of the previous block, work coordinates (program
                            coordinates: G54.. and G52/G92 applied, tool offset not)
``#5021..#5023``            current position, machine coordinates (tool length included)
``#5041..#5043``            current position, work coordinates, tool length offset included
``#5081..#5083``            tool length offset per axis
==========================  ===============================================================

Lengths are in the program's units (G20: inch, G21: mm). Every other ``#4001..#4130`` is
refused (an error naming the variable: the interpreter does not keep that state). The
simulated control has no servo lag, so the end point of the previous block is also the
current position. These variables are read-only (:data:`READ_ONLY`), as on the controls.
"""
from __future__ import annotations

from .codes import CYCLE_MOTIONS
from ..read.params import ParameterError

__all__ = ['fanuc_system_value', 'READ_ONLY', 'MODAL_FIRST', 'MODAL_LAST']

MODAL_FIRST = 4001
MODAL_LAST = 4130
"""``#4001..#4130``: modal information (G groups ``#4001..``, addresses ``#4101..``)."""

_POSITIONS = range(5001, 5004), range(5021, 5024), range(5041, 5044), range(5081, 5084)
READ_ONLY = frozenset([*range(MODAL_FIRST, MODAL_LAST + 1), *(n for r in _POSITIONS for n in r)])
"""Numbers a program may read but not assign in the Macro B dialects."""

# Modal groups whose only state here is fixed: the code that switches it on is refused.
_FIXED = {4011: 50.0, 4012: 67.0, 4016: 69.0, 4017: 15.0}


def fanuc_system_value(interp, n: int) -> float | None:
    """The value of system variable ``#n`` for a Macro B dialect, or ``None`` (not one).

    Parameters
    ----------
    interp
        The :class:`~.interp.Interpreter` (its modal state and position are read).
    n
        The variable number.

    Raises
    ------
    ParameterError
        For a variable of ``#4001..#4130`` whose state the interpreter does not keep.
    """
    if MODAL_FIRST <= n <= MODAL_LAST:
        value = _modal(interp, n)
        if value is None:
            msg = (f'system variable #{n} (modal information) is not simulated: only '
                   '#4001-#4003, #4005-#4012, #4014-#4017, #4109, #4119, #4120 are')
            raise ParameterError(msg)
        return value
    if n > 5083 or n < 5001:
        return None
    coords = interp.coords
    scale = interp.scale
    pos = interp.pos
    if n <= 5003:
        return coords.to_program(pos)[n - 5001] / scale
    if 5021 <= n <= 5023:
        return pos[n - 5021] / scale
    if 5041 <= n <= 5043:
        # the program point plus the tool length offset turned into the work frame
        t = coords.tlo
        work = coords.to_program(pos)
        c, s = coords.cos, coords.sin
        tx, ty = t[0] * c + t[1] * s, -t[0] * s + t[1] * c
        return (work[0] + tx, work[1] + ty, work[2] + t[2])[n - 5041] / scale
    if 5081 <= n <= 5083:
        return coords.tlo[n - 5081] / scale
    return None


def _modal(interp, n: int) -> float | None:
    """``#4001..#4130`` from the modal state, ``None`` where it is not kept."""
    motion = interp.motion
    if n == 4001:
        return float(motion) if motion in (0, 1, 2, 3) else None
    if n == 4002:
        return float(interp.plane)
    if n == 4003:
        return 90.0 if interp.absolute else 91.0
    if n == 4005:
        if interp.feed_per_rev is not None:
            return 95.0
        return 93.0 if interp.inverse_time else 94.0
    if n == 4006:
        return 21.0 if interp.scale == 0.001 else 20.0
    if n == 4007:
        comp = interp.comp
        return (41.0 if comp.left else 42.0) if comp.active else 40.0
    if n == 4008:
        return 43.0 if any(interp.coords.tlo) else 49.0
    if n == 4009:
        return float(motion) if motion in CYCLE_MOTIONS else 80.0
    if n == 4010:
        return float(interp.retract)
    if n == 4014:
        return interp.system_value('_coord_system') / 10.0
    if n == 4015:
        return 61.0 if interp.exact else 64.0
    if n == 4109:
        if interp.feed_per_rev is not None:
            return interp.feed_per_rev / interp.scale
        feed = interp.feed
        if not feed or feed == float('inf'):
            return 0.0
        return feed if interp.inverse_time else feed * 60.0 / interp.scale
    if n == 4119:
        return float(interp.rpm)
    if n == 4120:
        return float(interp.tool_selected)
    return _FIXED.get(n)
