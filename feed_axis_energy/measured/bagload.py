"""The rosbag2 form of a measured run: topics, metadata, and loading it back as a MeasuredRun.

A measured-run bag (written by :mod:`.importer`) holds, all in SI and stamped in seconds
from the run start (integer nanoseconds in the bag; a bag stamped in wall-clock time, e.g.
recorded from the live graph, reads the same, times counted from its first stamp):

========================  ============================================================
topic                     content (``trajectory_msgs/msg/JointTrajectory``, batched)
========================  ============================================================
``/measured/power``       joints = power axes + ``total``; ``velocities`` = power [W],
                          ``positions`` = cumulative energy [J] (trapezoid rule)
``/measured/kinematics``  joints = axes; ``positions`` [m], ``velocities`` [m/s],
                          ``accelerations`` [m/s^2]: only the fields that were measured
``/measured/command``     as kinematics, for the controller's commanded values
``/measured/electrical``  joints ``<axis>/current`` [A] and ``<axis>/voltage`` [V], values
                          in ``positions`` (only when mapped)
========================  ============================================================

The bag's ``custom_data`` key :data:`RUN_KEY` holds a JSON object describing the run (name,
load, source file and its SHA-256, the columns and units converted from, rows kept).

A manifest run whose ``data`` is a rosbag2 directory is loaded by :func:`load_run_from_bag`.
Its ``axes`` mapping selects axes and quantities; each ``column`` names the topic the
quantity is read from (``/measured/power``, ``/measured/kinematics``, ``/measured/command``,
``/measured/electrical``) and each ``unit`` must be the SI unit, because bags are SI.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..record import bagio
from ..errors import ConfigError, DataError, describe, shorten
from ..units import check_si_values, si_unit_of
from .campaign import AXIS_QUANTITIES, KINEMATIC_QUANTITIES, RunSpec
from .run import check_duration, check_gaps, MeasuredRun

__all__ = [
    'TOPIC_MEASURED_COMMAND', 'TOPIC_MEASURED_ELECTRICAL', 'RUN_KEY', 'QUANTITY_TOPIC',
    'QUANTITY_FIELD', 'electrical_joint', 'load_run_from_bag', 'rows_from_ranges',
]

TOPIC_MEASURED_COMMAND = '/measured/command'
TOPIC_MEASURED_ELECTRICAL = '/measured/electrical'
RUN_KEY = 'feed_axis_energy/measured_run'

# manifest quantity -> topic it is stored on
QUANTITY_TOPIC: dict[str, str] = {
    'power': bagio.TOPIC_MEASURED_POWER,
    'position': bagio.TOPIC_MEASURED_KINEMATICS,
    'velocity': bagio.TOPIC_MEASURED_KINEMATICS,
    'acceleration': bagio.TOPIC_MEASURED_KINEMATICS,
    'command_position': TOPIC_MEASURED_COMMAND,
    'command_velocity': TOPIC_MEASURED_COMMAND,
    'command_acceleration': TOPIC_MEASURED_COMMAND,
    'current': TOPIC_MEASURED_ELECTRICAL,
    'voltage': TOPIC_MEASURED_ELECTRICAL,
}
# manifest quantity -> JointTrajectoryPoint field it is stored in
QUANTITY_FIELD: dict[str, str] = {
    'power': 'velocities',
    'position': 'positions', 'command_position': 'positions',
    'velocity': 'velocities', 'command_velocity': 'velocities',
    'acceleration': 'accelerations', 'command_acceleration': 'accelerations',
    'current': 'positions', 'voltage': 'positions',
}
_RUN_FIELD = {
    'position': 'position_m', 'velocity': 'velocity_m_s', 'acceleration': 'acceleration_m_s2',
    'command_position': 'command_position_m', 'command_velocity': 'command_velocity_m_s',
    'command_acceleration': 'command_acceleration_m_s2',
}


def electrical_joint(axis: str, quantity: str) -> str:
    """Joint name of an electrical quantity on ``/measured/electrical`` (``X/current``)."""
    return f'{axis}/{quantity}'


def rows_from_ranges(ranges: list[list[int]]) -> np.ndarray:
    """Expand ``[[first, count], ...]`` (1-based file data rows) into one row array."""
    parts = [np.arange(int(first), int(first) + int(count), dtype=np.int64)
             for first, count in ranges]
    return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)


def load_run_from_bag(spec: RunSpec, *, min_duration_s: float | None = None) -> MeasuredRun:
    """Load a manifest run whose data is a measured-run rosbag2 directory.

    Parameters
    ----------
    spec
        The run; ``spec.data`` is the bag directory.
    min_duration_s
        Reject runs shorter than this [s]; default ``spec.min_duration_s``.

    Returns
    -------
    MeasuredRun
        The run in SI; ``t`` starts at 0, exact to the nanosecond of the stamps (wall-clock
        stamps included: :attr:`.bagio.Series.t0_ns`). ``extra`` carries ``t0_s``,
        ``excluded_rows`` and ``rows`` from the bag's metadata when present (else the first
        stamp [s], 0 and the sample numbers).

    Raises
    ------
    ConfigError
        The manifest asks for row filters, a non-SI unit, or names another topic as column.
    DataError
        Not a bag, a missing topic, joint or field, topics with different stamps, time that
        does not increase, a gap (unless ``spec.allow_gaps``) or a run that is too short.
    """
    file = str(spec.data)
    _check_spec(spec)
    _require_bag(spec.data)
    meta = bagio.read_custom_data(spec.data, RUN_KEY)
    topics = bagio.bag_topics(spec.data)
    cache: dict[str, bagio.Series] = {}

    def series(topic: str) -> bagio.Series:
        if topic not in cache:
            if topic not in topics:
                have = shorten(', '.join(sorted(topics)), limit=200) or 'none'
                msg = f'topic {topic!r} is not in the bag (topics: {have})'
                raise DataError(msg, file=file, column=topic)
            cache[topic] = bagio.read_series(spec.data, topic)
        return cache[topic]

    power_s = series(bagio.TOPIC_MEASURED_POWER)
    t = power_s.t
    if t.shape[0] < 2:
        msg = f'needs at least 2 samples on {bagio.TOPIC_MEASURED_POWER}, has {t.shape[0]}'
        raise DataError(msg, file=file, column=bagio.TOPIC_MEASURED_POWER)

    def take(quantity: str, joints: list[str]) -> np.ndarray:
        topic = QUANTITY_TOPIC[quantity]
        s = series(topic)
        if s.t0_ns != power_s.t0_ns or s.t.shape != t.shape or not np.array_equal(s.t, t):
            msg = (f'stamps differ from those of {bagio.TOPIC_MEASURED_POWER} '
                   f'({s.t.shape[0]} vs {t.shape[0]} samples); every topic of a measured '
                   'run must share them')
            raise DataError(msg, file=file, column=topic)
        arr = getattr(s, QUANTITY_FIELD[quantity])
        if arr is None:
            msg = f'has no {QUANTITY_FIELD[quantity]} field, needed for {quantity}'
            raise DataError(msg, file=file, column=topic)
        cols = []
        for joint in joints:
            if joint not in s.names:
                names = shorten(', '.join(s.names), limit=200)
                msg = f'no joint {shorten(joint)!r} (joints: {names})'
                raise DataError(msg, file=file, column=topic)
            cols.append(arr[:, s.names.index(joint)])
        out = np.column_stack(cols).astype(np.float64)
        for j, joint in enumerate(joints):
            check_si_values(out[:, j], file=file, column='', topic=f'{topic} ({joint})')
        return out

    _check_time(t, spec, file)
    check_duration(t, spec, min_duration_s, file=file)

    axes = spec.axis_names
    power_axes = spec.power_axes
    power = take('power', list(power_axes))
    kin: dict[str, np.ndarray] = {}
    for q in KINEMATIC_QUANTITIES:
        if q in spec.axes[axes[0]]:
            kin[_RUN_FIELD[q]] = take(q, list(axes))
    extra: dict[str, Any] = {
        'excluded_rows': 0, 'rows': np.arange(1, t.shape[0] + 1, dtype=np.int64),
        't0_s': power_s.t0_ns / 1e9,
    }
    if meta is not None:
        extra.update(_run_metadata(meta, n=t.shape[0], file=file))
    for q, key in (('current', 'current_a'), ('voltage', 'voltage_v')):
        having = [a for a, cols in spec.axes.items() if q in cols]
        if having:
            arr = take(q, [electrical_joint(a, q) for a in having])
            extra[key] = {a: arr[:, j].copy() for j, a in enumerate(having)}
    return MeasuredRun(name=spec.name, file=file, t=t - t[0], axes=axes,
                       power_axes=power_axes, power_w=power, load_kg=spec.load_kg,
                       extra=extra, **kin)


def _run_metadata(meta: Any, *, n: int, file: str) -> dict[str, Any]:
    """``t0_s``, ``excluded_rows`` and ``rows`` from the run's JSON metadata, checked."""
    where = f'{file}/metadata.yaml'
    key = f'custom_data.{RUN_KEY}'
    if not isinstance(meta, dict):
        msg = f'{key}: expected a JSON object, got {describe(meta)}'
        raise DataError(msg, file=where)
    out: dict[str, Any] = {}
    t0 = meta.get('t0_s', 0.0)
    if isinstance(t0, bool) or not isinstance(t0, (int, float)) or not math.isfinite(t0):
        msg = f'{key}.t0_s: expected a finite number, got {describe(t0)}'
        raise DataError(msg, file=where)
    out['t0_s'] = float(t0)
    excluded = meta.get('excluded_rows', 0)
    if isinstance(excluded, bool) or not isinstance(excluded, int) or excluded < 0:
        msg = f'{key}.excluded_rows: expected a whole number >= 0, got {describe(excluded)}'
        raise DataError(msg, file=where)
    out['excluded_rows'] = excluded
    ranges = meta.get('rows', [])
    ok = isinstance(ranges, list) and all(
        isinstance(r, list) and len(r) == 2
        and all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in r)
        for r in ranges)
    if not ok:
        msg = (f'{key}.rows: expected a list of [first row, count] pairs of whole numbers, '
               f'got {describe(ranges)}')
        raise DataError(msg, file=where)
    # counted before expanding: a damaged count must not allocate a huge array
    if sum(count for _, count in ranges) == n:
        out['rows'] = rows_from_ranges(ranges)
    return out


