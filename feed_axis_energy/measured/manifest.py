"""Campaign manifest: which measured runs exist, where their data is and what the columns mean.

A manifest is YAML::

    name: umich_mill                   # optional
    machine: ../umich_mill.yaml        # machine config, relative to this file
    defaults:                          # optional, merged under every run
      period_s: 0.1
      axes:
        X: {power: {column: X1_OutputPower, unit: kW}}
      rows:
        exclude_where: [{column: PROGRAM, not_equal: 1}]
    runs:
      - name: exp01
        load_kg: 0.0
        motion: {from_data: actual}    # or {program: parts/s.nc}; reconstruct: samples
        data: data/exp01.csv           # CSV file (or a rosbag2 directory)
        role: calibrate                # or validate; optional
        instrument: {window_s: period, stamp: end}   # optional; or: instrument: point
    split: {calibrate: [exp01], validate: [exp03]}   # optional, instead of per-run roles

A run may take part of its record: ``window: {start_s: 0, end_s: 120}`` (seconds from the
record's first sample, after the row filter) or ``window: {start_fraction: 0.5}`` (fractions
of the record's duration; a missing end is the end of the record). A sample at ``t`` is kept
when ``start <= t < end``, so two runs of one file with ``end_fraction: 0.5`` and
``start_fraction: 0.5`` split it into halves without a shared sample: one to calibrate, one
to validate (:class:`.campaign.TimeWindow`). A run simulated from its program whose data has
positions may declare the work offset between them, ``work_offset_m: {X: -0.0378, Y: 0.26931,
Z: 0.38333}`` (machine - program [m]); without it ``compare`` estimates it (:mod:`.spatial`).
``motion.start_m: {X: .., Y: .., Z: ..}`` (machine coordinates [m]) is where the machine stood
when the program started (a drive trace's first position); default the origin.

Per axis the quantities ``power``, ``position``, ``velocity``, ``acceleration``,
``command_position``, ``command_velocity``, ``command_acceleration``, ``current``,
``voltage``, ``torque`` and ``force`` map to ``{column, unit}``. Kinematic quantities are
given for every axis of a run or for none; at least one axis must have a column of what the
instrument measures (``power``, or ``current``/``torque``/``force``). A run has either a ``time:
{column, unit}`` or a ``period_s`` (the run's own setting wins over ``defaults``).

``instrument`` declares the power meter: ``point`` (point samples) or ``{window_s, stamp,
measures}`` with ``window_s`` a number of seconds (``0``: point samples) or ``period`` (one
median sampling period, the default), ``stamp`` one of ``end`` (default), ``centre``,
``start``, and ``measures`` one of ``shaft`` (default), ``motor``, ``supply`` (electrical
power of the machine's declared drives, ``docs/electrical.md``; ``{measures: motor}`` alone
keeps the default window), or a drive quantity ``current``, ``torque``, ``force``
(:mod:`.quantity`). With ``current``, ``kt_nm_a: {X: 1.1}`` declares torque constants
[N·m/A] (else the machine file's ``axes.<A>.drive.kt_nm_a``); ``invert: [X]`` negates the
traces of axes that count the other way than the model. ``filter_s`` (seconds, default 0)
declares a meter that smooths with a first-order lag of that time constant before its window
(a filtered drive trace; ``analyze`` estimates one when none is declared, docs/analyze.md).
Without it: a period window stamped at its end for runs with an NC program, point samples
for motion from the data (:func:`.campaign.default_instrument`). ``motion.reconstruct``
(motion from data only): ``pulses`` (default) rebuilds data coarser than the simulation rate
at that rate (:mod:`.motiondata`), ``samples`` takes the samples as they are.

Merging: mappings merge key by key (the run wins); ``rows.exclude_where`` lists are
concatenated (defaults first). Errors name the manifest file and the dotted key
(``runs[2].axes.X.power.unit``); keys that come from ``defaults`` are checked and named there.
"""
from __future__ import annotations

import copy
from dataclasses import replace
import difflib
import math
from pathlib import Path
from typing import Any

from ..errors import ConfigError, describe, shorten
from ..safeyaml import load_yaml_file
from ..units import si_unit_of
from .align import MAX_FILTER_S
from .campaign import (AXIS_QUANTITIES, Campaign, ColumnSpec, FILTER_OPS, InstrumentSpec,
                       KINEMATIC_QUANTITIES, RECONSTRUCT, ROLES, RowFilter, RunSpec, STAMPS,
                       TimeWindow)
