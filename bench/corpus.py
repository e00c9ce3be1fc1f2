"""Our G-code front end against the reference interpreter (LinuxCNC 2.9) on the shared corpus.

Run by hand from the repository root after ``scripts/test`` made the venv::

    PYTHONPATH=. .venv/bin/python bench/corpus.py [--corpus DIR] [--plan] [--json]
                                                  [--locate auto|yes|no]
                                                  [--mem-lines N] [--skip-largest K]
                                                  [--no-tool-table]

For every program of ``programs.csv`` it parses the program in-process, the way the
reference run (``shared/tools/run_oracle.py``) set the interpreter up:

* subroutine files: the other files of the same corpus folder under their original base
  names, lower-cased (the corpus flattens ``a/b/face.ngc`` to ``a__b__face.ngc``), linked
  into a temporary directory that is searched first, then the corpus folder itself;
* a tool table with tools 1..999 of zero radius and zero length, G28/G30 positions 0 (the
  reference's empty parameter file), start at the machine origin;
* a feed move with no F set is let pass (``allow_no_feed``): the reference is LinuxCNC's
  preview module (``gcodemodule.cc``), whose feed rate at the start is 1, not 0 as on the
  control, which refuses such a move. The programs accepted only so are counted and listed
  ("only as a preview"): without ``--allow-no-feed`` our commands refuse them as the control.

``--no-tool-table`` parses without the tool table instead (a planner's machine config): the
tools a program uses then run with length and radius 0 and a warning each, and the summary
counts the accepted programs that had such a tool.

Acceptance is counted with the program's own dialect (``programs.csv``; what a user of that
control would choose); agreement with the reference is checked on the programs both accept,
parsed with the ``linuxcnc`` dialect (the reference's own semantics: ``G4 P`` in seconds).
Compared (with ``gcode/stats.py``, which counts as the reference does): numbers of
feed moves, traverses, arcs and dwells; feed and traverse path length (relative 1e-6, at
least 1e-4 mm: the reference rounds to 4 decimals); total dwell; final position and bounding
box (1 um); rotary travel, rotary moves and the nominal feed time (A, B, C declared as the
reference's interpreter has them, U, V, W dropped). ``--plan`` also plans every accepted
program on ``config/three_axis_mill.yaml`` with the rotary axes of
``config/four_axis_mill.yaml`` (A) and ``config/five_axis_mill.yaml`` (B, C) (per block, no
samples) and checks that the duration is finite and not negative.

Prints acceptance per dialect (ours vs the reference), every refusal of a program the
reference accepts (file:line:column and our message), every disagreement (program, figure,
ours vs reference), the first differing move of each disagreeing program with its line,
found by running the reference move by move (``bench/oracle_trace.py``, needs LinuxCNC's
``gcode`` module; ``--locate``, by default when it is installed and at most 30 programs
disagree), which disagreements a model of a known quirk of the reference run reproduces
(``bench/oracle_quirks.py``: the program is parsed again with our interpreter copying the
quirk; it counts as explained only if every figure then agrees), every traceback, and a
summary line with the targets of issue 8 (>= 95 % of the programs the reference accepts,
0 tracebacks, 0 disagreements that no quirk explains). ``--mem-lines N``
(default 1 000 000; 0 skips it) generates an N-line CAM-like program in a temporary
directory and reports the peak resident memory of parsing it in a child process. Exit
status 0 (the figures are a report, not a verdict); 2 on a usage error; 1 when the corpus
cannot be found.
"""
from __future__ import annotations

import argparse
from collections import Counter
import csv
from dataclasses import dataclass, field
import inspect
import json
import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
import traceback
from typing import Any, Callable

ROOT = Path(__file__).resolve().parents[1]
for _p in (ROOT, ROOT / 'bench'):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

import oracle_quirks  # noqa: E402  (bench/oracle_quirks.py)
from shared_lookup import HINT, shared_path  # noqa: E402  (bench/shared_lookup.py)

from feed_axis_energy.errors import FeedAxisError, GcodeError  # noqa: E402
from feed_axis_energy.gcode.load import load_gcode  # noqa: E402
from feed_axis_energy.gcode.stats import ProgramStats, summarize  # noqa: E402

__all__ = ['find_corpus', 'load_corpus', 'run_ours', 'compare', 'evaluate', 'format_report',
           'report_json', 'memory_figure', 'Entry', 'OurResult', 'Disagreement', 'Report']

ROTARY_WORDS = ('A', 'B', 'C')
ACCEPTED = ('ok', 'ok_m2_appended')
"""Reference statuses that mean the reference interpreter ran the program to its end."""
REFERENCE_DIALECT = 'linuxcnc'
TARGET_ACCEPTANCE = 0.95
REL_LENGTH_TOL = 1e-6
ABS_LENGTH_TOL_MM = 1e-4    # the reference rounds lengths to 4 decimals
POSITION_TOL_MM = 1e-3      # 1 um
DWELL_TOL_S = 1e-4
ROTARY_TOL_DEG = 1e-3      # the reference rounds rotary travel to 4 decimals
NOMINAL_TOL_S = 1.5e-3      # and the nominal feed time to 3 decimals
ORACLE_TOOLS = 999          # tools T1..T999, zero radius and length (run_oracle.py)
DEFAULT_TIMEOUT_S = 60.0
MAX_AUTO_LOCATE = 30        # --locate auto: programs traced move by move at most


