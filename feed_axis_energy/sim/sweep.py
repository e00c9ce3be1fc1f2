"""What-if studies: one or many programs on variants of a machine, energy against cycle time.

A sweep varies named parameters over lists or ranges of values; every combination of the
values (the Cartesian product) is one variant, simulated for every program as an ordinary
campaign job (:class:`.batch.BatchJob`, so the same executors run it). Beside the variants,
each program is simulated once on the machine as configured (the *baseline*), so every row can
say how much energy and time it saves or costs.

Parameters are named three ways (:func:`parse_vary`):

* a run setting: ``feed_override`` (factor on the programmed feed of G1/G2/G3, as a control's
  feed override; 0 < f <= 10), ``rapid_override`` (factor on the rapid traverse speed the
  axis limits allow; 0 < r <= 1), ``load_kg`` (workpiece mass [kg]);
* a short name for a machine-config key on every axis (:data:`ALIASES`), e.g. ``jerk`` for
  ``axes.*.limits.jerk_m_s3``;
* any machine-config key by its dotted path, ``*`` standing for every key at that level:
  ``axes.Z.table_mass_kg``, ``axes.*.screw.lead_m``, ``braking``.

``NAME=V1,V2,...`` sets the values; ``NAME=START:STOP:N`` sets ``N`` values evenly spaced from
``START`` to ``STOP``; ``NAME*=F1,F2,...`` (or a range) multiplies the configured value(s) by
each factor, which keeps the differences between axes. The variant machine is validated like a
machine file, so a value out of range is an error naming the key.

Energy against cycle time: a variant is on the *Pareto front* of its program when no other
variant (or the baseline) of the same program needs at most as much energy and at most as
much time, and less of one of them (:func:`pareto_front`).
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
import copy
from dataclasses import dataclass
import functools
import itertools
import math
from typing import Any, cast

from ..errors import ConfigError, shorten

__all__ = ['ALIASES', 'RUN_KEYS', 'MAX_VALUES', 'Vary', 'parse_vary', 'resolve_paths',
           'apply_overrides', 'variant_machine', 'variants', 'pareto_front', 'override_moves']

ALIASES = {
    'acceleration': 'axes.*.limits.acceleration_m_s2',
    'jerk': 'axes.*.limits.jerk_m_s3',
    'velocity': 'axes.*.limits.velocity_m_s',
    'lead': 'axes.*.screw.lead_m',
    'table_mass': 'axes.*.table_mass_kg',
    'motor_inertia': 'axes.*.inertias.motor_kg_m2',
    'screw_efficiency': 'axes.*.screw.efficiency',
    'braking': 'braking',
    'profile': 'planner.profile',
    'corner_tolerance': 'planner.corner_tolerance_m',
}
"""Short names of machine-config keys (``*``: every axis)."""

RUN_KEYS = {
    # name: (lowest, highest, lowest included)
    'feed_override': (0.0, 10.0, False),
    'rapid_override': (0.0, 1.0, False),
    'load_kg': (0.0, 1.0e6, True),
}
"""Parameters of the run rather than the machine, with their ranges."""

MAX_VALUES = 1000
"""Most values one ``--vary`` may list or generate."""

_WHERE = 'command line'


@dataclass(frozen=True)
class Vary:
    """One varied parameter.

    Attributes
    ----------
    name
        As the user wrote it (shown in tables).
    key
        A :data:`RUN_KEYS` name, or the machine-config dotted path (aliases resolved).
    values
        The values, in the order given (numbers, or strings for keys such as ``braking``).
    relative
        True for ``NAME*=``: the values multiply the configured value(s).
    """

    name: str
    key: str
    values: tuple[Any, ...]
    relative: bool = False

    @property
    def is_run_key(self) -> bool:
        """True for a run setting (not a machine-config key)."""
        return self.key in RUN_KEYS


def _number(text: str) -> float | None:
    try:
        value = float(text)
    except ValueError:
        return None
    return value


def _range(text: str, *, spec: str) -> tuple[float, ...]:
    parts = text.split(':')
    nums = [_number(p) for p in parts]
    if len(parts) != 3 or any(v is None or not math.isfinite(v) for v in nums):
        msg = f'a range is START:STOP:N with numbers, got {shorten(spec)!r}'
        raise ConfigError(msg, file=_WHERE, key='vary')
    start, stop, count = cast('list[float]', nums)      # none is None (above)
    if count != int(count) or not 2 <= count <= MAX_VALUES:
        msg = (f'the N of START:STOP:N must be a whole number of 2 to {MAX_VALUES}, got '
               f'{shorten(parts[2])!r} in {shorten(spec)!r}')
        raise ConfigError(msg, file=_WHERE, key='vary')
    n = int(count)
    return tuple(start + (stop - start) * i / (n - 1) for i in range(n))


def _values(text: str, *, spec: str) -> tuple[Any, ...]:
    if ':' in text:
        return _range(text, spec=spec)
    items = [t.strip() for t in text.split(',')]
    if not text.strip() or any(not t for t in items):
        msg = f'expected values separated by commas, got {shorten(spec)!r}'
        raise ConfigError(msg, file=_WHERE, key='vary')
    if len(items) > MAX_VALUES:
        msg = f'at most {MAX_VALUES} values per parameter, got {len(items)}'
        raise ConfigError(msg, file=_WHERE, key='vary')
    out: list[Any] = []
    for item in items:
        value = _number(item)
        if value is not None and not math.isfinite(value):
            msg = f'values must be finite, got {shorten(item)!r} in {shorten(spec)!r}'
            raise ConfigError(msg, file=_WHERE, key='vary')
        out.append(item if value is None else value)
    if len(set(map(repr, out))) != len(out):
        msg = f'a value is listed twice in {shorten(spec)!r}'
        raise ConfigError(msg, file=_WHERE, key='vary')
    return tuple(out)


def parse_vary(spec: str) -> Vary:
    """Read one ``--vary`` argument: ``NAME=VALUES`` or ``NAME*=FACTORS`` (module docstring).

    Parameters
    ----------
    spec
        The argument.

    Returns
    -------
    Vary
        The parameter; machine-config paths are checked against a machine later
        (:func:`resolve_paths`).

    Raises
    ------
    ConfigError
        Bad syntax, a value of the wrong kind or outside its range (run settings).
    """
    name, sep, text = spec.partition('=')
    relative = name.endswith('*')
    name = name[:-1].strip() if relative else name.strip()
    if not sep or not name:
        msg = f'expected NAME=VALUES or NAME*=FACTORS, got {shorten(spec)!r}'
        raise ConfigError(msg, file=_WHERE, key='vary')
    parts = name.split('.')
    if any(not p or not all(c.isalnum() or c in '_*' for c in p) for p in parts):
        msg = f'a parameter name is a word or a dotted path, got {shorten(name)!r}'
        raise ConfigError(msg, file=_WHERE, key='vary')
    key = ALIASES.get(name, name)
    values = _values(text, spec=spec)
    numeric = all(isinstance(v, float) for v in values)
    if (relative or key in RUN_KEYS) and not numeric:
        what = 'factors' if relative else 'values'
        msg = f'{shorten(name)}: the {what} must be numbers, got {shorten(text)!r}'
        raise ConfigError(msg, file=_WHERE, key='vary')
    if relative and any(v < 0.0 for v in values):
        msg = f'{shorten(name)}: factors must be >= 0, got {shorten(text)!r}'
        raise ConfigError(msg, file=_WHERE, key='vary')
    if key in RUN_KEYS:
        if relative:
            msg = f'{name} is a factor already; write {name}=VALUES'
            raise ConfigError(msg, file=_WHERE, key='vary')
        low, high, low_ok = RUN_KEYS[key]
        for v in values:
            if not (low <= v <= high if low_ok else low < v <= high):
                bound = '>=' if low_ok else '>'
                msg = f'{name} must be {bound} {low:g} and <= {high:g}, got {v:g}'
                raise ConfigError(msg, file=_WHERE, key='vary')
    return Vary(name=name, key=key, values=values, relative=relative)


def resolve_paths(key: str, machine_dict: Mapping[str, Any]) -> list[tuple[str, ...]]:
    """The concrete key paths ``key`` (dotted, ``*`` = every key) names in a machine's YAML form.

    The last part may be a key the mapping does not hold yet (an optional key); every part
    before it must exist. Keys are checked again when the variant machine is validated.

    Raises
    ------
    ConfigError
        A part of the path that is not in the machine config.
    """
    paths: list[tuple[str, ...]] = [()]
    parts = key.split('.')
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        grown: list[tuple[str, ...]] = []
        for path in paths:
            node = _node(machine_dict, path)
            if not isinstance(node, Mapping):
                msg = f'{".".join(path)} holds a value, not a group of keys'
                raise ConfigError(msg, file=_WHERE, key=f'vary {shorten(key)}')
            if part == '*':
                grown.extend(path + (str(k),) for k in node)
            elif part in node or last:
                grown.append(path + (part,))
            else:
                where = '.'.join(path) or 'the top level'
                have = ', '.join(str(k) for k in node)
                msg = (f'the machine config has no key {part!r} at {where} '
                       f'(there: {shorten(have, limit=120)})')
                raise ConfigError(msg, file=_WHERE, key=f'vary {shorten(key)}')
        paths = grown
    if not paths:
        raise ConfigError('the path names no key', file=_WHERE, key=f'vary {shorten(key)}')
    return paths


def _node(d: Mapping[str, Any], path: Sequence[str]) -> Any:
    node: Any = d
    for part in path:
        node = node[part]
    return node


def apply_overrides(machine_dict: Mapping[str, Any],
                    overrides: Iterable[tuple[str, Any, bool]]) -> dict[str, Any]:
    """A copy of a machine's YAML form with ``(dotted key, value, relative)`` applied.

    Raises
    ------
    ConfigError
        A path not in the config, or a relative change of a value that is not a number.
    """
    d = copy.deepcopy(dict(machine_dict))
    for key, value, relative in overrides:
        for path in resolve_paths(key, d):
            parent = _node(d, path[:-1])
            if relative:
                old = parent.get(path[-1])
                if isinstance(old, bool) or not isinstance(old, (int, float)):
                    msg = (f'{".".join(path)} is not a number in the machine config, so it '
                           f'cannot be multiplied')
                    raise ConfigError(msg, file=_WHERE, key=f'vary {shorten(key)}')
                parent[path[-1]] = float(old) * value
            else:
                parent[path[-1]] = value
    return d


@functools.lru_cache(maxsize=8)
def _base_machine(path: str):
    """The machine file at ``path`` read, validated and turned into its YAML form, once."""
    from ..machine import load_machine, machine_to_dict
    machine = load_machine(path)
    return machine, machine_to_dict(machine)


@functools.lru_cache(maxsize=64)
def variant_machine(path: str, overrides: tuple[tuple[str, Any, bool], ...]):
    """The machine file at ``path`` with ``overrides`` applied, validated (cached per process).

    The file is read and parsed once per process; every variant is derived from the parsed
    form (:func:`apply_overrides` copies it), so a sweep of any size reads it once.

    Raises
    ------
    ConfigError
        The file, or a changed value the machine validation refuses (the message names the
        key and says which variant it is).
    """
    from ..machine import machine_from_dict
    machine, as_dict = _base_machine(path)
    if not overrides:
        return machine
    d = apply_overrides(as_dict, overrides)
    shown = ', '.join(f'{k}{"*" if r else ""}={_show(v)}' for k, v, r in overrides)
    return machine_from_dict(d, file=f'{path} [{shorten(shown, limit=160)}]')


def _show(value: Any) -> str:
    return f'{value:g}' if isinstance(value, float) else str(value)


def variants(params: Sequence[Vary]) -> list[tuple[Any, ...]]:
    """Every combination of the parameters' values (first parameter slowest)."""
    return list(itertools.product(*(p.values for p in params)))


