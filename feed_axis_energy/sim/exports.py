"""Tables out of a simulation: the time series and the per-block table as CSV or Parquet.

Both are written chunk by chunk into a directory that :func:`.outputs.staged_directory`
builds (renamed into place when complete, nothing left on failure): memory is one chunk of
samples, or of blocks, whatever the program's length.

* ``timeseries.csv`` / ``.parquet``: every ``decimate``-th sample (counted from the first,
  at the full rate): time, source line, per axis position, velocity, drawn power and
  cumulative energy, the total power and energy, and the power of every cause summed over
  the axes (:mod:`.breakdown`). Column names carry their SI unit (``X power [W]``; a rotary
  axis A, B, C has its position in rad and velocity in rad/s, ``C position [rad]``). With
  declared drives (:mod:`.electrical`) also the electrical power per axis at the motor
  terminals and at the supply side, the totals (the supply's with the cabinet's standby),
  their cumulative energies, and the electrical causes summed over the axes.
* ``blocks.csv`` / ``.parquet``: one row per source line that took time: line, the block's
  text (at most :data:`TEXT_CHARS` characters), duration, energy, energy per axis and per
  cause (summed over the axes), with declared drives the electrical energy at the motor
  terminals and at the supply side (the cabinet's standby for the line's time included);
  ascending line.
* ``rollups.csv`` / ``.parquet`` (when the simulation has roll-ups: G-code on the streamed
  path, :mod:`.rollup`): one row per operation, subroutine, tool and axis: group, name,
  energy, duration (with declared drives also the energy at the motor terminals and at the
  supply side); the rows of each of operation, subroutine and tool add up to the
  program's energy and time. Per operation and tool rather than a column of the time series:
  a sample carries only its source line (a line may run in several operations), and this
  table is exact and a few rows long.
"""
from __future__ import annotations

from collections.abc import Iterator, Sequence
import csv
import io
from pathlib import Path
from typing import Any, cast

import numpy as np

from ..physics import cause_names, cause_powers, LineEnergy
from ..errors import ConfigError, DataError, OutputError
from ..units import axis_units
from .simulate import SimulationResult

__all__ = ['FORMATS', 'TEXT_CHARS', 'TableWriter', 'require_pyarrow', 'SeriesExporter',
           'write_blocks', 'write_rollups', 'series_columns', 'iter_source_texts',
           'EXPORT_MARKER', 'ELECTRICAL_SERIES', 'ROLLUP_GROUPS']

FORMATS = ('csv', 'parquet')
TEXT_CHARS = 120
EXPORT_MARKER = '.feed_axis_energy_export'
"""File in an export directory: ``--force`` may replace a directory holding it."""
_BLOCK_ROWS = 65536
ROLLUP_GROUPS = ('operation', 'subroutine', 'tool', 'axis')


def require_pyarrow(option: str):
    """``(pyarrow, pyarrow.parquet)``, or a :class:`ConfigError` naming ``option``."""
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError as err:
        msg = (f'{option} needs the pyarrow package, which is not installed '
               '(pip install pyarrow==26.0.1, pinned in requirements.txt)')
        raise ConfigError(msg, file='command line', key=option.lstrip('-')) from err
    return pyarrow, pyarrow.parquet


