"""Models of the reference run's own quirks, to tell them from our mistakes.

``shared/corpus/gcode/oracle.json`` comes from LinuxCNC 2.9's interpreter driven through its
preview module (the Python ``gcode`` module that AXIS uses) by ``shared/tools/run_oracle.py``.
Three behaviours of that set-up are not what a machine does, and a program that meets them
disagrees with us for a reason that is not ours:

``stale-after-arc``
    The preview module's canon keeps the current position for the interpreter to re-read,
    but updates it on straight moves only (``ARC_FEED`` in ``gcodemodule.cc`` carries the
    comment ``XXX: set _pos_*``). After a tool change (M6) the interpreter re-reads that
    position, so when an arc was the last move before M6 the next move starts from the end
    of the last straight move instead of the arc's end. Model: at M6 our interpreter's
    position becomes the end of the last straight move; the harness still measures the next
    move from the arc's end (its own record follows arcs).
``no-tool-length``
    ``run_oracle.py`` turns the canon's positions into machine coordinates with the G5x and
    G92 offsets only ("tool length offsets are zero by construction", its docstring), which
    holds for its tool table of zero lengths but not for ``G43.1``/``G43.2`` offsets given in
    the program. Model: every move's end point is shifted by minus the tool length offset in
    force when the move is issued (each move starts where the previous shifted one ended).
``rotary-feed-in-inches``
    The preview module hands the canon feed rates in inches per minute (it converts a G21
    program's F from mm/min), and ``run_oracle.py`` divides a pure rotary move's degrees by
    that number: in a G21 program its nominal time of such a move is 25.4 times what F
    degrees per minute gives (LinuxCNC runs it at F degrees per minute). Model: our pure
    rotary feed moves in G21 run at F / 25.4 degrees per minute.
``first-units``
    ``run_oracle.py`` starts the interpreter in the units of the program's first G20/G21,
    so an F given before that code is read in those units (we start in G21, as LinuxCNC's
    default configuration does). Model: at the first G20/G21 the feed in force is
    re-read in the new units.

:func:`explain` re-runs a disagreeing program with each model (alone, then both) and returns
the models under which every figure agrees with the reference. A disagreement no model
reproduces stays unexplained. The models patch our interpreter only inside
:func:`quirks`; nothing here changes what ``feed-axis-energy`` does.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
import dataclasses
from itertools import combinations
from typing import Any

from feed_axis_energy.gcode.interp.interpreter import Interpreter
from feed_axis_energy.gcode.program import Move, MoveKind

__all__ = ['QUIRKS', 'quirks', 'explain']

QUIRKS = {
    'stale-after-arc': 'the reference re-reads at M6 the end of the last straight move, not '
                       "of a later arc (gcodemodule.cc ARC_FEED: 'XXX: set _pos_*')",
    'no-tool-length': 'run_oracle.py leaves G43.1/G43.2 tool length offsets out of its '
                      'machine positions',
    'rotary-feed-in-inches': 'run_oracle.py times a pure rotary move of a G21 program with '
                             'the F the preview converted to inch/min (25.4 times too long)',
    'first-units': 'run_oracle.py starts in the units of the program\'s first G20/G21, so an '
                   'earlier F is read in those units',
}

_STRAIGHT = (MoveKind.RAPID, MoveKind.LINEAR)
_MOTION = (MoveKind.RAPID, MoveKind.LINEAR, MoveKind.ARC_CW, MoveKind.ARC_CCW)


def _shift(p: tuple[float, float, float] | None,
           d: tuple[float, float, float]) -> tuple[float, float, float] | None:
    return None if p is None else (p[0] - d[0], p[1] - d[1], p[2] - d[2])


@contextmanager
def quirks(names: tuple[str, ...]) -> Iterator[None]:
    """Patch our interpreter with the named reference quirks while the block runs."""
    unknown = set(names) - set(QUIRKS)
    if unknown:
        raise ValueError(f'unknown quirk(s): {", ".join(sorted(unknown))}')
    saved: dict[str, Callable[..., Any]] = {}
    if 'stale-after-arc' in names:
        saved['before_motion'] = Interpreter.before_motion

        def before_motion(self: Interpreter, d: dict[str, str]) -> None:
            if self.tool_change and self.io_lineno != self.lineno:     # M6, not M61
                for m in reversed(self.moves):
                    if m.kind in _STRAIGHT:
                        self.pos = m.end
                        break
            saved['before_motion'](self, d)
        Interpreter.before_motion = before_motion
    if 'rotary-feed-in-inches' in names:
        saved['rotary_move'] = Interpreter.rotary_move

        def rotary_move(self: Interpreter, m: Move) -> Move:
            out = saved['rotary_move'](self, m)
            if (out.rot_end is not None and out.kind == MoveKind.LINEAR
                    and out.start == out.end and self.scale == 0.001
                    and not self.inverse_time):
                out = dataclasses.replace(out, feed_m_s=out.feed_m_s / 25.4)
            return out
        Interpreter.rotary_move = rotary_move
    if 'first-units' in names:
        saved['g_words'] = Interpreter.g_words
        seen_units: set[int] = set()

        def g_words(self: Interpreter, gl: Any) -> Any:
            before = self.scale
            out = saved['g_words'](self, gl)
            if id(self) not in seen_units and any(str(g) in ('20', '21') for g in gl):
                seen_units.add(id(self))
                if self.scale != before and self.feed is not None and not self.inverse_time:
                    self.feed = self.feed / before * self.scale
            return out
        Interpreter.g_words = g_words
    # The harness measures every move from where its previous move ended (its own record,
    # which follows arcs): chain our moves the same way, shifted by the tool length offset
    # under 'no-tool-length'. Without a quirk this changes nothing (our moves are chained).
    shift_tlo = 'no-tool-length' in names
    last_end: dict[int, tuple[float, float, float]] = {}   # id(interpreter) -> harness end

    def chained(method: Callable[..., Any]) -> Callable[..., Any]:
        def run_line(self: Interpreter, *args: Any) -> Any:
            n = len(self.moves)
            result = method(self, *args)
            tlo = self.coords.tlo if shift_tlo else (0.0, 0.0, 0.0)
            moves = self.moves
            prev = last_end.get(id(self))
            for i in range(n, len(moves)):
                m: Move = moves[i]
                if m.kind not in _MOTION:
                    continue
                start = prev if prev is not None else _shift(m.start, tlo)
                end = _shift(m.end, tlo)
                moves[i] = dataclasses.replace(m, start=start, end=end,
                                               center=_shift(m.center, tlo))
                prev = end
            if prev is not None:
                last_end[id(self)] = prev
            return result
        return run_line
    # Both ways a line is run: the word-list path and the fast lane for plain motion lines.
    for attr in ('line', 'contour_line'):
        if hasattr(Interpreter, attr):
            saved[attr] = getattr(Interpreter, attr)
            setattr(Interpreter, attr, chained(saved[attr]))
    try:
        yield
    finally:
        for attr, fn in saved.items():
            setattr(Interpreter, attr, fn)


def explain(run: Callable[[], Any], agrees: Callable[[Any], bool]) -> tuple[str, ...] | None:
    """The smallest set of quirks under which a program agrees with the reference.

    Parameters
    ----------
    run
        Parses the program and returns our result (called once per combination, inside
        :func:`quirks`).
    agrees
        True when a result agrees with the reference in every figure.

    Returns
    -------
    tuple of str or None
        The quirk names (the smallest set that agrees), or ``None`` when no model
        reproduces the reference.
    """
    for k in range(1, len(QUIRKS) + 1):
        for names in combinations(QUIRKS, k):
            with quirks(names):
                result = run()
            if agrees(result):
                return names
    return None