def pareto_front(points: Sequence[tuple[float, float]]) -> list[bool]:
    """Which ``(time, energy)`` points no other point dominates (at most as much of both,
    less of one). Equal points are all on the front.
    """
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front = [False] * len(points)
    best = math.inf
    k = 0
    while k < len(order):
        # points with the same time: only those with the lowest energy can be on the front
        j = k
        while j < len(order) and points[order[j]][0] == points[order[k]][0]:
            j += 1
        group = order[k:j]
        low = min(points[i][1] for i in group)
        if low < best:
            for i in group:
                front[i] = points[i][1] == low
            best = low
        k = j
    return front


def override_moves(moves: Iterable[Any], *, feed: float = 1.0, rapid: float = 1.0,
                   limits: Mapping[str, Any] | None = None) -> Iterable[Any]:
    """The program's moves as a control runs them with feed and rapid overrides.

    ``feed`` multiplies the programmed path feed of every linear move and arc (what a control's
    feed override does; the machine's axis limits still cap the speed). ``rapid`` caps a rapid
    move's path speed at that fraction of the speed its axis limits allow along its direction
    (``limits``: :class:`.trajectory.AxisLimits` by axis name). Dwells and stops are unchanged.
    """
    from dataclasses import replace
    from ..gcode import MoveKind, PROGRAM_AXES
    if feed == 1.0 and rapid == 1.0:
        yield from moves
        return
    vmax = [math.inf] * 3
    for name, al in (limits or {}).items():
        if name in PROGRAM_AXES:
            vmax[PROGRAM_AXES.index(name)] = al.velocity_m_s
    cut = (MoveKind.LINEAR, MoveKind.ARC_CW, MoveKind.ARC_CCW)
    for mv in moves:
        if feed != 1.0 and mv.kind in cut and math.isfinite(mv.feed_m_s) and mv.feed_m_s > 0:
            mv = replace(mv, feed_m_s=mv.feed_m_s * feed)
        elif rapid != 1.0 and mv.kind == MoveKind.RAPID and mv.length_m > 0.0:
            speed = _rapid_speed(mv, vmax)
            if math.isfinite(speed):
                mv = replace(mv, feed_m_s=rapid * speed)
        yield mv


