"""Problems of an NC program on a machine: the parser's errors and warnings, plus sanity checks.

``check`` runs the parser so that an error in a line is kept and parsing goes on with the
next line (at most :data:`MAX_ERRORS` errors; an error in an O-word, macro or subprogram
line, or in the program's structure, such as an O-word without its end, still stops it);
:func:`problem_from_error` turns each error into a :class:`Problem` with file, line, column
and the offending text. The sanity checks run over
the parsed moves in one streaming pass (:class:`MoveChecker`) and give warnings, each naming
the first line concerned:

* ``travel``: the tool goes beyond an axis's travel (``axes.<A>.travel_m`` of the machine
  config, machine coordinates; arcs by their exact extremes); one warning per axis and side,
  with the number of moves and the farthest position;
* ``feed``: a programmed feed whose component along an axis exceeds that axis's velocity
  limit (``axes.<A>.limits.velocity_m_s``; the planner slows the move down, so the program
  runs longer than written); one warning per axis, with the number of moves and the largest
  component;
* ``dwell``: a dwell longer than ``max_dwell_s`` (default :data:`DEFAULT_MAX_DWELL_S`, one
  hour: a ``G4 P4000`` written for a control that reads milliseconds is 4000 s here), each
  listed;
* ``no-motion``: a program that never moves the tool.

The checks are pure; :func:`program_problems` reads a program file (streamed) and checks it
on a machine, :func:`sanity_checker` and :func:`checked_warning_texts` serve ``simulate``.
The command ``feed-axis-energy check`` (``cli/check.py``) is the shell.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import chain
import math
from operator import attrgetter
from pathlib import Path
import re
from typing import Any, Callable, cast, Iterable, Mapping, Sequence

import numpy as np

from ..errors import GcodeError, shorten
from .load import iter_moves
from .stats import arc_extremes, arc_geometry, MoveStats, ProgramStats
from .program import Move, MoveKind, PROGRAM_AXES

# looked up once: an enum member read from its class per move costs more than the check
_RAPID = MoveKind.RAPID
_LINEAR = MoveKind.LINEAR
_START = attrgetter('start')
_END = attrgetter('end')

__all__ = ['Problem', 'CheckLimits', 'MoveChecker', 'check_moves', 'problem_from_error',
           'problems_from_warnings', 'DEFAULT_MAX_DWELL_S', 'MAX_LISTED_DWELLS', 'MAX_ERRORS',
           'check_limits', 'program_problems', 'warning_texts', 'sanity_checker',
           'checked_warning_texts']

MAX_ERRORS = 100
"""Errors listed per program at most: checking goes on after each line with an error, and
the 100th ends it."""
DEFAULT_MAX_DWELL_S = 3600.0
"""Dwells longer than this [s] are reported (``--max-dwell-s``)."""
MAX_LISTED_DWELLS = 100
"""Long dwells listed one by one; more are summed up in one further warning."""
_FEED_MARGIN = 1.0 + 1e-9     # a feed equal to the limit is not above it
_TRAVEL_MARGIN_M = 1e-9
_MIN_ARRAY_RUN = 16           # shorter runs of straight moves are checked one by one


@dataclass(frozen=True)
class Problem:
    """One error or warning about a program.

    Attributes
    ----------
    severity
        ``'error'`` (the program cannot be simulated) or ``'warning'``.
    kind
        ``'parse'`` for the parser's own messages, else ``'travel'``, ``'feed'``,
        ``'dwell'`` or ``'no-motion'``.
    file, line, column
        The place (line 0: the whole file; column 0: the whole line).
    message
        What is wrong.
    text
        The offending text (cut to about 60 characters), or ``''``.
    """

    severity: str
    kind: str
    file: str
    line: int
    column: int
    message: str
    text: str = ''

    def __str__(self) -> str:
        near = f' near {self.text!r}' if self.text else ''
        return f'{self.file}:{self.line}:{self.column}: {self.severity}: {self.message}{near}'

    def as_dict(self) -> dict[str, object]:
        """The problem as a JSON-ready mapping."""
        return dict(severity=self.severity, kind=self.kind, file=self.file, line=self.line,
                    column=self.column, message=self.message, text=self.text)


@dataclass(frozen=True)
class CheckLimits:
    """What the sanity checks compare against.

    Attributes
    ----------
    travel_m
        ``{axis: (min, max)}`` [m], machine coordinates; axes without an entry are not
        checked.
    velocity_m_s
        ``{axis: limit}`` [m/s]; axes without an entry are not checked.
    max_dwell_s
        Dwells longer than this [s] are reported.
    """

    travel_m: Mapping[str, tuple[float, float]]
    velocity_m_s: Mapping[str, float]
    max_dwell_s: float = DEFAULT_MAX_DWELL_S


def problem_from_error(err: GcodeError) -> Problem:
    """The parser's error as a :class:`Problem` (file, line, column and offending text)."""
    return Problem('error', 'parse', err.file, err.line, err.column,
                   getattr(err, 'reason', str(err)), shorten(getattr(err, 'text', '')))


