"""Import measured runs into rosbag2/MCAP bags (layout in :mod:`.bagload`), all or nothing.

Every destination is checked first (run names and the manifest name must be plain names
confined to the output directory, none may exist, :mod:`..outputs`) and every run is loaded
and checked (CSV errors stop the import before anything is written); each bag is written
into a hidden temporary directory next to its destination and renamed into place when
complete. A manifest listing the bags (same machine, loads, roles and motion sources) is
written last, so the imported runs can be used wherever the CSV runs were. If anything fails
part-way (or SIGTERM/SIGINT arrive), every bag this import wrote is removed again.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
import hashlib
import os
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np
import yaml

from ..record import bagio, StreamBagWriter
from ..physics import EnergyIntegrator
from ..errors import ConfigError, DataError, OutputError, shorten
from ..outputs import check_target, confined, Rollback, staged_directory, write_text_atomic
from ..units import si_unit_of
from .bagload import (QUANTITY_TOPIC, RUN_KEY, TOPIC_MEASURED_COMMAND, TOPIC_MEASURED_ELECTRICAL,
                      electrical_joint)
from .csvload import load_run
from .run import MeasuredRun
from .campaign import AXIS_QUANTITIES, Campaign, RunSpec

__all__ = ['FORMAT_VERSION', 'ImportedRun', 'ImportResult', 'excerpt_run', 'run_series',
           'run_metadata', 'write_run_bag', 'bag_manifest', 'import_campaign']

FORMAT_VERSION = 1
"""Version of the metadata object stored under :data:`.bagload.RUN_KEY`."""


@dataclass(frozen=True)
class ImportedRun:
    """One bag written by the import.

    Attributes
    ----------
    name
        Run name.
    bag
        The bag directory.
    samples
        Number of samples.
    duration_s
        Time from first to last sample [s].
    messages
        Messages written (all topics).
    size_bytes
        Size of the bag directory's files.
    """

    name: str
    bag: Path
    samples: int
    duration_s: float
    messages: int
    size_bytes: int


@dataclass(frozen=True)
class ImportResult:
    """What :func:`import_campaign` wrote: the bags and the manifest listing them."""

    runs: tuple[ImportedRun, ...]
    manifest: Path


def excerpt_run(run: MeasuredRun, *, start_s: float = 0.0,
                duration_s: float | None = None) -> MeasuredRun:
    """Return the samples with ``start_s <= t <= start_s + duration_s``, time from 0 again.

    Parameters
    ----------
    run
        A loaded run.
    start_s
        Start of the excerpt, in the run's time [s].
    duration_s
        Length [s]; ``None`` keeps everything from ``start_s`` on.

    Returns
    -------
    MeasuredRun
        The excerpt; ``extra['t0_s']`` and ``extra['rows']`` still point into the source.

    Raises
    ------
    DataError
        When fewer than 2 samples fall into the excerpt.
    """
    stop = np.inf if duration_s is None else start_s + duration_s
    eps = 1e-9
    keep = (run.t >= start_s - eps) & (run.t <= stop + eps)
    if int(keep.sum()) < 2:
        msg = (f'excerpt {start_s:g} s + {duration_s} s of run {run.name!r} holds '
               f'{int(keep.sum())} samples (the run lasts {run.t[-1]:.6g} s); need at least 2')
        raise DataError(msg, file=run.file)
    first = int(np.flatnonzero(keep)[0])
    arrays: dict[str, Any] = {}
    for name in ('position_m', 'velocity_m_s', 'acceleration_m_s2', 'command_position_m',
                 'command_velocity_m_s', 'command_acceleration_m_s2'):
        arr = getattr(run, name)
        arrays[name] = None if arr is None else arr[keep]
    extra = dict(run.extra)
    extra['t0_s'] = float(run.extra.get('t0_s', 0.0) + run.t[first])
    if 'rows' in extra:
        extra['rows'] = np.asarray(extra['rows'])[keep]
    for key in ('current_a', 'voltage_v'):
        if key in extra:
            extra[key] = {a: v[keep] for a, v in extra[key].items()}
    return replace(run, t=run.t[keep] - run.t[first], power_w=run.power_w[keep], extra=extra,
                   **arrays)


def run_series(run: MeasuredRun) -> dict[str, bagio.Series]:
    """Return ``{topic: Series}`` of a run in the measured-run bag layout (see :mod:`.bagload`).

    Parameters
    ----------
    run
        The run (SI).

    Returns
    -------
    dict
        Power always; kinematics, command and electrical topics when the run has them.
    """
    t = run.t
    power = np.column_stack([run.power_w, run.total_power_w])
    energy = EnergyIntegrator(power.shape[1]).update(t, power)
    out = {bagio.TOPIC_MEASURED_POWER: bagio.Series(
        t=t, names=tuple(run.power_axes) + ('total',), positions=energy, velocities=power)}
    for topic, fields in ((bagio.TOPIC_MEASURED_KINEMATICS,
                           ('position_m', 'velocity_m_s', 'acceleration_m_s2')),
                          (TOPIC_MEASURED_COMMAND,
                           ('command_position_m', 'command_velocity_m_s',
                            'command_acceleration_m_s2'))):
        arrays = [getattr(run, f) for f in fields]
        if any(a is not None for a in arrays):
            out[topic] = bagio.Series(t=t, names=tuple(run.axes), positions=arrays[0],
                                      velocities=arrays[1], accelerations=arrays[2])
    names: list[str] = []
    cols: list[np.ndarray] = []
    for key, quantity in (('current_a', 'current'), ('voltage_v', 'voltage')):
        for axis, values in run.extra.get(key, {}).items():
            names.append(electrical_joint(axis, quantity))
            cols.append(np.asarray(values, dtype=float))
    if names:
        out[TOPIC_MEASURED_ELECTRICAL] = bagio.Series(t=t, names=tuple(names),
                                                      positions=np.column_stack(cols))
    return out


def _row_ranges(rows: np.ndarray) -> list[list[int]]:
    rows = np.asarray(rows, dtype=np.int64)
    if rows.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(rows) != 1) + 1
    starts = np.concatenate(([0], breaks))
    ends = np.concatenate((breaks, [rows.size]))
    return [[int(rows[s]), int(e - s)] for s, e in zip(starts, ends)]


def _relative(path: str | Path, base: Path | None = None) -> str:
    """``path`` relative to ``base`` (default: the working directory), POSIX style."""
    base = Path.cwd().resolve() if base is None else base
    try:
        return Path(os.path.relpath(Path(path).resolve(), base)).as_posix()
    except ValueError:  # pragma: no cover - another drive on Windows
        return Path(path).as_posix()


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, 'rb') as fh:
        for block in iter(lambda: fh.read(1 << 20), b''):
            digest.update(block)
    return digest.hexdigest()


def run_metadata(run: MeasuredRun, spec: RunSpec, *,
                 excerpt: tuple[float, float | None] | None = None) -> dict[str, Any]:
    """Describe a run for the bag's ``custom_data`` (JSON-serialisable).

    Parameters
    ----------
    run
        The (possibly excerpted) run.
    spec
        Its manifest entry: source file, columns and units converted from.
    excerpt
        ``(start_s, duration_s)`` when the bag holds an excerpt.

    Returns
    -------
    dict
        ``format_version``, ``name``, ``load_kg``, ``role``, ``axes``, ``power_axes``,
        ``source`` (file name, path, SHA-256, manifest and key), ``columns`` (axis ->
        quantity -> column, unit converted from, SI unit), ``time``, ``motion``, ``t0_s``,
        ``excluded_rows``, ``rows`` (``[[first, count], ...]`` 1-based data rows of the
        source), ``excerpt``, ``energy`` (integration rule).
    """
    # Paths are kept relative to the manifest (and the manifest to the working directory
    # where possible), so a bag does not carry one machine's directory layout.
    manifest_dir = Path(spec.manifest).resolve().parent
    source: dict[str, Any] = {'file': spec.data.name,
                              'path': _relative(spec.data, manifest_dir),
                              'path_base': 'manifest directory',
                              'kind': spec.data_kind, 'manifest': _relative(spec.manifest),
                              'key': spec.key}
    if spec.data.is_file():
        source['sha256'] = _sha256(spec.data)
    columns = {axis: {q: {'column': cs.column, 'unit': cs.unit,
                          'si_unit': si_unit_of(cs.unit, quantity=AXIS_QUANTITIES[q])}
                      for q, cs in cols.items()}
               for axis, cols in spec.axes.items()}
    time: dict[str, Any]
    if spec.time is not None:
        time = {'column': spec.time.column, 'unit': spec.time.unit}
    else:
        time = {'period_s': spec.period_s}
    motion: dict[str, Any]
    if spec.motion_program is not None:
        motion = {'program': str(spec.motion_program)}
    else:
        motion = {'from_data': spec.motion_from_data}
    return {
        'format_version': FORMAT_VERSION, 'name': run.name, 'load_kg': run.load_kg,
        'role': spec.role, 'axes': list(run.axes), 'power_axes': list(run.power_axes),
        'source': source, 'columns': columns, 'time': time, 'motion': motion,
        't0_s': float(run.extra.get('t0_s', 0.0)),
        'excluded_rows': int(run.extra.get('excluded_rows', 0)),
        'rows': _row_ranges(run.extra.get('rows', np.zeros(0))),
        'excerpt': None if excerpt is None else {'start_s': excerpt[0],
                                                 'duration_s': excerpt[1]},
        'energy': 'cumulative trapezoid rule of the power samples, from 0 J at t = 0',
    }


def write_run_bag(path: str | Path, run: MeasuredRun, *, metadata: dict[str, Any],
                  batch: int = 100, option: str = 'bag') -> ImportedRun:
    """Write one run as a rosbag2/MCAP directory, renamed into place only when complete.

    Parameters
    ----------
    path
        Bag directory to create; it must not exist.
    run
        The run (SI).
    metadata
        Stored as JSON under :data:`.bagload.RUN_KEY` in ``custom_data``.
    batch
        Samples per message.
    option
        What ``path`` comes from, for error messages.

    Returns
    -------
    ImportedRun
        What was written.

    Raises
    ------
    OutputError
        If ``path`` exists or is a symbolic link.
    """
    path = Path(path)
    messages = 0
    # The bag is named after its directory (the MCAP file too): staged_directory builds it
    # under its final name inside a hidden temporary directory.
    with staged_directory(path, option=option, forceable=False) as staged, \
            StreamBagWriter(staged) as writer:
        for topic, series in run_series(run).items():
            messages += writer.write_series(topic, series, batch=batch)
        writer.set_custom_data(RUN_KEY, metadata)
    size = sum(f.stat().st_size for f in path.iterdir() if f.is_file())
    return ImportedRun(name=run.name, bag=path, samples=int(run.t.shape[0]),
                       duration_s=float(run.t[-1] - run.t[0]), messages=messages,
                       size_bytes=size)


def bag_manifest(campaign: Campaign, runs: Sequence[tuple[RunSpec, MeasuredRun, Path]], *,
                 out_file: Path) -> dict[str, Any]:
    """Return the manifest (YAML form) of imported bags, with paths relative to ``out_file``.

    Parameters
    ----------
    campaign
        The source campaign (machine, name).
    runs
        ``(spec, run, bag)`` per imported run.
    out_file
        Where the manifest will be written.

    Returns
    -------
    dict
        A manifest that :func:`.manifest.load_campaign` accepts and :func:`.csvload.load_run`
        loads through :func:`.bagload.load_run_from_bag`.
    """
    base = out_file.parent.resolve()

    def rel(p: Path) -> str:
        return Path(os.path.relpath(Path(p).resolve(), base)).as_posix()

    entries = []
    for spec, run, bag in runs:
        axes = {axis: {q: {'column': QUANTITY_TOPIC[q],
                           'unit': si_unit_of(cs.unit, quantity=AXIS_QUANTITIES[q])}
                       for q, cs in cols.items()}
                for axis, cols in spec.axes.items()}
        if spec.motion_program is not None:
            motion: dict[str, Any] = {'program': rel(spec.motion_program)}
            if spec.motion_start_m is not None:
                motion['start_m'] = dict(zip(('X', 'Y', 'Z'), spec.motion_start_m))
        else:
            motion = {'from_data': str(spec.motion_from_data)}
            if spec.motion_reconstruct != 'pulses':
                motion['reconstruct'] = spec.motion_reconstruct
        duration = float(run.t[-1] - run.t[0])
        entry: dict[str, Any] = {
            'name': spec.name, 'load_kg': spec.load_kg, 'motion': motion, 'data': rel(bag),
            # informational for bags: their stamps are used
            'period_s': round(float(np.median(np.diff(run.t))), 9),
            'axes': axes, 'min_duration_s': min(spec.min_duration_s, duration),
        }
        if spec.allow_gaps:
            entry['allow_gaps'] = True
        if spec.role is not None:
            entry['role'] = spec.role
        if spec.work_offset_m:
            entry['work_offset_m'] = dict(spec.work_offset_m)
        # a run's window was applied when it was loaded: its bag holds the window only
        meter = spec.instrument
        if meter.declared:
            entry['instrument'] = {'window_s': 'period' if meter.window_s is None
                                   else meter.window_s, 'stamp': meter.stamp}
        if meter.measures != 'shaft':
            entry.setdefault('instrument', {})['measures'] = meter.measures
        if meter.kt_nm_a:
            entry.setdefault('instrument', {})['kt_nm_a'] = dict(meter.kt_nm_a)
        if meter.invert:
            entry.setdefault('instrument', {})['invert'] = list(meter.invert)
        if meter.filter_s:
            entry.setdefault('instrument', {})['filter_s'] = meter.filter_s
        entries.append(entry)
    return {
        'name': campaign.name,
        'description': f'rosbag2 import of {campaign.file.name}'
                       + (f': {campaign.description}' if campaign.description else ''),
        'machine': rel(campaign.machine),
        'runs': entries,
    }


def _destinations(specs: Sequence[RunSpec], out_dir: Path,
                  manifest_name: str) -> tuple[Path, list[tuple[Path, str]]]:
    """Check every destination before anything is written; the manifest and bag paths.

    Each run name and the manifest name must be one plain name (:func:`.outputs.confined`),
    no two may be equal ignoring case, and none may exist.
    """
    if os.path.lexists(out_dir) and not out_dir.is_dir():
        raise OutputError('is not a directory', path=out_dir, option='--out')
    options = [f'{Path(spec.manifest).name} {spec.key}.name' if spec.key else 'run name'
               for spec in specs]
    names = [spec.name for spec in specs]
    bags = []
    seen: dict[str, str] = {}
    for name, option in zip(names, options):
        bag = confined(out_dir, name, option=option, reserved=(manifest_name,),
                       why='the name of the manifest written into --out (--manifest-name)')
        other = seen.setdefault(name.casefold(), option)
        if other != option:
            raise OutputError(f'{shorten(name)!r} names the same bag directory as {other} on '
                              'a file system that ignores case', option=option)
        bags.append((check_target(bag, option=option, kind='directory', forceable=False),
                     option))
    manifest = confined(out_dir, manifest_name, option='--manifest-name',
                        reserved=tuple(names), why='the name of a run (a bag directory)')
    check_target(manifest, option='--manifest-name', kind='file', forceable=False)
    return manifest, bags


def import_campaign(campaign: Campaign, out_dir: str | Path, *,
                    runs: Sequence[str] | None = None, start_s: float = 0.0,
                    duration_s: float | None = None, manifest_name: str = 'campaign.yaml',
                    batch: int = 100,
                    progress: Callable[[float], None] | None = None) -> ImportResult:
    """Import runs of a campaign into ``out_dir/<run name>/`` bags plus a manifest.

    Parameters
    ----------
    campaign
        The source campaign.
    out_dir
        Output directory (created if needed); no bag directory or manifest there may exist.
    runs
        Run names to import; default all.
    start_s, duration_s
        Import only this excerpt of each run (default: all of it).
    manifest_name
        File name of the manifest written into ``out_dir``.
    batch
        Samples per message.
    progress
        Called with the fraction done.

    Returns
    -------
    ImportResult
        The bags and the manifest.

    Raises
    ------
    KeyError
        An unknown run name.
    OutputError
        A run name or ``manifest_name`` that is no plain name inside ``out_dir``, two
        destinations that are one, or a destination that exists (all checked before anything
        is written).
    DataError, ConfigError
        A run that cannot be loaded (before anything is written).
    """
    if start_s < 0 or (duration_s is not None and not duration_s > 0):
        msg = f'excerpt needs start_s >= 0 and duration_s > 0, got {start_s}, {duration_s}'
        raise ConfigError(msg, file='import', key='excerpt')
    out_dir = Path(out_dir)
    specs = [campaign.run(n) for n in runs] if runs else list(campaign.runs)
    manifest, bags = _destinations(specs, out_dir, manifest_name)
    excerpt = None if start_s == 0.0 and duration_s is None else (start_s, duration_s)
    for spec in specs:
        unstored = [f'{a}.{q}' for a, cols in spec.axes.items() for q in cols
                    if q not in QUANTITY_TOPIC]
        if not spec.power_axes or unstored:
            what = unstored[0] if unstored else 'a run without power columns'
            msg = (f'a measured-run bag holds power (and current, voltage, kinematics); '
                   f'{what} has no place in it: compare such a run from its CSV file')
            raise ConfigError(msg, file=spec.manifest, key=f'{spec.key}.axes')
    loaded = []
    for spec in specs:
        run = load_run(spec)
        if excerpt is not None:
            run = excerpt_run(run, start_s=start_s, duration_s=duration_s)
        loaded.append((spec, run))
    written = []
    with Rollback(created=out_dir) as rollback:
        for i, ((spec, run), (bag, option)) in enumerate(zip(loaded, bags)):
            meta = run_metadata(run, spec, excerpt=excerpt)
            written.append(write_run_bag(bag, run, metadata=meta, batch=batch, option=option))
            rollback.add(bag)
            if progress is not None:
                progress((i + 1) / (len(loaded) + 1))
        doc = bag_manifest(campaign, [(s, r, w.bag) for (s, r), w in zip(loaded, written)],
                           out_file=manifest)
        text = yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=99)
        write_text_atomic(manifest, '# Written by feed-axis-energy import; the bags are in SI '
                          '(see docs/measured.md).\n' + text, option='--manifest-name',
                          forceable=False)
    if progress is not None:
        progress(1.0)
    return ImportResult(runs=tuple(written), manifest=manifest)
