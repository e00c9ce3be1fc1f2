"""Where a fitted loss function or effect is valid: the speeds, loads, positions it saw.

``fit-loss --out-machine`` writes, beside each fitted ``loss``, the axis key::

    loss_calibrated: {feed_mm_s: [6.0, 20.0], load_kg: [0.0, 0.0]}

(the feeds of the steady segments used and the loads of the runs fitted);
``analyze --out-machine`` writes ``calibrated: {feed_mm_s, load_kg, position_m}`` into each
effect it adds. :func:`range_warnings` compares such a range with the speeds, loads and
positions a loss or effect is applied at, so ``compare``, ``fit-loss`` and ``analyze`` can
say when it is extrapolated. Only steady
motion counts (``|a|`` at most ``max_accel_m_s2``): every move passes through low speeds
while it accelerates, which says nothing about the steady loss.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..configcheck import check_mapping, is_finite_number
from ..errors import ConfigError, describe

__all__ = ['CalibratedRange', 'calibrated_from_value', 'RangeUse', 'range_warnings',
           'observed_range', 'machine_warnings']

_LIMITS = {'feed_mm_s': 1.0e6, 'load_kg': 1.0e6, 'position_m': 1.0e3}


@dataclass(frozen=True)
class CalibratedRange:
    """Speeds and loads a loss function was fitted on.

    Attributes
    ----------
    feed_mm_s
        ``(lowest, highest)`` steady feed of the fit [mm/s].
    load_kg
        ``(lowest, highest)`` load of the runs fitted [kg], or ``None`` (not recorded).
    position_m
        ``(lowest, highest)`` position travelled while moving [m], or ``None``.
    """

    feed_mm_s: tuple[float, float]
    load_kg: tuple[float, float] | None = None
    position_m: tuple[float, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        """YAML form."""
        out: dict[str, Any] = {'feed_mm_s': [float(v) for v in self.feed_mm_s]}
        if self.load_kg is not None:
            out['load_kg'] = [float(v) for v in self.load_kg]
        if self.position_m is not None:
            out['position_m'] = [float(v) for v in self.position_m]
        return out


def _pair(value: Any, *, file: str, key: str, limit: float,
          signed: bool = False) -> tuple[float, float]:
    if (not isinstance(value, (list, tuple)) or len(value) != 2
            or not all(is_finite_number(v) for v in value)):
        msg = f'expected a list [low, high] of two finite numbers, got {describe(value)}'
        raise ConfigError(msg, file=file, key=key)
    low, high = float(value[0]), float(value[1])
    if not (-limit if signed else 0.0) <= low <= high <= limit:
        floor = f'-{limit:g}' if signed else '0'
        msg = f'expected {floor} <= low <= high <= {limit:g}, got [{low:g}, {high:g}]'
        raise ConfigError(msg, file=file, key=key)
    return low, high


def calibrated_from_value(value: Any, *, file: str, key: str) -> CalibratedRange | None:
    """Validate an axis's ``loss_calibrated`` mapping (``None`` when absent).

    Raises
    ------
    ConfigError
        Not a mapping of ``feed_mm_s`` (required) and ``load_kg`` pairs ``[low, high]``
        with ``0 <= low <= high``, naming the dotted key.
    """
    if value is None:
        return None
    d = check_mapping(value, file=file, key=key, allowed=tuple(_LIMITS))
    if 'feed_mm_s' not in d:
        raise ConfigError('missing required value; expected [low, high] [mm/s]', file=file,
                          key=f'{key}.feed_mm_s')
    feed = _pair(d['feed_mm_s'], file=file, key=f'{key}.feed_mm_s', limit=_LIMITS['feed_mm_s'])
    load = (_pair(d['load_kg'], file=file, key=f'{key}.load_kg', limit=_LIMITS['load_kg'])
            if 'load_kg' in d else None)
    pos = (_pair(d['position_m'], file=file, key=f'{key}.position_m',
                 limit=_LIMITS['position_m'], signed=True) if 'position_m' in d else None)
    return CalibratedRange(feed_mm_s=feed, load_kg=load, position_m=pos)


@dataclass(frozen=True)
class RangeUse:
    """How one run uses one axis: its load and its samples of speed and acceleration.

    Attributes
    ----------
    run
        Run name (for the message).
    load_kg
        Load of the run [kg].
    speed_m_s, accel_m_s2
        Speed ``|v|`` [m/s] and acceleration [m/s^2] of the axis, ``(n,)``; ``accel_m_s2``
        ``None`` when unknown (every moving sample counts).
    position_m
        Position of the axis [m], ``(n,)``, or ``None`` (not checked).
    """

    run: str
    load_kg: float
    speed_m_s: np.ndarray
    accel_m_s2: np.ndarray | None = None
    position_m: np.ndarray | None = None


def range_warnings(ranges: Mapping[str, CalibratedRange | None],
                   uses: Mapping[str, Sequence[RangeUse]], *, what: str = 'loss function',
                   max_accel_m_s2: float = 0.05, min_speed_m_s: float = 0.5e-3,
                   rel_tol: float = 0.05) -> list[str]:
    """Warnings for axes used outside their calibrated speeds or loads.

    Parameters
    ----------
    ranges
        Axis -> calibrated range (``None``: not recorded, no warning).
    uses
        Axis -> the runs that apply it.
    what
        Name of the thing calibrated, for the message.
    max_accel_m_s2, min_speed_m_s
        A sample counts when ``|a| <= max_accel_m_s2`` and ``|v| >= min_speed_m_s``.
    rel_tol
        Speeds within this fraction of the range ends count as inside.

    Returns
    -------
    list of str
        One sentence per axis and kind (speed, load), with figures and units.
    """
    out = []
    for axis, rng in ranges.items():
        if rng is None or not uses.get(axis):
            continue
        low, high = rng.feed_mm_s
        speeds = []
        for use in uses[axis]:
            s = np.abs(np.asarray(use.speed_m_s, dtype=float)) * 1000.0
            keep = s >= min_speed_m_s * 1000.0
            if use.accel_m_s2 is not None:
                keep &= np.abs(np.asarray(use.accel_m_s2, dtype=float)) <= max_accel_m_s2
            speeds.append(s[keep & np.isfinite(s)])
        steady = np.concatenate(speeds) if speeds else np.zeros(0)
        outside = (steady < low * (1.0 - rel_tol)) | (steady > high * (1.0 + rel_tol))
        if steady.size and np.any(outside):
            out.append(f'axis {axis}: {what} calibrated at {low:.3g}-{high:.3g} mm/s is used at '
                       f'{steady.min():.3g}-{steady.max():.3g} mm/s ('
                       f'{100.0 * np.mean(outside):.1f} % of the steady moving samples '
                       'outside): extrapolated')
        if rng.position_m is not None:
            lo_m, hi_m = rng.position_m
            pos_parts = [np.asarray(u.position_m, dtype=float)[
                np.abs(np.asarray(u.speed_m_s)) >= min_speed_m_s]
                for u in uses[axis] if u.position_m is not None]
            pos = np.concatenate(pos_parts) if pos_parts else np.zeros(0)
            # a quarter of a millimetre: the sampling of a position range is not exact
            off = (pos < lo_m - 2.5e-4) | (pos > hi_m + 2.5e-4)
            if pos.size and np.any(off):
                out.append(f'axis {axis}: {what} calibrated at positions '
                           f'{1e3 * lo_m:.1f}-{1e3 * hi_m:.1f} mm is used at '
                           f'{1e3 * pos.min():.1f}-{1e3 * pos.max():.1f} mm '
                           f'({100.0 * np.mean(off):.1f} % of the moving samples outside): '
                           'extrapolated')
        if rng.load_kg is not None:
            lo_kg, hi_kg = rng.load_kg
            off_kg = sorted({u.load_kg for u in uses[axis]
                             if not lo_kg - 1e-9 <= u.load_kg <= hi_kg + 1e-9})
            if off_kg:
                shown = ', '.join(f'{v:g}' for v in off_kg)
                out.append(f'axis {axis}: {what} calibrated at loads {lo_kg:g}-{hi_kg:g} kg is '
                           f'used at {shown} kg: extrapolated')
    return out


def observed_range(uses: Sequence[RangeUse], *, max_accel_m_s2: float = 0.05,
                   min_speed_m_s: float = 0.5e-3) -> CalibratedRange | None:
    """The range a fit on ``uses`` saw: steady speeds, loads, positions while moving.

    ``None`` when no sample is moving steadily.
    """
    speeds, positions = [], []
    for u in uses:
        s = np.abs(np.asarray(u.speed_m_s, dtype=float))
        moving = s >= min_speed_m_s
        steady = moving if u.accel_m_s2 is None else (
            moving & (np.abs(np.asarray(u.accel_m_s2, dtype=float)) <= max_accel_m_s2))
        speeds.append(s[steady])
        if u.position_m is not None:
            positions.append(np.asarray(u.position_m, dtype=float)[moving])
    speed = np.concatenate(speeds) if speeds else np.zeros(0)
    if not speed.size:
        return None
    pos = np.concatenate(positions) if positions else np.zeros(0)
    loads = [u.load_kg for u in uses]
    return CalibratedRange(
        feed_mm_s=(float(1e3 * speed.min()), float(1e3 * speed.max())),
        load_kg=(float(min(loads)), float(max(loads))),
        position_m=(float(pos.min()), float(pos.max())) if pos.size else None)


def machine_warnings(machine: Any, uses: Mapping[str, Sequence[RangeUse]]) -> list[str]:
    """Range warnings of a machine's loss functions and declared effects.

    Parameters
    ----------
    machine
        A :class:`~.machine.Machine` (axes with ``loss_calibrated``, effects with
        ``calibrated``).
    uses
        Axis -> the runs that apply it.
    """
    out = range_warnings({a.name: a.loss_calibrated for a in machine.axes}, uses)
    for e in machine.effects:
        if e.calibrated is None:
            continue
        axes = [e.axis] if e.axis is not None else [a.name for a in machine.axes]
        out += range_warnings({a: e.calibrated for a in axes}, uses,
                              what=f'effect {e.id}')
    return out