# --------------------------------------------------------------------------------------
# the corpus
# --------------------------------------------------------------------------------------
def find_corpus(explicit: str | os.PathLike[str] | None = None) -> Path | None:
    """Return the corpus folder, or ``None`` if there is none.

    Parameters
    ----------
    explicit
        A folder given on the command line; used as is.

    Returns
    -------
    Path or None
        ``explicit``, else ``corpus/gcode`` of the shared data (``$FAE_SHARED``, else
        ``<repo>/../shared``; :mod:`shared_lookup`) if it holds ``oracle.json`` and
        ``programs.csv``.
    """
    if explicit is not None:
        return Path(explicit)
    return shared_path('corpus', 'gcode', needs=('oracle.json', 'programs.csv'))


@dataclass(frozen=True)
class Entry:
    """One corpus program: where it is, what it is written for and what the reference did."""

    file: str            # path relative to the corpus folder
    dialect: str         # programs.csv 'dialect'
    generator: str
    lines: int
    oracle: dict[str, Any]

    @property
    def reference_accepts(self) -> bool:
        """True when the reference interpreter ran the program to its end."""
        return self.oracle.get('status') in ACCEPTED

    @property
    def rotary(self) -> bool:
        """True when the reference moved a rotary axis (A/B/C) in this program."""
        return bool(self.oracle.get('n_rotary_moves'))


def load_corpus(corpus: Path) -> list[Entry]:
    """Read ``programs.csv`` and ``oracle.json`` of a corpus folder.

    Parameters
    ----------
    corpus
        The folder.

    Returns
    -------
    list of Entry
        In the order of ``programs.csv``.
    """
    with open(corpus / 'oracle.json', encoding='utf-8') as fh:
        oracle = json.load(fh)
    out = []
    with open(corpus / 'programs.csv', encoding='utf-8', newline='') as fh:
        for row in csv.DictReader(fh):
            name = row['file']
            out.append(Entry(file=name, dialect=row.get('dialect') or 'other',
                             generator=row.get('generator') or '',
                             lines=int(row.get('lines') or 0),
                             oracle=oracle.get(name, {'status': 'missing'})))
    return out


class SubroutineLinks:
    """Temporary directories of subroutine links, one per corpus folder (as the reference).

    Every file of the folder is linked under its base name lower-cased (the part after the
    last ``__``), the first in sorted order winning a clash, exactly as ``run_oracle.py``.
    """

    def __init__(self) -> None:
        self._tmp = tempfile.TemporaryDirectory(prefix='fae-corpus-')
        self._dirs: dict[Path, Path] = {}

    def for_folder(self, folder: Path) -> Path:
        """Return the link directory of ``folder`` (made on first use)."""
        folder = folder.resolve()
        if folder not in self._dirs:
            links = Path(self._tmp.name) / f'{len(self._dirs):03d}'
            links.mkdir()
            for name in sorted(os.listdir(folder)):
                src = folder / name
                if not src.is_file():
                    continue
                dst = links / name.split('__')[-1].lower()
                if not dst.exists():
                    dst.symlink_to(src)
            self._dirs[folder] = links
        return self._dirs[folder]

    def real_names(self, text: str) -> str:
        """Replace the links' paths in ``text`` (an error message) by the files they name."""
        if self._tmp.name not in text:
            return text
        for links in self._dirs.values():
            for link in links.iterdir():
                text = text.replace(str(link), str(link.resolve()))
        return text

    def close(self) -> None:
        """Remove the links."""
        self._tmp.cleanup()


# --------------------------------------------------------------------------------------
# our side
# --------------------------------------------------------------------------------------
@dataclass
class OurResult:
    """What our front end made of one program."""

    status: str                       # 'ok', 'error', 'traceback', 'timeout'
    error: str = ''
    line: int | None = None
    column: int | None = None
    stats: ProgramStats | None = None
    warnings: int = 0
    seconds: float = 0.0
    plan: str = ''                    # '', 'ok <duration>', or the planning error
    preview_only: str = ''            # the no-feed warning of a program accepted only so
    missing_tools: int = 0            # tools the table lacked (each run with length 0)


class _Timeout(Exception):
    pass


def _on_alarm(signum: int, frame: Any) -> None:
    raise _Timeout


def _parse_keywords(dialect: str | None, search_path: list[Path], *,
                    tool_table: bool = True) -> dict[str, Any]:
    """Keywords for ``load_gcode`` that set it up as the reference was (those it accepts);
    ``tool_table=False``: no tool table (``--no-tool-table``: a planner's machine config)."""
    params = inspect.signature(load_gcode).parameters
    kw: dict[str, Any] = {}
    if 'home' in params:
        kw['home'] = (0.0, 0.0, 0.0)
    if 'tools' in params and tool_table:
        kw['tools'] = {t: (0.0, 0.0) for t in range(1, ORACLE_TOOLS + 1)}
    if 'allow_no_feed' in params:
        kw['allow_no_feed'] = True          # the preview's feed rate 1 at the start
    if dialect is not None and 'dialect' in params:
        kw['dialect'] = dialect
    for name in ('search_path', 'subroutine_path'):
        if name in params:
            kw[name] = [str(p) for p in search_path]
            break
    if 'rotary_axes' in params:
        # the reference's interpreter has all nine axes: A, B, C turn (as on a machine
        # config that declares them, config/five_axis_mill.yaml), U, V, W are dropped (no
        # figure of the reference counts them)
        kw['rotary_axes'] = ROTARY_WORDS
        kw['ignore_axes'] = ('U', 'V', 'W')
    return kw


def known_dialects() -> tuple[str, ...]:
    """Dialect names our front end knows (``gcode/settings.DIALECTS`` once it exists)."""
    try:
        from feed_axis_energy.gcode.settings import DIALECTS
    except ImportError:
        return (REFERENCE_DIALECT,)
    return tuple(DIALECTS)


