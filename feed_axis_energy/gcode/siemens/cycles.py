"""Siemens standard cycles that move the feed axes in a way known from their parameters.

Drilling (at the current position in the working plane, along the plane normal; values in
the program's coordinates, the frame in force applies):

* ``CYCLE81(RTP, RFP, SDIS, DP, DPR)``: ``G0`` to the reference plane plus the safety
  distance (``RFP + SDIS``), ``G1`` to the final depth, ``G0`` to the retraction plane
  ``RTP``. The depth is ``RFP - DPR`` when ``DPR`` is given (not 0), else ``DP`` (absolute).
* ``CYCLE82(RTP, RFP, SDIS, DP, DPR, DTB)``: as CYCLE81 with a dwell of ``DTB`` seconds at
  the depth.
* ``CYCLE83(RTP, RFP, SDIS, DP, DPR, FDEP, FDPR, DAM, DTB, DTS, FRF, VARI)``: deep-hole
  drilling in steps. The first step ends at ``FDEP`` (or ``RFP - FDPR``), each further step
  is the one before less ``DAM`` but not less than ``DAM`` (``DAM = 0``: equal steps), the
  last one ends at the depth. The first step runs at ``FRF`` times the feed (``FRF = 0``: 1).
  ``VARI = 0`` (chip breaking): after each step the drill backs off 1 mm at the feed
  (G1) and goes on. ``VARI = 1`` (chip removal): after each step ``G0`` to
  ``RFP + SDIS``, a dwell of ``DTS`` seconds, ``G0`` back to the step's end less the
  anticipation distance (0.6 mm up to 30 mm of depth, else depth / 50, at most 7 mm, as
  the manual's cycle computes it), then feed on. ``DTB`` seconds of dwell at the end of
  every step; ``G0`` to ``RTP`` at the end.
* ``CYCLE85(RTP, RFP, SDIS, DP, DPR, DTB, FFR, RFF)``: boring: in at ``FFR``, a dwell of
  ``DTB`` s, out to ``RFP + SDIS`` at ``RFF``, ``G0`` to ``RTP``.
* ``CYCLE89(RTP, RFP, SDIS, DP, DPR, DTB)``: boring: in and out at the feed, with a dwell.

A dwell given negative is in spindle revolutions (converted with the spindle speed).

Patterns (``HOLES1(SPCA, SPCO, STA1, FDIS, DBH, NUM)``: a row of holes from the reference
point at angle ``STA1``, the first at distance ``FDIS``, then every ``DBH``;
``HOLES2(CPA, CPO, RAD, STA1, INDA, NUM)``: holes on a circle, from angle ``STA1`` in steps
of ``INDA`` (0: the full circle divided by ``NUM``)): the tool goes to each position in
rapid at its current height and the modal cycle (``MCALL``) runs there.

Everything else a cycle name stands for is refused by the reader with the name and place
(pockets, slots, thread and tapping cycles, ``CYCLE800`` swivelling, ...).
"""
from __future__ import annotations

import math
from typing import Any, Callable, cast

from .frames import plane_axes, Vec3
from .geometry import Geometry, Words
from .text import Scanner

__all__ = ['DRILLING', 'PATTERNS', 'drill', 'pattern_points']

DRILLING = {'CYCLE81': 5, 'CYCLE82': 6, 'CYCLE83': 12, 'CYCLE85': 8, 'CYCLE89': 6}
"""Drilling cycles simulated -> the number of their parameters used (later ones must be
empty or 0: the extended forms of the 840D sl with depth and display modes are refused)."""
PATTERNS = {'HOLES1': 6, 'HOLES2': 6}
"""Hole patterns -> number of parameters."""

CHIP_BREAK_MM = 1.0
"""How far the drill backs off after each step of CYCLE83 with VARI = 0 [mm]."""


_NAMES = {
    'CYCLE81': ('RTP', 'RFP', 'SDIS', 'DP', 'DPR'),
    'CYCLE82': ('RTP', 'RFP', 'SDIS', 'DP', 'DPR', 'DTB'),
    'CYCLE83': ('RTP', 'RFP', 'SDIS', 'DP', 'DPR', 'FDEP', 'FDPR', 'DAM', 'DTB', 'DTS', 'FRF',
                'VARI'),
    'CYCLE85': ('RTP', 'RFP', 'SDIS', 'DP', 'DPR', 'DTB', 'FFR', 'RFF'),
    'CYCLE89': ('RTP', 'RFP', 'SDIS', 'DP', 'DPR', 'DTB'),
}


def _args(values: list[Any], n: int) -> list[float]:
    return [0.0 if i >= len(values) or values[i] is None else float(values[i])
            for i in range(n)]


def _dwell(g: Geometry, t: float, s: Scanner) -> list[Words]:
    if t == 0:
        return []
    if t < 0:
        if g.rpm <= 0:
            s.fail('dwell in spindle revolutions with no spindle speed set')
        t = -t * 60.0 / g.rpm
    return [g.dwell_words(t)]


