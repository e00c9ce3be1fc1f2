"""The measured-run type shared by the CSV and bag loaders (:mod:`.csvload`,
:mod:`.bagload`), and the checks both apply."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..errors import DataError, shorten
from ..physics import last_direction
from .campaign import RunSpec, TimeWindow

__all__ = ['GAP_FACTOR', 'MeasuredRun', 'check_duration', 'check_gaps', 'take_window']

GAP_FACTOR = 1.5
"""A time step longer than this many median periods is a gap."""


@dataclass(frozen=True)
class MeasuredRun:
    """A measured run in SI units; arrays follow ``(n_samples, n_axes)``.

    Attributes
    ----------
    name
        Run name from the manifest.
    file
        The data file.
    t
        Sample times [s], strictly increasing, starting at 0 (the original start is
        ``extra['t0_s']``), shape ``(n,)``.
    axes
        All axes of the run, in manifest order (``k`` of them).
    power_axes
        The axes that have measured power (a subset of ``axes``, same order).
    power_w
        Measured power [W], shape ``(n, len(power_axes))`` (``(n, 0)`` for a drive trace
        without power columns).
    position_m, velocity_m_s, acceleration_m_s2
        Actual kinematics, shape ``(n, k)``, or ``None`` if not mapped.
    command_position_m, command_velocity_m_s, command_acceleration_m_s2
        Commanded kinematics, shape ``(n, k)``, or ``None`` if not mapped.
    load_kg
        Load on the table [kg].
    extra
        ``excluded_rows`` (count), ``rows`` (1-based file data row of each sample),
        ``t0_s``, ``current_a`` / ``voltage_v`` / ``torque_nm`` / ``force_n`` (axis ->
        ``(n,)``) when mapped.
    """

    name: str
    file: str
    t: np.ndarray
    axes: tuple[str, ...]
    power_axes: tuple[str, ...]
    power_w: np.ndarray
    load_kg: float
    position_m: np.ndarray | None = None
    velocity_m_s: np.ndarray | None = None
    acceleration_m_s2: np.ndarray | None = None
    command_position_m: np.ndarray | None = None
    command_velocity_m_s: np.ndarray | None = None
    command_acceleration_m_s2: np.ndarray | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def total_power_w(self) -> np.ndarray:
        """Sum of the measured axis powers [W], shape ``(n,)``."""
        return self.power_w.sum(axis=1)

    def derivatives(self, source: str) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Measured velocity [m/s] and acceleration [m/s^2] of ``source``, ``None`` if unmapped.

        ``source`` is ``'actual'`` or ``'commanded'``, as for :meth:`positions`.
        """
        if source == 'commanded':
            return self.command_velocity_m_s, self.command_acceleration_m_s2
        return self.velocity_m_s, self.acceleration_m_s2

    def positions(self, source: str) -> np.ndarray:
        """Positions to rebuild the motion from: ``source`` is ``'actual'`` or ``'commanded'``.

        Parameters
        ----------
        source
            ``'actual'`` or ``'commanded'``.

        Returns
        -------
        numpy.ndarray
            Positions [m], shape ``(n, k)``.

        Raises
        ------
        DataError
            If the run has no such position columns.
        """
        arr = {'actual': self.position_m, 'commanded': self.command_position_m}.get(source)
        if arr is None:
            msg = f'run {shorten(self.name)!r} has no {source} position columns'
            raise DataError(msg, file=self.file)
        return arr


def check_duration(t: np.ndarray, spec: RunSpec, min_duration_s: float | None, *, file: str,
                   after: str = '') -> None:
    """Raise :class:`DataError` if the run is shorter than ``min_duration_s``.

    ``None`` means the run's own ``spec.min_duration_s``; ``after`` qualifies the duration
    in the message (e.g. ``' after filtering'``).
    """
    duration = float(t[-1] - t[0])
    limit = spec.min_duration_s if min_duration_s is None else min_duration_s
    if duration < limit:
        msg = f'run lasts {duration:.6g} s{after}, shorter than the minimum {limit:g} s'
        raise DataError(msg, file=file)


