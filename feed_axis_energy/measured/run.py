"""The measured-run type shared by the CSV and bag loaders (:mod:`.csvload`,
:mod:`.bagload`), and the checks both apply."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import DataError, shorten
from .campaign import RunSpec

__all__ = ['GAP_FACTOR', 'MeasuredRun', 'check_duration', 'check_gaps']

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
