"""Modal interpreter of the G-code parser: words of one line -> moves in SI units.

The dialect is documented in :mod:`.gcode`. :class:`Interpreter` keeps the whole modal state;
:meth:`Interpreter.line` runs a line's words, handling the common case (one motion G word,
axis, centre, F and N words) inline and anything rarer in small helpers. The plain-line fast
path (:mod:`.run`) first offers the usual CAM line to ``contour_line`` (:mod:`.motion`),
which runs it without a word dictionary and allocates little more than its
:class:`~.program.Move`. The rooms of the rest: motion (:mod:`.motion`), splines
(:mod:`.splines`), cutter compensation (:mod:`.comp`), modes and M codes
(:mod:`.modes`), coordinate systems (:mod:`.frames`).
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any, cast, NoReturn, TYPE_CHECKING

from ..canon import CENTER_ARC_RADIUS_TOLERANCE_MM
from .codes import ALLOWED_LETTERS, COMP_FORBIDDEN, MOTION_TEXT, SPLINE_MOTIONS
from .coords import COORD_G_CODES, Coords
from ..expand.cutter import CutterComp
from ..expand.cycles import CycleMemory
from ..dialect import Dialect, dialect_by_name
from .comp import CompMixin
from .frames import CoordsMixin
from .modes import ModesMixin
from .motion import MotionMixin
from .rotary import RotaryAxes
from ..read.lexer import blank_comments, locate_word
from ..expand.nurbs import NurbsState
from ..expand.splines import SplineMixin
from ...errors import GcodeError
from ..program import Move

if TYPE_CHECKING:
    from .coordstate import ParamStore, Vec3
    from .state import Lines

__all__ = ['Interpreter']

_AXIS_LETTERS = ('X', 'Y', 'Z')
# Letters that need no check beyond the motion itself (T is recorded by check_extras).
_STRAIGHT_WORDS = frozenset('XYZFN')
_ARC_WORDS = frozenset('XYZIJKRPFN')


class Interpreter(MotionMixin, SplineMixin, CompMixin, ModesMixin, CoordsMixin):
    """Modal state of a program being parsed and the interpretation of its lines.

    Parameters
    ----------
    file
        Name used in errors and warnings.
    start
        Tool position [m] before the first line.
    arc_tolerance_m
        Absolute part of the arc end-point tolerance [m].
    lines
        The source lines (as split by the caller), to show the offending word in errors.
    home
        The G28 position [m] in machine coordinates (initial #5161..#5163), or ``None``:
        0, as in LinuxCNC's fresh parameter file (G28 then warns).
    tools
        Tool table: tool number -> ``ToolSpec`` (or a radius [m], a mapping or an object
        with ``radius_m`` and ``length_m``); ``None``: an empty table.
    strict_tools
        A tool the table lacks is an error (LinuxCNC with its table); otherwise it runs
        with length and radius 0 and one warning per tool number (:mod:`.tools`).
    allow_no_feed
        A feed move with no feed rate ever set runs at the machine's axis limits with one
        warning (a preview); otherwise it is an error, as on the control.
    dialect
        The :class:`~.dialect.Dialect` (or its name); ``None``: linuxcnc.
    params
        The parameter table shared with the front's reader (``None``: a private one).
    ignore_axes
        Axis letters (A, B, C, U, V, W) whose words are dropped with one warning each.
    rotary_axes
        Rotary axis letters (among A, B, C) the machine has: their words move them
        (:mod:`.rotary`); other rotary words are refused (or ignored).
    """

    __slots__ = ('file', 'arc_tol', 'pos', 'motion', 'plane', 'scale', 'absolute',
                 'arc_absolute', 'inverse_time', 'feed', 'exact', 'coord', 'moves',
                 'warnings', 'lineno', 'lines', 'ended', 'g_cache', 'g43_lineno', 'home',
                 'coords', 'frame', 'rotated', 'coord_line', 'coord_todo', 'retract',
                 'cycle_memory', 'series', 'comp', 'routing',
                 'comp_code', 'pending_lineno', 'tool_change', 'tools', 'tool_selected',
                 'tool_loaded', 'spindle', 'p_unit', 'dialect', 'src', 'io_lineno',
                 'warned', 'ignore_axes', 'rpm', 'polar_line', 'polar_inc',
                 'arc_quick', 'nurbs', 'd_selected', 'feed_per_rev', 'on_tool',
                 'allow_no_feed', 'user_m_lineno', 'rotary')

    def __init__(self, file: str, start: tuple[float, float, float],
                 arc_tolerance_m: float | None,
                 *, lines: Lines | None, home: tuple[float, float, float] | None = None,
                 tools: Mapping[int, object] | None = None, dialect: Dialect | None = None,
                 params: ParamStore | None = None, ignore_axes: Iterable[str] = (),
                 strict_tools: bool = False, allow_no_feed: bool = False,
                 rotary_axes: Iterable[str] = (),
                 work_offsets: Mapping[str, tuple[float, float, float]] | None = None):
        self.file = file
        self.arc_tol = None if arc_tolerance_m is None else float(arc_tolerance_m)
        # radius differences below this pass every arc check (motion)
        self.arc_quick = CENTER_ARC_RADIUS_TOLERANCE_MM * 1e-3
        if self.arc_tol is not None:
            self.arc_quick = min(self.arc_quick, self.arc_tol)
        self.pos = (float(start[0]), float(start[1]), float(start[2]))
        self.motion: int | None = None      # G80 at start-up
        self.plane = 17
        self.scale = 0.001                  # G21: program units are mm
        self.absolute = True                # G90
        self.arc_absolute = False           # G91.1
        self.inverse_time = False           # G94
        self.feed_per_rev: float | None = None  # under G95: F [m/rev] (0: none given yet)
        self.feed: float | None = None      # m/s under G94, 1/min (this line only) under G93
        self.exact = False                  # G64
        self.coord = 1                      # G54 (coordinate system 1..9, see coords.py)
        self.moves: list[Move] = []
        self.warnings: list[str] = []
        self.lineno = 0
        self.lines = lines
        self.ended = False
        self.g_cache: dict[str | float, tuple[str, Any, int]] = {}
        self.g43_lineno = -1                # line of the last G43 (its H word is legal there)
        self.home = None if home is None else cast('Vec3', tuple(float(v) for v in home))
        self.coords = Coords(tools=tools, home_m=self.home, params=params,
                             strict_tools=strict_tools, work_offsets_m=work_offsets)
        self.coords.on_missing_tool = self.missing_tool
        self.allow_no_feed = bool(allow_no_feed)
        self.frame = self.coords.offset     # machine - program for absolute axis words
        self.rotated = False                # G10 L2 R: target() turns the whole point
        self.coord_line = -1                # line with coordinate codes to execute
        self.coord_todo: dict[str, object] = {}
        self.retract = 99                   # G99: LinuxCNC's start-up canned-cycle return
        self.cycle_memory = CycleMemory()   # sticky cycle words, initial level of a series
        self.series = False                 # the last motion was a canned cycle
        self.comp = CutterComp(file=file, units_m=self.scale)
        self.routing = False                # moves go through self.comp (comp.engaged)
        self.comp_code: int | None = None   # the G40/G41/G42(.1) of the pending line
        self.pending_lineno = -1            # line with work to do before its motion
        self.tool_change = False            # M6 on the pending line
        self.tools = self.coords.tools      # the same table: G10 L1 writes reach G41
        self.tool_selected = 0              # T word
        self.tool_loaded = 0                # tool in the spindle (after M6); 0 = none
        self.on_tool = None                 # called with the tool loaded by M6 / M61
        self.spindle = 0                    # 1 M3, -1 M4, 0 stopped (M5 / start-up)
        self.p_unit = 1.0                   # seconds per unit of a dwell's P word
        self.dialect = dialect_by_name(dialect)
        if self.dialect.dwell_p == 'milliseconds':
            self.p_unit = 0.001
        self.src = None                     # the front's current Block (None: plain lines)
        self.io_lineno = -1                 # line with an I/O M code (its P/Q/E/L words)
        self.user_m_lineno = -1             # line with a user M code M100-M199 (its P/Q)
        self.warned: set[str] = set()       # warnings given once
        self.ignore_axes = frozenset(ignore_axes)   # axis letters dropped with a warning
        self.rpm = 0.0                      # S word (spindle speed, rev/min)
        self.polar_line = -1                # line with G91 polar words (@ [m], ^ [rad])
        self.polar_inc = (0.0, 0.0)
        self.d_selected: int | None = None  # Fanuc/Haas: D chosen on an earlier line
        self.nurbs = NurbsState()           # G5.x control points and modes (splines.py)
        rotary = frozenset(rotary_axes)     # rotary axes of the machine (rotary.py)
        self.rotary = RotaryAxes(rotary) if rotary else None

    # -- errors ---------------------------------------------------------------------------
    def fail(self, msg: str, letter: str, *, value: float | None = None,
             nth: int = 0) -> NoReturn:
        """Raise a :class:`GcodeError` at the word ``letter`` (``value``, ``nth``) of the line."""
        src = self.src
        if src is None:
            file, line, raw = self.file, self.lineno, cast('Lines', self.lines)[self.lineno - 1]
        else:           # a block of the front's reader (perhaps in a subroutine file)
            file, line, raw = src.file, src.line, src.text
        code = blank_comments(raw, file=file, line=line)
        column, text = locate_word(code, letter, value=value, nth=nth)
        raise GcodeError(msg, file=file, line=line, column=column, text=text[:60])

    def missing_tool(self, number: int) -> None:
        """A tool the table lacks runs with length and radius 0: one warning per number."""
        key = f'tool {number}'
        if key not in self.warned:
            self.warned.add(key)
            self.warnings.append(f'{self.file}:{self.lineno}: tool {number} is not in the tool '
                                 'table: it runs with length and radius 0 (give it under '
                                 'gcode.tools of the machine config or with --tool; '
                                 '--strict-tools refuses it)')

    def end_block(self) -> None:
        """After a block of the front's reader: its markers must not reach the next block,
        which may carry the same (main-program) line number."""
        self.pending_lineno = self.coord_line = self.g43_lineno = self.io_lineno = -1
        self.user_m_lineno = -1
        self.polar_line = -1
        self.nurbs.motion_line = self.nurbs.end_line = -1
        if self.rotary is not None:
            self.rotary.line = self.rotary.g53_line = -1

    def abandon_line(self) -> None:
        """After an error in a line that the run goes on from (``GcodeRun(max_errors=...)``):
        drop what the line left pending (tool change, cutter compensation and coordinate
        codes, line markers); modes it set before the error stay set."""
        self.end_block()
        self.tool_change = False
        self.comp_code = None
        self.coord_todo = {}

    def num(self, letter: str, text: str | float) -> float:
        """Value of a word; blanks inside the number are ignored (LinuxCNC rule)."""
        try:
            return float(text)
        except ValueError:
            pass
        try:
            # a value (float) never fails float(): only a text gets here
            return float(''.join(text.split()))  # type: ignore[union-attr]
        except ValueError:
            self.fail(
                f'{letter}{"".join(text.split())} is not a number',  # type: ignore[union-attr]
                letter)

    def first_axis(self, d: dict[str, str | float]) -> str:
        """First axis letter present on the line, else ``G`` (for error places: a full circle
        may be written without axis words)."""
        return next((a for a in _AXIS_LETTERS if a in d), 'G')

    def refuse_rotary(self, what: str) -> None:
        """Fail at the line's first rotary word if it has one (``what`` cannot take it)."""
        rot = self.rotary
        if rot is not None and rot.pending(self.lineno):
            self.fail(f'a rotary axis word in {what} is not supported', rot.first_letter())

    def rotary_move(self, m: Move) -> Move:
        """``m`` with the rotary axes turning to the line's rotary words (if any); cutter
        radius compensation cannot take them."""
        rot = self.rotary
        if rot is None or not rot.pending(self.lineno):
            return m
        if self.comp.active:
            self.refuse_rotary('cutter radius compensation (G41/G42)')
        return rot.move(m, rot.target(self.lineno, self.coord, self.absolute),
                        inverse_time=self.inverse_time, feed=self.feed, scale=self.scale)

    # -- one line -------------------------------------------------------------------------
    def line(self, words: Sequence[tuple[str, str | float]]) -> None:
        """Interpret the ``(letter, number text)`` words of one line (letters upper case)."""
        d = dict(words)
        ml: Any             # the M word, then the M words, then the stop actions
        dwell = g9 = g64 = False
        if len(d) == len(words):
            g = d.pop('G', None)
            ml = d.pop('M', None)
            if ml is not None:
                ml = (ml,)
            if g is None:
                motion = None
            else:
                motion = MOTION_TEXT.get(g)
                if motion is None:
                    motion, dwell, g9, g64 = self.g_words((g,))
        else:
            gl, ml = self.split_repeated(words, d)
            motion = None
            if gl:
                motion, dwell, g9, g64 = self.g_words(gl)
        if not d.keys() <= ALLOWED_LETTERS:
            self.unknown_letter(d)
        if ml:
            ml = self.m_words(ml)
        if 'F' in d:
            self.set_feed(d['F'])
        if motion is not None:
            self.motion = motion
        if dwell and 'X' in d and self.dialect.dwell_x_seconds:
            self.dwell_x(d)
        mode = self.motion
        has_axes = 'X' in d or 'Y' in d or 'Z' in d
        if self.rotary is not None and not has_axes:
            has_axes = self.rotary.pending(self.lineno)
        is_arc = mode == 2 or mode == 3
        if dwell or g64 or not d.keys() <= (_ARC_WORDS if is_arc and has_axes
                                            else _STRAIGHT_WORDS):
            has_axes = self.check_extras(d, is_arc, has_axes, dwell, g64,
                                         motion is not None) or has_axes
        if self.pending_lineno == self.lineno:
            self.before_motion(d)
        if self.coord_line == self.lineno and self.apply_coords(d, motion is not None):
            pass                # the axis words were G10/G92/... data, or G28/G30 moved
        elif has_axes:
            if mode is None:
                self.fail('axis words but no motion mode (G0/G1/G2/G3) is active',
                          self.first_axis(d))
            if mode > 3:
                self.refuse_rotary('a canned cycle, spline, probe or tap')
                if mode < 60:
                    self.spline(d, mode, g9)
                elif mode < 100:
                    self.cycle(d, mode)
                else:
                    self.probe_or_tap(d, mode, g9)
            else:
                if self.series:
                    self.end_series()
                if is_arc:
                    self.arc(d, mode, g9, motion is not None)
                else:
                    self.straight(d, mode, g9, motion is not None)
        elif motion is not None and motion <= 1:
            self.stand_still(d, motion, g9)
        elif motion in SPLINE_MOTIONS:
            self.spline(d, motion, g9)      # G5.2 P.. L..; G5/G5.1 fail (no end point)
        if ml:
            self.stop(ml)

    def check_extras(self, d: dict[str, str | float], is_arc: bool, has_axes: bool, dwell: bool,
                     g64: bool, explicit: bool = False) -> bool | None:
        """Words other than axes/F/N/S: run the dwell, refuse words nothing uses
        (``explicit``: the line has a motion G word).

        Returns True for a full circle written without axis words (it moves all the same).
        """
        if 'O' in d:
            o = self.num('O', d['O'])
            if len(d) > 1 or o != int(o):
                self.fail('O-word subroutines and control flow are not supported', 'O')
        if 'H' in d and self.g43_lineno != self.lineno:
            self.fail('H word with no G43 to use it', 'H')
        if 'T' in d:
            self.select_tool(d['T'])
        if 'S' in d:
            self.rpm = self.num('S', d['S'])
            if self.feed_per_rev:
                self.feed = self.feed_per_rev * self.rpm / 60.0 or None
        if self.io_lineno == self.lineno:
            d = {k: v for k, v in d.items() if k not in 'PQEL'}    # the I/O M code's words
        else:
            if self.user_m_lineno == self.lineno:
                d = {k: v for k, v in d.items() if k not in 'PQ'}   # the user program's
            if 'E' in d:
                self.fail('E word with no M66/M67/M68 to use it', 'E')
        if 'D' in d and not (self.pending_lineno == self.lineno
                             and self.comp_code not in (None, 40)):
            if not self.dialect.modal_d:
                self.fail('D word with no G41/G42 (or G41.1/G42.1) to use it', 'D')
            self.d_selected = self.d_number(d['D'])     # Fanuc/Haas: for the next G41/G42
        if self.coord_line == self.lineno and self.coord_todo.get('nonmodal') == 'G10':
            return None         # coords.py checks G10's L, P and R words
        if self.motion in SPLINE_MOTIONS and (has_axes or explicit):
            self.spline_words(d, self.motion, dwell)
            return False        # splines.py checks the spline's words
        cycle_move = has_axes and (self.motion or 0) > 3
        if cycle_move:
            if dwell:
                self.fail('G4 and a canned cycle on one line would share the P word', 'G',
                          value=4.0)
            return False        # cycles.py checks the cycle's words
        if 'Q' in d and not g64:
            self.fail('Q word with no canned cycle (G73, G83) or G64 to use it', 'Q')
        if 'L' in d:
            self.fail('L word with no canned cycle to use it', 'L')
        arc_move = is_arc and has_axes
        if is_arc and not has_axes:
            if 'R' in d:
                self.fail('an R-form arc needs an end point (use I/J/K for a full circle)',
                          'R')
            # LinuxCNC: a full circle may be written with its centre offsets only.
            arc_move = 'I' in d or 'J' in d or 'K' in d
        if not arc_move:
            for letter in 'IJKR':
                if letter in d:
                    self.fail(f'{letter} word with no G2/G3 arc to use it', letter)
        if dwell:
            if arc_move:
                self.fail('G4 and an arc on one line would share the P word', 'G', value=4.0)
            self.dwell(d)
        elif 'P' in d and not (arc_move or g64):
            self.fail('P word with no G4, G2/G3 or G64 to use it', 'P')
        return arc_move and not has_axes

    def g_words(self, gl) -> tuple[int | None, bool, bool, bool]:
        """Apply the modal G codes of a line; return (motion, dwell, G9, G64 present)."""
        seen: dict[str, int] = {}
        motion = None
        dwell = g9 = g64 = nurbs_end = False
        cache = self.g_cache
        for text in gl:
            entry = cache.get(text)
            if entry is None:
                entry = self.g_lookup(text)
                cache[text] = entry
            group, arg, code = entry
            if group in seen:
                if group == 'motion' and 800 in (code, seen[group]) and code != seen[group]:
                    # LinuxCNC 2.9 lets G80 stand beside another motion code (Fanuc safety
                    # blocks such as G0 G17 G40 G49 G80 G90): the other code wins.
                    if code == 800:
                        continue
                else:
                    same = seen[group] == code
                    self.fail(f'G{seen[group] / 10:g} and G{code / 10:g} are in the same '
                              f'modal group ({group}) on one line', 'G', value=code / 10,
                              nth=int(same))
            seen[group] = code
            if self.comp.active and group in COMP_FORBIDDEN:
                self.comp_forbidden(group, arg, code)
            if group == 'motion':
                motion = -1 if arg is None else arg
            elif group == 'nonmodal':
                dwell = arg == 'dwell'
                g9 = arg == 'exact'
                nurbs_end = arg == 'nurbs_end'
                if code in COORD_G_CODES:
                    self.coord_codes(group, arg, code)
            elif group == 'plane':
                self.plane = arg
            elif group == 'units':
                self.scale = arg
                self.comp.units_m = arg
            elif group == 'distance':
                self.absolute = arg
            elif group == 'arc_distance':
                self.arc_absolute = arg
            elif group == 'feed_mode':
                inverse, per_rev = arg is True, arg == 'rev'
                if inverse != self.inverse_time or per_rev != (self.feed_per_rev is not None):
                    # a new feed mode needs a new F (LinuxCNC)
                    self.inverse_time = inverse
                    self.feed_per_rev = 0.0 if per_rev else None
                    self.feed = None
            elif group == 'control':
                self.exact = arg
                g64 = code == 640
            elif group == 'cutter':
                self.comp_code = arg
                self.pending_lineno = self.lineno
            elif group == 'retract':
                self.retract = arg
            elif group == 'tool_length' or group == 'coord':
                self.coord_codes(group, arg, code)
            elif group == 'control_mode':
                self.control_mode(code)
        if nurbs_end or motion in SPLINE_MOTIONS:
            self.spline_g_codes(motion, nurbs_end)
        if motion == -1:
            # G80: no motion mode until the next G0/G1/G2/G3; a series of cycles ends.
            self.motion = None
            motion = None
            self.end_series()
        return motion, dwell, g9, g64
