"""Motion of the interpreter: G0/G1 and G2/G3 (centre, LinuxCNC's checks), feeds.

A mixin of :class:`~.interp.Interpreter` (split off along the motion seam to keep modules
small); it uses the interpreter's state (``pos``, ``plane``, ``scale``, ``feed``, ...) and
helpers (``fail``, ``route``, ``rotated_target``). The rules are those of LinuxCNC 2.9's
``arc_data_ijk`` / ``arc_data_r`` (see :mod:`.canon` for the tolerances).

Two ways in, one way out: :meth:`MotionMixin.straight` / :meth:`MotionMixin.arc` take a
line's word dictionary (``Interpreter.line``), :meth:`MotionMixin.contour_line` the usual
CAM line as :data:`.lexer.CONTOUR_RE` splits it (no dictionary, no word checks: it declines
whatever it cannot finish exactly as ``line`` would); both build the move with
:meth:`MotionMixin.straight_from` / :meth:`MotionMixin.arc_from` and the end point with
:meth:`MotionMixin.point`.
"""
from __future__ import annotations

import math
from typing import cast, NoReturn, overload, TYPE_CHECKING

from ..canon import (centre_tolerance_m, FULL_TURN_EPS_RAD, radius_error, RADIUS_TOLERANCE_MM,
                     radius_tolerance_m)
from .codes import MOTION_TEXT
from ..program import arc_move, Move, MoveKind, straight_move

if TYPE_CHECKING:
    from .coordstate import Vec3
    from .state import InterpreterState
else:
    InterpreterState = object     # the declarations are for the type checker only

__all__ = ['MotionMixin']

_INF = float('inf')
_MOTION_KIND = (MoveKind.RAPID, MoveKind.LINEAR, MoveKind.ARC_CW, MoveKind.ARC_CCW)
_PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}
_CENTRE_LETTERS = ('I', 'J', 'K')
_AXIS_LETTERS = ('X', 'Y', 'Z')
# LinuxCNC's TINY (interp_internal.hh): an R this close to half the chord is a half circle.
_TINY = 1e-12
_TWO_PI = 2.0 * math.pi
# Radii above RADIUS_TOLERANCE (1.27e-6 m in either unit system) whose difference is within
# the smallest absolute tolerance in force pass every check of canon (the interpreter keeps
# that bound in ``arc_quick``: LinuxCNC's G21 value 2.83e-5 m, or a smaller arc_tolerance_m).
_R_MIN = RADIUS_TOLERANCE_MM * 1e-3


