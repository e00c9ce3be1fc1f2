"""What a campaign is made of: programs (files, globs, directories) x machines x loads.

The jobs of a campaign come from the command line or from a small YAML file read through
:func:`.safeyaml.load_yaml_file`::

    programs: [parts/*.nc, fixtures/, extra/probe.ngc]   # files, globs, directories
    machines: [config/demonstrator.yaml]                 # optional (default: demonstrator)
    loads_kg: [0, 17.336, 22.711]                        # optional (default: [0])
    rate_hz: 1000                                        # optional (default: the machine's)
    profile: jerk                                        # optional (default: the machine's)

Relative paths in the file are relative to the file's directory. A directory stands for its
G-code files (:data:`GCODE_SUFFIXES`, not its subdirectories), a glob (``*``, ``?``, ``[``)
for the files it matches, sorted by name; a glob or directory with no program is an error,
while a named file that cannot be read becomes a failed job (the campaign goes on).
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
import glob
import itertools
import os
from pathlib import Path
import re
from typing import Any

from .batch import BatchJob, MAX_JOBS, PROFILES
from ..errors import ConfigError, describe, shorten
from ..outputs import confined

__all__ = ['GCODE_SUFFIXES', 'BatchSpec', 'expand_programs', 'make_jobs', 'load_batch_file',
           'bag_name']

GCODE_SUFFIXES = ('.nc', '.ngc', '.gcode', '.tap', '.cnc')
"""File name endings taken as programs when a directory is named (case-insensitive)."""
_GLOB_CHARS = frozenset('*?[')
_KEYS = ('programs', 'machines', 'loads_kg', 'rate_hz', 'profile')


@dataclass(frozen=True)
class BatchSpec:
    """The inputs of a batch file (shown names with their absolute paths).

    Attributes
    ----------
    programs
        ``(shown, absolute path)`` of every program.
    machines
        ``(shown, absolute path)`` of every machine config; empty: the default machine.
    loads_kg
        Workpiece masses [kg]; empty: ``[0]``.
    rate_hz, profile
        Overrides of the machines' planner settings, or ``None``.
    """

    programs: tuple[tuple[str, str], ...]
    machines: tuple[tuple[str, str], ...] = ()
    loads_kg: tuple[float, ...] = ()
    rate_hz: float | None = None
    profile: str | None = None


def _absolute(path: str, base: Path | None) -> str:
    p = Path(path).expanduser()
    if not p.is_absolute() and base is not None:
        p = base / p
    return os.path.abspath(p)


def expand_programs(items: Iterable[str], *, base: Path | None = None,
                    where: str = 'command line') -> list[tuple[str, str]]:
    """Turn program arguments (files, globs, directories) into ``(shown, absolute)`` pairs.

    Parameters
    ----------
    items
        As given; relative ones are relative to ``base`` (``None``: the working directory).
    base
        Directory of relative names (a batch file's directory).
    where
        Source of the names, for messages (``'command line'`` or the batch file).

    Returns
    -------
    list of (str, str)
        In argument order; a glob's or directory's files sorted by name.

    Raises
    ------
    ConfigError
        A glob or directory without programs, or more than :data:`.batch.MAX_JOBS` programs.
    """
    out: list[tuple[str, str]] = []
    for item in items:
        full = _absolute(item, base)
        if _GLOB_CHARS & set(item):
            found = _limited(glob.iglob(full, recursive=True), where=where)
            files = sorted(f for f in found if os.path.isfile(f))
            if not files:
                msg = f'no program file matches {shorten(item)!r}'
                raise ConfigError(msg, file=where, key='programs')
            start = os.getcwd() if base is None else str(base)
            out += [(f if os.path.isabs(item) else os.path.relpath(f, start), f)
                    for f in files]
        elif os.path.isdir(full):
            entries = _limited((e.path for e in os.scandir(full)), where=where)
            files = sorted(f for f in entries
                           if f.lower().endswith(GCODE_SUFFIXES) and os.path.isfile(f))
            if not files:
                msg = (f'directory {shorten(item)!r} holds no program '
                       f'({", ".join(GCODE_SUFFIXES)})')
                raise ConfigError(msg, file=where, key='programs')
            out += [(os.path.join(item, os.path.basename(f)), f) for f in files]
        else:
            out.append((item, full))
        if len(out) > MAX_JOBS:
            msg = f'more than {MAX_JOBS:,} programs; split the campaign'
            raise ConfigError(msg, file=where, key='programs')
    return out


def _limited(paths: Iterable[str], *, where: str) -> list[str]:
    """At most MAX_JOBS + 1 entries, so a huge directory is not listed whole."""
    found = list(itertools.islice(paths, MAX_JOBS + 1))
    if len(found) > MAX_JOBS:
        msg = f'more than {MAX_JOBS:,} files match; split the campaign'
        raise ConfigError(msg, file=where, key='programs')
    return found


def make_jobs(programs: Sequence[tuple[str, str]], machines: Sequence[tuple[str, str]],
              loads_kg: Sequence[float], *, rate_hz: float | None = None,
              profile: str | None = None, top_blocks: int = 0,
              max_samples: int = 0, out_dir: str | os.PathLike[str] | None = None,
              force: bool = False, compression: str = 'zstd', strict_tools: bool = False,
              allow_no_feed: bool = False,
              subroutine_path: Sequence[str] = (), method: str = 'phases') -> list[BatchJob]:
    """Every program x machine x load, program-major (program 1 on every machine first).

    Parameters
    ----------
    programs, machines
        ``(shown, absolute path)`` pairs (:func:`expand_programs`).
    loads_kg
        Workpiece masses [kg].
    rate_hz, profile, top_blocks, max_samples
        As :class:`.batch.BatchJob`.
    out_dir
        Directory for one recording per job, named by :func:`bag_name`; ``None``: none.
    force, compression, strict_tools, allow_no_feed, subroutine_path, method
        As :class:`.batch.BatchJob`.

    Returns
    -------
    list of BatchJob
        Indexed 0.. in that order.

    Raises
    ------
    ConfigError
        No jobs, more than :data:`.batch.MAX_JOBS`, or an invalid load, rate or profile.
    """
    count = len(programs) * len(machines) * len(loads_kg)
    if count == 0:
        msg = 'no jobs: give at least one program, machine and load'
        raise ConfigError(msg, file='batch')
    if count > MAX_JOBS:
        msg = (f'{len(programs)} programs x {len(machines)} machines x {len(loads_kg)} loads '
               f'= {count:,} jobs, more than {MAX_JOBS:,}; split the campaign')
        raise ConfigError(msg, file='batch')
    jobs = []
    for i, ((prog, prog_path), (mach, mach_path), load) in enumerate(
            itertools.product(programs, machines, loads_kg)):
        out = ''
        if out_dir is not None:
            name = bag_name(i, count, prog_path, mach_path if len(machines) > 1 else None,
                            float(load) if len(loads_kg) > 1 else None)
            out = os.path.abspath(confined(out_dir, name, option='--out'))
        jobs.append(BatchJob(index=i, program=prog, program_path=prog_path, machine=mach,
                             machine_path=mach_path, load_kg=float(load), rate_hz=rate_hz,
                             profile=profile, top_blocks=top_blocks,
                             max_samples=max_samples, out=out, force=force,
                             compression=compression, strict_tools=bool(strict_tools),
                             allow_no_feed=bool(allow_no_feed),
                             subroutine_path=tuple(subroutine_path), method=method))
    return jobs


def _plain(text: str) -> str:
    """Letters, digits, ``.``, ``_`` and ``-`` of ``text`` (others as ``_``), at most 40."""
    return re.sub(r'[^A-Za-z0-9._-]+', '_', text)[:40].strip('._-') or 'x'


def bag_name(index: int, count: int, program: str, machine: str | None = None,
             load_kg: float | None = None) -> str:
    """The recording's name of job ``index`` (0-based) of ``count``.

    The 1-based job number, zero-padded to the width of ``count`` (unique and sorting in
    job order), then the program file's stem, and the machine file's stem and the load
    when the campaign has several: ``007-part_a-three_axis_mill-17.336kg``. Characters other
    than letters, digits, ``.``, ``_`` and ``-`` become ``_``; each part at most 40.
    """
    parts = [f'{index + 1:0{len(str(count))}d}', _plain(Path(program).stem)]
    if machine is not None:
        parts.append(_plain(Path(machine).stem))
    if load_kg is not None:
        parts.append(_plain(f'{load_kg:g}kg'))
    return '-'.join(parts)


def _text_list(value: Any, key: str, *, file: str) -> list[str]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not value:
        msg = f'expected a non-empty list of paths, got {describe(value)}'
        raise ConfigError(msg, file=file, key=key)
    for i, item in enumerate(value):
        if not isinstance(item, str) or not item.strip() or '\0' in item:
            msg = f'expected a path (text), got {describe(item)}'
            raise ConfigError(msg, file=file, key=f'{key}[{i}]')
    return value


def _number(value: Any, key: str, *, file: str, low: float, high: float,
            low_open: bool = False) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if ok:
        x = float(value)
        ok = (low < x if low_open else low <= x) and x <= high   # refuses nan and inf
    if not ok:
        bound = '>' if low_open else '>='
        msg = f'expected a number {bound} {low:g} and <= {high:g}, got {describe(value)}'
        raise ConfigError(msg, file=file, key=key)
    return float(value)


def load_batch_file(path: str | Path) -> BatchSpec:
    """Read a batch file (format in the module docstring).

    Parameters
    ----------
    path
        The YAML file.

    Returns
    -------
    BatchSpec
        Programs expanded, paths made absolute (relative to the file's directory).

    Raises
    ------
    ConfigError
        Naming the file and key: unreadable or invalid YAML, an unknown key, a wrong type,
        a load, rate or profile out of range, a glob or directory without programs.
    """
    from ..safeyaml import load_yaml_file
    file = str(path)
    data = load_yaml_file(path, what='batch file')
    if not isinstance(data, dict):
        msg = f'expected a mapping with the key "programs", got {describe(data)}'
        raise ConfigError(msg, file=file)
    for key in data:
        if key not in _KEYS:
            msg = f'unknown key (expected {", ".join(_KEYS)})'
            raise ConfigError(msg, file=file, key=shorten(str(key)))
    if 'programs' not in data:
        raise ConfigError('missing (a list of program files, globs or directories)',
                          file=file, key='programs')
    base = Path(os.path.abspath(path)).parent
    programs = expand_programs(_text_list(data['programs'], 'programs', file=file),
                               base=base, where=file)
    machines: list[tuple[str, str]] = []
    if data.get('machines') is not None:
        machines = [(m, _absolute(m, base))
                    for m in _text_list(data['machines'], 'machines', file=file)]
    loads: list[float] = []
    if data.get('loads_kg') is not None:
        raw = data['loads_kg'] if isinstance(data['loads_kg'], list) else [data['loads_kg']]
        if not raw or len(raw) > MAX_JOBS:
            msg = f'expected a list of 1 to {MAX_JOBS} masses [kg], got {describe(raw)}'
            raise ConfigError(msg, file=file, key='loads_kg')
        loads = [_number(v, f'loads_kg[{i}]', file=file, low=0.0, high=1e6)
                 for i, v in enumerate(raw)]
    rate = None
    if data.get('rate_hz') is not None:
        rate = _number(data['rate_hz'], 'rate_hz', file=file, low=0.0, high=1e6, low_open=True)
    profile = data.get('profile')
    if profile is not None and profile not in PROFILES:
        msg = f'expected one of {", ".join(PROFILES)}, got {describe(profile)}'
        raise ConfigError(msg, file=file, key='profile')
    return BatchSpec(programs=tuple(programs), machines=tuple(machines),
                     loads_kg=tuple(loads), rate_hz=rate, profile=profile)
