"""Code tables of the interpreter: which G and M codes and word letters it executes.

Kept apart from the lexer (which only reads words) so that wiring a feature in the
interpreter changes one table here. G codes are keyed by ``round(10 * number)`` so that
``G41.1`` is 411; each maps to ``(modal group, argument)``.
"""
from __future__ import annotations

from .coords import COORD_G_CODES

__all__ = ['G_CODES', 'G_UNSUPPORTED', 'M_CODES', 'ALLOWED_LETTERS', 'UNSUPPORTED_LETTERS',
           'IGNORABLE_AXES',
           'CYCLE_MOTIONS', 'SPLINE_MOTIONS', 'COMP_FORBIDDEN', 'MOTION_TEXT']

# Canned cycles are motion modes (LinuxCNC: modal group 1): the argument is the cycle code.
CYCLE_MOTIONS = frozenset({73, 81, 82, 83, 84, 85, 86, 87, 88, 89})
# G5, G5.1, G5.2 (splines.py): motion group, argument 10 x code (below the cycles' 73).
SPLINE_MOTIONS = frozenset({50, 51, 52})

G_CODES: dict[int, tuple[str, object]] = {
    0: ('motion', 0), 10: ('motion', 1), 20: ('motion', 2), 30: ('motion', 3),
    800: ('motion', None),
    # Probing (run to the end point: no contact is simulated) and rigid tapping.
    382: ('motion', 382), 383: ('motion', 383), 384: ('motion', 384), 385: ('motion', 385),
    331: ('motion', 331),
    **{c: ('motion', c) for c in SPLINE_MOTIONS},
    # G5.3 ends a G5.2 NURBS: LinuxCNC's modal group 0 (splines.py).
    53: ('nonmodal', 'nurbs_end'),
    **{c * 10: ('motion', c) for c in CYCLE_MOTIONS},
    40: ('nonmodal', 'dwell'), 90: ('nonmodal', 'exact'),
    170: ('plane', 17), 180: ('plane', 18), 190: ('plane', 19),
    200: ('units', 0.0254), 210: ('units', 0.001),
    900: ('distance', True), 910: ('distance', False),
    901: ('arc_distance', True), 911: ('arc_distance', False),
    # Feed mode: G93 inverse time, G94 units per minute, G95 units per spindle revolution.
    930: ('feed_mode', True), 940: ('feed_mode', False), 950: ('feed_mode', 'rev'),
    610: ('control', True), 611: ('control', True), 640: ('control', False),
    # Cutter radius compensation (group 7): 40 off, 41 left, 42 right; .1 = D is a diameter.
    400: ('cutter', 40), 410: ('cutter', 41), 420: ('cutter', 42),
    411: ('cutter', 411), 421: ('cutter', 421),
    # G10, G28/G30 (+ .1), G52, G53, G92.x, G43.x/G49 and G54..G59.3: executed by coords.py
    **COORD_G_CODES,
    # Canned-cycle return level (group 10): LinuxCNC starts in G99 (to R).
    980: ('retract', 98), 990: ('retract', 99),
    960: ('spindle_mode', None), 970: ('spindle_mode', None),
    80: ('lathe', None),
}

# The motion G words as written on most lines (G0..G3, G00..G03): number text -> mode, so
# that the common line needs no G_CODES lookup.
# (keyed by str | float: a block of the front's reader carries values, never found here)
MOTION_TEXT: dict[str | float, int] = {t: int(t)
                                       for t in ('0', '00', '1', '01', '2', '02', '3', '03')}

# Codes we know and refuse, with the reason shown to the user.
G_UNSUPPORTED: dict[int, str] = {
    70: 'lathe diameter mode',
    330: 'spindle-synchronised motion',
    740: 'lathe/left-hand tapping cycle', 760: 'lathe threading cycle',
    171: 'UVW planes', 181: 'UVW planes', 191: 'UVW planes',
}

# M codes keyed by integer: (group, action); ``None`` action means ignored for the feed axes.
M_CODES: dict[int, tuple[str, str | None]] = {
    0: ('stop', 'pause'), 1: ('stop', 'pause'), 2: ('stop', 'end'), 30: ('stop', 'end'),
    3: ('spindle', 'cw'), 4: ('spindle', 'ccw'), 5: ('spindle', 'off'),
    6: ('tool', 'change'), 7: ('coolant', None), 8: ('coolant', None),
    9: ('coolant', None),
}

# Letters the interpreter understands (the extra axes are refused with a reason).
ALLOWED_LETTERS = frozenset('GMXYZIJKRFPSTNOQHLDE')
UNSUPPORTED_LETTERS: dict[str, str] = {
    **{a: f'axis {a} is not supported (only X, Y, Z are simulated)' for a in 'ABCUVW'},
}
# Axes that --ignore-axes may drop.
IGNORABLE_AXES = frozenset('ABCUVW')

# What LinuxCNC 2.9 refuses while cutter radius compensation is on (its messages; checked
# with its interpreter): a change of plane or coordinate system, and any G61/G64 or G98/G99.
COMP_FORBIDDEN: dict[str, str] = {
    'plane': 'Cannot change planes with cutter radius compensation on',
    'coord': 'Cannot change coordinate systems with cutter radius compensation on',
    'control': 'Cannot change control mode with cutter radius compensation on',
    'retract': 'Cannot change retract mode with cutter radius compensation on',
}
