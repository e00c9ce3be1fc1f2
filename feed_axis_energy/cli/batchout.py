"""Output of ``batch``: the text table, the CSV text and the check of a ``--csv`` target.

The CSV file itself is written with :func:`feed_axis_energy.outputs.write_text_atomic`
(:func:`write_csv`): through a hidden temporary sibling, never through a symbolic link,
an existing file replaced only with ``--force``, nothing left on failure.
"""
from __future__ import annotations

import csv
import io
import os
from pathlib import Path

from feed_axis_energy.cli.common import format_table
from feed_axis_energy.sim import JobResult
from feed_axis_energy.errors import ConfigError, shorten
from feed_axis_energy.outputs import write_text_atomic

__all__ = ['print_table', 'csv_text', 'check_csv_target', 'write_csv',
           'rollup_cell', 'ROLLUP_COLUMNS']


def _axes(results: list[JobResult]) -> list[str]:
    """Axis names of all successful jobs, in the order first seen."""
    names: dict[str, None] = {}
    for r in results:
        if r.ok:
            names.update((a, None) for a in r.summary['energy_j'] if a != 'total')
    return list(names)


def _electrical(summary: dict, key: str) -> float | None:
    """The electrical energy total [J] at ``key`` (``motor_energy_j``, ``supply_energy_j``),
    or None where the machine declares no drives."""
    side = summary.get('electrical') or {}
    values = side.get(key)
    return None if not values else values['total']


def print_table(results: list[JobResult]) -> None:
    """Print one row per job (errors listed below the table).

    With drives declared on any machine, a column of the electrical energy at the supply
    side ('-' for a job whose machine declares none)."""
    electrical = any(r.ok and _electrical(r.summary, 'supply_energy_j') is not None
                     for r in results)
    header = ['job', 'program', 'machine', 'load [kg]', 'duration [s]', 'samples',
              'energy [J]', 'peak power [W]', 'loss energy [J]']
    header += ['supply energy [J]'] if electrical else []
    header += ['status']
    rows = []
    for r in results:
        job = r.job
        cells = [str(job.index + 1), shorten(job.program), shorten(Path(job.machine).name),
                 f'{job.load_kg:.3f}']
        if r.ok:
            s = r.summary
            cells += [f'{s["duration_s"]:.3f}', str(s['samples']),
                      f'{s["energy_j"]["total"]:.2f}', f'{s["peak_power_w"]["total"]:.1f}',
                      f'{s["loss_energy_j"]:.2f}']
            if electrical:
                supply = _electrical(s, 'supply_energy_j')
                cells.append('-' if supply is None else f'{supply:.2f}')
            cells.append('ok')
        else:
            cells += ['-'] * (6 if electrical else 5) + ['failed']
        rows.append(cells)
    print(format_table(header, rows))
    failed = [r for r in results if not r.ok]
    if failed:
        print()
        print(f'{len(failed)} of {len(results)} jobs failed:')
        for r in failed:
            print(f'job {r.job.index + 1}: {r.error}')


def csv_text(results: list[JobResult]) -> str:
    """One CSV row per job: inputs, status, summary values (full precision) or the error.

    The electrical energy totals at the motor terminals and the supply side are empty where
    the job's machine declares no drives (``docs/electrical.md``)."""
    axes = _axes(results)
    header = (['job', 'program', 'machine', 'load [kg]', 'status', 'duration [s]', 'samples',
               'rate [Hz]', 'energy [J]', 'peak power [W]', 'loss energy [J]',
               'braking energy [J]']
              + [f'energy {a} [J]' for a in axes] + [f'peak power {a} [W]' for a in axes]
              + ['machine name', 'error', 'energy uncertainty [J]']
              + [f'energy by {g} [J]' for g in ROLLUP_COLUMNS]
              + ['motor energy [J]', 'supply energy [J]'])
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator='\n')
    writer.writerow(header)
    for r in results:
        job = r.job
        row = [job.index + 1, job.program, job.machine, repr(job.load_kg)]
        if r.ok:
            s = r.summary
            row += ['ok', repr(s['duration_s']), s['samples'], repr(s['rate_hz']),
                    repr(s['energy_j']['total']), repr(s['peak_power_w']['total']),
                    repr(s['loss_energy_j']), repr(s['regenerated_energy_j'])]
            row += [repr(s['energy_j'][a]) if a in s['energy_j'] else '' for a in axes]
            row += [repr(s['peak_power_w'][a]) if a in s['peak_power_w'] else '' for a in axes]
            row += [s['machine'], '', _uncertainty(s)]
            row += [rollup_cell(s, g) for g in ROLLUP_COLUMNS]
            row += ['' if e is None else repr(e) for e in
                    (_electrical(s, 'motor_energy_j'), _electrical(s, 'supply_energy_j'))]
        else:
            row += ['failed'] + [''] * (7 + 2 * len(axes)) + ['', r.error, '']
            row += [''] * (len(ROLLUP_COLUMNS) + 2)
        writer.writerow(row)
    return buf.getvalue()


ROLLUP_COLUMNS = ('operation', 'tool')
"""Roll-ups in the CSV, one cell each (the JSON output has all of them, ``rollups``)."""


def _uncertainty(summary: dict) -> str:
    """The loss-function uncertainty of the total [J], or '' where not known."""
    spread = summary.get('energy_uncertainty')
    return repr(spread['energy_sd_j']['total']) if spread else ''


def rollup_cell(summary: dict, group: str) -> str:
    """A roll-up as one compact cell: a JSON object ``{name: J}``, largest energy first.

    JSON, so that names with commas, semicolons or quotes (CAM comments) come back intact
    with ``json.loads``; empty where the run has no roll-ups (a trajectory CSV, declared
    effects that need the whole record).
    """
    import json
    items = (summary.get('rollups') or {}).get(group)
    if not items:
        return ''
    return json.dumps({str(it['name']): it['energy_j'] for it in items}, ensure_ascii=False,
                      separators=(',', ':'))


def check_csv_target(path: Path, *, force: bool) -> None:
    """Refuse a --csv target that is a link, a directory, exists (without force) or has no parent.

    Raises
    ------
    ConfigError
        Naming the option and the path.
    """
    shown = shorten(str(path))
    if os.path.islink(path):
        msg = f'{shown!r} is a symbolic link; not written through'
        raise ConfigError(msg, file='command line', key='csv')
    if os.path.lexists(path):
        if os.path.isdir(path):
            msg = f'{shown!r} is a directory; name a file'
            raise ConfigError(msg, file='command line', key='csv')
        if not force:
            msg = f'{shown!r} exists already; choose a new name or add --force'
            raise ConfigError(msg, file='command line', key='csv')
    parent = Path(path).parent
    if os.path.islink(parent) or not parent.is_dir():
        msg = f'the directory of {shown!r} does not exist or is a symbolic link'
        raise ConfigError(msg, file='command line', key='csv')


def write_csv(path: Path, text: str, *, force: bool = False) -> None:
    """Write the CSV ``text`` to the ``--csv`` target ``path``, line ends untranslated.

    :func:`check_csv_target` first (its directory must exist, not be a link), then
    :func:`feed_axis_energy.outputs.write_text_atomic`.

    Raises
    ------
    ConfigError
        As :func:`check_csv_target`.
    OutputError
        The file appeared while writing (without ``force``), or the disk refused (nothing
        is left).
    """
    check_csv_target(path, force=force)
    write_text_atomic(path, text, option='--csv', force=force, newline='')