def run_ours(path: Path, *, dialect: str | None, search_path: list[Path],
             timeout_s: float = DEFAULT_TIMEOUT_S,
             planner: Callable[[Any], str] | None = None,
             tool_table: bool = True) -> OurResult:
    """Parse one program in-process and summarize its moves.

    Parameters
    ----------
    path
        The program file.
    dialect
        Dialect to parse with (passed only if ``load_gcode`` takes one).
    search_path
        Subroutine directories, searched in order.
    timeout_s
        Wall-clock limit (a runaway program gives status ``timeout``).
    planner
        Optional: called with the parsed program, returns ``'ok ...'`` or the error.
    tool_table
        Give the reference's tool table (tools 1..999 of zero size); ``False``: none.

    Returns
    -------
    OurResult
        Status ``ok``, ``error`` (a :class:`GcodeError`: message, line, column),
        ``traceback`` (any other exception: the last lines of its traceback) or ``timeout``.
    """
    kw = _parse_keywords(dialect, search_path, tool_table=tool_table)
    use_alarm = hasattr(signal, 'setitimer') and timeout_s > 0
    t0 = time.perf_counter()
    if use_alarm:
        old = signal.signal(signal.SIGALRM, _on_alarm)
        signal.setitimer(signal.ITIMER_REAL, timeout_s)
    try:
        program = load_gcode(path, **kw)
        stats = summarize(program.moves)
        res = OurResult('ok', stats=stats, warnings=len(program.warnings))
        res.preview_only = next((w for w in program.warnings if '--allow-no-feed' in w), '')
        res.missing_tools = sum(1 for w in program.warnings if 'is not in the tool table' in w)
        if planner is not None:
            res.plan = planner(program)
    except _Timeout:
        res = OurResult('timeout', error=f'no result within {timeout_s:g} s')
    except GcodeError as err:
        res = OurResult('error', error=str(err), line=err.line, column=err.column)
    except Exception:  # noqa: B902 - counting tracebacks is the point
        tb = traceback.format_exc().strip().splitlines()
        res = OurResult('traceback', error=' | '.join(tb[-3:]))
    finally:
        if use_alarm:
            signal.setitimer(signal.ITIMER_REAL, 0.0)
            signal.signal(signal.SIGALRM, old)
    res.seconds = time.perf_counter() - t0
    return res


def make_planner(machine_path: Path) -> Callable[[Any], str]:
    """Return a function that plans a program on a machine (per block, no samples)."""
    from feed_axis_energy.machine.file import load_machine
    from feed_axis_energy.plan.stream import estimate_plan
    machine = load_machine(machine_path)
    limits = machine.limits()
    # the rotary axes the parse declares (ROTARY_WORDS) plan with the shipped 4- and 5-axis
    # configs' limits: A from four_axis_mill.yaml, B and C from five_axis_mill.yaml
    for config in ('four_axis_mill.yaml', 'five_axis_mill.yaml'):
        extra = load_machine(ROOT / 'config' / config).limits()
        limits.update({a: extra[a] for a in ROTARY_WORDS if a in extra and a not in limits})
    options = machine.planner.options()

    def plan(program: Any) -> str:
        try:
            est = estimate_plan(program.moves, limits, options=options, file=program.file)
        except FeedAxisError as err:
            return f'refused: {err}'
        if not math.isfinite(est.duration_s) or est.duration_s < 0.0:
            return f'bad duration {est.duration_s!r} s'
        return f'ok {est.duration_s:.3f} s'
    return plan


# --------------------------------------------------------------------------------------
# comparison
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Disagreement:
    """One figure on which we and the reference differ."""

    file: str
    what: str
    ours: Any
    reference: Any
    line: int | None = None       # a line of ours where the difference may start

    def text(self) -> str:
        """One line for the report."""
        where = f'{self.file}:{self.line}' if self.line else self.file
        return f'{where}: {self.what}: ours {self.ours}, reference {self.reference}'


def _close(ours: float, ref: float, *, rel: float, absolute: float) -> bool:
    return abs(ours - ref) <= max(rel * abs(ref), absolute)


def _compare_rotary(file: str, s: Any, ref: dict[str, Any]) -> list[Disagreement]:
    """Rotary travel and moves, and the nominal feed time where the reference has it."""
    out: list[Disagreement] = []
    if s.n_rotary_moves != ref.get('n_rotary_moves', 0):
        out.append(Disagreement(file, 'n_rotary_moves', s.n_rotary_moves,
                                ref.get('n_rotary_moves')))
    if not _close(s.rotary_travel_deg, float(ref.get('rotary_travel_deg', 0.0)),
                  rel=REL_LENGTH_TOL, absolute=ROTARY_TOL_DEG):
        out.append(Disagreement(file, 'rotary_travel_deg', f'{s.rotary_travel_deg:.4f}',
                                ref.get('rotary_travel_deg')))
    nominal = ref.get('nominal_feed_time_s')
    if nominal is not None and not _close(s.nominal_feed_time_s, float(nominal),
                                          rel=REL_LENGTH_TOL, absolute=NOMINAL_TOL_S):
        out.append(Disagreement(file, 'nominal_feed_time_s', f'{s.nominal_feed_time_s:.3f}',
                                nominal))
    return out