class MotionMixin(InterpreterState):
    """G0/G1, G2/G3 and feeds for :class:`~.interp.Interpreter`."""

    __slots__ = ()

    def contour_line(self, g: str | None, x: str | None, y: str | None, z: str | None,
                     i: str | None, j: str | None, k: str | None, r: str | None,
                     f: str | None) -> bool:
        """Run the usual CAM line from its words as :data:`.lexer.CONTOUR_RE` splits them
        (number texts, ``None`` for a word not given) exactly as :meth:`line` would, without
        its word dictionary and checks.

        Returns
        -------
        bool
            False, having changed nothing, for a line off the common path: no axis word,
            no G0..G3 in force, a canned-cycle series, G93 or G95, a rotated coordinate system,
            G90.1, a centre word the move does not use, an R/I/J/K mix, a negative F, a
            feed move without a feed rate, an arc that needs LinuxCNC's radius checks. The
            caller then gives the line to :meth:`line`, which runs it or reports the error
            at its word. True when the move has been issued.

        Raises
        ------
        GcodeError
            Only for an R word that cannot make the arc (the error :meth:`line` would
            report first for that line).
        """
        if x is None and y is None and z is None:
            return False
        # Codes pending on the line (pending_lineno, coord_line) are set while line() runs
        # it; this runs first, so none can be pending here.
        mode = self.motion if g is None else MOTION_TEXT[g]
        if (mode is None or mode > 3 or self.series or self.inverse_time or self.rotated
                or self.feed_per_rev is not None):
            return False
        feed = self.feed
        if f is not None:
            feed = float(f)             # ModesMixin.set_feed, same arithmetic
            if feed < 0.0:
                return False
            feed = feed * self.scale / 60.0
        start = self.pos
        end = self.point(x, y, z)
        if mode < 2:
            if i is not None or j is not None or k is not None or r is not None:
                return False
            m = self.straight_from(start, end, mode, feed, False, True, None)
        else:
            if r is not None:
                if i is not None or j is not None or k is not None:
                    return False
                # The only error possible here is R's own (line() would report it first).
                ca, cb = self.centre_from_radius(r, start, end, mode == 3)
            else:
                if self.arc_absolute:
                    return False
                a, b, n = _PLANE_AXES[self.plane]
                given = (i, j, k)
                if given[n] is not None:
                    return False
                oa = given[a]
                ob = given[b]
                if oa is None and ob is None:
                    return False
                s = self.scale
                ca = start[a] if oa is None else start[a] + float(oa) * s
                cb = start[b] if ob is None else start[b] + float(ob) * s
            m = self.arc_from(start, end, ca, cb, -1 if mode == 2 else 1, feed, False, True,
                              None)
        if m is None:
            return False
        if f is not None:
            self.feed = feed
        self.motion = mode
        if self.routing:
            self.route(m)
        else:
            self.moves.append(m)
        self.pos = end
        return True

    def point(self, x: str | float | None, y: str | float | None,
              z: str | float | None) -> tuple[float, float, float]:
        """End point [m] of a move from its axis words (number texts or values; ``None``:
        not given) in the current, unrotated frame."""
        px, py, pz = pos = self.pos
        s = self.scale
        try:
            if self.absolute:
                ox, oy, oz = self.frame
                if x is not None:
                    px = float(x) * s + ox
                if y is not None:
                    py = float(y) * s + oy
                if z is not None:
                    pz = float(z) * s + oz
            else:
                if x is not None:
                    px += float(x) * s
                if y is not None:
                    py += float(y) * s
                if z is not None:
                    pz += float(z) * s
        except ValueError:
            # Rare: blanks inside a number, or not a number at all.
            new = list(pos)
            for index, (letter, text) in enumerate(zip(_AXIS_LETTERS, (x, y, z))):
                if text is not None:
                    v = self.num(letter, text) * s
                    new[index] = v + self.frame[index] if self.absolute else pos[index] + v
            px, py, pz = new
        return (px, py, pz)

    def target(self, d: dict[str, str | float]) -> tuple[float, float, float]:
        """End point [m] of a move from the axis words of the line."""
        if self.rotated:
            return self.rotated_target(d)
        get = d.get
        return self.point(get('X'), get('Y'), get('Z'))

    def centre_from_offsets(self, d: dict[str, str | float], start: tuple[float, float, float],
                            a: int, b: int, n: int) -> tuple[float, float]:
        """In-plane centre [m] from I/J/K (incremental under G91.1, absolute under G90.1)."""
        normal = _CENTRE_LETTERS[n]
        if normal in d:
            self.normal_centre_word(normal, d[normal])
        la = _CENTRE_LETTERS[a]
        lb = _CENTRE_LETTERS[b]
        if la not in d and lb not in d:
            self.fail(f'arc needs {la}/{lb} (centre) or R (radius) in G{self.plane}',
                      self.first_axis(d))
        oa = self.num(la, d[la]) * self.scale if la in d else 0.0
        ob = self.num(lb, d[lb]) * self.scale if lb in d else 0.0
        if self.arc_absolute:
            return oa + self.frame[a], ob + self.frame[b]
        return start[a] + oa, start[b] + ob

    def arc(self, d: dict, mode: int, g9: bool, explicit: bool) -> None:
        """Emit a G2/G3 arc or helix after LinuxCNC's radius checks."""
        start = self.pos
        end = self.target(d)
        a, b, n = _PLANE_AXES[self.plane]
        turn = 1
        if 'P' in d:
            p = self.num('P', d['P'])
            if p != int(p) or p < 1:
                self.fail('P on G2/G3 is the number of turns: a whole number >= 1', 'P')
            turn = int(p)
        if mode == 2:
            turn = -turn
        if 'R' in d:
            if 'I' in d or 'J' in d or 'K' in d:
                self.fail('give either R or I/J/K for an arc, not both', 'R')
            ca, cb = self.centre_from_radius(d['R'], start, end, mode == 3)
        else:
            la = _CENTRE_LETTERS[a]
            lb = _CENTRE_LETTERS[b]
            try:
                if _CENTRE_LETTERS[n] in d or self.arc_absolute:
                    raise ValueError
                ca = start[a] + float(d[la]) * self.scale if la in d else start[a]
                cb = start[b] + float(d[lb]) * self.scale if lb in d else start[b]
                if la not in d and lb not in d:
                    raise ValueError
            except ValueError:
                # The checking (and absolute-centre) path.
                ca, cb = self.centre_from_offsets(d, start, a, b, n)
        m = self.arc_from(start, end, ca, cb, turn, self.feed, g9, explicit, d)
        if self.rotary is not None:
            m = self.rotary_move(m)
        if self.routing:
            self.route(m)
        else:
            self.moves.append(m)
        self.pos = end

    @overload
    def arc_from(self, start: Vec3, end: Vec3, ca: float, cb: float, turn: int,
                 feed: float | None, g9: bool, explicit: bool, d: dict) -> Move: ...

    @overload
    def arc_from(self, start: Vec3, end: Vec3, ca: float, cb: float, turn: int,
                 feed: float | None, g9: bool, explicit: bool, d: None) -> Move | None: ...

    def arc_from(self, start: tuple[float, float, float], end: tuple[float, float, float],
                 ca: float, cb: float, turn: int, feed: float | None, g9: bool,
                 explicit: bool, d: dict | None) -> Move | None:
        """The arc from ``start`` to ``end`` about the in-plane centre ``(ca, cb)`` [m] with
        LinuxCNC's rotation ``turn`` at ``feed`` (the rate in force on the line), after the
        radius checks; ``None`` instead of the checks and of ``feed_for`` (both report at
        the line's words) when ``d`` is ``None``."""
        a, b, n = _PLANE_AXES[self.plane]
        sa = start[a] - ca
        sb = start[b] - cb
        ea = end[a] - ca
        eb = end[b] - cb
        r0 = math.hypot(sa, sb)
        r1 = math.hypot(ea, eb)
        if r0 < _R_MIN or r1 < _R_MIN or abs(r1 - r0) > self.arc_quick:
            if d is None:
                return None
            self.check_radii(d, r0, r1, explicit)
        # canon.arc_sweep_rad, inline on this hot path (same rule, same arithmetic).
        ang = math.atan2(sa * eb - sb * ea, sa * ea + sb * eb)
        sweep = (ang if turn > 0 else -ang) % _TWO_PI
        if sweep < FULL_TURN_EPS_RAD:
            sweep = _TWO_PI
        if turn != 1 and turn != -1:
            sweep += (abs(turn) - 1) * _TWO_PI
        if turn < 0:
            sweep = -sweep
        length = math.hypot(sweep * 0.5 * (r0 + r1), end[n] - start[n])
        if not feed or self.inverse_time:
            if d is None:
                return None
            feed = self.feed_for(d, length, explicit)
        if n == 2:
            centre = (ca, cb, start[2])
        else:
            c = [0.0, 0.0, 0.0]
            c[a] = ca
            c[b] = cb
            c[n] = start[n]
            centre = (c[0], c[1], c[2])
        # canon.arc_feed, inline on this hot path.
        return arc_move(MoveKind.ARC_CCW if turn > 0 else MoveKind.ARC_CW, self.lineno, start,
                        end, feed, self.exact or g9, centre, self.plane, abs(turn) - 1, length,
                        sweep)

    def probe_or_tap(self, d: dict, mode: int, g9: bool) -> None:
        """G38.2-G38.5 probing: a feed to the end point (no contact is simulated, one
        warning); G33.1 rigid tapping: in to the end point and back at K x S."""
        if self.series:
            self.end_series()
        if self.comp.active:
            self.fail('Cannot probe or tap with cutter radius compensation on', 'G',
                      value=mode / 10)
        if mode != 331:
            if not self.feed or self.inverse_time:
                self.fail('probing (G38.x) needs a feed rate in units per minute (G94 F)',
                          'G', value=mode / 10)
            if 'probe' not in self.warned:
                self.warned.add('probe')
                self.warnings.append(f'{self.file}:{self.lineno}: G{mode / 10:g} probing runs '
                                     'to its end point (no contact is simulated)')
            self.straight(d, 1, g9, True)
            self.probe_result()         # coords: #5061..#5070
            return
        if 'K' not in d:
            self.fail('G33.1 rigid tapping needs K (the distance per spindle revolution)', 'G',
                      value=33.1)
        pitch = abs(self.num('K', d['K'])) * self.scale
        if pitch == 0.0 or self.rpm <= 0.0:
            self.fail('G33.1 needs a non-zero K and a spindle speed S (feed = K x S)', 'K')
        start = self.pos
        end = self.target(d)
        feed = pitch * self.rpm / 60.0
        length = math.dist(start, end)
        for a, b, back in ((start, end, False), (end, start, True)):
            self.emit(Move(kind=MoveKind.LINEAR, line=self.lineno, start=a, end=b,
                           feed_m_s=feed, exact_stop=True, length_m=length, tap_return=back))

    def check_radii(self, d: dict, r0: float, r1: float, explicit: bool) -> None:
        """LinuxCNC's zero-radius and end-on-circle checks (see :mod:`.canon`)."""
        scale = self.scale
        if min(r0, r1) < radius_tolerance_m(scale):
            self.fail_motion(f'arc radius is zero (radius {r0 * 1e3:.4f} mm at the start, '
                             f'{r1 * 1e3:.4f} mm at the end)', explicit, d)
        tol = self.arc_tol if self.arc_tol is not None else centre_tolerance_m(scale)
        if radius_error(r0, r1, tol):
            self.fail(f'arc end is not on the circle: radius {r0 * 1e3:.4f} mm at the start, '
                      f'{r1 * 1e3:.4f} mm at the end (LinuxCNC tolerance {tol * 1e3:.4f} mm, '
                      f'or 0.1 % of the radius up to {100 * tol * 1e3:.4f} mm)',
                      self.first_axis(d) if any(x in d for x in 'XYZ') else 'G')

    def centre_from_radius(self, r_text: str | float, start: tuple[float, float, float],
                           end: tuple[float, float, float], ccw: bool) -> tuple[float, float]:
        """In-plane centre [m] from the R word (negative R: the arc over 180 degrees),
        LinuxCNC's ``arc_data_r``: any radius that reaches the end point, however large."""
        a, b, _ = _PLANE_AXES[self.plane]
        r = self.num('R', r_text) * self.scale
        if r == 0.0:
            self.fail('R0: an arc needs a non-zero radius', 'R')
        da = end[a] - start[a]
        db = end[b] - start[b]
        if da == 0.0 and db == 0.0:
            self.fail('R-form arc ending where it starts: use I/J/K for a full circle', 'R')
        chord = math.hypot(da, db)
        half = 0.5 * chord
        ar = abs(r)
        if half - ar > radius_tolerance_m(self.scale):
            self.fail(f'R {ar * 1e3:.4f} mm is smaller than half the chord '
                      f'({half * 1e3:.4f} mm): the arc cannot reach its end point', 'R')
        if half / ar > 1.0 - _TINY:
            half = ar
        h = math.sqrt(max(ar * ar - half * half, 0.0))
        # The centre lies left of the chord for a CCW arc of at most 180 degrees.
        side = (1.0 if ccw else -1.0) * (1.0 if r > 0.0 else -1.0) * h / chord
        return (start[a] + 0.5 * da - side * db, start[b] + 0.5 * db + side * da)

    def feed_for(self, d: dict[str, str | float], length: float, explicit: bool) -> float:
        """Path feed [m/s] of a feed move of ``length`` metres on this line."""
        feed = self.feed
        if self.feed_per_rev is not None:
            what = 'an F (per revolution)' if not self.feed_per_rev else 'a spindle speed S'
            self.fail_motion(f'G95 feed per revolution: a feed move needs {what}', explicit, d)
        if self.inverse_time:
            if 'F' not in d:
                self.fail_motion('G93 inverse time: every feed move needs F on its line',
                                 explicit, d)
            if feed == 0.0:
                self.fail('F0 in G93: the move would never finish', 'F')
            return length * cast(float, feed) / 60.0     # set_feed gave it with the F word
        if feed == 0.0:
            # an F0 in force: LinuxCNC refuses it, its preview too ("Cannot do G1 with zero
            # feed rate"), whatever allow_no_feed says
            if 'F' in d:
                self.fail('feed rate is zero', 'F')
            self.fail_motion('feed move with the feed rate F0 in force (LinuxCNC: Cannot do '
                             'G1 with zero feed rate)', explicit, d)
        if not self.allow_no_feed:
            # no F since the start (or since G93/G95 ended): LinuxCNC's control, Fanuc
            # (alarm PS0011) and grbl (error 22) refuse the move at run time
            self.fail_motion('feed move with no feed rate (F) set: the control refuses it '
                             '(LinuxCNC: Cannot do G1 with zero feed rate); give an F word '
                             'before it, or --allow-no-feed to preview it at the machine\'s '
                             'axis limits', explicit, d)
        if 'no feed' not in self.warned:
            self.warned.add('no feed')
            self.warnings.append(f'{self.file}:{self.lineno}: feed move with no feed rate (F) '
                                 "set: it runs at the machine's axis limits (--allow-no-feed; "
                                 'the control refuses this, LinuxCNC\'s preview accepts it)')
        return _INF

    def fail_motion(self, msg: str, explicit: bool, d: dict[str, str | float]) -> NoReturn:
        """Fail at the word that asked for this line's motion (its G word or first axis)."""
        if explicit:
            self.fail(msg, 'G', value=float(cast(int, self.motion)))
        self.fail(msg, self.first_axis(d))

    def straight(self, d: dict[str, str | float], mode: int, g9: bool, explicit: bool) -> None:
        """Emit a G0/G1 move (also of zero length: LinuxCNC issues it, the planner drops
        it)."""
        start = self.pos
        end = self.target(d)
        m = self.straight_from(start, end, mode, self.feed, g9, explicit, d)
        if self.rotary is not None:
            m = self.rotary_move(m)
        if self.routing:
            self.route(m)
        else:
            self.moves.append(m)
        self.pos = end

    @overload
    def straight_from(self, start: Vec3, end: Vec3, mode: int, feed: float | None, g9: bool,
                      explicit: bool, d: dict) -> Move: ...

    @overload
    def straight_from(self, start: Vec3, end: Vec3, mode: int, feed: float | None, g9: bool,
                      explicit: bool, d: None) -> Move | None: ...

    def straight_from(self, start: tuple[float, float, float],
                      end: tuple[float, float, float], mode: int, feed: float | None,
                      g9: bool, explicit: bool, d: dict | None) -> Move | None:
        """The G0 (``mode`` 0) or G1 move at ``feed`` (the rate in force on the line);
        ``None`` instead of ``feed_for`` (which reports at the line's words) when ``d`` is
        ``None``."""
        length = math.dist(start, end)
        if mode == 0:
            feed = _INF
        elif not feed or self.inverse_time:
            if d is None:
                return None
            feed = self.feed_for(d, length, explicit)
        return straight_move(_MOTION_KIND[mode], self.lineno, start, end, feed,
                             self.exact or g9, length)

    def stand_still(self, d: dict[str, str | float], mode: int, g9: bool) -> None:
        """G0/G1 without axis words: LinuxCNC issues a move to where the tool is (a G1
        without any feed rate is let pass without one under ``allow_no_feed``, as the
        preview does; the control refuses it as any G1 without a feed rate)."""
        if mode == 1 and (self.feed is None or self.inverse_time):
            if (self.feed is None and not self.inverse_time and self.feed_per_rev is None
                    and not self.allow_no_feed):
                self.feed_for(d, 0.0, True)         # raises
            return
        if self.series:
            self.end_series()
        self.straight(d, mode, g9, True)

    def normal_centre_word(self, letter: str, text: str | float) -> None:
        """A centre word along the plane normal (K in G17): LinuxCNC refuses it; other
        dialects ignore a zero one (FreeCAD writes K0) with one warning."""
        if self.num(letter, text) != 0.0 or self.dialect.normal_centre_zero == 'error':
            self.fail(f'{letter} is not an in-plane centre word for G{self.plane} (LinuxCNC: '
                      f'{letter} word given for arc in G{self.plane} plane)', letter)
        key = f'normal {letter}'
        if key not in self.warned:
            self.warned.add(key)
            self.warnings.append(f'{self.file}:{self.lineno}: {letter}0 on a G{self.plane} '
                                 f'arc is ignored ({self.dialect.name} dialect; LinuxCNC '
                                 'refuses it)')