_WARNING_RE = re.compile(r'(?s)(?P<file>.*?):(?P<line>\d+)(?::(?P<col>\d+))?: (?P<msg>.*)')


def problems_from_warnings(warnings: Iterable[str], *, file: str) -> list[Problem]:
    """The parser's warnings (``file:line[:column]: message``) as problems."""
    out = []
    for w in warnings:
        m = _WARNING_RE.fullmatch(w)
        if m:
            out.append(Problem('warning', 'parse', m['file'], int(m['line']),
                               int(m['col'] or 0), m['msg']))
        else:
            out.append(Problem('warning', 'parse', file, 0, 0, w))
    return out


class _Excess:
    """First line, count and extreme value of the moves beyond one limit."""

    __slots__ = ('line', 'count', 'worst')

    def __init__(self) -> None:
        self.line = 0
        self.count = 0
        self.worst = 0.0


class MoveChecker:
    """The sanity checks over a stream of moves (see the module docstring).

    Parameters
    ----------
    file
        Program file, named in the warnings.
    limits
        Travel, velocity and dwell limits.
    line_text
        Optional: returns the source text of a line (shown as the offending text).
    """

    def __init__(self, *, file: str, limits: CheckLimits,
                 line_text: Callable[[int], str] | None = None) -> None:
        self.file = file
        self.limits = limits
        self.line_text = line_text
        self.stats = MoveStats()
        self.travel: dict[tuple[str, str], _Excess] = {}
        self.feed: dict[str, _Excess] = {}
        self.dwells: list[Move] = []
        self.n_long_dwells = 0
        self.long_dwell_s = 0.0
        self._axes = [(i, name, limits.travel_m.get(name), limits.velocity_m_s.get(name))
                      for i, name in enumerate(PROGRAM_AXES)]
        inf = float('inf')
        travel = [t for _, _, t, _ in self._axes]
        speed = [v for _, _, _, v in self._axes]
        # the thresholds of _add_straight per axis, as add() computes them (none: inf)
        self._bounds = (
            np.array([-inf if t is None else t[0] - _TRAVEL_MARGIN_M for t in travel]),
            np.array([inf if t is None else t[1] + _TRAVEL_MARGIN_M for t in travel]),
            np.array([inf if v is None else v * _FEED_MARGIN for v in speed]))

    def add(self, move: Move) -> None:
        """Check one move."""
        self.stats.add(move)
        kind = move.kind
        if kind == MoveKind.DWELL:
            if move.dwell_s > self.limits.max_dwell_s:
                self.n_long_dwells += 1
                self.long_dwell_s += move.dwell_s
                if len(self.dwells) < MAX_LISTED_DWELLS:
                    self.dwells.append(move)
            return
        if kind == MoveKind.STOP:
            return
        points = [move.start, move.end]
        if kind in (MoveKind.ARC_CW, MoveKind.ARC_CCW):
            points += arc_extremes(move)
        for i, name, travel, vmax in self._axes:
            if travel is not None:
                lo = min(p[i] for p in points)
                hi = max(p[i] for p in points)
                if lo < travel[0] - _TRAVEL_MARGIN_M:
                    self._note(self.travel, (name, 'min'), move.line, lo, lower=True)
                if hi > travel[1] + _TRAVEL_MARGIN_M:
                    self._note(self.travel, (name, 'max'), move.line, hi, lower=False)
            if vmax is not None and kind != MoveKind.RAPID:
                v = _axis_speed(move, i)
                if v > vmax * _FEED_MARGIN:
                    self._note(self.feed, name, move.line, v, lower=False)

    def add_many(self, moves: Sequence[Move]) -> None:
        """Check a batch of moves: the same warnings as :meth:`add` on each in turn.

        Runs of straight moves (feeds and rapids) are checked with arrays (``simulate``
        feeds its moves this way: checked one by one they cost as much as parsing); arcs,
        dwells, stops and short runs go through :meth:`add`. Moves are taken in program
        order, so every warning names the same first line, count and extreme value as
        with :meth:`add`; the program statistics (:meth:`result`) are those of :meth:`add`
        except that the lengths of a run are computed with arrays (equal to the last bits).
        """
        run: list[Move] = []
        rapid, linear = _RAPID, _LINEAR
        for move in moves:
            kind = move.kind
            if kind == linear or kind == rapid:
                run.append(move)
                continue
            self._add_run(run)
            run = []
            self.add(move)
        self._add_run(run)

    def add_all(self, moves: Iterable[Move], *, batch: int = 4096) -> None:
        """Check the moves of any iterable (a stream) in batches of ``batch``
        (:meth:`add_many`). If the iterable raises (a parse error part-way), the moves it
        gave before are checked, then the error propagates."""
        taken: list[Move] = []
        try:
            for move in moves:
                taken.append(move)
                if len(taken) >= batch:
                    self.add_many(taken)
                    taken = []
        finally:
            self.add_many(taken)

    def _add_run(self, run: list[Move]) -> None:
        if len(run) < _MIN_ARRAY_RUN:
            for move in run:
                self.add(move)
        else:
            self._add_straight(run)

    def _add_straight(self, moves: Sequence[Move]) -> None:
        n = len(moves)
        # points flattened into fromiter: half the time of np.array on a list of tuples
        start = np.fromiter(chain.from_iterable(map(_START, moves)), float,
                            count=3 * n).reshape(n, 3)
        end = np.fromiter(chain.from_iterable(map(_END, moves)), float,
                          count=3 * n).reshape(n, 3)
        line = np.array([m.line for m in moves], dtype=np.int64)
        r = _RAPID
        rapid = np.array([m.kind == r for m in moves], dtype=bool)
        feed = np.array([m.feed_m_s for m in moves], dtype=float)
        self.stats.add_straight(moves, start, end, rapid)
        d = end - start
        length = np.sqrt(np.einsum('ij,ij->i', d, d))
        lo = np.minimum(start, end)
        hi = np.maximum(start, end)
        usable = ~rapid & np.isfinite(feed) & (feed > 0.0) & (length > 0.0)
        # all axes at once (no limit: +-inf); a note only for an axis with a hit
        below, above, fast = self._bounds
        lo_hit = lo < below
        hi_hit = hi > above
        with np.errstate(invalid='ignore', divide='ignore'):
            v = np.where(usable[:, None], feed[:, None] * np.abs(d) / length[:, None], 0.0)
        v_hit = v > fast
        lo_any, hi_any, v_any = (cast('list[bool]', h.any(axis=0).tolist())
                                 for h in (lo_hit, hi_hit, v_hit))
        for i, name, _travel, _vmax in self._axes:
            if lo_any[i]:
                self._note_many(self.travel, (name, 'min'), line, lo[:, i], lo_hit[:, i],
                                lower=True)
            if hi_any[i]:
                self._note_many(self.travel, (name, 'max'), line, hi[:, i], hi_hit[:, i],
                                lower=False)
            if v_any[i]:
                self._note_many(self.feed, name, line, v[:, i], v_hit[:, i], lower=False)

    @staticmethod
    def _note_many(table: dict, key: object, line: np.ndarray, value: np.ndarray,
                   hit: np.ndarray, *, lower: bool) -> None:
        """:meth:`_note` for every ``hit`` of a run, in order."""
        idx = np.nonzero(hit)[0]
        if idx.size == 0:
            return
        e = table.get(key)
        if e is None:
            e = table[key] = _Excess()
            e.line = int(line[idx[0]])
            e.worst = float(value[idx[0]])
        e.count += int(idx.size)
        worst = float(value[idx].min() if lower else value[idx].max())
        if (worst < e.worst) if lower else (worst > e.worst):
            e.worst = worst

    @staticmethod
    def _note(table: dict, key: object, line: int, value: float, *, lower: bool) -> None:
        e = table.get(key)
        if e is None:
            e = table[key] = _Excess()
            e.line = line
            e.worst = value
        e.count += 1
        if (value < e.worst) if lower else (value > e.worst):
            e.worst = value

    def _text(self, line: int) -> str:
        if self.line_text is None or line <= 0:
            return ''
        try:
            return shorten(self.line_text(line).strip())
        except (IndexError, KeyError):
            return ''

    def problems(self) -> list[Problem]:
        """The warnings found so far, in the order travel, feed, dwell, no motion."""
        out = []
        for (name, side), e in self.travel.items():
            lo, hi = self.limits.travel_m[name]
            bound = lo if side == 'min' else hi
            moves = 'move goes' if e.count == 1 else f'{e.count} moves go'
            msg = (f'{moves} beyond the {name} travel ({side} {bound * 1e3:.3f} mm): '
                   f'{name} reaches {e.worst * 1e3:.3f} mm (machine coordinates)')
            out.append(Problem('warning', 'travel', self.file, e.line, 0, msg,
                               self._text(e.line)))
        for name, e in self.feed.items():
            vmax = self.limits.velocity_m_s[name]
            moves = 'move asks' if e.count == 1 else f'{e.count} moves ask'
            msg = (f'{moves} for a feed above the {name} axis limit: {e.worst * 6e4:.1f} '
                   f'mm/min along {name} > {vmax * 6e4:.1f} mm/min (the planner slows '
                   f'down: the program runs longer than written)')
            out.append(Problem('warning', 'feed', self.file, e.line, 0, msg,
                               self._text(e.line)))
        for m in self.dwells:
            msg = (f'dwell of {m.dwell_s:.6g} s is longer than {self.limits.max_dwell_s:g} s '
                   f'(a G4 P written in milliseconds for another control?)')
            out.append(Problem('warning', 'dwell', self.file, m.line, 0, msg,
                               self._text(m.line)))
        if self.n_long_dwells > len(self.dwells):
            more = self.n_long_dwells - len(self.dwells)
            msg = (f'{more} more dwells longer than {self.limits.max_dwell_s:g} s '
                   f'({self.long_dwell_s:.6g} s in all {self.n_long_dwells})')
            out.append(Problem('warning', 'dwell', self.file, 0, 0, msg))
        s = self.stats.result()
        if s.feed_length_m + s.traverse_length_m == 0.0:
            msg = 'the program never moves the tool'
            out.append(Problem('warning', 'no-motion', self.file, 0, 0, msg))
        return out

    def result(self) -> ProgramStats:
        """Summary of the moves checked (:class:`~.stats.ProgramStats`)."""
        return self.stats.result()