def compare(file: str, ours: OurResult, ref: dict[str, Any]) -> list[Disagreement]:
    """Compare our summary of a program with the reference's.

    Parameters
    ----------
    file
        The program (for the report).
    ours
        Our result (status ``ok``).
    ref
        The reference's entry of ``oracle.json`` (millimetres, seconds).

    Returns
    -------
    list of Disagreement
        Empty when every figure agrees within the tolerances of the module docstring.
    """
    s = ours.stats
    out: list[Disagreement] = []
    kinds = {'n_feed_moves': ('LINEAR', s.n_feed_moves), 'n_traverses': ('RAPID', s.n_traverses),
             'n_arcs': ('ARC_CW', s.n_arcs), 'n_dwells': ('DWELL', s.n_dwells)}
    for key, (kind, n) in kinds.items():
        if n != ref.get(key):
            # The line where the counts part is found by the move-by-move trace (--locate).
            out.append(Disagreement(file, key, n, ref.get(key)))
    lengths = (('feed_path_length_mm', s.feed_length_m), ('traverse_path_length_mm',
                                                          s.traverse_length_m))
    for key, metres in lengths:
        mm = metres * 1e3
        if not _close(mm, float(ref.get(key, math.nan)), rel=REL_LENGTH_TOL,
                      absolute=ABS_LENGTH_TOL_MM):
            out.append(Disagreement(file, key, f'{mm:.4f}', ref.get(key)))
    if not _close(s.dwell_s, float(ref.get('dwell_s_total', math.nan)), rel=REL_LENGTH_TOL,
                  absolute=DWELL_TOL_S):
        out.append(Disagreement(file, 'dwell_s_total', f'{s.dwell_s:.4f}',
                                ref.get('dwell_s_total')))
    fin = [v * 1e3 for v in s.final_position]
    if not _near(fin, ref.get('final_position')):
        out.append(Disagreement(file, 'final_position', _fmt(fin), ref.get('final_position')))
    if hasattr(s, 'rotary_travel_deg'):
        out += _compare_rotary(file, s, ref)
    box = ref.get('bbox_mm')
    if s.bbox_min is None or box is None:
        if not (s.bbox_min is None and box is None):
            ours_box = None if s.bbox_min is None else 'a box'
            out.append(Disagreement(file, 'bbox_mm', ours_box, 'a box' if box else None))
    else:
        lo = [v * 1e3 for v in s.bbox_min]
        hi = [v * 1e3 for v in s.bbox_max]
        if not (_near(lo, box.get('min')) and _near(hi, box.get('max'))):
            out.append(Disagreement(file, 'bbox_mm', f'{_fmt(lo)}..{_fmt(hi)}',
                                    f'{box.get("min")}..{box.get("max")}'))
    return out


def _near(ours: list[float], ref: Any) -> bool:
    if not isinstance(ref, list) or len(ref) != 3:
        return False
    return all(abs(a - float(b)) <= POSITION_TOL_MM for a, b in zip(ours, ref))


def _fmt(v: list[float]) -> str:
    return '[' + ', '.join(f'{x:.4f}' for x in v) + ']'


_KIND_NAMES = {'RAPID': 'traverse', 'LINEAR': 'feed', 'ARC_CW': 'arc', 'ARC_CCW': 'arc',
               'DWELL': 'dwell'}