def check_gaps(t: np.ndarray, spec: RunSpec, *, file: str, column: str,
               rows: np.ndarray | None = None) -> None:
    """Raise :class:`DataError` at the first gap, unless ``spec.allow_gaps``.

    A gap is a time step longer than :data:`GAP_FACTOR` median periods of the increasing
    times ``t`` [s]. The error names ``column`` (the time column, or the topic) and the
    sample after the gap as ``row``: ``rows[i]`` (the CSV data row of each sample), or the
    1-based sample number when ``rows`` is ``None``.
    """
    if spec.allow_gaps:
        return
    median = float(np.median(np.diff(t), overwrite_input=True))  # before the steps are kept
    dt = np.diff(t)
    gaps = np.flatnonzero(dt > GAP_FACTOR * median)
    if gaps.size:
        i = int(gaps[0]) + 1
        msg = (f'gap of {dt[i - 1]:.6g} s before this row, more than {GAP_FACTOR:g} x the '
               f'median period {median:.6g} s (set allow_gaps: true to accept it)')
        raise DataError(msg, file=file, column=column,
                        row=i + 1 if rows is None else int(rows[i]))


_PER_SAMPLE = ('position_m', 'velocity_m_s', 'acceleration_m_s2', 'command_position_m',
               'command_velocity_m_s', 'command_acceleration_m_s2')


def take_window(run: MeasuredRun, window: TimeWindow | None, *,
                key: str = 'window') -> MeasuredRun:
    """The samples of ``run`` inside ``window`` (all of it for ``None``), time from 0 again.

    ``extra['t0_s']`` moves by the window's start, ``extra['rows']`` keeps the file rows of
    the samples kept, ``extra['window_s']`` records ``(start, end)`` [s] from the record's
    first sample and ``extra['direction_before']`` (axis -> -1, 0, +1) the direction each axis
    last moved in before the window (from the measured velocity); every per-sample array
    (kinematics, power, current, voltage, torque, force) is cut alike.

    Raises
    ------
    DataError
        Fewer than 2 samples in the window (naming the window, the record's duration and
        ``key``, the manifest key).
    """
    if window is None:
        return run
    duration = float(run.t[-1] - run.t[0])
    start, end = window.bounds_s(duration)
    rel = run.t - run.t[0]
    keep = (rel >= start) & (rel < end)
    if int(keep.sum()) < 2:
        msg = (f'{key}: the window {window.describe()} holds {int(keep.sum())} sample(s) of '
               f'a record of {duration:.6g} s; it needs at least 2')
        raise DataError(msg, file=run.file)
    idx = np.flatnonzero(keep)
    t = run.t[idx]
    shift = float(t[0])
    extra = dict(run.extra)
    for name in ('current_a', 'voltage_v', 'torque_nm', 'force_n'):
        if name in extra:
            extra[name] = {a: np.asarray(v)[idx] for a, v in extra[name].items()}
    if extra.get('rows') is not None:
        extra['rows'] = np.asarray(extra['rows'])[idx]
    extra['t0_s'] = float(extra.get('t0_s', 0.0)) + shift
    extra['window_s'] = (shift, float(t[-1]))
    for source in (run.velocity_m_s, run.command_velocity_m_s):
        if source is not None and idx[0] > 0:
            # the direction each axis last moved in before the window: what a drive holds at
            # rest depends on it (physics/standstill.py), and the window cut it off
            before = last_direction(source[:idx[0]])[-1]
            extra['direction_before'] = dict(zip(run.axes, (float(d) for d in before)))
            break
    arrays = {name: getattr(run, name)[idx] for name in _PER_SAMPLE
              if getattr(run, name) is not None}
    return replace(run, t=t - shift, power_w=run.power_w[idx], extra=extra, **arrays)