def _axis_speed(move: Move, i: int) -> float:
    """Largest speed [m/s] along axis ``i`` that the programmed feed asks for in ``move``."""
    feed = move.feed_m_s
    if not math.isfinite(feed) or feed <= 0.0:
        return 0.0
    if move.kind == MoveKind.LINEAR:
        length = math.dist(move.start, move.end)
        return feed * abs(move.end[i] - move.start[i]) / length if length > 0.0 else 0.0
    length = move.length_m
    if length <= 0.0:
        return 0.0
    (a, b, normal), theta0, sweep, _, _ = arc_geometry(move)
    axial = abs(move.end[normal] - move.start[normal]) / length
    if i == normal:
        return feed * axial
    in_plane = feed * math.sqrt(max(0.0, 1.0 - axial * axial))
    # The tangent at angle t is (-sin t, cos t) (either way round): its component along the
    # plane's first axis is |sin t|, along the second |cos t|, at most over the sweep.
    lo, hi = (theta0, theta0 + sweep) if sweep >= 0.0 else (theta0 + sweep, theta0)
    shift = _HALF_PI if i == a else 0.0
    return in_plane * _max_abs_cos(lo - shift, hi - shift)


_HALF_PI = 0.5 * math.pi


def _max_abs_cos(lo: float, hi: float) -> float:
    """Largest ``|cos t|`` for ``t`` in ``[lo, hi]``."""
    if math.floor(hi / math.pi) * math.pi >= lo:
        return 1.0
    return max(abs(math.cos(lo)), abs(math.cos(hi)))


