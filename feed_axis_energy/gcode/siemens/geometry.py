"""One Sinumerik block's words -> the interpreter's words, in machine coordinates.

The front keeps the Siemens path state the RS274NGC interpreter does not have: units
(``G70``/``G71``/``G700``/``G710``), absolute and incremental dimensions (``G90``/``G91``,
``AC()``/``IC()``), the frames (:mod:`.frames`), polar coordinates (``G110``/``G111``/
``G112``, ``AP=``/``RP=``), and the arc forms the interpreter lacks (``CR=``, ``CIP``,
``CT``, ``TURN=``, arcs about the pole). Every motion leaves as an absolute ``G0``/``G1``/
``G2``/``G3`` block in millimetres, machine coordinates (the interpreter stays in G21, G90,
G54 with zero offsets), arcs with incremental centre words ``I J K``; the interpreter then
does what it does for every dialect (arc checks, feeds, cutter compensation, dwells,
tool changes). Everything is in millimetres here; the interpreter converts to metres.
"""
from __future__ import annotations

import math
from typing import Callable, NamedTuple

from .frames import Frame, plane_axes, rotation, Vec3, IDENTITY, Mat3
from .text import Scanner

__all__ = ['Geometry', 'Word', 'Words']

Words = list[tuple[str, float]]


class Word(NamedTuple):
    """An address of a Sinumerik block, evaluated.

    Attributes
    ----------
    name
        ``X``, ``G``, ``CR``, ``I1``, ... or a keyword (``CIP``, ``CT``, ``SUPA``).
    value
        The number (a text for ``T="NAME"``).
    mode
        ``''``, ``'AC'`` or ``'IC'`` (written as ``X=AC(..)``), ``'KW'`` for a keyword.
    col
        0-based column of the word in the line.
    """

    name: str
    value: float | str
    mode: str
    col: int


_MOTION_KEYWORDS = {'CIP': 5, 'CT': 6}
_PATH_MODES = {60: 61, 64: 64, 641: 64, 642: 64, 643: 64, 644: 64, 645: 64, 9: 9}
_QUIET_G = frozenset({601, 602, 603, 450, 451, 97, 971, 500})
_SETTABLE = frozenset(range(54, 58)) | frozenset(range(505, 600))
_PASS_LETTERS = frozenset('ABCUVW')
_GEOMETRY = frozenset({'X', 'Y', 'Z', 'I', 'J', 'K', 'I1', 'J1', 'K1', 'CR', 'AP', 'RP',
                       'TURN'})