def _require_bag(path: Path) -> None:
    bagio.read_metadata(path)


def _check_spec(spec: RunSpec) -> None:
    if spec.exclude:
        msg = ('row filters (rows.exclude_where) apply to CSV input only; a measured-run bag '
               'holds the rows kept at import')
        raise ConfigError(msg, file=spec.manifest, key=f'{spec.key}.rows')
    if not spec.power_axes:
        msg = ('a measured-run bag is stamped by its power topic; a trace without power '
               '(current, torque, force) is compared from its CSV file')
        raise ConfigError(msg, file=spec.manifest, key=f'{spec.key}.data')
    for axis, cols in spec.axes.items():
        for q, cs in cols.items():
            key = f'{spec.key}.axes.{axis}.{q}'
            if q not in QUANTITY_TOPIC:
                msg = f'a measured-run bag has no topic for {q}; read it from the CSV file'
                raise ConfigError(msg, file=spec.manifest, key=key)
            si = si_unit_of(cs.unit, quantity=AXIS_QUANTITIES[q])
            if cs.unit != si:
                msg = f'a rosbag2 run is in SI: the unit must be {si!r}, got {shorten(cs.unit)!r}'
                raise ConfigError(msg, file=spec.manifest, key=f'{key}.unit')
            if cs.column != QUANTITY_TOPIC[q]:
                msg = (f'for a rosbag2 run the column names the topic; {q} is on '
                       f'{QUANTITY_TOPIC[q]!r}, got {shorten(cs.column)!r}')
                raise ConfigError(msg, file=spec.manifest, key=f'{key}.column')


def _check_time(t: np.ndarray, spec: RunSpec, file: str) -> None:
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0.0)
    if bad.size:
        i = int(bad[0]) + 1
        msg = f'time does not increase at sample {i + 1} ({t[i - 1]:.9g} s then {t[i]:.9g} s)'
        raise DataError(msg, file=file, column=bagio.TOPIC_MEASURED_POWER, row=i + 1)
    check_gaps(t, spec, file=file, column=bagio.TOPIC_MEASURED_POWER)