def check_moves(moves: Iterable[Move], *, file: str, limits: CheckLimits,
                line_text: Callable[[int], str] | None = None
                ) -> tuple[list[Problem], ProgramStats]:
    """Run the sanity checks over a program's moves.

    Parameters
    ----------
    moves
        The moves in order (any iterable: one pass).
    file
        Program file for the warnings.
    limits
        What to compare against.
    line_text
        Optional source text of a line, shown as the offending text.

    Returns
    -------
    tuple
        The warnings and the program's :class:`~.stats.ProgramStats`.
    """
    checker = MoveChecker(file=file, limits=limits, line_text=line_text)
    checker.add_all(moves)
    return checker.problems(), checker.result()


# -- a program file on a machine (the checks of the command ``check``) --------------------
def check_limits(machine: Any, max_dwell_s: float = DEFAULT_MAX_DWELL_S) -> CheckLimits:
    """The :class:`CheckLimits` of ``machine`` (a :class:`~feed_axis_energy.machine.Machine`:
    its axes' ``travel_m`` and ``limits.velocity_m_s``) with the dwell threshold [s]."""
    travel = {}
    velocity = {}
    for axis in machine.axes:
        t = getattr(axis, 'travel_m', None)
        if t is not None:
            travel[axis.name] = (float(t[0]), float(t[1]))
        velocity[axis.name] = float(axis.limits.velocity_m_s)
    return CheckLimits(travel_m=travel, velocity_m_s=velocity, max_dwell_s=max_dwell_s)