class TableWriter:
    """One table written in pieces as CSV or Parquet (one Parquet row group per piece).

    Parameters
    ----------
    path
        The file to create (inside a staged directory: it must not exist).
    columns
        Column names.
    fmt
        ``'csv'`` or ``'parquet'``.
    text_columns
        Names of the columns that hold text.
    int_columns
        Names of the columns that hold integers (the others are floats).
    """

    def __init__(self, path: Path, columns: Sequence[str], *, fmt: str,
                 text_columns: Sequence[str] = (), int_columns: Sequence[str] = ()) -> None:
        if fmt not in FORMATS:
            msg = f'TableWriter: format must be one of {FORMATS}, got {fmt!r}'
            raise ValueError(msg)
        self.path = Path(path)
        self.columns = list(columns)
        self.fmt = fmt
        self.text = set(text_columns)
        self.ints = set(int_columns)
        self.rows = 0
        self._fh = None
        self._pq: Any = None
        if fmt == 'csv':
            self._fh = open(self.path, 'x', encoding='utf-8', newline='')
            csv.writer(self._fh).writerow(self.columns)
        else:
            pa, pq = require_pyarrow('--parquet')
            self._pa = pa
            fields = [pa.field(c, pa.string() if c in self.text else
                               pa.int64() if c in self.ints else pa.float64())
                      for c in self.columns]
            self._schema = pa.schema(fields)
            self._pq = pq.ParquetWriter(str(self.path), self._schema, compression='zstd')

    def write(self, data: dict[str, Any]) -> None:
        """Append rows: ``{column: array or list}``, every column, equal lengths."""
        n = len(next(iter(data.values()))) if data else 0
        if n == 0:
            return
        if self._fh is not None:
            self._fh.write(_csv_rows(self.columns, data, self.text, self.ints))
        else:
            pa = self._pa
            arrays = [pa.array(data[c], type=pa.string()) if c in self.text
                      else pa.array(np.asarray(data[c], dtype=np.int64)) if c in self.ints
                      else pa.array(np.asarray(data[c], dtype=float)) for c in self.columns]
            self._pq.write_table(pa.Table.from_arrays(arrays, schema=self._schema))
        self.rows += n

    def close(self) -> None:
        """Finish the file (flushed to disk)."""
        if self._fh is not None:
            self._fh.flush()
            self._fh.close()
            self._fh = None
        if self._pq is not None:
            self._pq.close()
            self._pq = None


def _csv_rows(columns: list[str], data: dict[str, Any], text: set[str],
              ints: set[str]) -> str:
    """CSV text of the rows; floats as their shortest round-trip text, text quoted as
    needed."""
    cells = []
    for c in columns:
        if c in text:
            cells.append(data[c])
        elif c in ints:
            cells.append(np.asarray(data[c], dtype=np.int64).tolist())
        else:
            cells.append(list(map(repr, np.asarray(data[c], dtype=float).tolist())))
    buf = io.StringIO()
    csv.writer(buf).writerows(zip(*cells))
    return buf.getvalue()


ELECTRICAL_SERIES = ('copper', 'iron', 'converter', 'standby', 'braking_burned')


def series_columns(axes: Sequence[str], causes: Sequence[str], *,
                   electrical: bool = False) -> list[str]:
    """Column names of the time series (see the module docstring)."""
    cols = ['t [s]', 'line']
    cols += [f'{a} position [{axis_units(a)[0]}]' for a in axes]
    cols += [f'{a} velocity [{axis_units(a)[1]}]' for a in axes]
    for what, unit in (('power', 'W'), ('energy', 'J')):
        cols += [f'{a} {what} [{unit}]' for a in axes]
    cols += ['total power [W]', 'total energy [J]']
    cols += [f'{c} power [W]' for c in causes]
    if electrical:
        for point in ('motor', 'supply'):
            cols += [f'{a} {point} power [W]' for a in axes]
            cols += [f'total {point} power [W]', f'total {point} energy [J]']
        cols += [f'electrical {c} power [W]' for c in ELECTRICAL_SERIES]
    return cols


