"""Load one measured run from CSV into SI arrays, all or nothing.

The file is read once with the :mod:`csv` module, in blocks of rows
(:func:`~feed_axis_energy.csvtable.iter_csv_blocks`) whose text is let go once converted, so
memory holds the run's numbers, not its text; in each block the rows matching the manifest's
``rows.exclude_where`` filters are dropped first, then every mapped column is parsed, checked
(numbers, finite, no empty cells) and converted to SI once; a bad cell is reported in the
order of a whole-file check (time, its order and gaps, duration, then the other columns).
Time is either a column or the original row index times ``period_s``, so rows removed by a
filter leave a visible gap.
Errors are :class:`~feed_axis_energy.errors.DataError` naming file, column and the
1-based data row as counted in the file (row 1 is the first line after the header).
:func:`load_run` is also the entry for a run whose data is a measured-run bag
(:mod:`.bagload`); the gap and duration checks of both are in :mod:`.run`.
"""
from __future__ import annotations

import difflib
from itertools import chain
from typing import Any, cast

import numpy as np

from ..csvtable import column_values, iter_csv_blocks, MIN_STEP_S
from ..errors import DataError, shorten
from ..units import check_si_values, to_si
from .campaign import AXIS_QUANTITIES, KINEMATIC_QUANTITIES, ColumnSpec, RowFilter, RunSpec
from .bagload import load_run_from_bag
from .run import check_duration, check_gaps, MeasuredRun, take_window

__all__ = ['load_run']

_FIELD = {
    'position': 'position_m',
    'velocity': 'velocity_m_s',
    'acceleration': 'acceleration_m_s2',
    'command_position': 'command_position_m',
    'command_velocity': 'command_velocity_m_s',
    'command_acceleration': 'command_acceleration_m_s2',
}


def load_run(spec: RunSpec, *, min_duration_s: float | None = None) -> MeasuredRun:
    """Load a manifest run: the one entry for CSV and bag runs.

    A CSV file is read here (rows filtered, values checked and converted to SI); a
    measured-run bag directory goes to :func:`.bagload.load_run_from_bag`. A run with a
    ``window`` keeps the samples inside it (:func:`.run.take_window`), its time from 0.

    Parameters
    ----------
    spec
        The run from :func:`~feed_axis_energy.measured.manifest.load_campaign`.
    min_duration_s
        Reject runs shorter than this [s]; default ``spec.min_duration_s``.

    Returns
    -------
    MeasuredRun
        The run; nothing is returned half-loaded.

    Raises
    ------
    DataError
        Naming file, column and 1-based data row: missing column (with the closest header
        name), non-numeric, empty, NaN or infinite cell, duplicate or decreasing time, a gap
        longer than :data:`.run.GAP_FACTOR` median periods (unless ``spec.allow_gaps``), an
        empty file or one with a header only, or a run shorter than ``min_duration_s``. A bag
        run: as :func:`.bagload.load_run_from_bag` (also a :class:`ConfigError`). A window
        with fewer than 2 samples.
    """
    if spec.data_kind != 'csv':
        run = load_run_from_bag(spec, min_duration_s=min_duration_s)
    else:
        run = _load_csv(spec, min_duration_s)
    return take_window(run, spec.window, key=f'{spec.key}.window' if spec.key else 'window')


def _load_csv(spec: RunSpec, min_duration_s: float | None) -> MeasuredRun:
    file = str(spec.data)
    blocks = iter_csv_blocks(spec.data)
    first = next(blocks)
    index = _column_index(first[0], spec, file)
    axes = spec.axis_names
    power_axes = spec.power_axes
    wanted: list[tuple[str, ColumnSpec, str]] = []     # (key, column, quantity), in check order
    if spec.time is not None:
        wanted.append(('time', spec.time, 'time'))
    wanted += [(f'power:{a}', spec.axes[a]['power'], 'power') for a in power_axes]
    kinematic = [q for q in KINEMATIC_QUANTITIES if q in spec.axes[axes[0]]]
    wanted += [(f'{q}:{a}', spec.axes[a][q], AXIS_QUANTITIES[q]) for q in kinematic for a in axes]
    electric = [(q, a) for q in ('current', 'voltage', 'torque', 'force')
                for a, cols in spec.axes.items()
                if q in cols]
    wanted += [(f'{q}:{a}', spec.axes[a][q], q) for q, a in electric]
    cols = _Columns()
    samples: list[np.ndarray] = []
    kept_numbers: list[np.ndarray] = []
    total = 0
    for _, rows, numbers in chain([first], blocks):
        # the block's text is converted and let go: the file is never held as text at once
        # position among data rows (blank lines skipped): the sample index when time = i * period
        first_row = total
        total += len(rows)
        keep = np.ones(len(rows), dtype=bool)
        for filt in spec.exclude:
            keep &= ~_matches(filt, rows, index[filt.column], numbers, file)
        kept = [row for row, k in zip(rows, keep) if k]
        # row numbers in 32 bits (a file of 2^31 rows is beyond any run): half the memory
        numbers = numbers[keep].astype(np.int32 if total < 2**31 else np.int64)
        if spec.time is None:
            samples.append(first_row + np.flatnonzero(keep))
        kept_numbers.append(numbers)
        for key, cs, quantity in wanted:
            cols.add(key, kept, index[cs.column], numbers, file, cs, quantity)
    numbers = np.concatenate(kept_numbers)
    kept_numbers.clear()
    excluded = total - numbers.size
    if numbers.size < 2:
        msg = (f'needs at least 2 data rows, has {numbers.size} '
               f'({total} in the file, {excluded} excluded by the manifest filter)')
        raise DataError(msg, file=file)

    t = _time(spec, np.concatenate(samples) if samples else None, numbers, file, cols)
    check_duration(t, spec, min_duration_s, file=file, after=' after filtering')
    t0 = float(t[0])
    t -= t0           # in place: a long run holds one copy of its stamps

    power = (np.column_stack([cols.get(f'power:{a}') for a in power_axes])
             if power_axes else np.zeros((t.size, 0)))      # a drive trace: current only
    kin: dict[str, np.ndarray] = {}
    for q in kinematic:
        kin[_FIELD[q]] = np.column_stack([cols.get(f'{q}:{a}') for a in axes])
    extra: dict[str, Any] = {
        'excluded_rows': excluded, 'rows': numbers, 't0_s': t0,
    }
    for q, key in (('current', 'current_a'), ('voltage', 'voltage_v'), ('torque', 'torque_nm'),
                   ('force', 'force_n')):
        got = {a: cols.get(f'{q}:{a}') for qq, a in electric if qq == q}
        if got:
            extra[key] = got
    return MeasuredRun(name=spec.name, file=file, t=t, axes=axes,
                       power_axes=power_axes, power_w=power, load_kg=spec.load_kg,
                       extra=extra, **kin)