def program_problems(path: Path, *, machine: Any, keywords: dict[str, Any],
                     max_dwell_s: float) -> tuple[list[Problem], ProgramStats | None]:
    """Parse one program and check its moves.

    Parameters
    ----------
    path
        The program file.
    machine
        The :class:`~feed_axis_energy.machine.Machine` (see :func:`check_limits`).
    keywords
        Keywords for :func:`~feed_axis_energy.gcode.iter_moves` (tools, G28 position,
        dialect, axes to ignore).
    max_dwell_s
        Dwell threshold [s].

    Returns
    -------
    tuple
        The problems (:class:`Problem`: the errors if any, the parser's warnings, the
        sanity warnings, with the source text of their line) in line order, and the
        :class:`~feed_axis_energy.gcode.stats.ProgramStats` (``None`` when the program is
        refused).
    """
    name = str(path)
    # Streamed: a program of any length is checked in bounded memory. An error in a line is
    # kept and checking goes on with the next line (up to MAX_ERRORS).
    stream = iter_moves(path, **keywords, max_errors=MAX_ERRORS)
    checker = MoveChecker(file=name, limits=check_limits(machine, max_dwell_s))
    errors: list[GcodeError] = []
    try:
        checker.add_all(stream)     # the moves before a fatal error are checked too
    except GcodeError as err:
        errors.append(err)
    errors = stream.errors + errors
    # The parser's warnings and those of the moves of the lines that parsed, before and
    # after an error, are problems of the program too.
    sanity = checker.problems()
    if errors:      # lines were dropped: "never moves" would say nothing about the program
        sanity = [p for p in sanity if p.kind != 'no-motion']
    problems = problems_from_warnings(stream.warnings, file=name) + sanity
    problems += [problem_from_error(err) for err in errors]
    # In line order (a file-level warning, line 0, first), as a reader goes through the file.
    ordered = sorted(_with_text(problems, path), key=lambda p: p.line)
    return ordered, None if errors else checker.result()


def _with_text(problems: list[Problem], path: Path) -> list[Problem]:
    """Fill in the source text of the lines the problems name (one streaming pass)."""
    name = str(path)
    wanted = {p.line for p in problems if p.line > 0 and not p.text and p.file == name}
    if not wanted:
        return problems
    texts: dict[int, str] = {}
    try:
        with open(path, 'rb') as fh:
            for n, raw in enumerate(fh, 1):
                if n in wanted:
                    texts[n] = shorten(raw.decode('utf-8', 'replace').strip())
                    if len(texts) == len(wanted):
                        break
    except OSError:
        return problems
    return [replace(p, text=texts.get(p.line, p.text)) if p.file == name else p
            for p in problems]


def warning_texts(path: Path, program: Any, machine: Any) -> list[str]:
    """The parser's and the sanity checks' warnings of a parsed program, as text lines."""
    checker = sanity_checker(path, machine)
    for move in program.moves:
        checker.add(move)
    return checked_warning_texts(path, program.warnings, checker)


def sanity_checker(path: Path, machine: Any) -> MoveChecker:
    """A :class:`MoveChecker` with ``check``'s default limits on ``machine``: feed it moves
    (``add``, ``add_many``), e.g. while they stream."""
    return MoveChecker(file=str(path), limits=check_limits(machine, DEFAULT_MAX_DWELL_S))


def checked_warning_texts(path: Path, parser_warnings: list[str],
                          checker: MoveChecker) -> list[str]:
    """The parser's warnings and those of a fed :func:`sanity_checker`, as text lines in line
    order. Used by ``simulate`` for its ``warnings`` (JSON) and its stderr lines."""
    problems = problems_from_warnings(parser_warnings, file=str(path))
    sanity = checker.problems()
    return [_warning_line(p) for p in sorted(problems + sanity, key=lambda p: p.line)]


def _warning_line(p: Problem) -> str:
    where = f'{p.file}:{p.line}' if p.line else p.file
    near = f' near {p.text!r}' if p.text else ''
    return f'{where}: {p.message}{near}'