def _rapid_speed(mv: Any, vmax: Sequence[float]) -> float:
    """Path speed of a straight rapid at which the first axis reaches its speed limit: the
    planner's own rule (:func:`feed_axis_energy.plan.segments.line_speed_limits`) on the move's
    direction."""
    from ..plan import line_speed_limits
    d = [e - s for s, e in zip(mv.start, mv.end)]
    norm = math.sqrt(sum(x * x for x in d))
    if norm == 0.0:
        return math.inf
    return float(line_speed_limits([x / norm for x in d], vmax))


@dataclass(frozen=True)
class SweepRow:
    """One program on one variant: what it took, and how it compares.

    Attributes
    ----------
    program
        The program as named.
    values
        The varied parameters' values (``None`` for all of them on the baseline row).
    baseline
        True for the machine as configured, without overrides.
    ok
        False when the simulation failed (``error`` says why; the numbers are ``nan``).
    cycle_time_s, energy_j
        Duration of the program [s] and energy of all axes [J] (:func:`sweep_energy`).
    energy_per_part_j
        ``energy_j`` divided by the parts one run of the program makes.
    d_energy_pct, d_time_pct
        Change against the program's baseline [%] (``nan`` when the baseline failed).
    pareto
        On the program's energy-time Pareto front (baseline included).
    error
        The failure's message, or ``''``.
    energy_point
        Where ``energy_j`` is taken: ``'shaft'`` (mechanical), or with declared drives the
        meter's point ``'motor'`` or ``'supply'`` (:func:`sweep_energy`).
    energy_sd_j
        Standard uncertainty of ``energy_j`` from the loss functions' covariance [J]
        (:mod:`.uncertainty`; ``nan`` where not known).
    """

    program: str
    values: tuple[Any, ...] | None
    baseline: bool
    ok: bool
    cycle_time_s: float
    energy_j: float
    energy_per_part_j: float
    d_energy_pct: float
    d_time_pct: float
    pareto: bool
    error: str = ''
    energy_point: str = 'shaft'
    energy_sd_j: float = math.nan

    def to_dict(self, params: Sequence[Vary]) -> dict[str, Any]:
        """Plain JSON-able values (numbers absent where they are not known)."""
        out: dict[str, Any] = {
            'program': self.program, 'baseline': self.baseline,
            'values': (None if self.values is None else
                       {p.name + ('*' if p.relative else ''): v
                        for p, v in zip(params, self.values)}),
            'status': 'ok' if self.ok else 'failed'}
        if not self.ok:
            out['error'] = self.error
            return out
        out.update(cycle_time_s=self.cycle_time_s, energy_j=self.energy_j,
                   energy_per_part_j=self.energy_per_part_j, pareto=self.pareto,
                   energy_point=self.energy_point)
        if math.isfinite(self.d_energy_pct):
            out.update(d_energy_pct=self.d_energy_pct, d_time_pct=self.d_time_pct)
        if math.isfinite(self.energy_sd_j):
            out['energy_sd_j'] = self.energy_sd_j
        return out