class _Columns:
    """The mapped columns, converted to SI block by block.

    A bad cell is kept as the column's first error and raised when the column is asked for,
    so that the checks run in the same order as on a file read whole (time first, then its
    order and the duration, then power, kinematics, current and voltage).
    """

    def __init__(self) -> None:
        self.parts: dict[str, list[np.ndarray]] = {}
        self.errors: dict[str, DataError] = {}

    def add(self, key: str, rows: list[list[str]], j: int, numbers: np.ndarray, file: str,
            cs: ColumnSpec, quantity: str) -> None:
        """Convert column ``j`` of one block's kept ``rows``."""
        if key in self.errors:
            return
        try:
            raw = column_values(rows, j, numbers, file, cs.column)
            values = check_si_values(to_si(raw, cs.unit, quantity=quantity), file=file,
                                     column=cs.column, rows=numbers)
        except DataError as err:
            self.errors[key] = err
            return
        self.parts.setdefault(key, []).append(values)

    def get(self, key: str) -> np.ndarray:
        """The whole column; its first bad cell raised as :class:`DataError`."""
        if key in self.errors:
            raise self.errors[key]
        parts = self.parts.pop(key)         # the blocks go once joined
        return parts[0] if len(parts) == 1 else np.concatenate(parts)


def _column_index(header: list[str], spec: RunSpec, file: str) -> dict[str, int]:
    wanted = [cs.column for cols in spec.axes.values() for cs in cols.values()]
    wanted += [f.column for f in spec.exclude]
    if spec.time is not None:
        wanted.append(spec.time.column)
    index: dict[str, int] = {}
    for name in wanted:
        hits = [i for i, h in enumerate(header) if h == name]
        if not hits:
            lower = {h.lower(): h for h in header}
            close = difflib.get_close_matches(name.lower(), list(lower), n=1, cutoff=0.5)
            hint = f'; did you mean {shorten(lower[close[0]])!r}?' if close else ''
            msg = f'no such column in the header{hint}'
            raise DataError(msg, file=file, column=name)
        if len(hits) > 1:
            msg = f'the header has this column {len(hits)} times (fields {hits[0] + 1}, ' \
                  f'{hits[1] + 1}); cannot tell which one is meant'
            raise DataError(msg, file=file, column=name)
        index[name] = hits[0]
    return index


def _matches(filt: RowFilter, rows: list[list[str]], j: int, numbers: np.ndarray,
             file: str) -> np.ndarray:
    if isinstance(filt.value, str):
        text = np.array([row[j].strip() for row in rows], dtype=object)
        eq = text == filt.value
        return eq if filt.op == 'equal' else ~eq
    values = column_values(rows, j, numbers, file, filt.column)
    if filt.op == 'equal':
        return values == filt.value
    if filt.op == 'not_equal':
        return values != filt.value
    if filt.op == 'greater':
        return values > filt.value
    return values < filt.value


def _time(spec: RunSpec, sample: np.ndarray | None, numbers: np.ndarray, file: str,
          cols: _Columns) -> np.ndarray:
    if spec.time is not None:
        name = spec.time.column
        t = cols.get('time')
    else:
        name = '<row index>'
        # a spec without time has a period, and then the sample indices were kept
        t = cast(np.ndarray, sample) * float(cast(float, spec.period_s))
    dt = np.diff(t)
    bad = np.flatnonzero(dt < 0.999 * MIN_STEP_S)  # 0.999: rounding of decimal times
    if bad.size:
        i = int(bad[0]) + 1
        if dt[i - 1] == 0.0:
            what = 'repeats the previous time'
        elif dt[i - 1] < 0.0:
            what = 'goes back in time'
        else:
            what = f'follows the previous time after only {dt[i - 1]:.3g} s'
        msg = (f'{what} ({t[i - 1]:.9g} s then {t[i]:.9g} s); time must increase by at '
               f'least {MIN_STEP_S:g} s (stamps are whole nanoseconds)')
        raise DataError(msg, file=file, column=name, row=int(numbers[i]))
    del dt, bad
    check_gaps(t, spec, file=file, column=name, rows=numbers)
    return t