class Geometry:
    """Path state of the Sinumerik front (see the module docstring).

    Parameters
    ----------
    start_mm
        Tool position [mm] in machine coordinates before the first block.
    warn
        Called with a message once per kind of warning (the reader adds the place).
    """

    def __init__(self, start_mm: Vec3, warn: Callable[[str, str], None]):
        self.pos: Vec3 = start_mm           # programmed position, machine coordinates [mm]
        self.frame = Frame()
        self.warn = warn
        self.unit = 1.0                     # mm per program unit (G71/G710)
        self.feed_inch = False              # G700: F in inch/min
        self.absolute = True                # G90
        self.plane = 17
        self.motion = 1                     # G1: Siemens' default (MD GCODE_RESET_VALUES)
        self.pole: tuple[float, float] = (0.0, 0.0)
        self.ap = 0.0                       # last polar angle [deg] and radius [mm]
        self.rp = 0.0
        self.tangent: Vec3 | None = None    # direction of the last path motion (program)
        self.rpm = 0.0
        self.feed: float | None = None      # mm/min as handed on
        self.comp = 40
        self.offsets: dict[int, Vec3] = {}  # settable work offsets given [mm]
        self.rotary: frozenset[str] = frozenset()   # the machine's rotary axis letters

    # -- PROC ... SAVE ---------------------------------------------------------------------
    def snapshot(self) -> tuple[object, ...]:
        """The modal state a ``PROC ... SAVE`` subprogram restores on return: frames, work
        offset, units, G90/G91, plane, motion mode, pole."""
        f = self.frame
        return (f.matrix, f.shift, f.offset, self.unit, self.feed_inch, self.absolute,
                self.plane, self.motion, self.pole, self.ap, self.rp)

    def restore(self, saved: tuple[object, ...]) -> Words:
        """Restore :meth:`snapshot`; the interpreter words that follow (the plane)."""
        f = self.frame
        plane = self.plane
        (matrix, shift, offset, self.unit, self.feed_inch, self.absolute, self.plane,
         self.motion, self.pole, self.ap, self.rp) = saved     # type: ignore[assignment]
        f.matrix, f.shift, f.offset = matrix, shift, offset    # type: ignore[assignment]
        f.forget_inverse()
        return [] if plane == self.plane else [('G', float(self.plane))]

    # -- positions -------------------------------------------------------------------------
    def program_position(self, *, suppress: bool = False) -> Vec3:
        """The current position in program coordinates [mm]."""
        return self.frame.to_program(self.pos, suppress=suppress)

    def move_words(self, mode: int, target: Vec3) -> Words:
        """A straight ``G0``/``G1`` to ``target`` (program coordinates) as interpreter words;
        the position and path direction follow (for the cycles and pattern moves)."""
        start = self.program_position()
        self.tangent = _sub(target, start) if target != start else self.tangent
        m = self.frame.to_machine(target)
        self.pos = m
        return [('G', float(mode)), ('X', m[0]), ('Y', m[1]), ('Z', m[2])]

    def dwell_words(self, seconds: float) -> Words:
        """A dwell of ``seconds``."""
        return [('G', 4.0), ('P', seconds)]

    def feed_words(self, mm_min: float) -> Words:
        """Set the feed [mm/min] (the cycles' own feeds)."""
        self.feed = mm_min
        return [('F', mm_min)]

    # -- settable offsets and frames -------------------------------------------------------
    def select_offset(self, code: int) -> None:
        """``G54``..``G57``, ``G505``..``G599`` (``G500``: none)."""
        if code == 500:
            self.frame.offset = (0.0, 0.0, 0.0)
            return
        if code not in self.offsets:
            self.warn(f'G{code}', f'settable work offset G{code}: its values are data of the '
                      'control, not of the program, so they are taken as 0 (moves are in the '
                      "program's coordinates; a drive trace in machine coordinates differs "
                      'by this offset)')
        self.frame.offset = self.offsets.get(code, (0.0, 0.0, 0.0))

    def frame_statement(self, kind: str, words: list[Word], s: Scanner) -> None:
        """``TRANS``/``ATRANS``/``ROT``/``AROT``/``SCALE``/``ASCALE``/``MIRROR``/
        ``AMIRROR`` with their axis words."""
        absolute = not kind.startswith('A')
        base = kind[1:] if not absolute else kind
        values: dict[str, float] = {}
        for w in words:
            ok = w.name in ('X', 'Y', 'Z') or (base == 'ROT' and w.name == 'RPL')
            if not ok or w.mode == 'KW' or isinstance(w.value, str):
                s.fail(f'{kind} takes X, Y, Z{" or RPL" if base == "ROT" else ""} with '
                       f'numbers, not {w.name}', w.col)
            if w.name in values:
                s.fail(f'{w.name} twice in one {kind}', w.col)
            values[w.name] = float(w.value)
        if absolute and not values:
            self.frame.clear()
            return
        if base == 'TRANS':
            t = tuple(values.get(a, 0.0) * self.unit for a in 'XYZ')
            self.frame.chain(IDENTITY, t, absolute=absolute)   # type: ignore[arg-type]
        elif base == 'ROT':
            self.frame.chain(self._rotation(values, words, s), absolute=absolute)
        elif base == 'SCALE':
            f = [values.get(a, 1.0) for a in 'XYZ']
            if any(v == 0 for v in f):
                s.fail(f'{kind} with a factor of 0 flattens the axis', words[0].col)
            m: Mat3 = ((f[0], 0.0, 0.0), (0.0, f[1], 0.0), (0.0, 0.0, f[2]))
            self.frame.chain(m, absolute=absolute)
        else:
            f = [-1.0 if a in values else 1.0 for a in 'XYZ']
            m = ((f[0], 0.0, 0.0), (0.0, f[1], 0.0), (0.0, 0.0, f[2]))
            self.frame.chain(m, absolute=absolute)

    def _rotation(self, values: dict[str, float], words: list[Word], s: Scanner) -> Mat3:
        if 'RPL' in values:
            if len(values) > 1:
                s.fail('RPL= with axis words: turn either in the plane or about axes',
                       words[0].col)
            return rotation(plane_axes(self.plane)[2], values['RPL'])
        out = IDENTITY
        for letter, axis in (('Z', 2), ('Y', 1), ('X', 0)):    # RPY: Z, then Y', then X''
            if letter in values:
                out = _matmul(out, rotation(axis, values[letter]))
        return out

    # -- one block -------------------------------------------------------------------------
    def block(self, words: list[Word], s: Scanner) -> list[Words]:
        """The interpreter blocks of one Sinumerik block (empty: nothing to hand on)."""
        extra: Words = []
        motion: int | None = None
        dwell = suppress = area = False
        pole_code = 0
        comp: int | None = None
        geo: dict[str, Word] = {}
        for w in words:
            if w.mode == 'KW':
                if w.name in _MOTION_KEYWORDS:
                    motion = _MOTION_KEYWORDS[w.name]
                elif w.name == 'SUPA':
                    suppress = True
                continue
            if w.name == 'G':
                code = self._g_code(w, s)
                if code in (0, 1, 2, 3):
                    motion = code
                elif code == 4:
                    dwell = True
                elif code in _PATH_MODES:
                    extra.append(('G', float(_PATH_MODES[code])))
                elif code in (17, 18, 19):
                    self.plane = code
                    extra.append(('G', float(code)))
                elif code in (40, 41, 42):
                    comp = code
                elif code in (53, 153):
                    suppress = True
                elif code in _SETTABLE or code == 500:
                    self.select_offset(code)
                elif code in (70, 71, 700, 710):
                    self.unit = 25.4 if code in (70, 700) else 1.0
                    self.feed_inch = code == 700
                elif code in (90, 91):
                    self.absolute = code == 90
                elif code in (93, 94, 95):
                    extra.append(('G', float(code)))
                elif code in (110, 111, 112):
                    pole_code = code
                elif code in (25, 26):
                    area = True
                elif code not in _QUIET_G:
                    s.fail(f'G{code} is not simulated in the sinumerik dialect', w.col)
                continue
            if w.name in _GEOMETRY:
                if w.name in geo:
                    s.fail(f'{w.name} twice in one block', w.col)
                geo[w.name] = w
            elif w.name in ('F', 'S') and dwell:
                geo[w.name] = w
            elif w.name == 'F':
                f = float(w.value) * (25.4 if self.feed_inch else 1.0)
                self.feed = f
                extra.append(('F', f))
            elif w.name == 'S':
                self.rpm = float(w.value)
                extra.append(('S', float(w.value)))
            elif w.name == 'M':
                extra.append(('M', float(w.value)))
            elif w.name == 'T':
                if isinstance(w.value, str):
                    self.warn('T="' + w.value + '"', f'named tool T="{w.value}": tool data '
                              'are by number in the machine config, so it runs with length '
                              'and radius 0')
                    extra.append(('T', 0.0))
                else:
                    extra.append(('T', float(w.value)))
            elif w.name == 'D':
                self.warn('D', 'D (cutting edge) words select tool offsets of the control; '
                          'the radius used by G41/G42 is the loaded tool\'s (0 for named tools)')
            elif w.name == 'H':
                self.warn('H', 'H words (auxiliary functions to the PLC) are ignored')
            elif w.name in _PASS_LETTERS:
                extra.append((w.name, float(w.value)))
            else:
                s.fail(f'address {w.name} is not simulated in the sinumerik dialect', w.col)
        if area:
            self.warn('G25', 'G25/G26 working area limits are not checked (their axis '
                      'words are limits, not a move)')
            return [extra] if extra else []
        if comp is not None and comp == self.comp:
            comp = None                   # G41 again while G41 is on: no change (Siemens)
        if comp is not None:
            sense = self.frame.arc_sense(self.plane) if not suppress else 1
            self.comp = comp
            if sense == -1 and comp != 40:
                comp = 83 - comp          # a mirrored frame swaps the side
            extra.append(('G', float(comp)))
        if dwell:
            return [self._dwell(geo, s) + extra]
        if motion is not None:
            self.motion = motion
        if pole_code:
            self._pole(pole_code, geo, s, suppress)
            return [extra] if extra else []
        moved = self._motion(geo, s, suppress)
        if moved is None:
            if self.motion in (0, 1) and any(name in self.rotary for name, _ in extra):
                # a rotary axis of the machine alone (G1 B0): it moves in the modal G0/G1
                return [[('G', float(self.motion))] + extra]
            return [extra] if extra else []
        return [moved + extra]

    def _g_code(self, w: Word, s: Scanner) -> int:
        value = float(w.value)
        if value != int(value) or value < 0:
            s.fail(f'G{value:g} is not a Sinumerik G code', w.col)
        return int(value)

    def _dwell(self, geo: dict[str, Word], s: Scanner) -> Words:
        if 'F' in geo:
            seconds = float(geo['F'].value)
        elif 'S' in geo:
            if self.rpm <= 0:
                s.fail('G4 S (dwell in spindle revolutions) with no spindle speed set',
                       geo['S'].col)
            seconds = float(geo['S'].value) * 60.0 / self.rpm
        else:
            s.fail('G4 without F (seconds) or S (revolutions)')
        if seconds < 0:
            s.fail('negative dwell time')
        return self.dwell_words(seconds)

    # -- coordinates -----------------------------------------------------------------------
    def _value(self, w: Word, start: float) -> float:
        """An axis word's program coordinate [mm] from ``start`` (G90/G91, AC/IC)."""
        v = float(w.value) * self.unit
        inc = w.mode == 'IC' or (w.mode == '' and not self.absolute)
        return start + v if inc else v

    def _pole(self, code: int, geo: dict[str, Word], s: Scanner, suppress: bool) -> None:
        a, b, n = plane_axes(self.plane)
        here = self.program_position(suppress=suppress)
        ref = {110: (here[a], here[b]), 111: (0.0, 0.0), 112: self.pole}[code]
        if 'AP' in geo or 'RP' in geo:
            ang = float(geo['AP'].value) if 'AP' in geo else 0.0
            rad = float(geo['RP'].value) * self.unit if 'RP' in geo else 0.0
            self.pole = (ref[0] + rad * math.cos(math.radians(ang)),
                         ref[1] + rad * math.sin(math.radians(ang)))
            return
        letters = 'XYZ'
        da = float(geo[letters[a]].value) * self.unit if letters[a] in geo else 0.0
        db = float(geo[letters[b]].value) * self.unit if letters[b] in geo else 0.0
        for k in geo:
            if k not in (letters[a], letters[b]):
                s.fail(f'{k} in a pole definition G{code}', geo[k].col)
        self.pole = (ref[0] + da, ref[1] + db)

    def _motion(self, geo: dict[str, Word], s: Scanner, suppress: bool) -> Words | None:
        mode = self.motion
        start = self.program_position(suppress=suppress)
        target = list(start)
        has_axes = False
        for i, letter in enumerate('XYZ'):
            if letter in geo:
                target[i] = self._value(geo[letter], start[i])
                has_axes = True
        a, b, n = plane_axes(self.plane)
        polar = 'AP' in geo or 'RP' in geo
        if polar:
            for key in ('AP', 'RP'):
                if key in geo:
                    v = float(geo[key].value) * (self.unit if key == 'RP' else 1.0)
                    old = self.ap if key == 'AP' else self.rp
                    v = old + v if geo[key].mode == 'IC' else v
                    if key == 'AP':
                        self.ap = v
                    else:
                        self.rp = v
            if 'XYZ'[a] in geo or 'XYZ'[b] in geo:
                s.fail('polar AP/RP with a Cartesian axis of the plane in one block',
                       geo['AP' if 'AP' in geo else 'RP'].col)
            target[a] = self.pole[0] + self.rp * math.cos(math.radians(self.ap))
            target[b] = self.pole[1] + self.rp * math.sin(math.radians(self.ap))
            has_axes = True
        if mode in (2, 3, 5, 6):
            centre_words = any(k in geo for k in ('I', 'J', 'K', 'CR'))
            if not has_axes and not centre_words:
                for key in ('I1', 'J1', 'K1', 'TURN'):
                    if key in geo:
                        s.fail('arc without an end point', geo[key].col)
                return None
            return self._arc(mode, start, (target[0], target[1], target[2]), geo, s,
                             suppress, polar)
        for key in ('I', 'J', 'K', 'CR', 'I1', 'J1', 'K1', 'TURN'):
            if key in geo:
                s.fail(f'{key} with no arc (G2/G3/CIP/CT) to use it', geo[key].col)
        if not has_axes:
            return None
        end = tuple(target)
        if end != start:
            self.tangent = _sub(end, start)         # type: ignore[arg-type]
        m = self.frame.to_machine(end, suppress=suppress)   # type: ignore[arg-type]
        self.pos = m
        return [('G', float(mode)), ('X', m[0]), ('Y', m[1]), ('Z', m[2])]

    def _arc(self, mode: int, start: Vec3, end: Vec3, geo: dict[str, Word], s: Scanner,
             suppress: bool, polar: bool) -> Words:
        a, b, n = plane_axes(self.plane)
        first = next(iter(geo.values())).col if geo else 0
        sa, sb = start[a], start[b]
        ea, eb = end[a], end[b]
        if mode == 5:                                  # CIP: through an intermediate point
            mid = list(start)
            for i, key in enumerate(('I1', 'J1', 'K1')):
                if key in geo:
                    mid[i] = self._value(geo[key], start[i])
            if not any(k in geo for k in ('I1', 'J1', 'K1')):
                s.fail('CIP needs an intermediate point I1=/J1=/K1=', first)
            if max(abs(mid[n] - start[n]), abs(end[n] - start[n])) > 1e-9:
                s.fail('CIP circle out of the working plane is not simulated', first)
            centre = _circumcentre((sa, sb), (mid[a], mid[b]), (ea, eb))
            if centre is None:
                s.fail('CIP: start, intermediate and end point lie on one line', first)
            cross = (mid[a] - sa) * (eb - mid[b]) - (mid[b] - sb) * (ea - mid[a])
            ccw = cross > 0
        elif mode == 6:                                # CT: tangential to the last motion
            t = self.tangent
            if t is None or math.hypot(t[a], t[b]) < 1e-12:
                s.fail('CT needs a previous motion in the plane to be tangent to', first)
            tl = math.hypot(t[a], t[b])
            ta, tb = t[a] / tl, t[b] / tl
            da, db = ea - sa, eb - sb
            side = ta * db - tb * da
            if abs(side) < 1e-9 * max(1.0, math.hypot(da, db)):
                return self._line_from_arc(end, suppress)
            na, nb = -tb, ta                           # left normal of the tangent
            r = (da * da + db * db) / (2.0 * (da * na + db * nb))
            centre = (sa + r * na, sb + r * nb)
            ccw = r > 0
        elif 'CR' in geo:
            if polar:
                s.fail('CR= with polar AP/RP: the arc of a polar block turns about the pole',
                       geo['CR'].col)
            r = float(geo['CR'].value) * self.unit
            centre = _centre_from_radius((sa, sb), (ea, eb), r, mode == 3, s, geo['CR'].col)
            ccw = mode == 3
        elif polar:
            centre = self.pole
            ccw = mode == 3
        else:
            off = {'I': 0.0, 'J': 0.0, 'K': 0.0}
            for key in off:
                if key in geo:
                    w = geo[key]
                    v = float(w.value) * self.unit
                    axis = 'IJK'.index(key)
                    off[key] = v - start[axis] if w.mode == 'AC' else v
                    if axis == n and v != 0.0 and w.mode != 'AC':
                        s.fail(f'{key} is along the plane normal of G{self.plane}', w.col)
            centre = (start[a] + off['IJK'[a]], start[b] + off['IJK'[b]])
            ccw = mode == 3
        sense = 1 if suppress else self.frame.arc_sense(self.plane)
        if sense is None:
            s.fail('arc in a frame that rotates it out of the working plane, or scales the '
                   'plane axes unequally, is not simulated', first)
        if sense == -1:
            ccw = not ccw
        c3 = [0.0, 0.0, 0.0]
        c3[a], c3[b], c3[n] = centre[0], centre[1], start[n]
        cm = self.frame.to_machine(tuple(c3), suppress=suppress)   # type: ignore[arg-type]
        em = self.frame.to_machine(end, suppress=suppress)
        out: Words = [('G', 3.0 if ccw else 2.0), ('X', em[0]), ('Y', em[1]), ('Z', em[2]),
                      ('IJK'[a], cm[a] - self.pos[a]), ('IJK'[b], cm[b] - self.pos[b])]
        if 'TURN' in geo:
            turns = float(geo['TURN'].value)
            if turns != int(turns) or turns < 0:
                s.fail('TURN= takes a whole number of extra turns', geo['TURN'].col)
            out.append(('P', turns + 1.0))
        ra, rb = ea - centre[0], eb - centre[1]
        tan = [0.0, 0.0, 0.0]
        # the program's sense (before a mirror) gives the program's tangent
        prog_ccw = ccw if sense == 1 else not ccw
        tan[a], tan[b] = (-rb, ra) if prog_ccw else (rb, -ra)
        self.tangent = (tan[0], tan[1], tan[2])
        self.pos = em
        return out

    def _line_from_arc(self, end: Vec3, suppress: bool) -> Words:
        """A CT whose end lies on the tangent: a straight feed move (as the control)."""
        start = self.program_position(suppress=suppress)
        if end != start:
            self.tangent = _sub(end, start)
        m = self.frame.to_machine(end, suppress=suppress)
        self.pos = m
        return [('G', 1.0), ('X', m[0]), ('Y', m[1]), ('Z', m[2])]