class SeriesExporter:
    """The time series, decimated, written chunk by chunk to every requested format.

    Parameters
    ----------
    directories
        ``{fmt: directory}`` (existing, e.g. staged) to write ``timeseries.<fmt>`` into.
    decimate
        Keep every ``decimate``-th sample of the full-rate grid (1: all).
    """

    def __init__(self, directories: dict[str, Path], *, decimate: int = 1) -> None:
        if decimate < 1:
            msg = f'decimate must be >= 1, got {decimate}'
            raise ConfigError(msg, file='command line', key='decimate')
        self.directories = dict(directories)
        self.decimate = int(decimate)
        self.seen = 0
        self._writers: list[TableWriter] = []
        self._elec_last: tuple[float, float, float] | None = None   # t, motor, supply [W]
        self._elec_energy = np.zeros(2)                              # motor, supply [J]

    def write(self, chunk: SimulationResult) -> None:
        """Take one chunk at the full rate (without ``Motion.gaps``), in time order."""
        if chunk.motion.gaps:
            msg = 'SeriesExporter.write needs chunks at the full rate (expand_gaps)'
            raise ValueError(msg)
        p, dyn = chunk.power, chunk.dynamics
        m = int(p.t.shape[0])
        keep = np.nonzero((self.seen + np.arange(m)) % self.decimate == 0)[0]
        self.seen += m
        if keep.size == 0:
            return
        causes = cause_powers(dyn, p.mechanical_w, braking=p.braking,
                              effects=p.effect_power_w)
        names = cause_names([label for label, _ in p.effect_power_w])
        elec = p.electrical
        if not self._writers:
            cols = series_columns(p.axes, names, electrical=elec is not None)
            self._writers = [TableWriter(d / f'timeseries.{fmt}', cols, fmt=fmt,
                                         int_columns=('line',))
                             for fmt, d in self.directories.items()]
        data: dict[str, Any] = {'t [s]': p.t[keep], 'line': p.line[keep]}
        for j, a in enumerate(p.axes):
            pos_unit, vel_unit, _ = axis_units(a)
            data[f'{a} position [{pos_unit}]'] = dyn.position_m[keep, j]
            data[f'{a} velocity [{vel_unit}]'] = dyn.velocity_m_s[keep, j]
            data[f'{a} power [W]'] = p.power_w[keep, j]
            data[f'{a} energy [J]'] = p.energy_j[keep, j]
        data['total power [W]'] = p.total_w[keep]
        data['total energy [J]'] = p.total_energy_j[keep]
        summed = causes[:, :, keep].sum(axis=1)
        for i, c in enumerate(names):
            data[f'{c} power [W]'] = summed[i]
        if elec is not None:
            data.update(self._electrical(p.t, p.axes, elec, keep))
        for name, values in data.items():
            bad = ~np.isfinite(values)
            if np.any(bad):
                at = float(p.t[keep][int(np.argmax(bad))])
                msg = f'the time series is not finite: {name} at t = {at:.6g} s'
                raise DataError(msg, file=chunk.program or '<simulation>')
        for w in self._writers:
            w.write(data)

    def _electrical(self, t: np.ndarray, axes: Sequence[str], elec: Any,
                    keep: np.ndarray) -> dict[str, np.ndarray]:
        """The electrical columns of the kept samples; the cumulative energies integrate
        every sample (trapezoid, continued from the previous chunk)."""
        totals = np.column_stack((elec.motor_w.sum(axis=1),
                                  elec.supply_w.sum(axis=1) + elec.cabinet_w))
        de = np.zeros_like(totals)
        de[1:] = 0.5 * (totals[1:] + totals[:-1]) * np.diff(t)[:, None]
        if self._elec_last is not None:
            t0, motor0, supply0 = self._elec_last
            de[0] = 0.5 * (totals[0] + (motor0, supply0)) * (t[0] - t0)
        energy = np.cumsum(de, axis=0) + self._elec_energy
        self._elec_energy = energy[-1].copy()
        self._elec_last = (float(t[-1]), float(totals[-1, 0]), float(totals[-1, 1]))
        out: dict[str, np.ndarray] = {}
        for i, (point, power) in enumerate((('motor', elec.motor_w),
                                            ('supply', elec.supply_w))):
            for j, a in enumerate(axes):
                out[f'{a} {point} power [W]'] = power[keep, j]
            out[f'total {point} power [W]'] = totals[keep, i]
            out[f'total {point} energy [J]'] = energy[keep, i]
        parts = dict(elec.parts)
        parts['braking_burned'] = elec.burned_w
        for c in ELECTRICAL_SERIES:
            out[f'electrical {c} power [W]'] = parts[c][keep].sum(axis=1)
        return out

    def close(self) -> None:
        """Finish every file."""
        for w in self._writers:
            w.close()


def iter_source_texts(path: Path, lines: np.ndarray, *,
                      limit: int = TEXT_CHARS) -> Iterator[str]:
    """The text of every 1-based line of ``lines`` (ascending), read line by line, cut to
    ``limit`` characters with ``...``; ``''`` for lines the file lacks or cannot give."""
    wanted = iter(np.asarray(lines, dtype=np.int64).tolist())
    target = next(wanted, None)
    given = 0
    try:
        with open(path, encoding='utf-8', errors='replace', newline=None) as fh:
            for number, text in enumerate(fh, 1):
                while target is not None and target < number:
                    given += 1
                    yield ''
                    target = next(wanted, None)
                if target is None:
                    return
                if target == number:
                    text = text.rstrip('\n').strip()
                    given += 1
                    yield text if len(text) <= limit else text[:limit] + '...'
                    target = next(wanted, None)
    except OSError:
        pass
    for _ in range(int(np.asarray(lines).shape[0]) - given):
        yield ''


