"""The G-code part of a machine config: dialect, tool table, how programs are read, and axis
travel limits.

A machine file may hold (all optional)::

    gcode:
      dialect: linuxcnc            # default G-code dialect (``--dialect`` overrides it)
      tools:                       # tool table: T number -> radius and length offset
        1: {radius_m: 0.003, length_m: 0.0452}
        2: {radius_m: 0.0, length_m: 0.06}
      strict_tools: false          # true: a tool the table lacks is an error (--strict-tools)
      allow_no_feed: false         # true: G1 with no F previews at the axis limits
      subroutine_path: [subs, /srv/nc/lib]   # searched after the program's folder
      work_offsets_m:              # settable work offsets (machine - program) [m]
        G54: {X: 0.0, Y: 0.0, Z: 0.0}
        G57: {X: 0.512, Y: 0.2843, Z: 0.4833}
    axes:
      X:
        travel_m: [-0.2, 0.3]     # travel limits in machine coordinates [m]

``radius_m`` is what cutter radius compensation G41/G42 D.. offsets the path by (LinuxCNC's
tool table holds the diameter: half of it); ``length_m`` is the tool length offset G43 H..
applies to Z. A tool the program asks for that the table lacks runs with length and radius 0
and one warning per tool number (a process planner rarely has the machine's table), or is an
error of the program with ``strict_tools: true`` (``--strict-tools`` turns it on too).
``allow_no_feed: true`` (``--allow-no-feed``) lets a feed move with no F set run at the axis
limits with a warning, as LinuxCNC's preview does; the control refuses it (the default).
``subroutine_path`` lists directories searched for ``o<name> call`` files after the
program's own, as LinuxCNC's ``[RS274NGC] SUBROUTINE_PATH`` (``--subroutine-path`` adds
more after them); a relative one is taken from the machine file's folder, and each must be
an existing directory. ``work_offsets_m`` holds the values of the settable work offsets
``G54``..``G59`` (the origin of the program's coordinates in machine coordinates, per axis
X, Y, Z [m], a missing axis 0): the control's data, not the program's. LinuxCNC's front
stores them as its parameters #5221.. (what its var file would hold), the Sinumerik front as
its settable offsets ``G54``..``G57``; a system the table lacks is 0 (the Sinumerik front
warns). A drive trace in machine coordinates then lines up with the simulated positions.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import os
from types import MappingProxyType
from typing import Any, Mapping

from ..configcheck import check_choice, check_float, check_mapping, is_finite_number
from ..errors import ConfigError, describe, shorten, shorten_path

__all__ = ['ToolSpec', 'GcodeSettings', 'DIALECTS', 'MAX_TOOLS', 'MAX_TOOL_NUMBER',
           'MAX_SUBROUTINE_DIRS', 'gcode_from_dict', 'gcode_to_dict', 'travel_from_value',
           'parse_tool_option', 'with_tools', 'check_subroutine_dir', 'with_program_options',
           'WORK_OFFSETS']

DIALECTS = ('linuxcnc', 'fanuc', 'haas', 'grbl', 'mach3', 'sinumerik')
"""Dialect names a config may choose (the profiles live in ``gcode/dialect.py``)."""
MAX_TOOLS = 10_000
"""Entries a tool table may hold (a config is read whole; this bounds it)."""
MAX_TOOL_NUMBER = 99_999
_TRAVEL_LIMIT_M = 1.0e3
WORK_OFFSETS = ('G54', 'G55', 'G56', 'G57', 'G58', 'G59')
"""The settable work offsets a config may give values for (``gcode.work_offsets_m``)."""


@dataclass(frozen=True)
class ToolSpec:
    """One tool of the tool table.

    Attributes
    ----------
    radius_m
        Cutter radius [m] used by G41/G42 (``>= 0``).
    length_m
        Tool length offset [m] applied to Z by G43 (may be negative).
    """

    radius_m: float = 0.0
    length_m: float = 0.0


def _empty_tools() -> Mapping[int, ToolSpec]:
    return MappingProxyType({})


@dataclass(frozen=True)
class GcodeSettings:
    """The ``gcode:`` section of a machine config.

    Attributes
    ----------
    dialect
        Default dialect of the programs run on this machine (one of :data:`DIALECTS`).
    tools
        Read-only mapping ``{T number: ToolSpec}``; ``machine.gcode.tools[1].radius_m``.
    strict_tools
        A tool the table lacks is an error (else length and radius 0, one warning).
    allow_no_feed
        A feed move with no F set previews at the axis limits (else it is an error).
    subroutine_path
        Directories searched for subroutine files after the program's own.
    work_offsets_m
        Read-only mapping ``{'G54'..'G59': (x, y, z)}`` [m]: the settable work offsets.
    """

    dialect: str = 'linuxcnc'
    tools: Mapping[int, ToolSpec] = field(default_factory=_empty_tools)
    strict_tools: bool = False
    allow_no_feed: bool = False
    subroutine_path: tuple[str, ...] = ()
    work_offsets_m: Mapping[str, tuple[float, float, float]] = field(
        default_factory=lambda: MappingProxyType({}))

    def tool(self, number: int) -> ToolSpec | None:
        """Return tool ``number`` of the table, or ``None`` if the table lacks it."""
        return self.tools.get(number)


def _tool_number(name: Any, *, file: str) -> int:
    # YAML reads `1:` as an int; JSON-like files may quote it
    number = name
    if isinstance(name, str) and name.strip().isdigit() and len(name.strip()) <= 6:
        number = int(name.strip())
    if isinstance(number, bool) or not isinstance(number, int) \
            or not 1 <= number <= MAX_TOOL_NUMBER:
        msg = f'expected a tool number 1 ... {MAX_TOOL_NUMBER} as key, got {describe(name)}'
        raise ConfigError(msg, file=file, key='gcode.tools')
    return number


def _tools(value: Any, *, file: str) -> Mapping[int, ToolSpec]:
    if value is None:
        return _empty_tools()
    table = check_mapping(value, file=file, key='gcode.tools', allowed=None)
    if len(table) > MAX_TOOLS:
        msg = f'expected at most {MAX_TOOLS} tools, got {len(table)}'
        raise ConfigError(msg, file=file, key='gcode.tools')
    out: dict[int, ToolSpec] = {}
    for name, entry in table.items():
        number = _tool_number(name, file=file)
        key = f'gcode.tools.{number}'
        if number in out:
            msg = f'tool {number} is given twice'
            raise ConfigError(msg, file=file, key=key)
        entry = check_mapping(entry, file=file, key=key, allowed=('radius_m', 'length_m'))
        out[number] = ToolSpec(
            radius_m=check_float(entry, 'radius_m', file=file, key=key, default=0.0,
                                 minimum=0.0, strict=False, maximum=1.0),
            length_m=check_float(entry, 'length_m', file=file, key=key, default=0.0,
                                 minimum=-10.0, strict=False, maximum=10.0))
    return MappingProxyType(dict(sorted(out.items())))


def gcode_from_dict(value: Any, *, file: str) -> GcodeSettings:
    """Build and validate the ``gcode:`` section (``None``: the defaults).

    Parameters
    ----------
    value
        The section as read from YAML.
    file
        Where it came from, for error messages.

    Returns
    -------
    GcodeSettings
        The validated settings.

    Raises
    ------
    ConfigError
        Unknown key, unknown dialect, bad tool number or value; names the dotted key.
    """
    if value is None:
        return GcodeSettings()
    d = check_mapping(value, file=file, key='gcode',
                      allowed=('dialect', 'tools', 'strict_tools', 'allow_no_feed',
                               'subroutine_path', 'work_offsets_m'))
    return GcodeSettings(
        dialect=check_choice(d, 'dialect', DIALECTS, file=file, key='gcode',
                             default='linuxcnc'),
        tools=_tools(d.get('tools'), file=file),
        strict_tools=bool(check_choice(d, 'strict_tools', (False, True), file=file,
                                       key='gcode', default=False)),
        allow_no_feed=bool(check_choice(d, 'allow_no_feed', (False, True), file=file,
                                        key='gcode', default=False)),
        subroutine_path=_subroutine_path(d.get('subroutine_path'), file=file),
        work_offsets_m=_work_offsets(d.get('work_offsets_m'), file=file))


def _work_offsets(value: Any, *, file: str) -> Mapping[str, tuple[float, float, float]]:
    if value is None:
        return MappingProxyType({})
    key = 'gcode.work_offsets_m'
    table = check_mapping(value, file=file, key=key, allowed=WORK_OFFSETS)
    out = {}
    for name in WORK_OFFSETS:
        if name not in table:
            continue
        axes = check_mapping(table[name], file=file, key=f'{key}.{name}',
                             allowed=('X', 'Y', 'Z'))
        values = []
        for axis in ('X', 'Y', 'Z'):
            v = axes.get(axis, 0.0)
            if not is_finite_number(v) or abs(v) > _TRAVEL_LIMIT_M:
                msg = (f'expected a finite number within +-{_TRAVEL_LIMIT_M:g} m, got '
                       f'{describe(v)}')
                raise ConfigError(msg, file=file, key=f'{key}.{name}.{axis}')
            values.append(float(v))
        out[name] = (values[0], values[1], values[2])
    return MappingProxyType(out)


MAX_SUBROUTINE_DIRS = 64
"""Entries ``gcode.subroutine_path`` and ``--subroutine-path`` may hold together."""


def check_subroutine_dir(text: str, *, where: str, file: str, base: str | None = None) -> str:
    """One subroutine directory, made absolute (``base``: the folder a relative one is in).

    Parameters
    ----------
    text
        The directory as the user wrote it.
    where
        The key or option that named it, for the message (``gcode.subroutine_path[0]``,
        ``--subroutine-path``).
    file
        The config file, or ``'command line'``.
    base
        Folder of a relative ``text`` (``None``: the working directory).

    Raises
    ------
    ConfigError
        Naming ``where``, when the directory does not exist or is not a directory.
    """
    if not isinstance(text, str) or not text.strip():
        msg = f'expected a directory name, got {describe(text)}'
        raise ConfigError(msg, file=file, key=where)
    path = os.path.expanduser(text)
    if base is not None and not os.path.isabs(path):
        path = os.path.join(base, path)
    path = os.path.abspath(path)
    if not os.path.isdir(path):
        what = 'does not exist' if not os.path.exists(path) else 'is not a directory'
        msg = f'subroutine directory {shorten_path(path)!r} {what}'
        raise ConfigError(msg, file=file, key=where)
    return path


def _subroutine_path(value: Any, *, file: str) -> tuple[str, ...]:
    if value is None:
        return ()
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, (list, tuple)):
        msg = f'expected a list of directories, got {describe(value)}'
        raise ConfigError(msg, file=file, key='gcode.subroutine_path')
    if len(value) > MAX_SUBROUTINE_DIRS:
        msg = f'expected at most {MAX_SUBROUTINE_DIRS} directories, got {len(value)}'
        raise ConfigError(msg, file=file, key='gcode.subroutine_path')
    base = os.path.dirname(os.path.abspath(file)) if not file.startswith('<') else None
    return tuple(check_subroutine_dir(v, where=f'gcode.subroutine_path[{i}]', file=file,
                                      base=base) for i, v in enumerate(value))


def gcode_to_dict(settings: GcodeSettings) -> dict[str, Any] | None:
    """Return the YAML form of ``settings``, or ``None`` when all are defaults."""
    if settings == GcodeSettings():
        return None
    out: dict[str, Any] = {'dialect': settings.dialect}
    if settings.tools:
        out['tools'] = {n: {'radius_m': t.radius_m, 'length_m': t.length_m}
                        for n, t in settings.tools.items()}
    if settings.strict_tools:
        out['strict_tools'] = True
    if settings.allow_no_feed:
        out['allow_no_feed'] = True
    if settings.subroutine_path:
        out['subroutine_path'] = list(settings.subroutine_path)
    if settings.work_offsets_m:
        out['work_offsets_m'] = {name: dict(zip(('X', 'Y', 'Z'), v))
                                 for name, v in settings.work_offsets_m.items()}
    return out


def travel_from_value(value: Any, *, file: str, key: str) -> tuple[float, float] | None:
    """Validate an axis's ``travel_m: [min, max]`` [m] (``None`` when absent).

    Raises
    ------
    ConfigError
        Not a list of two finite numbers within +-1000 m with ``min < max``.
    """
    if value is None:
        return None
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        msg = f'expected a list [min, max] of two numbers [m], got {describe(value)}'
        raise ConfigError(msg, file=file, key=key)
    low, high = (_travel_end(v, file=file, key=f'{key}[{i}]') for i, v in enumerate(value))
    if not low < high:
        msg = f'expected min < max, got [{low:g}, {high:g}]'
        raise ConfigError(msg, file=file, key=key)
    return (low, high)


def _travel_end(v: Any, *, file: str, key: str) -> float:
    if not is_finite_number(v) or abs(v) > _TRAVEL_LIMIT_M:
        msg = f'expected a finite number within +-{_TRAVEL_LIMIT_M:g} m, got {describe(v)}'
        raise ConfigError(msg, file=file, key=key)
    return float(v)


def parse_tool_option(text: str) -> tuple[int, ToolSpec]:
    """Read a command-line tool ``T:RADIUS_MM[:LENGTH_MM]`` (``3:2.5:45.2``).

    Parameters
    ----------
    text
        The option's value.

    Returns
    -------
    tuple
        The tool number and its :class:`ToolSpec` (SI units).

    Raises
    ------
    ValueError
        With a message naming what is wrong (the value is quoted cut to 60 characters).
    """
    parts = text.split(':')
    shown = shorten(text)
    if len(parts) not in (2, 3):
        msg = f'expected T:RADIUS_MM or T:RADIUS_MM:LENGTH_MM, got {shown!r}'
        raise ValueError(msg)
    number = parts[0].strip()
    if not number.isdigit() or len(number) > 6 or not 1 <= int(number) <= MAX_TOOL_NUMBER:
        msg = f'tool number must be 1 ... {MAX_TOOL_NUMBER}, got {shorten(parts[0])!r}'
        raise ValueError(msg)
    values = []
    for part, low, high in zip(parts[1:], (0.0, -1.0e4), (1.0e3, 1.0e4)):
        try:
            v = float(part)
        except ValueError:
            msg = f'expected a number of millimetres, got {shorten(part)!r} in {shown!r}'
            raise ValueError(msg) from None
        if not low <= v <= high:  # also refuses nan and inf
            msg = f'expected {low:g} ... {high:g} mm, got {shorten(part)!r} in {shown!r}'
            raise ValueError(msg)
        values.append(v / 1000.0)
    return int(number), ToolSpec(*values)


def with_tools(settings: GcodeSettings, tools: Mapping[int, ToolSpec]) -> GcodeSettings:
    """Return ``settings`` with ``tools`` added to (or replacing entries of) its table."""
    table = dict(settings.tools)
    table.update(tools)
    return replace(settings, tools=MappingProxyType(dict(sorted(table.items()))))


def with_program_options(settings: GcodeSettings, *, strict_tools: bool = False,
                         allow_no_feed: bool = False,
                         subroutine_path: tuple[str, ...] = ()) -> GcodeSettings:
    """Return ``settings`` with the command line's program options on top.

    ``strict_tools`` and ``allow_no_feed`` turn the config's setting on (never off);
    ``subroutine_path`` (directories already checked, :func:`check_subroutine_dir`) is
    searched after the config's ``gcode.subroutine_path``.

    Raises
    ------
    ConfigError
        More than :data:`MAX_SUBROUTINE_DIRS` directories in all.
    """
    dirs = tuple(settings.subroutine_path) + tuple(str(d) for d in subroutine_path)
    if len(dirs) > MAX_SUBROUTINE_DIRS:
        msg = f'expected at most {MAX_SUBROUTINE_DIRS} subroutine directories, got {len(dirs)}'
        raise ConfigError(msg, file='command line', key='subroutine-path')
    return replace(settings, strict_tools=settings.strict_tools or bool(strict_tools),
                   allow_no_feed=settings.allow_no_feed or bool(allow_no_feed),
                   subroutine_path=dirs)