def _sub(p: Vec3, q: Vec3) -> Vec3:
    return (p[0] - q[0], p[1] - q[1], p[2] - q[2])


def _matmul(x: Mat3, y: Mat3) -> Mat3:
    return tuple(tuple(sum(x[i][k] * y[k][j] for k in range(3)) for j in range(3))
                 for i in range(3))     # type: ignore[return-value]


def _circumcentre(p: tuple[float, float], q: tuple[float, float],
                  r: tuple[float, float]) -> tuple[float, float] | None:
    """Centre of the circle through three points (``None``: on one line)."""
    ax, ay = p
    bx, by = q
    cx, cy = r
    d = 2.0 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
    scale = max(abs(ax - cx), abs(ay - cy), abs(bx - ax), abs(by - ay), 1e-300)
    if abs(d) < 1e-12 * scale * scale:
        return None
    a2, b2, c2 = ax * ax + ay * ay, bx * bx + by * by, cx * cx + cy * cy
    ux = (a2 * (by - cy) + b2 * (cy - ay) + c2 * (ay - by)) / d
    uy = (a2 * (cx - bx) + b2 * (ax - cx) + c2 * (bx - ax)) / d
    return ux, uy


def _centre_from_radius(p: tuple[float, float], q: tuple[float, float], r: float, ccw: bool,
                        s: Scanner, col: int) -> tuple[float, float]:
    """Centre of the arc from ``p`` to ``q`` with radius ``|r|`` (``r < 0``: the arc over
    180 degrees), turning counter-clockwise if ``ccw``."""
    dx, dy = q[0] - p[0], q[1] - p[1]
    chord = math.hypot(dx, dy)
    if chord == 0.0:
        s.fail('CR= arc ending at its start: a full circle is written with I/J', col)
    if r == 0.0:
        s.fail('CR=0', col)
    half = chord / 2.0
    rr = abs(r)
    if half > rr:
        if half - rr > 0.00127 + 1e-9:       # LinuxCNC's R-form tolerance, in mm
            s.fail(f'CR={r:g} is shorter than half the chord ({half:g} mm)', col)
        rr = half
    h = math.sqrt(max(rr * rr - half * half, 0.0))
    ux, uy = dx / chord, dy / chord
    left = (-uy, ux)
    side = 1.0 if (ccw == (r > 0)) else -1.0
    return (p[0] + dx / 2 + side * h * left[0], p[1] + dy / 2 + side * h * left[1])