def reference_trace(path: Path, *, timeout_s: float = 120.0) -> list[list[Any]] | None:
    """The reference's canonical calls for one program (``bench/oracle_trace.py``).

    Returns ``None`` where LinuxCNC's ``gcode`` module or the oracle script is missing.
    """
    if not os.path.exists('/usr/bin/python3'):
        return None
    try:
        proc = subprocess.run(['/usr/bin/python3', str(ROOT / 'bench' / 'oracle_trace.py'),
                               str(path)], capture_output=True, text=True,
                              timeout=timeout_s + 30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    if proc.returncode != 0 or not proc.stdout.strip():
        return None
    return json.loads(proc.stdout.strip().splitlines()[-1]).get('trace')


def first_difference(moves: list[Any], trace: list[list[Any]]) -> str:
    """Describe the first canonical call where our moves and the reference's trace differ.

    Parameters
    ----------
    moves
        Our moves (STOP moves are skipped: the reference's trace has none).
    trace
        The reference's ``[kind, line, x, y, z, length]`` / ``[dwell, line, s]`` calls.

    Returns
    -------
    str
        ``''`` when the sequences agree, else the index, kind, line and end point of both.
    """
    # A rigid tap's way back is part of the reference's one 'tap' call (length in and back).
    ours = [m for m in moves if m.kind.name in _KIND_NAMES and not m.tap_return]
    for i in range(max(len(ours), len(trace))):
        if i >= len(ours):
            return f'move {i}: ours ended; reference {_call(trace[i])}'
        m = ours[i]
        kind = _KIND_NAMES[m.kind.name]
        if i >= len(trace):
            return f'move {i}: ours {kind} line {m.line}; reference ended'
        ref = trace[i]
        same = kind == ref[0] or (kind == 'feed' and ref[0] in ('probe', 'tap'))
        if same and kind == 'dwell':
            same = abs(m.dwell_s - ref[2]) <= DWELL_TOL_S
        elif same:
            same = all(abs(a * 1e3 - b) <= POSITION_TOL_MM for a, b in zip(m.end, ref[2:5]))
            length = m.length_m if kind == 'arc' else math.dist(m.start, m.end)
            if ref[0] == 'tap':
                length *= 2.0
            if same and len(ref) > 5:
                same = _close(length * 1e3, ref[5], rel=REL_LENGTH_TOL,
                              absolute=ABS_LENGTH_TOL_MM)
        if not same:
            if kind == 'dwell':
                end = f'{m.dwell_s:g} s'
            else:
                length = m.length_m if kind == 'arc' else math.dist(m.start, m.end)
                end = f'{_fmt([v * 1e3 for v in m.end])} length {length * 1e3:.4f} mm'
            return (f'move {i}: ours {kind} line {m.line} to {end}; '
                    f'reference {_call(ref)}')
    return ''


def _call(ref: list[Any]) -> str:
    if ref[0] == 'dwell':
        return f'dwell line {ref[1]} {ref[2]:g} s'
    length = f' length {ref[5]:.4f} mm' if len(ref) > 5 else ''
    return f'{ref[0]} line {ref[1]} to {_fmt(ref[2:5])}{length}'


def reference_available() -> bool:
    """True when LinuxCNC's ``gcode`` module can be imported by /usr/bin/python3."""
    if not os.path.exists('/usr/bin/python3'):
        return False
    try:
        proc = subprocess.run(['/usr/bin/python3', '-c', 'import gcode; gcode.parse'],
                              capture_output=True, cwd='/', timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return proc.returncode == 0


def locate(corpus: Path, file: str) -> str:
    """First difference between us and the reference on one corpus program ('' if none)."""
    path = corpus / file
    trace = reference_trace(path)
    if trace is None:
        return 'reference trace not available'
    links = SubroutineLinks()
    try:
        kw = _parse_keywords(REFERENCE_DIALECT, [links.for_folder(path.parent), path.parent])
        moves = list(load_gcode(path, **kw).moves)
    except FeedAxisError as err:
        return f'ours refused: {err}'
    finally:
        links.close()
    return first_difference(moves, trace)


# --------------------------------------------------------------------------------------
# the whole corpus
# --------------------------------------------------------------------------------------
@dataclass
class Report:
    """Everything the corpus run found."""

    corpus: str
    entries: list[Entry]
    accept: dict[str, OurResult]               # parsed with the program's own dialect
    agree: dict[str, OurResult]                # parsed with the reference's dialect
    disagreements: list[Disagreement]
    skipped: list[str]
    seconds: float
    planned: bool = False
    located: dict[str, str] = field(default_factory=dict)   # file -> first difference
    # file -> the reference quirks (bench/oracle_quirks.py) that reproduce its disagreement
    explained: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def unexplained_files(self) -> list[str]:
        """Disagreeing programs that no model of a reference quirk reproduces."""
        return [f for f in self.disagreeing_files() if f not in self.explained]

    def tracebacks(self) -> list[tuple[str, OurResult]]:
        """Programs on which our side raised something other than GcodeError (or hung)."""
        out = []
        for results in (self.accept, self.agree):
            for name, r in results.items():
                if r.status in ('traceback', 'timeout') and (name, r) not in out:
                    out.append((name, r))
        return out

    def refused_but_accepted(self) -> list[tuple[Entry, OurResult]]:
        """Programs the reference runs to the end and we refuse."""
        return [(e, self.accept[e.file]) for e in self.entries
                if e.file in self.accept and e.reference_accepts
                and self.accept[e.file].status != 'ok']

    def disagreeing_files(self) -> list[str]:
        """Programs with at least one disagreement, in corpus order."""
        bad = {d.file for d in self.disagreements}
        return [e.file for e in self.entries if e.file in bad]


def _dialect_for(entry: Entry, known: tuple[str, ...]) -> str | None:
    return entry.dialect if entry.dialect in known else None


def evaluate(corpus: Path, *, plan: bool = False, skip_largest: int = 0,
             timeout_s: float = DEFAULT_TIMEOUT_S,
             progress: Callable[[str], None] | None = None,
             tool_table: bool = True) -> Report:
    """Run our front end over the corpus and compare with the reference.

    Parameters
    ----------
    corpus
        The corpus folder (``programs.csv``, ``oracle.json``, one folder per repository).
    plan
        Also plan every accepted program (``config/three_axis_mill.yaml``).
    skip_largest
        Leave out the programs with the most lines (for a quick run).
    timeout_s
        Wall-clock limit per program.
    progress
        Called with one line per program.
    tool_table
        As :func:`run_ours` (``False``: how programs fare on a config without a tool
        table; the programs using a tool are then counted with the missing-tool warning).

    Returns
    -------
    Report
        Results per program, disagreements and the programs skipped.
    """
    t0 = time.perf_counter()
    entries = load_corpus(corpus)
    skipped: list[str] = []
    if skip_largest > 0:
        largest = sorted(entries, key=lambda e: e.lines, reverse=True)[:skip_largest]
        skipped = [e.file for e in largest]
        entries = [e for e in entries if e.file not in set(skipped)]
    planner = make_planner(ROOT / 'config' / 'three_axis_mill.yaml') if plan else None
    known = known_dialects()
    links = SubroutineLinks()
    accept: dict[str, OurResult] = {}
    agree: dict[str, OurResult] = {}
    disagreements: list[Disagreement] = []
    explained: dict[str, tuple[str, ...]] = {}
    try:
        for i, e in enumerate(entries, 1):
            path = corpus / e.file
            search = [links.for_folder(path.parent), path.parent]
            own = _dialect_for(e, known)
            r = run_ours(path, dialect=own, search_path=search, timeout_s=timeout_s,
                         planner=planner, tool_table=tool_table)
            r.error = links.real_names(r.error)
            accept[e.file] = r
            if e.reference_accepts:
                if own in (None, REFERENCE_DIALECT) or REFERENCE_DIALECT not in known:
                    ra = r
                else:
                    ra = run_ours(path, dialect=REFERENCE_DIALECT, search_path=search,
                                  timeout_s=timeout_s, tool_table=tool_table)
                agree[e.file] = ra
                if ra.status == 'ok':
                    found = compare(e.file, ra, e.oracle)
                    disagreements += found
                    if found:
                        quirks = _explain(e, path, search, timeout_s, tool_table)
                        if quirks:
                            explained[e.file] = quirks
            if progress is not None:
                progress(f'[{i}/{len(entries)}] {r.status:9s} {r.seconds:6.2f} s  {e.file}')
    finally:
        links.close()
    return Report(corpus=str(corpus), entries=entries, accept=accept, agree=agree,
                  disagreements=disagreements, skipped=skipped,
                  seconds=time.perf_counter() - t0, planned=plan, explained=explained)


def _explain(entry: Entry, path: Path, search: list[Path], timeout_s: float,
             tool_table: bool = True) -> tuple[str, ...] | None:
    """The reference quirks under which a disagreeing program agrees (None: no model does)."""
    dialect = REFERENCE_DIALECT if REFERENCE_DIALECT in known_dialects() else None

    def run() -> OurResult:
        return run_ours(path, dialect=dialect, search_path=search, timeout_s=timeout_s,
                        tool_table=tool_table)
    return oracle_quirks.explain(
        run, lambda r: r.status == 'ok' and not compare(entry.file, r, entry.oracle))


# --------------------------------------------------------------------------------------
# output
# --------------------------------------------------------------------------------------
def acceptance_table(report: Report) -> list[dict[str, Any]]:
    """Rows per dialect (and a total): programs, accepted by the reference, by us, by both."""
    rows: dict[str, Counter] = {}
    for e in report.entries:
        ours_ok = report.accept[e.file].status == 'ok'
        for key in (e.dialect, 'all'):
            c = rows.setdefault(key, Counter())
            c['programs'] += 1
            c['reference'] += e.reference_accepts
            c['ours'] += ours_ok
            c['both'] += ours_ok and e.reference_accepts
            c['agree'] += (e.reference_accepts and e.file in report.agree
                           and report.agree[e.file].status == 'ok'
                           and e.file not in set(report.disagreeing_files()))
    order = sorted(k for k in rows if k != 'all') + ['all']
    empty = dict(programs=0, reference=0, ours=0, both=0, agree=0)
    return [dict(empty, dialect=k, **rows.get(k, {})) for k in order]


def summary(report: Report) -> dict[str, Any]:
    """The figures of the issue's targets."""
    total = acceptance_table(report)[-1]
    ref = total['reference']
    rate = total['both'] / ref if ref else 0.0
    # The target counts programs "on a machine with the axes they use": ours have X, Y, Z.
    linear = [e for e in report.entries if e.reference_accepts and not e.rotary]
    both_linear = sum(1 for e in linear if report.accept[e.file].status == 'ok')
    preview = [e for e in report.entries if e.reference_accepts
               and report.accept[e.file].status == 'ok' and report.accept[e.file].preview_only]
    tooled = [e for e in report.entries if e.reference_accepts
              and report.accept[e.file].status == 'ok' and report.accept[e.file].missing_tools]
    return dict(programs=total['programs'], reference_accepts=ref, we_accept=total['ours'],
                preview_only=len(preview), missing_tools=len(tooled),
                we_accept_of_reference=total['both'], acceptance_of_reference=rate,
                reference_accepts_xyz=len(linear), we_accept_of_reference_xyz=both_linear,
                acceptance_of_reference_xyz=both_linear / len(linear) if linear else 0.0,
                target_acceptance=TARGET_ACCEPTANCE, tracebacks=len(report.tracebacks()),
                disagreeing_programs=len(report.disagreeing_files()),
                disagreements=len(report.disagreements),
                explained_programs=len(report.explained),
                unexplained_programs=len(report.unexplained_files()),
                agreeing_programs=total['agree'], seconds=report.seconds)


def format_report(report: Report) -> str:
    """The human-readable report."""
    out = [f'corpus {report.corpus}: {len(report.entries)} programs'
           + (f' ({len(report.skipped)} largest skipped: {", ".join(report.skipped)})'
              if report.skipped else '')]
    out.append('')
    out.append('acceptance per dialect (ours: parsed with the program\'s dialect; agree: '
               'both accept and every figure matches)')
    head = ('dialect', 'programs', 'reference', 'ours', 'both', 'agree')
    out.append('  '.join(f'{h:>9s}' for h in head))
    for row in acceptance_table(report):
        out.append('  '.join(f'{row[h]:>9}' for h in head))
    refused = report.refused_but_accepted()
    out.append('')
    out.append(f'refused by us, accepted by the reference: {len(refused)}')
    prefix = report.corpus.rstrip('/') + '/'
    for e, r in refused:
        msg = r.error.replace(prefix, '')
        if not msg.startswith(e.file):
            msg = f'{e.file}: {msg}'    # the error lies in a subroutine file it calls
        out.append(f'  [{e.dialect}] {_one_line(msg)}')
    preview = [(e, report.accept[e.file]) for e in report.entries if e.reference_accepts
               and report.accept[e.file].status == 'ok' and report.accept[e.file].preview_only]
    out.append('')
    out.append(f'accepted only as a preview (a feed move with no F set: the reference\'s '
               f'preview starts at F1, the control refuses; --allow-no-feed): {len(preview)}')
    for e, r in preview:
        out.append(f'  [{e.dialect}] {_one_line(r.preview_only.replace(prefix, ""))}')
    out.append('')
    out.append(f'disagreements on programs both accept: {len(report.disagreements)} in '
               f'{len(report.disagreeing_files())} programs')
    for d in report.disagreements:
        out.append(f'  {d.text()}')
    if report.explained:
        out.append('reproduced by a model of a quirk of the reference run '
                   '(bench/oracle_quirks.py): the program agrees when our interpreter copies it')
        for name, quirks in report.explained.items():
            out.append(f'  {name}: {", ".join(quirks)}')
        for quirk in sorted({q for qs in report.explained.values() for q in qs}):
            out.append(f'    {quirk}: {oracle_quirks.QUIRKS[quirk]}')
    if report.located:
        out.append('first difference move by move (reference trace, bench/oracle_trace.py):')
        for name, where in report.located.items():
            out.append(f'  {name}: {where or "the move sequences agree"}')
    tbs = report.tracebacks()
    out.append('')
    out.append(f'tracebacks and timeouts: {len(tbs)}')
    for name, r in tbs:
        out.append(f'  {name}: {r.status}: {r.error}')
    if report.planned:
        bad = [(n, r.plan) for n, r in report.accept.items()
               if r.status == 'ok' and not r.plan.startswith('ok')]
        out.append('')
        n_ok = sum(1 for r in report.accept.values() if r.status == 'ok')
        out.append(f'planned on three_axis_mill: {n_ok - len(bad)} ok, {len(bad)} refused by '
                   f'the planner')
        for n, msg in bad:
            out.append(f'  {n}: {_one_line(msg)}')
    s = summary(report)
    out.append('')
    out.append(f'SUMMARY acceptance {s["we_accept_of_reference"]}/{s["reference_accepts"]} of '
               f'the programs the reference accepts = {100 * s["acceptance_of_reference"]:.1f} %, '
               f'{s["we_accept_of_reference_xyz"]}/{s["reference_accepts_xyz"]} = '
               f'{100 * s["acceptance_of_reference_xyz"]:.1f} % of those without rotary-axis '
               f'motion (target >= {100 * TARGET_ACCEPTANCE:.0f} %), all programs '
               f'{s["we_accept"]}/{s["programs"]}, {s["preview_only"]} of the accepted only '
               f'as a preview (--allow-no-feed), {s["missing_tools"]} with tools the table '
               f'lacks (length and radius 0); tracebacks {s["tracebacks"]} (target 0); '
               f'disagreements {s["disagreements"]} in {s["disagreeing_programs"]} programs, '
               f'{s["explained_programs"]} of them reproduced by reference quirks, '
               f'{s["unexplained_programs"]} unexplained (target 0); {s["seconds"]:.1f} s')
    return '\n'.join(out)


def _one_line(text: str, limit: int = 240) -> str:
    text = ' '.join(str(text).split())
    return text if len(text) <= limit else text[:limit] + '...'


def report_json(report: Report) -> dict[str, Any]:
    """The report as one JSON-ready object."""
    def result(r: OurResult) -> dict[str, Any]:
        d: dict[str, Any] = dict(status=r.status, error=r.error or None, line=r.line,
                                 column=r.column, warnings=r.warnings,
                                 seconds=round(r.seconds, 4))
        if r.plan:
            d['plan'] = r.plan
        if r.preview_only:
            d['preview_only'] = r.preview_only
        return d
    return dict(
        corpus=report.corpus, skipped=report.skipped, summary=summary(report),
        acceptance=acceptance_table(report),
        refused_but_reference_accepts=[dict(file=e.file, dialect=e.dialect, error=r.error)
                                       for e, r in report.refused_but_accepted()],
        disagreements=[dict(file=d.file, what=d.what, ours=d.ours, reference=d.reference,
                            line=d.line) for d in report.disagreements],
        first_difference=report.located,
        explained={k: list(v) for k, v in report.explained.items()},
        tracebacks=[dict(file=n, status=r.status, error=r.error)
                    for n, r in report.tracebacks()],
        programs={e.file: dict(dialect=e.dialect, reference=e.oracle.get('status'),
                               ours=result(report.accept[e.file]))
                  for e in report.entries})


# --------------------------------------------------------------------------------------
# memory of a long program
# --------------------------------------------------------------------------------------
def write_cam_program(path: Path, n_lines: int) -> None:
    """Write an ``n_lines`` CAM-like program (3-axis raster with arcs at the row ends).

    Streams to the file (a million lines never sit in memory).
    """
    with open(path, 'w', encoding='ascii') as fh:
        fh.write('%\n(CAM-LIKE RASTER FOR THE MEMORY FIGURE)\nG21 G90 G94 G17\n'
                 'G0 Z5.000\nG0 X0.000 Y0.000\nG1 Z-1.000 F300\n')
        written = 6
        y = 0.0
        x = 0.0
        direction = 1.0
        row = 0
        while written < n_lines - 2:
            # A row of short feed moves with a varying Z (a 3D surface finish pass) ...
            for _ in range(48):
                x += 0.5 * direction
                z = -1.0 - 0.2 * math.sin(0.05 * x + 0.1 * row)
                fh.write(f'G1 X{x:.3f} Y{y:.3f} Z{z:.3f}\n')
                written += 1
            # ... turned round by a half circle.
            y_next = y + 1.0
            fh.write(f'G{3 if direction > 0 else 2} X{x:.3f} Y{y_next:.3f} J0.500 F600\n')
            written += 1
            y = y_next
            direction = -direction
            row += 1
            if row % 100 == 0:
                x = 0.0
                y = 0.0
                fh.write('G0 Z5.000\nG0 X0.000 Y0.000\nG1 Z-1.000 F300\n')
                written += 3
        fh.write('G0 Z5.000\nM30\n')


_CHILD = textwrap.dedent('''
    import sys, time
    sys.path.insert(0, sys.argv[2])

    def status_kb(key):
        # VmHWM (peak) belongs to this process image: unlike ru_maxrss it does not carry
        # the forking parent's peak over the exec.
        with open('/proc/self/status') as fh:
            for line in fh:
                if line.startswith(key + ':'):
                    return int(line.split()[1])
        return 0

    import feed_axis_energy.gcode.load as g
    from feed_axis_energy.gcode.stats import MoveStats
    base = status_kb('VmRSS')
    t0 = time.perf_counter()
    acc = MoveStats()
    if sys.argv[3] == 'stream' and hasattr(g, 'iter_moves'):
        for m in g.iter_moves(sys.argv[1]):
            acc.add(m)
        how = 'iter_moves (streaming)'
    else:
        prog = g.load_gcode(sys.argv[1])
        for m in prog.moves:
            acc.add(m)
        how = 'load_gcode (whole Program)'
    dt = time.perf_counter() - t0
    peak = status_kb('VmHWM')
    s = acc.result()
    print(how, dt, base, peak, s.n_motions)
''')


def memory_figure(n_lines: int, *, mode: str = 'stream') -> dict[str, Any]:
    """Peak resident memory of parsing an ``n_lines`` CAM-like program in a child process.

    Parameters
    ----------
    n_lines
        Program length.
    mode
        ``'stream'`` (``iter_moves`` where the front end has it) or ``'whole'``
        (``load_gcode``: the whole :class:`Program`).

    Returns
    -------
    dict
        ``lines``, ``file_mb``, ``how``, ``seconds``, ``rss_before_mb`` (after imports),
        ``peak_rss_mb``, ``moves``; or ``error``.
    """
    with tempfile.TemporaryDirectory(prefix='fae-mem-') as tmp:
        path = Path(tmp) / 'cam_raster.nc'
        write_cam_program(path, n_lines)
        size = path.stat().st_size
        proc = subprocess.run([sys.executable, '-c', _CHILD, str(path), str(ROOT), mode],
                              capture_output=True, text=True, timeout=1800)
    if proc.returncode != 0:
        return dict(lines=n_lines, error=_one_line(proc.stderr.strip().splitlines()[-1]
                                                   if proc.stderr.strip() else 'failed'))
    how, dt, base, peak, moves = proc.stdout.strip().rsplit('\n', 1)[-1].rsplit(' ', 4)
    # /proc/self/status figures are in KiB.
    return dict(lines=n_lines, file_mb=round(size / 1e6, 1), how=how, seconds=round(float(dt), 2),
                rss_before_mb=round(int(base) / 1024, 1), peak_rss_mb=round(int(peak) / 1024, 1),
                moves=int(moves))


def main(argv: list[str] | None = None) -> int:
    """Command line: see the module docstring."""
    ap = argparse.ArgumentParser(
        prog='bench/corpus.py', description=__doc__.split('\n\n')[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog='Exit status: 0 report printed, 1 corpus not found, 2 usage error.')
    ap.add_argument('--corpus', help='corpus folder (default: $FAE_SHARED/corpus/gcode, '
                                     'else ../shared/corpus/gcode beside the repository)')
    ap.add_argument('--plan', action='store_true',
                    help='also plan every accepted program on config/three_axis_mill.yaml')
    ap.add_argument('--json', action='store_true', help='print one JSON object')
    ap.add_argument('--mem-lines', type=int, default=1_000_000, metavar='N',
                    help='lines of the generated program for the memory figure '
                         '(default 1000000; 0: skip)')
    ap.add_argument('--mem-mode', choices=('stream', 'whole'), default='stream',
                    help='parse the memory program with iter_moves (default, if the front end '
                         'has it) or load_gcode')
    ap.add_argument('--skip-largest', type=int, default=0, metavar='K',
                    help='leave out the K programs with the most lines')
    ap.add_argument('--timeout', type=float, default=DEFAULT_TIMEOUT_S, metavar='S',
                    help=f'wall-clock limit per program [s] (default {DEFAULT_TIMEOUT_S:g})')
    ap.add_argument('--locate', choices=('auto', 'yes', 'no'), default='auto',
                    help='run the reference move by move on each disagreeing program and '
                         'print the first differing move and its line (needs '
                         'linuxcnc-uspace; auto, the default: when it is installed and at '
                         f'most {MAX_AUTO_LOCATE} programs disagree)')
    ap.add_argument('--no-tool-table', action='store_true',
                    help='parse without a tool table (the reference had tools 1..999 of zero '
                         'size): tools the programs use run with length and radius 0 and a '
                         'warning; counted as "missing tools" in the summary')
    ap.add_argument('--quiet', action='store_true', help='no progress on stderr')
    args = ap.parse_args(argv)
    if args.mem_lines < 0 or args.skip_largest < 0 or not args.timeout > 0:
        ap.error('--mem-lines and --skip-largest must be >= 0, --timeout > 0')
    corpus = find_corpus(args.corpus)
    if corpus is None or not (corpus / 'oracle.json').is_file():
        where = f'at {args.corpus}' if args.corpus else f'found; give --corpus DIR or {HINT}'
        print(f'error: no corpus (programs.csv + oracle.json) {where}', file=sys.stderr)
        return 1

    def progress(msg: str) -> None:
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)

    report = evaluate(corpus, plan=args.plan, skip_largest=args.skip_largest,
                      timeout_s=args.timeout, progress=progress,
                      tool_table=not args.no_tool_table)
    bad = report.disagreeing_files()
    if args.locate == 'yes' or (args.locate == 'auto' and 0 < len(bad) <= MAX_AUTO_LOCATE
                                and reference_available()):
        for name in bad:
            progress(f'locating the first difference in {name} ...')
            report.located[name] = locate(corpus, name)
    mem = None
    if args.mem_lines:
        progress(f'memory figure: parsing a generated {args.mem_lines}-line program ...')
        mem = memory_figure(args.mem_lines, mode=args.mem_mode)
    if args.json:
        doc = report_json(report)
        doc['memory'] = mem
        print(json.dumps(doc, indent=1))
    else:
        print(format_report(report))
        if mem is not None:
            if 'error' in mem:
                print(f'MEMORY {mem["lines"]} lines: failed: {mem["error"]}')
            else:
                print(f'MEMORY {mem["lines"]} lines ({mem["file_mb"]} MB) with {mem["how"]}: '
                      f'peak RSS {mem["peak_rss_mb"]} MB (after imports {mem["rss_before_mb"]} '
                      f'MB), {mem["seconds"]} s, {mem["moves"]} motions')
    return 0


if __name__ == '__main__':
    sys.exit(main())