from .quantity import MEASURES, quantity_of

__all__ = ['campaign_from_dict', 'load_campaign']

_TOP_KEYS = ('name', 'description', 'machine', 'defaults', 'runs', 'split')
_RUN_KEYS = (
    'name', 'notes', 'load_kg', 'motion', 'data', 'period_s', 'time', 'axes', 'rows', 'role',
    'min_duration_s', 'allow_gaps', 'instrument', 'window', 'work_offset_m',
)
_DEFAULT_KEYS = tuple(k for k in _RUN_KEYS if k not in ('name', 'data', 'notes', 'window'))
_WINDOW_KEYS = ('start_s', 'end_s', 'start_fraction', 'end_fraction')


def load_campaign(path: str | Path, *, check_files: bool = True) -> Campaign:
    """Read and validate a campaign manifest.

    Parameters
    ----------
    path
        Manifest YAML file.
    check_files
        Also check that the machine config, programs and data files exist.

    Returns
    -------
    Campaign
        Runs with absolute paths and checked units.

    Raises
    ------
    ConfigError
        Naming the manifest and the dotted key of the first bad value.
    """
    path = Path(path)
    data = load_yaml_file(path, error=ConfigError, what='manifest')
    return campaign_from_dict(data, file=path, check_files=check_files)


def campaign_from_dict(data: Any, *, file: str | Path, check_files: bool = True) -> Campaign:
    """Validate an already parsed manifest; relative paths are resolved against ``file``.

    Parameters
    ----------
    data
        The parsed YAML document.
    file
        The manifest's path (names it in errors and anchors relative paths).
    check_files
        Also check that referenced files exist.

    Returns
    -------
    Campaign
        The validated campaign.

    Raises
    ------
    ConfigError
        Naming the manifest and the dotted key of the first bad value.
    """
    ctx = _Ctx(Path(file), check_files)
    top = ctx.mapping(data, '', _TOP_KEYS, required=('machine', 'runs'))
    machine = ctx.path(top['machine'], 'machine')
    defaults = {}
    if top.get('defaults') is not None:
        defaults = ctx.mapping(top['defaults'], 'defaults', _DEFAULT_KEYS)
        ctx.check_run_fields(defaults, 'defaults', partial=True)
    runs_raw = top['runs']
    if not isinstance(runs_raw, list) or not runs_raw:
        ctx.fail('runs', f'expected a non-empty list of runs, got {_kind(runs_raw)}')
    runs = []
    seen: dict[str, str] = {}
    for i, raw in enumerate(runs_raw):
        key = f'runs[{i}]'
        own = ctx.mapping(raw, key, _RUN_KEYS, required=('name', 'data'))
        spec = ctx.run_spec(_merge(defaults, own), own, key)
        if spec.name in seen:
            ctx.fail(f'{key}.name',
                     f'duplicate run name {shorten(spec.name)!r} (also {seen[spec.name]})')
        seen[spec.name] = key
        runs.append(spec)
    if top.get('split') is not None:
        runs = ctx.apply_split(top['split'], runs)
    name = top.get('name') or ctx.file.stem
    if not isinstance(name, str):
        ctx.fail('name', f'expected text, got {_kind(name)}')
    description = top.get('description') or ''
    return Campaign(file=ctx.file, name=name, machine=machine, runs=tuple(runs),
                    description=str(description))


def _kind(value: Any) -> str:
    return describe(value)


def _merge(base: dict, over: dict) -> dict:
    out = copy.deepcopy(base)
    for key, value in over.items():
        if key == 'rows' and isinstance(value, dict) and isinstance(out.get('rows'), dict):
            rows = dict(out['rows'])
            for rk, rv in value.items():
                if isinstance(rv, list) and isinstance(rows.get(rk), list):
                    rows[rk] = rows[rk] + rv
                else:
                    rows[rk] = rv
            out['rows'] = rows
        elif isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    # The more specific level chooses between a time column and a fixed period.
    if 'time' in over and 'period_s' not in over:
        out.pop('period_s', None)
    if 'period_s' in over and 'time' not in over:
        out.pop('time', None)
    return out