def write_blocks(directories: dict[str, Path], blocks: LineEnergy, *, program: Path | None,
                 limit: int = TEXT_CHARS) -> int:
    """Write ``blocks.<fmt>`` (see the module docstring) into every directory; return rows.

    Parameters
    ----------
    directories
        ``{fmt: directory}``.
    blocks
        Energy per line with the per-block breakdown (``by_axis_j``, ``by_cause_j``).
    program
        The program file the block texts are read from (``None``: no texts).
    limit
        Characters of text kept per block.
    """
    if blocks.by_axis_j is None or blocks.by_cause_j is None:
        msg = 'write_blocks needs the per-block breakdown (block_breakdown=True)'
        raise OutputError(msg)
    electrical = blocks.motor_j is not None and blocks.supply_j is not None
    cols = (['line', 'text', 'duration [s]', 'energy [J]']
            + [f'{a} energy [J]' for a in blocks.axes]
            + [f'{c} energy [J]' for c in blocks.causes]
            + (['motor energy [J]', 'supply energy [J]'] if electrical else []))
    writers = [TableWriter(d / f'blocks.{fmt}', cols, fmt=fmt, text_columns=('text',),
                           int_columns=('line',))
               for fmt, d in directories.items()]
    texts = (iter_source_texts(program, blocks.lines, limit=limit) if program is not None
             else None)
    n = len(blocks)
    try:
        for lo in range(0, n, _BLOCK_ROWS):
            hi = min(n, lo + _BLOCK_ROWS)
            data: dict[str, Any] = {
                'line': blocks.lines[lo:hi],
                'text': [next(texts) for _ in range(hi - lo)] if texts else [''] * (hi - lo),
                'duration [s]': blocks.duration_s[lo:hi],
                'energy [J]': blocks.energy_j[lo:hi]}
            for j, a in enumerate(blocks.axes):
                data[f'{a} energy [J]'] = blocks.by_axis_j[lo:hi, j]
            for j, c in enumerate(blocks.causes):
                data[f'{c} energy [J]'] = blocks.by_cause_j[lo:hi, j]
            if electrical:
                # the casts: a table with an electrical side has both
                data['motor energy [J]'] = cast(np.ndarray, blocks.motor_j)[lo:hi]
                data['supply energy [J]'] = cast(np.ndarray, blocks.supply_j)[lo:hi]
            for w in writers:
                w.write(data)
    finally:
        for w in writers:
            w.close()
    return n


def write_rollups(directories: dict[str, Path], rollups: dict[str, Any] | None) -> int:
    """Write ``rollups.<fmt>`` (see the module docstring) into every directory; return rows.

    Parameters
    ----------
    directories
        ``{fmt: directory}``.
    rollups
        The summary's ``rollups`` (``{group: [{'name', 'energy_j', 'duration_s'}]}``, with
        declared drives also ``motor_energy_j`` and ``supply_energy_j``: two more columns);
        ``None`` or empty: nothing is written.
    """
    if not rollups:
        return 0
    items = [(g, it) for g in ROLLUP_GROUPS for it in rollups.get(g) or ()]
    electrical = bool(items) and all('supply_energy_j' in it for _, it in items)
    rows = [(g, str(it['name']), float(it['energy_j']), float(it['duration_s']))
            + ((float(it['motor_energy_j']), float(it['supply_energy_j'])) if electrical
               else ()) for g, it in items]
    cols = (['group', 'name', 'energy [J]', 'duration [s]']
            + (['motor energy [J]', 'supply energy [J]'] if electrical else []))
    data = {c: [r[i] for r in rows] for i, c in enumerate(cols)}
    for fmt, d in directories.items():
        w = TableWriter(d / f'rollups.{fmt}', cols, fmt=fmt, text_columns=('group', 'name'))
        try:
            w.write(data)
        finally:
            w.close()
    return len(rows)
