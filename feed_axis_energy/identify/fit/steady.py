"""Steady segments of measured runs and the loss power they show (paper, section 2.1).

Step 1 and 2 of :mod:`.lossfit`: stretches of steady motion of one axis and the mean
power spent on passive resistances during each (see that module's docstring).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math
from typing import Any

import numpy as np

from ...machine import Machine, moved_mass_kg, RangeUse
from ...errors import ConfigError, DataError
from ...units import GRAVITY_M_S2
from ...measured import GAP_FACTOR, MeasuredRun

__all__ = ['SteadyOptions', 'SteadySegment', 'steady_segments', 'run_segments',
           'range_uses', 'VELOCITY_SOURCES']

VELOCITY_SOURCES = ('auto', 'actual', 'commanded')
_MM_PER_M = 1000.0


@dataclass(frozen=True)
class SteadyOptions:
    """How steady segments are found and which ones count.

    Attributes
    ----------
    rel_speed_tol
        Every speed of a segment lies within this fraction of the segment's mean speed.
    max_accel_m_s2
        Largest ``|acceleration|`` of a steady sample [m/s^2].
    min_speed_m_s
        Slowest speed that counts as moving [m/s].
    min_duration_s
        Shortest segment kept, after trimming [s].
    trim_s
        Time cut from both ends of a segment [s].
    min_loss_power_w
        Segments with less loss power than this are excluded [W].
    feed_rel_tol
        Feeds closer than this fraction count as one feed.
    min_feeds
        Distinct feeds needed for a fit (at least 2).
    velocity
        ``'actual'``, ``'commanded'`` or ``'auto'`` (commanded velocity if mapped: the feed
        the program asked for, free of measurement noise; else actual; else differentiated
        positions).
    """

    rel_speed_tol: float = 0.03
    max_accel_m_s2: float = 0.05
    min_speed_m_s: float = 0.5e-3
    min_duration_s: float = 0.5
    trim_s: float = 0.1
    min_loss_power_w: float = 0.05
    feed_rel_tol: float = 0.05
    min_feeds: int = 3
    velocity: str = 'auto'

    def __post_init__(self) -> None:
        for name in ('rel_speed_tol', 'max_accel_m_s2', 'min_speed_m_s', 'feed_rel_tol'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                msg = f'must be a finite number > 0, got {value!r}'
                raise ConfigError(msg, file='fit options', key=name)
        for name in ('min_duration_s', 'trim_s', 'min_loss_power_w'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                msg = f'must be a finite number >= 0, got {value!r}'
                raise ConfigError(msg, file='fit options', key=name)
        if int(self.min_feeds) != self.min_feeds or self.min_feeds < 2:
            msg = f'must be a whole number >= 2, got {self.min_feeds!r}'
            raise ConfigError(msg, file='fit options', key='min_feeds')
        if self.velocity not in VELOCITY_SOURCES:
            msg = f'expected one of {", ".join(VELOCITY_SOURCES)}, got {self.velocity!r}'
            raise ConfigError(msg, file='fit options', key='velocity')


@dataclass(frozen=True)
class SteadySegment:
    """A stretch of steady motion of one axis and what it says about the loss.

    Attributes
    ----------
    run, axis
        Where it comes from.
    t_start_s, t_end_s
        First and last sample used (after trimming) [s].
    samples
        Number of samples averaged.
    velocity_m_s
        Mean signed velocity [m/s].
    power_w
        Mean measured axis power [W].
    loss_power_w
        Power spent on passive resistances [W] (see the module docstring).
    used
        Whether the segment enters the fit.
    reason
        Why not: ``'negative power'`` or ``'tiny power'``; empty when used.
    """

    run: str
    axis: str
    t_start_s: float
    t_end_s: float
    samples: int
    velocity_m_s: float
    power_w: float
    loss_power_w: float
    used: bool = True
    reason: str = ''

    @property
    def feed_mm_s(self) -> float:
        """Feed ``x`` [mm/s]."""
        return abs(self.velocity_m_s) * _MM_PER_M

    @property
    def coefficient(self) -> float:
        """Loss coefficient ``y = P_loss / x`` [W/(mm/s)]."""
        return self.loss_power_w / self.feed_mm_s

    def to_dict(self) -> dict[str, Any]:
        """Plain-type form (for JSON)."""
        return {'run': self.run, 'axis': self.axis, 't_start_s': self.t_start_s,
                't_end_s': self.t_end_s, 'samples': self.samples,
                'feed_mm_s': self.feed_mm_s, 'velocity_m_s': self.velocity_m_s,
                'power_w': self.power_w, 'loss_power_w': self.loss_power_w,
                'coefficient_w_per_mm_s': self.coefficient, 'used': self.used,
                'reason': self.reason}


def steady_segments(t: np.ndarray, v: np.ndarray, acc: np.ndarray, *,
                    options: SteadyOptions = SteadyOptions()) -> list[tuple[int, int]]:
    """Index ranges ``[i0, i1)`` of steady motion of one axis.

    Parameters
    ----------
    t
        Sample times [s], ``(n,)``, increasing.
    v, acc
        Velocity [m/s] and acceleration [m/s^2], ``(n,)``.
    options
        Thresholds (see :class:`SteadyOptions`).

    Returns
    -------
    list of (int, int)
        Half-open index ranges, after trimming, each at least ``options.min_duration_s``
        long, in time order.
    """
    t = np.asarray(t, dtype=float)
    v = np.asarray(v, dtype=float)
    speed = np.abs(v)
    sign = np.sign(v)
    still = np.abs(np.asarray(acc, dtype=float)) <= options.max_accel_m_s2
    ok = (speed >= options.min_speed_m_s) & still
    dt = np.diff(t)
    median = float(np.median(dt)) if dt.size else 0.0
    # A new candidate stretch starts where motion stops, reverses or the record has a gap.
    cut = np.ones(t.shape[0], dtype=bool)
    cut[1:] = (sign[1:] != sign[:-1]) | (dt > GAP_FACTOR * median) | ~ok[:-1]
    out: list[tuple[int, int]] = []
    starts = np.flatnonzero(cut & ok)
    for i0 in starts:
        i1 = int(i0) + 1
        while i1 < t.shape[0] and ok[i1] and not cut[i1]:
            i1 += 1
        out.extend(_split_by_speed(t, speed, int(i0), i1, options))
    return out


def _split_by_speed(t: np.ndarray, speed: np.ndarray, i0: int, i1: int,
                    options: SteadyOptions) -> list[tuple[int, int]]:
    """Greedily grow segments whose speeds all stay within the tolerance of their mean."""
    tol = options.rel_speed_tol
    out = []
    start = i0
    while start < i1:
        total = lo = hi = speed[start]
        end = start + 1
        while end < i1:
            s = speed[end]
            mean = (total + s) / (end - start + 1)
            if max(hi, s) - mean > tol * mean or mean - min(lo, s) > tol * mean:
                break
            total += s
            lo, hi = min(lo, s), max(hi, s)
            end += 1
        trimmed = _trim(t, start, end, options.trim_s)
        if trimmed is not None and t[trimmed[1] - 1] - t[trimmed[0]] >= options.min_duration_s:
            out.append(trimmed)
        start = end
    return out


def _trim(t: np.ndarray, i0: int, i1: int, trim_s: float) -> tuple[int, int] | None:
    eps = 1e-9
    lo = int(np.searchsorted(t[i0:i1], t[i0] + trim_s - eps)) + i0
    hi = int(np.searchsorted(t[i0:i1], t[i1 - 1] - trim_s + eps, side='right')) + i0
    return (lo, hi) if hi - lo >= 2 else None


def kinematics(run: MeasuredRun, source: str) -> tuple[np.ndarray, np.ndarray, str]:
    """Velocity and acceleration ``(n, k)`` of the run from the chosen source."""
    actual = (run.velocity_m_s, run.acceleration_m_s2, run.position_m, 'actual')
    command = (run.command_velocity_m_s, run.command_acceleration_m_s2,
               run.command_position_m, 'commanded')
    order = {'actual': [actual], 'commanded': [command], 'auto': [command, actual]}[source]
    for vel, acc, _, name in order:
        if vel is not None:
            if acc is None:
                acc = np.gradient(vel, run.t, axis=0)
            return vel, acc, f'{name} velocity'
    for _, _, pos, name in order:
        if pos is not None:
            vel = np.gradient(pos, run.t, axis=0)
            return vel, np.gradient(vel, run.t, axis=0), f'{name} position, differentiated'
    msg = (f'run {run.name!r} has no {"" if source == "auto" else source + " "}velocity or '
           'position columns; steady segments need measured or commanded motion')
    raise DataError(msg, file=run.file)


def run_segments(run: MeasuredRun, axis: str, *, machine: Machine | None = None,
                 options: SteadyOptions = SteadyOptions()) -> list[SteadySegment]:
    """Steady segments of one axis of one run, with their mean and loss power.

    Parameters
    ----------
    run
        A measured run with power for ``axis``.
    axis
        Axis name.
    machine
        For the screw efficiency, inclination and moved mass; ``None``: ``eta = 1``,
        horizontal.
    options
        Thresholds.

    Returns
    -------
    list of SteadySegment
        In time order; excluded ones flagged with a reason.
    """
    if axis not in run.power_axes:
        msg = f'run {run.name!r} has no power for axis {axis!r}'
        raise DataError(msg, file=run.file)
    vel, acc, _ = kinematics(run, options.velocity)
    j = run.axes.index(axis)
    p = run.power_w[:, run.power_axes.index(axis)]
    eta, weight_n = 1.0, 0.0
    if machine is not None:
        spec = machine.axis(axis)
        eta = spec.screw.efficiency
        weight_n = (moved_mass_kg(machine, axis, run.load_kg) * GRAVITY_M_S2
                    * math.sin(math.radians(spec.inclination_deg)))
    out = []
    for i0, i1 in steady_segments(run.t, vel[:, j], acc[:, j], options=options):
        v_mean = float(np.mean(vel[i0:i1, j]))
        p_mean = float(np.mean(p[i0:i1]))
        drive = eta * p_mean if p_mean >= 0.0 else p_mean / eta
        loss_w = drive - weight_n * v_mean
        reason = ''
        if loss_w < 0.0:
            reason = 'negative power'
        elif loss_w < options.min_loss_power_w:
            reason = 'tiny power'
        out.append(SteadySegment(run=run.name, axis=axis, t_start_s=float(run.t[i0]),
                                 t_end_s=float(run.t[i1 - 1]), samples=i1 - i0,
                                 velocity_m_s=v_mean, power_w=p_mean, loss_power_w=loss_w,
                                 used=not reason, reason=reason))
    return out


def range_uses(runs: Sequence[MeasuredRun], *,
               velocity: str = 'auto') -> dict[str, list[RangeUse]]:
    """Axis -> the speeds, accelerations and loads of ``runs`` (for :mod:`..calibrated`).

    Runs without velocity or position columns are left out (nothing to check).
    """
    out: dict[str, list[RangeUse]] = {}
    for run in runs:
        try:
            vel, acc, _ = kinematics(run, velocity)
        except DataError:
            continue
        pos = run.position_m if run.position_m is not None else run.command_position_m
        for j, axis in enumerate(run.axes):
            out.setdefault(axis, []).append(RangeUse(
                run=run.name, load_kg=run.load_kg, speed_m_s=np.abs(vel[:, j]),
                accel_m_s2=acc[:, j], position_m=None if pos is None else pos[:, j]))
    return out