class _Ctx:
    """Validation helpers that know the manifest file for messages."""

    def __init__(self, file: Path, check_files: bool):
        self.file = file
        self.check_files = check_files

    def fail(self, key: str, message: str) -> None:
        raise ConfigError(message, file=str(self.file), key=key or '<top>')

    def mapping(self, value: Any, key: str, allowed: tuple[str, ...], *,
                required: tuple[str, ...] = ()) -> dict:
        if not isinstance(value, dict):
            self.fail(key, f'expected a mapping, got {_kind(value)}')
        for k in value:
            if not isinstance(k, str) or k not in allowed:
                shown = shorten(str(k))
                close = difflib.get_close_matches(shown, allowed, n=1)
                hint = f' (did you mean {close[0]!r}?)' if close else ''
                where = f'{key}.{shown}' if key else shown
                self.fail(where, f'unknown key{hint}; expected one of {", ".join(allowed)}')
        for k in required:
            if value.get(k) is None:
                self.fail(f'{key}.{k}' if key else k, 'required key is missing')
        return value

    def number(self, value: Any, key: str, *, minimum: float | None = None,
               positive: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(key, f'expected a number, got {_kind(value)}')
        out = float(value)
        if not math.isfinite(out):
            self.fail(key, f'expected a finite number, got {describe(value)}')
        if positive and out <= 0.0:
            self.fail(key, f'expected a positive number, got {describe(value)}')
        if minimum is not None and out < minimum:
            self.fail(key, f'expected a number >= {minimum:g}, got {describe(value)}')
        return out

    def text(self, value: Any, key: str) -> str:
        if not isinstance(value, str) or not value.strip():
            self.fail(key, f'expected non-empty text, got {_kind(value)}')
        return value.strip()

    def path(self, value: Any, key: str, *, directory_ok: bool = False) -> Path:
        text = self.text(value, key)
        if '\x00' in text:
            self.fail(key, f'a file name cannot contain a NUL character, got {describe(text)}')
        try:
            p = (self.file.parent / text).resolve()
            if self.check_files:
                if not p.exists():
                    self.fail(key, f'no such file: {shorten(str(p), limit=200)}')
                if p.is_dir() and not directory_ok:
                    self.fail(key, f'expected a file, got the directory {p}')
                if not (p.is_file() or p.is_dir()):  # reading a FIFO would block
                    self.fail(key, f'expected a regular file, got {shorten(str(p), limit=200)}')
        except (OSError, RuntimeError) as err:  # too long a name, a symlink loop
            msg = f'cannot use {describe(text)} as a file: {getattr(err, "strerror", None) or err}'
            raise ConfigError(msg, file=str(self.file), key=key) from None
        return p

    def column(self, value: Any, key: str, quantity: str) -> ColumnSpec:
        spec = self.mapping(value, key, ('column', 'unit'), required=('column', 'unit'))
        column = self.text(spec['column'], f'{key}.column')
        unit = self.text(spec['unit'], f'{key}.unit')
        try:
            si_unit_of(unit, quantity=quantity)
        except ConfigError as err:
            raise ConfigError(err.reason, file=str(self.file), key=f'{key}.unit') from err
        return ColumnSpec(column=column, unit=unit)

    def filters(self, value: Any, key: str) -> tuple[RowFilter, ...]:
        rows = self.mapping(value, key, ('exclude_where',))
        items = rows.get('exclude_where') or []
        if not isinstance(items, list):
            self.fail(f'{key}.exclude_where', f'expected a list, got {_kind(items)}')
        out = []
        for j, item in enumerate(items):
            ikey = f'{key}.exclude_where[{j}]'
            cond = self.mapping(item, ikey, ('column',) + FILTER_OPS, required=('column',))
            ops = [op for op in FILTER_OPS if op in cond]
            if len(ops) != 1:
                self.fail(ikey, f'expected exactly one of {", ".join(FILTER_OPS)}')
            op = ops[0]
            raw = cond[op]
            if isinstance(raw, bool) or not isinstance(raw, (int, float, str)):
                self.fail(f'{ikey}.{op}', f'expected a number or text, got {_kind(raw)}')
            if isinstance(raw, str) and op in ('greater', 'less'):
                self.fail(f'{ikey}.{op}', f'{op} needs a number, got {describe(raw)}')
            value_ = raw.strip() if isinstance(raw, str) else float(raw)
            out.append(RowFilter(self.text(cond['column'], f'{ikey}.column'), op, value_))
        return tuple(out)

    def axes(self, value: Any, key: str) -> dict[str, dict[str, ColumnSpec]]:
        if not isinstance(value, dict) or not value:
            self.fail(key, f'expected a mapping of axis names, got {_kind(value)}')
        out: dict[str, dict[str, ColumnSpec]] = {}
        for axis, cols in value.items():
            akey = f'{key}.{shorten(str(axis))}'
            if not isinstance(axis, str) or not axis.strip():
                self.fail(akey, 'axis names must be non-empty text')
            cols = self.mapping(cols if cols is not None else {}, akey, tuple(AXIS_QUANTITIES))
            out[axis] = {q: self.column(c, f'{akey}.{q}', AXIS_QUANTITIES[q])
                         for q, c in cols.items()}
        return out

    def motion(self, value: Any, key: str) -> tuple[Path | None, str | None, str]:
        m = dict(self.mapping(value, key, ('program', 'from_data', 'reconstruct', 'start_m')))
        given = 'reconstruct' in m
        rebuild = m.pop('reconstruct', 'pulses')
        if m.pop('start_m', None) is not None and 'program' not in m:
            self.fail(f'{key}.start_m', 'only for motion from a program')
        if len(m) != 1:
            self.fail(key, 'expected exactly one of program, from_data')
        if rebuild not in RECONSTRUCT:
            self.fail(f'{key}.reconstruct',
                      f'expected one of {", ".join(RECONSTRUCT)}, got {_kind(rebuild)}')
        if 'program' in m:
            if given:
                self.fail(f'{key}.reconstruct', 'only for motion from_data')
            return self.path(m['program'], f'{key}.program'), None, rebuild
        source = m['from_data']
        if source not in ('commanded', 'actual'):
            self.fail(f'{key}.from_data', f'expected commanded or actual, got {_kind(source)}')
        return None, source, rebuild

    def instrument(self, value: Any, key: str) -> InstrumentSpec:
        if value == 'point':
            return InstrumentSpec(window_s=0.0, stamp='end')
        if not isinstance(value, dict):
            self.fail(key, f'expected point or a mapping {{window_s, stamp}}, got {_kind(value)}')
        m = self.mapping(value, key, ('window_s', 'stamp', 'measures', 'kt_nm_a', 'invert',
                                      'noise', 'filter_s'))
        measures = m.get('measures', 'shaft')
        if measures not in MEASURES:
            self.fail(f'{key}.measures',
                      f'expected one of {", ".join(MEASURES)}, got {_kind(measures)}')
        kt: list[tuple[str, float]] = []
        if m.get('kt_nm_a') is not None:
            if measures != 'current':
                self.fail(f'{key}.kt_nm_a', f'torque constants convert a current trace; the '
                          f'instrument measures {measures}')
            given = m['kt_nm_a']
            if not isinstance(given, dict) or not given:
                self.fail(f'{key}.kt_nm_a', 'expected a mapping axis -> torque constant '
                          f'[N·m/A], got {_kind(given)}')
            for axis, v in given.items():
                if not isinstance(axis, str) or not axis.strip():
                    self.fail(f'{key}.kt_nm_a', 'axis names must be non-empty text')
                value_ = self.number(v, f'{key}.kt_nm_a.{shorten(str(axis))}', positive=True)
                if not 1.0e-4 <= value_ <= 1.0e3:
                    self.fail(f'{key}.kt_nm_a.{shorten(str(axis))}',
                              f'a torque constant lies in [1e-4, 1e3] N·m/A, got {value_:g}')
                kt.append((str(axis), value_))
        invert: list[str] = []
        if m.get('invert') is not None:
            raw = m['invert']
            if quantity_of(measures).is_power:
                self.fail(f'{key}.invert', 'only a current, torque or force trace has a sign '
                          f'convention to invert; the instrument measures {measures} power')
            if not isinstance(raw, list) or not all(isinstance(a, str) for a in raw):
                self.fail(f'{key}.invert', f'expected a list of axis names, got {_kind(raw)}')
            invert = [a.strip() for a in raw]
        noise = None
        if m.get('noise') is not None:
            noise = self.number(m['noise'], f'{key}.noise', positive=True)
        filter_s = 0.0
        if m.get('filter_s') is not None:
            filter_s = self.number(m['filter_s'], f'{key}.filter_s', minimum=0.0)
            if filter_s > MAX_FILTER_S:
                self.fail(f'{key}.filter_s', f'a meter\'s first-order time constant lies in '
                          f'[0, {MAX_FILTER_S:g}] s, got {filter_s:g}')
        if m and not set(m) - {'measures', 'kt_nm_a', 'invert', 'noise', 'filter_s'}:
            # what is measured only: the window and stamp stay the default of the run
            return InstrumentSpec(declared=False, measures=measures, kt_nm_a=tuple(kt),
                                  invert=tuple(invert), noise=noise, filter_s=filter_s)
        window = m.get('window_s', 'period')
        if window != 'period':
            window = self.number(window, f'{key}.window_s', minimum=0.0)
        stamp = m.get('stamp', 'end')
        if stamp not in STAMPS:
            self.fail(f'{key}.stamp', f'expected one of {", ".join(STAMPS)}, got {_kind(stamp)}')
        return InstrumentSpec(window_s=None if window == 'period' else window, stamp=stamp,
                              measures=measures, kt_nm_a=tuple(kt), invert=tuple(invert),
                              noise=noise, filter_s=filter_s)

    def window(self, value: Any, key: str) -> TimeWindow:
        w = self.mapping(value, key, _WINDOW_KEYS)
        seconds = [k for k in ('start_s', 'end_s') if k in w]
        fractions = [k for k in ('start_fraction', 'end_fraction') if k in w]
        if not w:
            self.fail(key, 'expected start_s and/or end_s, or start_fraction and/or '
                      'end_fraction')
        if seconds and fractions:
            self.fail(f'{key}.{fractions[0]}', 'give the window in seconds (start_s, end_s) '
                      'or as fractions of the record (start_fraction, end_fraction), not both')
        frac = bool(fractions)
        names = ('start_fraction', 'end_fraction') if frac else ('start_s', 'end_s')
        start = self.number(w.get(names[0], 0.0), f'{key}.{names[0]}', minimum=0.0)
        end = None
        if w.get(names[1]) is not None:
            end = self.number(w[names[1]], f'{key}.{names[1]}', positive=True)
            if end <= start:
                self.fail(f'{key}.{names[1]}', f'the window ends ({end:g}) where or before it '
                          f'starts ({start:g})')
        if frac and (start >= 1.0 or (end is not None and end > 1.0)):
            bad = names[0] if start >= 1.0 else names[1]
            self.fail(f'{key}.{bad}', 'a fraction of the record lies in [0, 1] (the start '
                      'below 1)')
        return TimeWindow(start=start, end=end, fraction=frac)

    def check_run_fields(self, d: dict, key: str, *, partial: bool) -> dict[str, Any]:
        """Check the typed fields present in ``d``; return their converted values."""
        out: dict[str, Any] = {}
        if d.get('load_kg') is not None:
            out['load_kg'] = self.number(d['load_kg'], f'{key}.load_kg', minimum=0.0)
        if d.get('period_s') is not None:
            out['period_s'] = self.number(d['period_s'], f'{key}.period_s', positive=True)
        if d.get('time') is not None:
            out['time'] = self.column(d['time'], f'{key}.time', 'time')
        if d.get('axes') is not None:
            out['axes'] = self.axes(d['axes'], f'{key}.axes')
        if d.get('rows') is not None:
            out['exclude'] = self.filters(d['rows'], f'{key}.rows')
        if d.get('motion') is not None:
            out['motion'] = self.motion(d['motion'], f'{key}.motion')
        if d.get('role') is not None:
            if d['role'] not in ROLES:
                self.fail(f'{key}.role', f'expected calibrate or validate, got {_kind(d["role"])}')
            out['role'] = d['role']
        if d.get('min_duration_s') is not None:
            out['min_duration_s'] = self.number(d['min_duration_s'], f'{key}.min_duration_s',
                                                minimum=0.0)
        if d.get('allow_gaps') is not None:
            if not isinstance(d['allow_gaps'], bool):
                got = _kind(d['allow_gaps'])
                self.fail(f'{key}.allow_gaps', f'expected true or false, got {got}')
            out['allow_gaps'] = d['allow_gaps']
        if d.get('instrument') is not None:
            out['instrument'] = self.instrument(d['instrument'], f'{key}.instrument')
        if d.get('window') is not None:
            out['window'] = self.window(d['window'], f'{key}.window')
        if d.get('work_offset_m') is not None:
            given = self.mapping(d['work_offset_m'], f'{key}.work_offset_m', ('X', 'Y', 'Z'))
            out['work_offset_m'] = tuple(
                (a, self.number(v, f'{key}.work_offset_m.{a}')) for a, v in given.items())
        if not partial and 'time' in out and 'period_s' in out:
            self.fail(f'{key}.time', 'give either time or period_s, not both')
        return out

    def run_spec(self, merged: dict, own: dict, key: str) -> RunSpec:
        name = self.text(merged['name'], f'{key}.name')
        f = self.check_run_fields(merged, key, partial=False)
        for req in ('load_kg', 'motion', 'axes'):
            if req not in f:
                self.fail(f'{key}.{req}', 'required key is missing (in the run or in defaults)')
        if 'time' not in f and 'period_s' not in f:
            self.fail(f'{key}.period_s', 'the run needs a time column (time) or a period_s')
        axes = f['axes']
        meter = f.get('instrument', InstrumentSpec(declared=False))
        column = quantity_of(meter.measures).column
        if not any(column in cols for cols in axes.values()):
            what = ('power' if column == 'power'
                    else f'{column} (the instrument measures {meter.measures})')
            self.fail(f'{key}.axes', f'no axis has a {column} column; {what} is needed for '
                      'comparison')
        for axis in meter.invert:
            if column not in axes.get(axis, {}):
                self.fail(f'{key}.instrument.invert',
                          f'axis {shorten(axis)!r} has no {column} column to invert')
        for axis, _kt in meter.kt_nm_a:
            if axis not in axes:
                self.fail(f'{key}.instrument.kt_nm_a.{shorten(axis)}',
                          f'no axis {shorten(axis)!r} in this run ({", ".join(axes)})')
        for q in KINEMATIC_QUANTITIES:
            having = [a for a, cols in axes.items() if q in cols]
            if having and len(having) != len(axes):
                missing = ', '.join(a for a in axes if a not in having)
                self.fail(f'{key}.axes.{missing.split(",")[0]}.{q}',
                          f'{q} is given for {", ".join(having)} but not for {missing}; '
                          'give it for every axis or none')
        program, from_data, rebuild = f['motion']
        start = None
        raw_start = (merged.get('motion') or {}).get('start_m')
        if raw_start is not None:
            given = self.mapping(raw_start, f'{key}.motion.start_m', ('X', 'Y', 'Z'))
            values = {a: self.number(v, f'{key}.motion.start_m.{a}') for a, v in given.items()}
            start = (values.get('X', 0.0), values.get('Y', 0.0), values.get('Z', 0.0))
        if from_data is not None:
            need = 'command_position' if from_data == 'commanded' else 'position'
            lacking = [a for a, cols in axes.items() if need not in cols]
            if lacking:
                self.fail(f'{key}.motion.from_data',
                          f'motion from {from_data} data needs {need} columns; '
                          f'axis {lacking[0]} has none')
        data = self.path(merged['data'], f'{key}.data', directory_ok=True)
        kind = 'rosbag2' if data.is_dir() or data.suffix == '' else 'csv'
        return RunSpec(
            name=name, data=data, data_kind=kind, load_kg=f['load_kg'], axes=axes,
            motion_program=program, motion_from_data=from_data,
            period_s=f.get('period_s'), time=f.get('time'), exclude=f.get('exclude', ()),
            role=f.get('role'), min_duration_s=f.get('min_duration_s', 0.0),
            allow_gaps=f.get('allow_gaps', False), manifest=str(self.file), key=key,
            instrument=f.get('instrument', InstrumentSpec(declared=False)),
            motion_reconstruct=rebuild, window=f.get('window'),
            work_offset_m=f.get('work_offset_m', ()), motion_start_m=start,
        )

    def apply_split(self, value: Any, runs: list[RunSpec]) -> list[RunSpec]:
        split = self.mapping(value, 'split', ROLES)
        names = {r.name for r in runs}
        role_of: dict[str, str] = {}
        for role, members in split.items():
            if not isinstance(members, list):
                self.fail(f'split.{role}', f'expected a list of run names, got {_kind(members)}')
            for j, member in enumerate(members):
                mkey = f'split.{role}[{j}]'
                if not isinstance(member, str):
                    self.fail(mkey, f'expected a run name, got {describe(member)}')
                if member not in names:
                    close = difflib.get_close_matches(shorten(member), sorted(names), n=1)
                    hint = f' (did you mean {close[0]!r}?)' if close else ''
                    self.fail(mkey, f'no run named {shorten(member)!r}{hint}')
                if member in role_of and role_of[member] != role:
                    self.fail(mkey, f'run {shorten(member)!r} is in both calibrate and validate')
                role_of[member] = role
        out = []
        for r in runs:
            new = role_of.get(r.name)
            if new is not None and r.role is not None and r.role != new:
                self.fail(f'{r.key}.role', f'role {r.role!r} contradicts split.{new} which '
                          f'lists {shorten(r.name)!r}')
            out.append(r if new is None else replace(r, role=new))
        return out
