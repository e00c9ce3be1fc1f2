"""A commanded or measured trajectory in a CSV file as the motion source of ``simulate``.

The header names every column with its unit in brackets: a time column ``time [s]`` (or
``t [ms]`` ...) and one position column per axis, ``X [mm]``; optional velocity and
acceleration columns ``X_vel [mm/s]``, ``X_acc [mm/s^2]`` are used instead of differences
of the positions where present (see
:func:`~feed_axis_energy.plan.fromsamples.motion_from_samples`).
Example::

    time [s],X [mm],Y [mm]
    0.000,0.0,0.0
    0.001,0.0001,0.0
"""
from __future__ import annotations

from pathlib import Path
import re

import numpy as np

from ..csvtable import column_values, MIN_STEP_S, read_csv_table
from ..errors import ConfigError, DataError, shorten
from ..plan import Motion, motion_from_samples
from ..units import check_si_values, to_si

__all__ = ['load_trajectory_csv', 'TIME_NAMES']

TIME_NAMES = ('time', 't')
_HEADER_RE = re.compile(r'^\s*([A-Za-z_][A-Za-z0-9_]*)\s*\[\s*([^\]]+?)\s*\]\s*$')


def _columns(header: list[str], file: str) -> dict[str, tuple[int, str]]:
    out: dict[str, tuple[int, str]] = {}
    for j, cell in enumerate(header):
        m = _HEADER_RE.match(cell)
        if m is None:
            msg = 'header cell must read "NAME [UNIT]", e.g. "time [s]" or "X [mm]"'
            raise DataError(msg, file=file, column=cell or f'#{j + 1}')
        name = m.group(1)
        if name in out:
            raise DataError('column appears twice in the header', file=file, column=name)
        out[name] = (j, m.group(2))
    return out


def load_trajectory_csv(path: str | Path, *, axes: tuple[str, ...]) -> Motion:
    """Read a trajectory CSV and return its motion for the machine axes ``axes``.

    Parameters
    ----------
    path
        The CSV file (header ``NAME [UNIT]`` per column, see the module docstring).
    axes
        The machine's axis names; every one needs a position column, other columns with
        axis-like names are an error (they would silently be ignored otherwise).

    Returns
    -------
    Motion
        Positions, velocities and accelerations in SI units; ``line`` is 0 everywhere.

    Raises
    ------
    DataError
        Naming the file, the column and the row: missing columns, bad units, values that are
        not numbers, time not strictly increasing.
    """
    file = str(path)
    header, rows, numbers = read_csv_table(Path(path))
    cols = _columns(header, file)
    time_name = next((n for n in TIME_NAMES if n in cols), None)
    if time_name is None:
        raise DataError('no time column in the header; expected "time [s]" (or "t [...]")',
                        file=file)
    allowed = ({time_name} | set(axes) | {f'{a}_vel' for a in axes}
               | {f'{a}_acc' for a in axes})
    unknown = [n for n in cols if n not in allowed]
    if unknown:
        msg = (f'unknown column in the header; expected time, the axes {", ".join(axes)} '
               'and optional <axis>_vel, <axis>_acc columns')
        raise DataError(msg, file=file, column=unknown[0])

    def values(name: str, quantity: str) -> np.ndarray:
        j, unit = cols[name]
        raw = column_values(rows, j, numbers, file, name)
        try:
            si = to_si(raw, unit, quantity=quantity)
        except ConfigError as err:
            msg = f'unit {shorten(unit)!r} in the header: {err.reason}'
            raise DataError(msg, file=file, column=name) from err
        return check_si_values(si, file=file, column=name, rows=numbers)

    t = values(time_name, 'time')
    bad = np.nonzero(np.diff(t) < 0.999 * MIN_STEP_S)[0]
    if bad.size:
        msg = f'time is not strictly increasing by at least {MIN_STEP_S:g} s per row'
        raise DataError(msg, file=file, column=time_name, row=int(numbers[bad[0] + 1]))
    missing = [a for a in axes if a not in cols]
    if missing:
        msg = f'no position column for machine axis {missing[0]} in the header ' \
              f'(expected "{missing[0]} [mm]")'
        raise DataError(msg, file=file, column=missing[0])
    pos = np.column_stack([values(a, 'length') for a in axes])
    vel = acc = None
    if all(f'{a}_vel' in cols for a in axes):
        vel = np.column_stack([values(f'{a}_vel', 'velocity') for a in axes])
    if all(f'{a}_acc' in cols for a in axes):
        acc = np.column_stack([values(f'{a}_acc', 'acceleration') for a in axes])
    return motion_from_samples(t - t[0], pos, axes=tuple(axes), source=file, vel=vel, acc=acc)
