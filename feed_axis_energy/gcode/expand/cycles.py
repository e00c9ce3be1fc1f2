"""Canned cycles G73 and G81..G89 expanded into rapid, feed and dwell primitives.

The expansion copies what LinuxCNC 2.9's interpreter does (``src/emc/rs274ngc/
interp_cycles.cc``, ``convert_cycle_xy/yz/zx`` and the ``CYCLE_MACRO`` of
``interp_internal.hh`` in the snapshot the reference package was built from, git
2023-02-08): the same moves, in the same order, including the zero-length positioning
moves it issues. Everything is computed in program coordinates as there and moved into
machine coordinates by the pure translation ``CycleSpec.offset`` at the end.

One cycle line (plane G17, the drilling axis Z; G18 drills along Y, G19 along X, with the
in-plane axes permuted as LinuxCNC does):

1. If the tool is below the R level, a rapid straight up to R (X, Y unchanged).
2. For each of the L repeats: the in-plane position moves by X/Y under G91 (absolute X/Y
   under G90: the same hole L times). First repeat from above R: rapid across at the
   current level, then down to R. Later repeats: rapid across at the clearance level, then
   down to R if the clearance level is above it.
3. The cycle itself (below), then the retract to the clearance level: R under G99, the
   *initial level* under G98 (the level when the series of cycles began; never below R).

Cycles (``bottom`` = Z, ``clear`` = clearance level):

* G81: feed to bottom, rapid to clear.  G82: the same with a dwell of P at the bottom.
* G73: pecks of Q, each followed by a rapid back-off of 0.010 inch (0.254 mm, LinuxCNC's
  ``G83_RAPID_DELTA``, applied in both unit systems), last feed to bottom, rapid to clear.
* G83: pecks of Q, after each a rapid out to R and a rapid back to 0.254 mm above the depth
  reached (same constant), last feed to bottom, rapid to clear.
* G84: feed to bottom, dwell P (0 unless given, or the last P of any cycle), feed out to
  clear. Really spindle-synchronised tapping with a reversal; modelled as feed in and feed
  out at the programmed F. Needs the spindle turning clockwise (M3).
* G85: feed to bottom, feed back to R, rapid to clear (a zero-length rapid under G99).
* G86: feed to bottom, dwell P, spindle stop, rapid to clear (the spindle does not move
  the feed axes). Needs a turning spindle.
* G87 (back boring, I/J offsets from the hole, K the top of the bore): rapid to the offset
  point at R, rapid down to bottom, rapid in to the hole, feed up to K, feed down to bottom,
  rapid out to the offset point, rapid up to clear, rapid over the hole. Needs a turning
  spindle.
* G88: feed to bottom, dwell P, spindle stop and program stop (``('stop',)``); the
  operator then retracts by hand. LinuxCNC resumes as if the tool were at the clearance
  level, so its next move starts at the bottom of the hole; here the manual retract is one
  rapid to clear so the path stays continuous (the only departure from the reference).
* G89: feed to bottom, dwell P, feed to clear.

Sticky words (LinuxCNC rule): R, the depth word (Z in G17), P, Q and I/J/K keep their value
for later lines *of the same cycle code*; a line that changes the cycle code must repeat R
and Z (and P, Q, IJK where the cycle needs them). L is never sticky (default 1).
Under G91, X/Y are increments applied on every repeat, R is relative to the initial level
and Z relative to R; G87's K is then relative to the bottom.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import NamedTuple, NoReturn

from ..read.lexer import blank_comments, locate_word
from ...errors import GcodeError

__all__ = ['CycleSpec', 'CycleMemory', 'CycleResult', 'Primitive', 'CYCLE_CODES',
           'PECK_BACKOFF_M', 'expand_cycle', 'word_failer']

Vec3 = tuple[float, float, float]
Primitive = tuple
"""``('rapid', xyz)``, ``('feed', xyz)``, ``('dwell', seconds)`` or ``('stop',)``."""
Fail = Callable[[str, str], NoReturn]

CYCLE_CODES = frozenset({73, 81, 82, 83, 84, 85, 86, 87, 88, 89})
# LinuxCNC's G83_RAPID_DELTA (interp_internal.hh): 0.010 inch, scaled by 25.4 under G21.
PECK_BACKOFF_M = 0.010 * 0.0254
# A peck depth within this of the bottom counts as the bottom (LinuxCNC compares its
# running depth exactly, in program units; metres round differently).
_DEPTH_EPS_M = 1e-12
# Plane -> (first in-plane axis, second in-plane axis, drilling axis).
_PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}
_AXIS_LETTERS = 'XYZ'
_CENTRE_LETTERS = 'IJK'
_DWELL_CYCLES = frozenset({82, 86, 88, 89})
_PECK_CYCLES = frozenset({73, 83})
_SPINDLE_CYCLES = frozenset({84, 86, 87, 88})


class CycleSpec(NamedTuple):
    """One canned-cycle line as the interpreter hands it over.

    Attributes
    ----------
    code
        73 or 81..89.
    plane
        17, 18 or 19.
    position
        Tool position before the line [m], machine coordinates.
    words
        The line's words: ``X Y Z R I J K Q`` in metres as written (program frame, absolute
        under G90, increments under G91), ``P`` in seconds (the interpreter converts a
        dialect's milliseconds), ``L`` as read. Only words present on the line.
    offset
        ``machine - program`` per axis [m] (work offset, G92, G52, tool length offset).
    incremental
        True under G91.
    retract
        98 (to the initial level) or 99 (to R; LinuxCNC's start-up mode).
    feed_m_s
        The current feed [m/s]; zero or ``None`` is an error as in LinuxCNC.
    inverse_time
        True under G93 (an error with canned cycles).
    cutter_comp
        True while G41/G42 is active (an error with canned cycles).
    spindle
        1 turning clockwise, -1 counter-clockwise, 0 stopped, ``None`` unknown (no check).
    polar
        LinuxCNC's polar increments under G91 in G17, ``(@ [m], ^ [rad])``: each repeat
        moves the hole by them in polar coordinates about the program origin (instead of
        X/Y increments).
    """

    code: int
    plane: int
    position: Vec3
    words: Mapping[str, float]
    offset: Vec3 = (0.0, 0.0, 0.0)
    incremental: bool = False
    retract: int = 99
    feed_m_s: float | None = None
    inverse_time: bool = False
    cutter_comp: bool = False
    spindle: int | None = None
    polar: tuple[float, float] | None = None


@dataclass(frozen=True)
class CycleMemory:
    """What LinuxCNC keeps between cycle lines (its ``cycle_*`` settings).

    The interpreter keeps one, starting with ``CycleMemory()``, stores the ``memory`` of
    every :class:`CycleResult`, and calls :meth:`end_series` whenever it executes a motion
    that is not a canned cycle (G0..G3, G80, ...).

    Attributes
    ----------
    code
        The cycle of the previous motion, ``None`` after any other motion.
    level
        Initial level of the current series of cycles [m, program frame, along the
        drilling axis of the plane in force then], ``None`` outside a series.
    r, depth, p, q, i, j, k
        The last R, depth (Z in G17), P, Q, I, J, K words, raw as written.
    """

    code: int | None = None
    level: float | None = None
    r: float = 0.0
    depth: float = 0.0
    p: float = 0.0
    q: float = 0.0
    i: float = 0.0
    j: float = 0.0
    k: float = 0.0

    def end_series(self) -> CycleMemory:
        """The memory after a motion that is not a cycle (R, Z and level are forgotten)."""
        return replace(self, code=None, level=None)


class CycleResult(NamedTuple):
    """The expansion of one cycle line.

    Attributes
    ----------
    primitives
        The moves in order, endpoints in machine coordinates [m].
    end
        Tool position after the line [m], machine coordinates.
    memory
        The memory to keep for the next line.
    """

    primitives: list[Primitive]
    end: Vec3
    memory: CycleMemory


def word_failer(file: str, line: int, text: str) -> Fail:
    """A ``fail(message, letter)`` that raises :class:`GcodeError` at the letter's word.

    Parameters
    ----------
    file, line
        The place of the cycle line.
    text
        The raw source line, to find the word's column.
    """
    def fail(message: str, letter: str) -> NoReturn:
        code = blank_comments(text, file=file, line=line)
        column, word = locate_word(code, letter)
        raise GcodeError(message, file=file, line=line, column=column, text=word[:60])
    return fail


def _check(spec: CycleSpec, memory: CycleMemory, fail: Fail) -> tuple[int, bool]:
    """Validate the line as LinuxCNC does; return (repeats L, same cycle as before)."""
    g = f'G{spec.code}'
    if spec.code not in CYCLE_CODES:
        fail(f'{g} is not a canned cycle', 'G')
    if spec.plane not in _PLANE_AXES:
        fail(f'canned cycles need plane G17, G18 or G19, not G{spec.plane}', 'G')
    if not spec.feed_m_s:
        fail('Cannot feed with zero feed rate (give F before the canned cycle)', 'G')
    if spec.inverse_time:
        fail('Cannot use inverse time feed with canned cycles (G93 is active)', 'G')
    if spec.cutter_comp:
        fail('Cannot use canned cycles with cutter compensation on (G40 first)', 'G')
    w = spec.words
    for letter, value in w.items():
        if not math.isfinite(value):
            fail(f'{letter} word is not a finite number', letter)
    same = memory.code == spec.code
    depth_letter = _AXIS_LETTERS[_PLANE_AXES[spec.plane][2]]
    if not same:
        if 'R' not in w:
            fail(f'R clearance plane unspecified in cycle: {g} starts a new cycle and '
                 'needs R', 'G')
        if depth_letter not in w:
            fail(f'{depth_letter} value unspecified in G{spec.plane} plane canned cycle: '
                 f'{g} starts a new cycle and needs {depth_letter}', 'G')
        if spec.code in _DWELL_CYCLES and 'P' not in w:
            fail(f'Dwell time P word missing with {g}', 'G')
        if spec.code in _PECK_CYCLES and 'Q' not in w:
            fail(f'Q word missing with {g}', 'G')
        if spec.code == 87:
            for letter in 'IJK':
                if letter not in w:
                    fail(f'{letter} word missing with G87', 'G')
    if 'P' in w and w['P'] < 0.0:
        fail('Negative P word used', 'P')
    repeats = 1
    if 'L' in w:
        lval = w['L']
        if lval != int(lval):
            fail('L (repeats) must be a whole number', 'L')
        if lval < 0:
            fail('Negative L word used', 'L')
        if lval == 0:
            fail('Cannot do zero repeats of cycle (L0)', 'L')
        repeats = int(lval)
    if spec.code in _SPINDLE_CYCLES and spec.spindle is not None:
        if spec.spindle == 0:
            fail(f'Spindle not turning in {g}', 'G')
        if spec.code == 84 and spec.spindle < 0:
            fail('Spindle turning counterclockwise in G84', 'G')
    return repeats, same


def expand_cycle(spec: CycleSpec, memory: CycleMemory | None = None, *,
                 fail: Fail | None = None, max_primitives: int = 1_000_000) -> CycleResult:
    """Expand one canned-cycle line into primitives (LinuxCNC 2.9 semantics).

    Parameters
    ----------
    spec
        The line and the modal state it runs in.
    memory
        What the previous cycle lines left (``None``: a fresh ``CycleMemory()``).
    fail
        ``fail(message, letter)`` raising the caller's error at the word ``letter`` (the
        interpreter's own); default: a :class:`GcodeError` without a place.
    max_primitives
        Refuse a line that would expand into more primitives (tiny Q with a deep hole, or
        a huge L): memory stays bounded.

    Returns
    -------
    CycleResult
        Primitives, end position and the memory for the next line.

    Raises
    ------
    GcodeError
        Through ``fail``: the errors LinuxCNC reports (R below the bottom, missing R/Z/P/Q/
        IJK, Q <= 0, negative P, L not a positive integer, zero feed, G93, cutter
        compensation on, spindle state).
    """
    if memory is None:
        memory = CycleMemory()
    if fail is None:
        fail = word_failer('<cycle>', 0, '')
    repeats, same = _check(spec, memory, fail)
    a, b, n = _PLANE_AXES[spec.plane]
    w = spec.words
    off = spec.offset
    cur = [spec.position[i] - off[i] for i in range(3)]      # program frame
    la, lb, ln = (_AXIS_LETTERS[i] for i in (a, b, n))
    depth_word = w.get(ln, memory.depth)
    r_word = w.get('R', memory.r)
    level = cur[n] if memory.level is None else memory.level
    old = level
    if spec.incremental:
        inc_a = w.get(la, 0.0)
        inc_b = w.get(lb, 0.0)
        r = r_word + old
        bottom = r + depth_word
        pa, pb = cur[a], cur[b]
    else:
        inc_a = inc_b = 0.0
        r = r_word
        bottom = depth_word
        pa = w.get(la, cur[a])
        pb = w.get(lb, cur[b])
    if r < bottom:
        fail(f'R less than {ln} in cycle in G{spec.plane} plane: R level '
             f'{r * 1e3:.4f} mm is below the bottom {bottom * 1e3:.4f} mm', 'R')
    p = w.get('P', memory.p if same or spec.code == 84 else 0.0)
    q = w.get('Q', memory.q)
    cl = _CENTRE_LETTERS
    ci, cj, ck = (w.get(cl[i], (memory.i, memory.j, memory.k)[i]) for i in range(3))
    if spec.code in _PECK_CYCLES:
        if q <= 0.0:
            fail('Negative or zero Q value used', 'Q')
        moves = ((r - bottom) / q + 2.0) * repeats * 3.0
        if not moves <= max_primitives:
            fail(f'the cycle would make about {moves:.3g} moves (more than '
                 f'{max_primitives}): Q is too small for the depth', 'Q')
    if repeats * 10 > max_primitives:
        fail(f'L{repeats}: too many repeats (limit {max_primitives // 10})', 'L')

    out: list[Primitive] = []
    current = cur[n]

    def point(pa_: float, pb_: float, pn_: float) -> Vec3:
        v = [0.0, 0.0, 0.0]
        v[a] = pa_ + off[a]
        v[b] = pb_ + off[b]
        v[n] = pn_ + off[n]
        return (v[0], v[1], v[2])

    if old < r:
        out.append(('rapid', point(cur[a], cur[b], r)))
        old = r
        current = r
    clear = r if spec.retract == 99 else old
    polar = spec.polar if spec.incremental else None
    if polar is not None and spec.plane != 17:
        fail('polar coordinates (@, ^) in a canned cycle need plane G17', 'G')
    for rep in range(repeats):
        if polar is None:
            pa += inc_a
            pb += inc_b
        else:
            radius = math.hypot(pa, pb) + polar[0]
            theta = math.atan2(pb, pa) + polar[1]
            pa = radius * math.cos(theta)
            pb = radius * math.sin(theta)
        if rep == 0 and current > r:
            out.append(('rapid', point(pa, pb, current)))
            out.append(('rapid', point(pa, pb, r)))
        else:
            out.append(('rapid', point(pa, pb, clear)))
            if clear > r:
                out.append(('rapid', point(pa, pb, r)))
        _cycle_body(out, spec.code, point, pa, pb, r=r, clear=clear, bottom=bottom,
                    p=p, q=q, centre=(ci, cj, ck), axes=(a, b, n),
                    incremental=spec.incremental)
    end = point(pa, pb, clear)
    new = CycleMemory(code=spec.code, level=level, r=r_word, depth=depth_word,
                      p=p if (spec.code in _DWELL_CYCLES or spec.code == 84) else memory.p,
                      q=q if spec.code in _PECK_CYCLES else memory.q,
                      i=ci if spec.code == 87 else memory.i,
                      j=cj if spec.code == 87 else memory.j,
                      k=ck if spec.code == 87 else memory.k)
    return CycleResult(out, end, new)


def _cycle_body(out: list[Primitive], code: int, point: Callable[[float, float, float], Vec3],
                pa: float, pb: float, *, r: float, clear: float, bottom: float, p: float,
                q: float, centre: tuple[float, float, float], axes: tuple[int, int, int],
                incremental: bool) -> None:
    """Append the moves of one repeat of cycle ``code`` at the hole (pa, pb)."""
    def feed(level: float) -> None:
        out.append(('feed', point(pa, pb, level)))

    def rapid(level: float) -> None:
        out.append(('rapid', point(pa, pb, level)))

    if code in _PECK_CYCLES:
        depth = r - q
        while depth > bottom + _DEPTH_EPS_M:
            feed(depth)
            if code == 83:
                rapid(r)
            rapid(depth + PECK_BACKOFF_M)
            depth -= q
        feed(bottom)
        rapid(clear)
    elif code in (81, 82, 86):
        feed(bottom)
        if code != 81:
            out.append(('dwell', p))
        rapid(clear)
    elif code == 84:
        feed(bottom)
        out.append(('dwell', p))
        feed(clear)
    elif code == 85:
        feed(bottom)
        feed(r)
        rapid(clear)
    elif code == 88:
        feed(bottom)
        out.append(('dwell', p))
        out.append(('stop',))
        rapid(clear)
    elif code == 89:
        feed(bottom)
        out.append(('dwell', p))
        feed(clear)
    else:  # 87: back boring
        a, b, n = axes
        oa = pa + centre[a]
        ob = pb + centre[b]
        middle = bottom + centre[n] if incremental else centre[n]
        out.append(('rapid', point(oa, ob, r)))
        out.append(('rapid', point(oa, ob, bottom)))
        rapid(bottom)
        feed(middle)
        feed(bottom)
        out.append(('rapid', point(oa, ob, bottom)))
        out.append(('rapid', point(oa, ob, clear)))
        rapid(clear)