def sweep_energy(summary: dict[str, Any]) -> tuple[float, str]:
    """``(energy [J], point)`` a sweep compares: with declared drives the electrical energy at
    the meter's point (``supply.measured_at``; so that motor and drive values change it),
    else the mechanical energy of all axes (``'shaft'``)."""
    elec = summary.get('electrical')
    if elec:
        return float(elec['energy_j']['total']), str(elec['measured_at'])
    return float(summary['energy_j']['total']), 'shaft'


def _pct(value: float, base: float) -> float:
    return 100.0 * (value - base) / base if base > 0.0 and math.isfinite(base) else math.nan


def sweep_rows(results: Sequence[tuple[str, tuple[Any, ...] | None, Any]], *,
               parts: float = 1.0) -> list[SweepRow]:
    """Rows of a sweep from ``(program, values or None for the baseline, JobResult)``.

    Parameters
    ----------
    results
        In job order; each program's rows stay in the order given.
    parts
        Parts made by one run of a program (energy per part = energy / parts).
    """
    base: dict[str, tuple[float, float]] = {}
    for program, values, r in results:
        if values is None and r.ok:
            base[program] = (r.summary['duration_s'], sweep_energy(r.summary)[0])
    points: dict[str, list[int]] = {}
    for i, (program, _, r) in enumerate(results):
        if r.ok:
            points.setdefault(program, []).append(i)
    front: set[int] = set()
    for idx in points.values():
        flags = pareto_front([(results[i][2].summary['duration_s'],
                               sweep_energy(results[i][2].summary)[0]) for i in idx])
        front.update(i for i, f in zip(idx, flags) if f)
    rows = []
    for i, (program, values, r) in enumerate(results):
        if not r.ok:
            rows.append(SweepRow(program, values, values is None, False, math.nan, math.nan,
                                 math.nan, math.nan, math.nan, False, error=r.error))
            continue
        t, (e, point) = r.summary['duration_s'], sweep_energy(r.summary)
        bt, be = base.get(program, (math.nan, math.nan))
        spread = r.summary.get('energy_uncertainty') or {}
        sd = float((spread.get('energy_sd_j') or {}).get('total', math.nan))
        rows.append(SweepRow(program, values, values is None, True, t, e, e / parts,
                             _pct(e, be), _pct(t, bt), i in front, energy_point=point,
                             energy_sd_j=sd))
    return rows
