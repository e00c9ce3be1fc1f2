"""G-code (RS-274 / ISO 6983, milling) to moves in SI units: the user's reference.

``parse_gcode(text)`` / ``load_gcode(path)`` return a :class:`~..program.Program`;
``iter_moves(path)`` streams the same moves in bounded memory. A program that cannot be
simulated exactly raises :class:`~..errors.GcodeError` naming ``file:line:column`` and the
offending word (a subroutine file names itself). Semantics are LinuxCNC 2.9's (RS274NGC),
checked against its interpreter; where controls differ a :mod:`dialect <.dialect>` profile
applies (``linuxcnc`` by default; ``fanuc``, ``haas``, ``grbl``, ``mach3``). Programs in
Siemens' own language (``sinumerik``, also chosen from a ``.MPF``/``.SPF`` file, a
``%_N_NAME_MPF`` header or ``G710``/``G700`` where the dialect would be ``linuxcnc``) are
read by their own front, :mod:`.siemens`, which hands the same interpreter RS274NGC words.

Layout (as LinuxCNC's rs274ngc): :mod:`.read` turns text into executed blocks
(:mod:`.read.source`: bytes, line ends; :mod:`.read.lexer`, :mod:`.read.expr`,
:mod:`.read.params`: words, expressions, parameters; :mod:`.read.flow`: O-words, Fanuc
subprograms, Macro B); :mod:`.interp` holds the modal state (:mod:`.interp.interpreter` with
:mod:`.interp.motion`, :mod:`.interp.modes`, :mod:`.interp.comp`, :mod:`.interp.frames`;
:mod:`.interp.coords`: coordinate systems, tool length); :mod:`.expand` expands one block
into primitives (:mod:`.expand.cycles`, :mod:`.expand.cutter`, :mod:`.expand.splines`);
:mod:`.canon` holds the canonical moves and arc rules, :mod:`.run` one pass (plain lines on
a fast path, the rest through the reader).

Reading
-------
* UTF-8 (BOM allowed), LF / CRLF / CR line ends; comments ``( )`` and ``;``; block delete
  ``/``; ``%`` lines (the second ends the program); grbl ``$`` lines skipped with a warning.
  Blanks inside words and lower-case letters are read as LinuxCNC reads them.
* Parameters ``#1``..``#5601``, ``#<local>``, ``#<_global>``, expressions ``[ ]`` with
  LinuxCNC's operators and functions; assignments take effect after their line. In the
  Macro B dialects (``fanuc``, ``haas``) Fanuc's read-only system variables: modal groups
  ``#4001``.. and positions ``#5001``.., ``#5021``.., ``#5041``.., ``#5081``..
  (:mod:`.interp.sysvars`: given from the modal state, or refused by number).
* O-word subroutines (in the program, or ``<name>.ngc`` next to it or on ``search_path``,
  LinuxCNC's ``SUBROUTINE_PATH``)
  and ``if/elseif/else``, ``while``, ``do``, ``repeat``, ``break/continue``; Fanuc
  ``O1234`` + ``M98 P.. L..`` / ``M99``. Loops stop with an error after 10^6 passes.
* Non-finite or absurd numbers (beyond 1e12 program units) are errors.

Motion (canonical moves, :mod:`.canon`)
---------------------------------------
* G0, G1; G2/G3 with I/J/K (incremental under G91.1, absolute under G90.1) or R (negative:
  over 180 degrees), P turns, helices; a full circle may be written with I/J only. Arc
  tolerances are LinuxCNC's: end and start radius may differ by 0.0283 mm (G20: 0.00283
  inch), or by up to 0.1 % of the radius, never by more than 2.83 mm (0.283 inch); an R may
  fall 0.00127 mm short of the chord. Parser and planner share one sweep (``Move.sweep_rad``):
  an end angle within 1e-12 rad of the start is a full turn, anything else the short way
  the arc runs.
* An explicit G0/G1 without axis words, and any zero-length move, is issued with length 0
  (as LinuxCNC; the planner drops it). A feed move with no F set is an error, as on the
  control; ``allow_no_feed`` runs it at the machine's limits with one warning (LinuxCNC's
  preview accepts it); an F0 in force is always an error.
* Polar words ``@`` (distance) and ``^`` (angle, degrees) in the XY plane, from the origin
  under G90 or added to the current point's under G91.
* Canned cycles G73, G81..G89 with G98/G99 (start-up G99) and L repeats, sticky R/Z/P/Q
  words, G80; the cycle is the motion mode. Cutter radius compensation G41/G42 (D = tool
  number, or the tool in the spindle), G41.1/G42.1 (D = diameter), G40, in G17/G18; the
  radius comes from the machine's ``gcode.tools`` (``tools=``); tool 0 or radius 0 leaves
  the path unchanged; what LinuxCNC refuses under compensation is refused. A tool the table
  lacks has length and radius 0 (one warning per tool), or is an error with
  ``strict_tools`` (:mod:`.interp.tools`).
* G38.2..G38.5 probing runs to its end point (no contact simulated, one warning); G33.1
  rigid tapping goes in and back at K x S.
* Splines (:mod:`.expand.splines`, LinuxCNC 2.9's rules and messages): G5 cubic (``I J`` first
  offset from the start, ``P Q`` second offset from the end; without I/J minus the previous
  P/Q) and G5.1 quadratic (``I J``), in G17 only, without Z; they leave the motion mode as
  it was. G5.2 NURBS: the start and one point per line (X Y together, weight P > 0, order
  L above 3, else 3; lines without G continue), issued at G5.3 (at least L points; no
  motion mode after it). All are issued as LinuxCNC's preview issues them: straight feeds,
  15 per control point, at the current Z. An unfinished G5.2 is dropped with a warning.
  Only in the ``linuxcnc`` dialect: the others refuse G5.x (Fanuc's G05/G05.1 are
  high-speed machining modes).
* G4 dwell (P unit per dialect); M0/M1 stop; M2/M30 end (later lines warned about).

Modes and coordinates
---------------------
G17/G18/G19, G20/G21, G90/G91, G90.1/G91.1, G93/G94/G95 (F cleared on a switch; G95: F per
spindle revolution times S), G61/G61.1/G64,
G9; G54..G59.3, G10 L1/L2/L10/L11/L20, G92/G92.1/G92.2/G92.3, G52, G53, G28/G30 (+ .1),
G43/G43.1/G43.2/G49 as LinuxCNC 2.9 (:mod:`.interp.coords`); moves are in machine coordinates.
S, T, M6, M61, M3..M9 are tracked where they matter (G84/G86 need a turning spindle, G41
without D uses the loaded tool, or in the Fanuc/Haas dialects the D of an earlier line);
harmless I/O M codes and the control's contouring modes per dialect are accepted, and in
the ``linuxcnc`` dialect the user M codes M100-M199 (no motion, one warning per code).

Refused with a clear message
----------------------------
Axes U/V/W and the rotary axes A/B/C a machine does not declare (``rotary_axes``: those
turn, :mod:`.interp.rotary`; or dropped with ``ignore_axes``/``--ignore-axes``, one warning
each), rotary words in a canned cycle or under cutter compensation,
G5.2 without a positive weight on its first point, G5.2 under G93 or cutter compensation
(G5/G5.1 under compensation as LinuxCNC), G33 spindle-synchronised motion, G7 lathe mode,
G17.1-G19.1 UVW planes, unknown G and M codes, words nothing uses.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
import gc
import os
from os import PathLike

from .canon import CENTER_ARC_RADIUS_TOLERANCE_MM
from .interp.codes import IGNORABLE_AXES
from .context import OperationContext
from .dialect import Dialect, dialect_by_name
from .run import GcodeRun
from .read.source import read_program
from .siemens import decode_siemens, read_siemens_program, siemens_evidence
from ..errors import ConfigError, GcodeError, shorten_path
from .program import Move, Program, ROTARY_AXES

__all__ = ['parse_gcode', 'load_gcode', 'iter_moves', 'MoveStream', 'DEFAULT_ARC_TOLERANCE_M']

# LinuxCNC's centre-format radius tolerance in G21 (canon.CENTER_ARC_RADIUS_TOLERANCE_MM):
# what arc_tolerance_m=None means for a metric program (G20: 0.002828 inch).
DEFAULT_ARC_TOLERANCE_M = CENTER_ARC_RADIUS_TOLERANCE_MM * 1e-3

Vec3 = tuple[float, float, float]


def parse_gcode(text: str, *, file: str = '<string>', start: Vec3 = (0.0, 0.0, 0.0),
                arc_tolerance_m: float | None = None, home: Vec3 | None = None,
                tools: Mapping[int, object] | None = None,
                dialect: str | Dialect | None = None,
                search_path: Sequence[str | PathLike[str]] = (),
                ignore_axes: Sequence[str] = (), strict_tools: bool = False,
                allow_no_feed: bool = False, rotary_axes: Sequence[str] = (),
                work_offsets: Mapping[str, Vec3] | None = None) -> Program:
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
        Tool table: tool number -> ``ToolSpec`` (or ``(radius_m, length_m)``, or a radius);
        ``None``: an empty table. A tool it lacks runs with length and radius 0 and one
        warning per tool number, unless ``strict_tools``.
    dialect
        A :class:`Dialect` or its name (``linuxcnc``, ``fanuc``, ``haas``, ``grbl``,
        ``mach3``); ``None``: ``linuxcnc``.
    search_path
        Directories searched for subroutine files (``o<name> call``) after the program's
        own (LinuxCNC's ``SUBROUTINE_PATH``; ``--subroutine-path``,
        ``gcode.subroutine_path``); each must be an existing directory.
    ignore_axes
        Axis letters among A, B, C, U, V, W whose words are dropped (one warning each);
        otherwise such a word is an error naming its line.
    strict_tools
        A tool the table lacks is an error at the word naming it (T, H, D, G10's P, M61's
        Q; G43 or G41/G42 without H/D for the loaded tool), as in LinuxCNC with its table.
    allow_no_feed
        A feed move in G94 with no F set since the start runs at the machine's axis limits
        with one warning (LinuxCNC's preview); otherwise it is an error naming its line and
        column, as on the control.
    rotary_axes
        Rotary axis letters among A, B, C that the machine has: their words turn them
        (:mod:`.interp.rotary`; the moves carry ``rot_start``/``rot_end``).
    work_offsets
        Values of the settable work offsets ``{'G54'..'G59': (x, y, z)}`` [m] (machine -
        program; a machine's ``gcode.work_offsets_m``); one the mapping lacks is 0.

    Returns
    -------
    Program
        The moves in order, ``n_lines`` and any warnings (``file:line: message``).

    Raises
    ------
    GcodeError
        For anything that cannot be simulated exactly; names file, line, column and word.
    ConfigError
        For an unknown dialect name, an axis that cannot be ignored or a ``search_path``
        entry that is not a directory.
    """
    chosen, note = _file_dialect(dialect_by_name(dialect), file, text[:8192])
    run = GcodeRun(text, file=file, start=start, arc_tolerance_m=arc_tolerance_m, home=home,
                   tools=tools, dialect=chosen,
                   search_path=_directories(search_path), ignore_axes=_axes(ignore_axes),
                   strict_tools=bool(strict_tools), allow_no_feed=bool(allow_no_feed),
                   rotary_axes=rotary_letters(rotary_axes), work_offsets=work_offsets)
    if note:
        run.interp.warnings.insert(0, note)
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
    context
        The operation, subroutine and tool of the moves (:class:`.context.OperationContext`:
        its marks are complete up to the moves handed on so far).
    """

    def __init__(self, path: str | PathLike[str], kw: dict, note: str = ''):
        self._path = path
        self._kw = kw
        self._note = note             # why the dialect was chosen from the file, if it was
        self._run: GcodeRun | None = None
        self.file = str(path)
        self.context = OperationContext()

    @property
    def warnings(self) -> list[str]:
        """Warnings so far (all of them after the last move)."""
        return [] if self._run is None else self._run.warnings

    @property
    def n_lines(self) -> int:
        """Lines of the program read so far (all of them after the last move)."""
        return 0 if self._run is None else self._run.n_lines

    @property
    def errors(self) -> list[GcodeError]:
        """Errors the run went on after (``max_errors`` of :func:`iter_moves`)."""
        return [] if self._run is None else self._run.errors

    def __iter__(self) -> Iterator[Move]:
        """The moves in order (the file is open while the iteration runs)."""
        for batch in self.batches():
            yield from batch

    def batches(self) -> Iterator[list[Move]]:
        """The moves in order as the interpreter hands them on, in lists of about ``batch``
        moves (:func:`iter_moves`); the context's marks are complete up to the last move
        of the list just given. A consumer that takes lists saves a generator step per
        move."""
        name = self.file
        if self._kw['dialect'].siemens:     # read whole (Latin-1 allowed), as subprograms
            text = read_siemens_program(self._path, file=name)
            self.context.reset()
            self._run = GcodeRun(text, file=name, context=self.context, **self._kw)
            if self._note:
                self._run.interp.warnings.insert(0, self._note)
            yield from self._run
            return
        try:
            fh = open(self._path, encoding='utf-8-sig', newline=None)
        except OSError as err:
            msg = f'cannot read the program: {err.strerror or err}'
            raise GcodeError(msg, file=name, line=0, column=0) from err
        with fh:
            self.context.reset()                  # the same object: callers hold it
            self._run = GcodeRun(stream=fh, file=name, context=self.context, **self._kw)
            try:
                yield from self._run
            except UnicodeDecodeError:
                read_program(self._path, file=name)     # raises, naming line and column
                raise


def iter_moves(path: str | PathLike[str], *, start: Vec3 = (0.0, 0.0, 0.0),
               arc_tolerance_m: float | None = None, home: Vec3 | None = None,
               tools: Mapping[int, object] | None = None,
               dialect: str | Dialect | None = None,
               search_path: Sequence[str | PathLike[str]] = (),
               ignore_axes: Sequence[str] = (), batch: int = 4096,
               max_errors: int = 0, strict_tools: bool = False,
               allow_no_feed: bool = False, rotary_axes: Sequence[str] = (),
               work_offsets: Mapping[str, Vec3] | None = None) -> MoveStream:
    """Stream the moves of a program file in bounded memory.

    Plain lines are read one at a time, so memory stays at ``batch`` moves however long
    the program; from the first line that needs the front's reader (parameters, O-words,
    ...) on, the rest of the text is read into memory.

    Parameters
    ----------
    path
        The program file.
    start, arc_tolerance_m, home, tools, dialect, search_path, ignore_axes, strict_tools
    allow_no_feed, rotary_axes, work_offsets
        As for :func:`parse_gcode`.
    batch
        Moves interpreted ahead of the consumer (at least 1).
    max_errors
        0: the first error is raised. ``N > 0`` (``check``): errors in lines are kept in
        the stream's ``errors`` and the run goes on with the next line; the ``N``-th error
        is raised (see :class:`~.run.GcodeRun`).

    Returns
    -------
    MoveStream
        Iterate over it for the moves; its ``warnings`` are complete at the end. Errors
        (:class:`GcodeError`) are raised during the iteration, at the line concerned.
    """
    chosen, note = _file_dialect(dialect_by_name(dialect), str(path), _head(path))
    kw = dict(start=start, arc_tolerance_m=arc_tolerance_m, home=home, tools=tools,
              dialect=chosen, search_path=_directories(search_path),
              batch=max(1, int(batch)), ignore_axes=_axes(ignore_axes),
              max_errors=max(0, int(max_errors)), strict_tools=bool(strict_tools),
              allow_no_feed=bool(allow_no_feed), rotary_axes=rotary_letters(rotary_axes),
              work_offsets=work_offsets)
    return MoveStream(path, kw, note)


def load_gcode(path: str | PathLike[str], *, start: Vec3 = (0.0, 0.0, 0.0),
               arc_tolerance_m: float | None = None, home: Vec3 | None = None,
               tools: Mapping[int, object] | None = None,
               dialect: str | Dialect | None = None,
               search_path: Sequence[str | PathLike[str]] = (),
               ignore_axes: Sequence[str] = (), strict_tools: bool = False,
               allow_no_feed: bool = False, rotary_axes: Sequence[str] = (),
               work_offsets: Mapping[str, Vec3] | None = None) -> Program:
    """Read a program file (UTF-8, a BOM allowed) and parse it (see :func:`parse_gcode`).

    Parameters
    ----------
    path
        The program file; its path is used as ``file`` in messages and in the result.
    start, arc_tolerance_m, home, tools, dialect, search_path, ignore_axes, strict_tools
    allow_no_feed, rotary_axes, work_offsets
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
    chosen, _ = _file_dialect(dialect_by_name(dialect), name, _head(path))
    if chosen.siemens:
        text = read_siemens_program(path, file=name)
    else:
        text = read_program(path, file=name)
    return parse_gcode(text, file=name, start=start, arc_tolerance_m=arc_tolerance_m,
                       home=home, tools=tools, dialect=dialect, search_path=search_path,
                       ignore_axes=ignore_axes, strict_tools=strict_tools,
                       allow_no_feed=allow_no_feed, rotary_axes=rotary_axes,
                       work_offsets=work_offsets)