def drill(name: str, values: list[Any], g: Geometry, s: Scanner) -> list[Words]:
    """The blocks of drilling cycle ``name`` at the current position (see the module)."""
    used = DRILLING[name]
    for k, v in enumerate(values):
        if isinstance(v, str) or (k >= used and v not in (None, 0.0)):
            s.fail(f'{name}: parameter {k + 1} ({v!r}) is not simulated (only the first '
                   f'{used}: {", ".join(_NAMES[name])}; the extended 840D sl forms with '
                   'depth and display modes are refused)')
    p = _args(values, used)
    rtp, rfp, sdis, dp, dpr = p[:5]
    depth = rfp - dpr if dpr != 0 else dp
    start = rfp + sdis
    if depth >= start:
        s.fail(f'{name}: the final depth ({depth:g}) is not below the reference plane plus '
               f'the safety distance ({start:g})')
    if rtp < start:
        s.fail(f'{name}: the retraction plane RTP={rtp:g} is below the reference plane plus '
               f'the safety distance ({start:g})')
    u = g.unit
    _, _, n = plane_axes(g.plane)
    here = list(g.program_position())

    def at(level: float) -> Vec3:
        q = list(here)
        q[n] = level * u
        return (q[0], q[1], q[2])

    out: list[Words] = [g.move_words(0, at(start))]
    if name in ('CYCLE81', 'CYCLE82', 'CYCLE89'):
        out.append(g.move_words(1, at(depth)))
        if name != 'CYCLE81':
            out += _dwell(g, p[5], s)
        if name == 'CYCLE89':
            out.append(g.move_words(1, at(start)))
    elif name == 'CYCLE85':
        dtb, ffr, rff = p[5], p[6], p[7]
        if ffr <= 0 or rff <= 0:
            s.fail('CYCLE85 needs the feeds FFR and RFF (> 0)')
        feed = g.feed
        out.append(g.feed_words(ffr * (25.4 if g.feed_inch else 1.0)))
        out.append(g.move_words(1, at(depth)))
        out += _dwell(g, dtb, s)
        out.append(g.feed_words(rff * (25.4 if g.feed_inch else 1.0)))
        out.append(g.move_words(1, at(start)))
        if feed is not None:
            out.append(g.feed_words(feed))
    else:
        out += _deep_hole(p, start, depth, g, s, at)
    out.append(g.move_words(0, at(rtp)))
    return out


def _deep_hole(p: list[float], start: float, depth: float, g: Geometry, s: Scanner,
               at: Callable[[float], Vec3]) -> list[Words]:
    rfp = p[1]
    fdep, fdpr, dam, dtb, dts, frf, vari = p[5:12]
    first = rfp - fdpr if fdpr != 0 else fdep
    if first >= start:
        s.fail(f'CYCLE83: the first drilling depth ({first:g}) is not below the reference '
               f'plane plus the safety distance ({start:g})')
    if vari not in (0, 1):
        s.fail(f'CYCLE83: VARI={vari:g} (0: chip breaking, 1: chip removal)')
    if dam < 0:
        s.fail(f'CYCLE83: DAM={dam:g} (a degression in mm, >= 0)')
    levels = [max(first, depth)]
    step = start - levels[0]
    while levels[-1] > depth:
        if len(levels) > 100_000:
            s.fail('CYCLE83: more than 100000 steps')
        if dam > 0:
            step = max(step - dam, dam)
        levels.append(max(levels[-1] - step, depth))
    total_mm = (start - depth) * g.unit
    anticipation = (0.6 if total_mm <= 30 else min(total_mm / 50.0, 7.0)) / g.unit
    feed = g.feed
    out: list[Words] = []
    for k, level in enumerate(levels):
        slow = k == 0 and frf not in (0, 1) and feed is not None
        if slow:
            out.append(g.feed_words(cast(float, feed) * frf))
        out.append(g.move_words(1, at(level)))
        if slow:
            out.append(g.feed_words(cast(float, feed)))
        out += _dwell(g, dtb, s)
        if k == len(levels) - 1:
            break
        if vari == 0:
            out.append(g.move_words(1, at(level + CHIP_BREAK_MM / g.unit)))
        else:
            out.append(g.move_words(0, at(start)))
            out += _dwell(g, dts, s)
            out.append(g.move_words(0, at(min(level + anticipation, start))))
    return out


def pattern_points(name: str, values: list[Any], g: Geometry,
                   s: Scanner) -> list[tuple[float, float]]:
    """The hole positions (plane coordinates of the program, mm) of ``HOLES1``/``HOLES2``."""
    for k, v in enumerate(values):
        if isinstance(v, str) or (k >= PATTERNS[name] and v not in (None, 0.0)):
            s.fail(f'{name}: parameter {k + 1} ({v!r}) is not simulated')
    p = _args(values, PATTERNS[name])
    num = p[5]
    if num != int(num) or num < 1 or num > 100_000:
        s.fail(f'{name}: NUM={num:g} must be a whole number of holes, 1 to 100000')
    u = g.unit
    pts = []
    if name == 'HOLES1':
        spca, spco, sta1, fdis, dbh = p[:5]
        c, d = math.cos(math.radians(sta1)), math.sin(math.radians(sta1))
        for i in range(int(num)):
            r = (fdis + i * dbh) * u
            pts.append((spca * u + r * c, spco * u + r * d))
    else:
        cpa, cpo, rad, sta1, inda = p[:5]
        if rad <= 0:
            s.fail(f'HOLES2: RAD={rad:g} must be > 0')
        step = inda if inda != 0 else 360.0 / num
        for i in range(int(num)):
            ang = math.radians(sta1 + i * step)
            pts.append((cpa * u + rad * u * math.cos(ang), cpo * u + rad * u * math.sin(ang)))
    return pts
