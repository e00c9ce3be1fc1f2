"""G-code (RS-274 / ISO 6983, milling) to a :class:`~.program.Program` of moves in SI units.

One pass over the text: each line is lexed with two precompiled regular expressions and
interpreted against the full modal state. Parsing either returns a whole program or raises
:class:`~.errors.GcodeError` naming ``file:line:column`` and the offending word.

Dialect (LinuxCNC semantics where dialects differ)
--------------------------------------------------
* Motion: G0, G1, G2/G3 (I/J/K centre or R radius; negative R = arc over 180 degrees;
  IJK with end == start = full circle; P = number of turns; the axis normal to the plane
  moves linearly = helix), G4 dwell (P in seconds), G80 (motion mode off).
* Modes, with their start-up values in brackets: plane G17/G18/G19 [G17], units G20/G21
  [G21, mm], distance G90/G91 [G90], arc centres G90.1/G91.1 [G91.1, incremental], feed
  G93/G94 [G94], path control G61 (and G61.1, treated the same)/G64 [G64; G64 P/Q
  tolerances are accepted and ignored], G9 (exact stop for this line), motion [G80: axis
  words before the first G0/G1/G2/G3 are an error].
* F is read in the units in force *after* the line's G20/G21 and keeps its physical speed
  when the units change later. Switching between G93 and G94 clears F (a new F is
  required). Under G93 every feed move needs F on its line; F is 1/minutes, so the move
  takes 60/F s and ``feed_m_s = length_m * F / 60``.
* Accepted and ignored for the feed axes: N, O (a bare program number), S, T, M3-M9,
  G40, G43 H (tool length offset: unknown tool length, so Z moves as programmed; a warning
  says so), G49, G54-G59 (motion stays in program coordinates; a change of coordinate system
  after the first move is reported as a warning), G8, G96/G97, G98/G99.
* G28 (needs the machine's ``home_m``, in program coordinates since work offsets are not
  simulated): a rapid to the intermediate point of the line's axis words, then those axes
  (all axes without axis words) rapid to the reference point; both stop at their end.
* M0/M1 give a STOP move; M2/M30 give a STOP move and end the program: later lines are
  ignored (with a warning if any of them holds code). A ``%`` line after code also ends it.
* Comments ``( ... )`` (no nesting, must close on the line) and ``;`` to end of line;
  a line whose first non-blank character is ``/`` is skipped (block delete switch on).
* Blanks and tabs are ignored between and inside words (LinuxCNC rule): ``X 10`` and even
  ``X1 0`` (= X10) are read. Letters may be lower case. Numbers: ``X.5``, ``X-1.``,
  ``X+2``; ``X1.2.3`` and ``Xabc`` are errors.
* Refused with "not supported": G28 without a reference point, G28.1, G30, G41/G42,
  G43.1/G43.2, G52/G53, G92, canned cycles (G73-G89), G95, G33, G38.x, G5.x, A/B/C/U/V/W,
  D/L words (H only with G43), parameters and expressions (``#``, ``[...]``), O-word
  control flow, unknown G/M codes and letters.
* Arc end check: the end must lie on the start circle within
  ``max(arc_tolerance_m, 0.1 % of the radius)``; the default ``arc_tolerance_m`` is 0.002 mm.
  An R smaller than half the chord by no more than the same tolerance gives a half circle.
  A spiral within tolerance is kept: its length uses the mean of the start and end radii.
* Zero-length G0/G1 moves produce no move (they would have no duration to plan).
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
import gc
from os import PathLike

from .canon import CENTER_ARC_RADIUS_TOLERANCE_MM
from .codes import IGNORABLE_AXES
from .dialect import Dialect, dialect_by_name
from .run import GcodeRun
from .source import read_program
from ..errors import ConfigError
from ..program import Move, Program

__all__ = ['parse_gcode', 'load_gcode', 'iter_moves', 'MoveStream',
           'DEFAULT_ARC_TOLERANCE_M', 'Dialect', 'dialect_by_name']

# LinuxCNC's centre-format radius tolerance in G21 (canon.CENTER_ARC_RADIUS_TOLERANCE_MM):
# what arc_tolerance_m=None means for a metric program (G20: 0.002828 inch).
DEFAULT_ARC_TOLERANCE_M = CENTER_ARC_RADIUS_TOLERANCE_MM * 1e-3

Vec3 = tuple[float, float, float]


def parse_gcode(text: str, *, file: str = '<string>', start: Vec3 = (0.0, 0.0, 0.0),
                arc_tolerance_m: float | None = None, home: Vec3 | None = None,
                tools: Mapping[int, object] | None = None,
                dialect: str | Dialect | None = None,
                search_path: Sequence[str | PathLike[str]] = (),
                ignore_axes: Sequence[str] = ()) -> Program:
    """Parse an NC program into moves in SI units.

    Parameters
    ----------
    text
        The program text (LF, CRLF or CR line ends).
    file
        Name used in error messages and stored in the result; subroutine files are looked
        for in its directory first.
    start
        Tool position [m] before the first line.
    arc_tolerance_m
        Absolute tolerance [m] of the arc end-point check (start and end radius may differ
        by this, or by up to 0.1 % of the radius but never by more than 100 times this);
        ``None``: LinuxCNC's, 0.02828 mm under G21 and 0.002828 inch under G20.
    home
        The G28 position [m] in machine coordinates (a machine's ``home_m``); without it
        #5161..#5163 are 0 as in LinuxCNC's fresh parameter file.
    tools
        Tool table: tool number -> ``ToolSpec`` (or ``(radius_m, length_m)``, or a radius).
        Without it G41/G42 work only with tool 0 (radius 0, the path unchanged) or
        G41.1/G42.1, and G43 H only with H0.
    dialect
        A :class:`Dialect` or its name (``linuxcnc``, ``fanuc``, ``haas``, ``grbl``,
        ``mach3``); ``None``: ``linuxcnc``.
    search_path
        Directories searched for subroutine files (``o<name> call``) after the program's.
    ignore_axes
        Axis letters among A, B, C, U, V, W whose words are dropped (one warning each);
        otherwise such a word is an error naming its line.

    Returns
    -------
    Program
        The moves in order, ``n_lines`` and any warnings (``file:line: message``).

    Raises
    ------
    GcodeError
        For anything that cannot be simulated exactly; names file, line, column and word.
    ConfigError
        For an unknown dialect name or an axis that cannot be ignored.
    """
    run = GcodeRun(text, file=file, start=start, arc_tolerance_m=arc_tolerance_m, home=home,
                   tools=tools, dialect=dialect_by_name(dialect), search_path=search_path,
                   ignore_axes=_axes(ignore_axes))
    # The parse allocates one Move per block and frees nothing: cyclic garbage collection
    # passes over the growing list find nothing and cost ~15 % of the time, so they are
    # paused for the duration (and resumed even when the program is refused).
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        moves: list[Move] = []
        for batch in run:
            moves += batch
    finally:
        if gc_was_enabled:
            gc.enable()
    return Program(file=file, moves=tuple(moves), n_lines=run.n_lines,
                   warnings=tuple(run.warnings))


class MoveStream:
    """The moves of a program file one by one, in bounded memory (see :func:`iter_moves`).

    Attributes
    ----------
    file
        The program's name.
    warnings
        ``file:line: message`` texts, complete once the iteration has ended.
    n_lines
        Number of lines of the program.
    """

    def __init__(self, run: GcodeRun):
        self._run = run
        self.file = run.file
        self.n_lines = run.n_lines

    @property
    def warnings(self) -> list[str]:
        """Warnings so far (all of them after the last move)."""
        return self._run.warnings

    def __iter__(self) -> Iterator[Move]:
        """The moves in order."""
        for batch in self._run:
            yield from batch


def iter_moves(path: str | PathLike[str], *, start: Vec3 = (0.0, 0.0, 0.0),
               arc_tolerance_m: float | None = None, home: Vec3 | None = None,
               tools: Mapping[int, object] | None = None,
               dialect: str | Dialect | None = None,
               search_path: Sequence[str | PathLike[str]] = (),
               ignore_axes: Sequence[str] = (), batch: int = 4096) -> MoveStream:
    """Read a program file and stream its moves (memory: the text plus ``batch`` moves).

    Parameters
    ----------
    path
        The program file.
    start, arc_tolerance_m, home, tools, dialect, search_path, ignore_axes
        As for :func:`parse_gcode`.
    batch
        Moves interpreted ahead of the consumer (at least 1).

    Returns
    -------
    MoveStream
        Iterate over it for the moves; its ``warnings`` are complete at the end. Errors
        (:class:`GcodeError`) are raised during the iteration, at the line concerned.
    """
    name = str(path)
    text = read_program(path, file=name)
    return MoveStream(GcodeRun(text, file=name, start=start, arc_tolerance_m=arc_tolerance_m,
                               home=home, tools=tools, dialect=dialect_by_name(dialect),
                               search_path=search_path, batch=max(1, int(batch)),
                               ignore_axes=_axes(ignore_axes)))


def load_gcode(path: str | PathLike[str], *, start: Vec3 = (0.0, 0.0, 0.0),
               arc_tolerance_m: float | None = None, home: Vec3 | None = None,
               tools: Mapping[int, object] | None = None,
               dialect: str | Dialect | None = None,
               search_path: Sequence[str | PathLike[str]] = (),
               ignore_axes: Sequence[str] = ()) -> Program:
    """Read a program file (UTF-8, a BOM allowed) and parse it (see :func:`parse_gcode`).

    Parameters
    ----------
    path
        The program file; its path is used as ``file`` in messages and in the result.
    start, arc_tolerance_m, home, tools, dialect, search_path, ignore_axes
        As for :func:`parse_gcode`.

    Returns
    -------
    Program
        The parsed program.

    Raises
    ------
    GcodeError
        Also when the file cannot be read (line 0, column 0, chained from the ``OSError``),
        is too large, or is not UTF-8 text (the message gives the line of the bad byte).
    """
    name = str(path)
    text = read_program(path, file=name)
    return parse_gcode(text, file=name, start=start, arc_tolerance_m=arc_tolerance_m,
                       home=home, tools=tools, dialect=dialect, search_path=search_path,
                       ignore_axes=ignore_axes)


def _axes(letters: Sequence[str]) -> tuple[str, ...]:
    """Upper-case axis letters for ``ignore_axes``, checked."""
    out = tuple(str(a).strip().upper() for a in letters)
    for a in out:
        if a not in IGNORABLE_AXES:
            shown = a[:60]
            msg = f'cannot ignore axis {shown!r}: only A, B, C, U, V, W can be ignored'
            raise ConfigError(msg, key='ignore_axes')
    return out