def _directories(paths: Sequence[str | PathLike[str]]) -> tuple[str, ...]:
    """The ``search_path`` entries, each checked to be an existing directory."""
    if isinstance(paths, (str, PathLike)):
        paths = (paths,)            # one directory, not its characters
    out = []
    for entry in paths:
        text = os.fspath(entry)
        if not os.path.isdir(text):
            what = 'does not exist' if not os.path.exists(text) else 'is not a directory'
            msg = f'subroutine directory {shorten_path(text)!r} {what}'
            raise ConfigError(msg, key='search_path')
        out.append(text)
    return tuple(out)


def _head(path: str | PathLike[str]) -> str:
    """The first lines of a program file (for :func:`_file_dialect`; '' if unreadable:
    reading it later reports the problem)."""
    try:
        with open(path, 'rb') as fh:
            data = fh.read(8192)
    except OSError:
        return ''
    return decode_siemens(data)


def _file_dialect(dialect: Dialect, file: str, head: str) -> tuple[Dialect, str]:
    """The dialect a program is read in, and a warning if the file chose it: a program
    marked as Sinumerik (:func:`~.siemens.siemens_evidence`) is read as such where the
    dialect would be the default, ``linuxcnc`` (whose interpreter refuses such a program
    at its first Siemens word)."""
    if dialect.name != 'linuxcnc':
        return dialect, ''
    why = siemens_evidence(file, head)
    if why is None:
        return dialect, ''
    note = (f'{file}:1: read in the sinumerik dialect, chosen from {why} '
            '(--dialect names another)')
    return dialect_by_name('sinumerik'), note


def rotary_letters(letters: Sequence[str]) -> tuple[str, ...]:
    """Upper-case rotary axis letters for ``rotary_axes``, checked."""
    out = tuple(str(a).strip().upper() for a in letters)
    for a in out:
        if a not in ROTARY_AXES:
            msg = f'not a rotary axis: {a[:60]!r} (expected A, B or C)'
            raise ConfigError(msg, key='rotary_axes')
    return out


def _axes(letters: Sequence[str]) -> tuple[str, ...]:
    """Upper-case axis letters for ``ignore_axes``, checked."""
    out = tuple(str(a).strip().upper() for a in letters)
    for a in out:
        if a not in IGNORABLE_AXES:
            shown = a[:60]
            msg = f'cannot ignore axis {shown!r}: only A, B, C, U, V, W can be ignored'
            raise ConfigError(msg, key='ignore_axes')
    return out
