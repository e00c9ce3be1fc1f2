"""The paper's loss-function fit (section 2.1): power regression from no-load runs.

Steps, per axis with measured power:

1. find the *steady* segments of each run: speed above ``min_speed_m_s``, one direction,
   ``|acceleration| <= max_accel_m_s2``, every speed within ``rel_speed_tol`` of the
   segment's mean speed, at least ``min_duration_s`` long after ``trim_s`` is cut from each
   end (the power peaks of acceleration and braking bleed into the first and last samples);
2. average the measured axis power over each segment and turn it into the power spent on the
   passive resistances, inverting the model of :mod:`..dynamics`: ``F·v = eta·P`` when the
   motor drives (``P >= 0``), ``F·v = P/eta`` when it is back-driven, minus the weight's
   share ``m·g·sin(incl)·v`` (zero on horizontal axes; ``eta = 1`` and no weight without a
   machine);
3. divide by the feed: loss coefficient ``y = P_loss / x`` [W/(mm/s)] at feed ``x`` [mm/s];
   segments whose loss power is negative or below ``min_loss_power_w`` are excluded (and
   counted), since the logarithm needs ``y > 0``;
4. fit ``y = a·x**b`` by linear least squares of ``ln y = ln a + b·ln x`` over the segments
   (one point per segment, unweighted). ``r2_log`` is R² of that fit in log-log space (the
   space it minimises); ``r2_linear`` is R² of ``y`` against ``a·x**b`` in linear space.

These are the units of :class:`..losses.PowerRegressionLoss` (``x_unit='mm/s'``,
``y_unit='W/(mm/s)'``), so the fitted model reproduces the steady loss power ``a·x**(1+b)``.
A fit with fewer than ``min_feeds`` distinct feeds (feeds within ``feed_rel_tol`` of each
other count as one) has status ``'insufficient'``; a fit with ``b < 0`` (which
``PowerRegressionLoss`` cannot represent) has status ``'out_of_range'``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
from typing import Any, Sequence

import numpy as np

from ..errors import ConfigError, DataError
from ..losses import PowerRegressionLoss
from ..machine import GRAVITY_M_S2, Machine, moved_mass_kg
from ..measured.csvload import GAP_FACTOR, MeasuredRun

__all__ = ['SteadyOptions', 'SteadySegment', 'LossFit', 'steady_segments', 'run_segments',
           'fit_power_regression', 'fit_loss', 'machine_with_losses', 'VELOCITY_SOURCES']

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


@dataclass(frozen=True)
class LossFit:
    """Result of the power-regression fit of one axis (a poor fit is a result, not an error).

    Attributes
    ----------
    axis
        Axis name.
    status
        ``'ok'``, ``'insufficient'`` (too few distinct feeds; ``a``/``b`` are ``None``) or
        ``'out_of_range'`` (``b < 0``).
    message
        One sentence explaining the status.
    a, b
        ``y = a·x**b`` with ``x`` in mm/s and ``y`` in W/(mm/s).
    r2_log
        R² of ``ln y`` in log-log space, where the fit is least squares.
    r2_linear
        R² of ``y`` in linear space.
    feeds_mm_s
        Distinct feeds (mean of each group of close feeds) [mm/s].
    segments
        Every steady segment found, used or not.
    """

    axis: str
    status: str
    message: str
    a: float | None = None
    b: float | None = None
    r2_log: float | None = None
    r2_linear: float | None = None
    feeds_mm_s: tuple[float, ...] = ()
    segments: tuple[SteadySegment, ...] = field(default=(), repr=False)

    @property
    def ok(self) -> bool:
        """``True`` when the fit can be used as a loss model."""
        return self.status == 'ok'

    @property
    def used(self) -> tuple[SteadySegment, ...]:
        """The segments that entered the fit."""
        return tuple(s for s in self.segments if s.used)

    @property
    def excluded(self) -> dict[str, int]:
        """Count of excluded segments per reason."""
        out: dict[str, int] = {}
        for s in self.segments:
            if not s.used:
                out[s.reason] = out.get(s.reason, 0) + 1
        return out

    def loss(self) -> PowerRegressionLoss:
        """The fitted loss model (``ValueError`` unless the status is ``'ok'``)."""
        if not self.ok:
            msg = f'axis {self.axis}: no usable fit ({self.status}: {self.message})'
            raise ValueError(msg)
        return PowerRegressionLoss(a=float(self.a), b=float(self.b), x_unit='mm/s',
                                   y_unit='W/(mm/s)')

    def to_dict(self, *, segments: bool = True) -> dict[str, Any]:
        """Plain-type form (for JSON); ``segments=False`` leaves the segment list out."""
        out = {'axis': self.axis, 'status': self.status, 'message': self.message,
               'a': self.a, 'b': self.b, 'x_unit': 'mm/s', 'y_unit': 'W/(mm/s)',
               'r2_log': self.r2_log, 'r2_space': 'log-log (ln y vs ln x)',
               'r2_linear': self.r2_linear, 'segments_used': len(self.used),
               'segments_excluded': self.excluded, 'feeds_mm_s': list(self.feeds_mm_s)}
        if segments:
            out['segments'] = [s.to_dict() for s in self.segments]
        return out


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


def _kinematics(run: MeasuredRun, source: str) -> tuple[np.ndarray, np.ndarray, str]:
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
    vel, acc, _ = _kinematics(run, options.velocity)
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


def _feed_groups(feeds: np.ndarray, rel_tol: float) -> list[float]:
    groups: list[list[float]] = []
    for f in np.sort(feeds):
        if groups and f <= groups[-1][0] * (1.0 + rel_tol):
            groups[-1].append(float(f))
        else:
            groups.append([float(f)])
    return [float(np.mean(g)) for g in groups]


def _r2(observed: np.ndarray, predicted: np.ndarray) -> float:
    ss_res = float(np.sum((observed - predicted) ** 2))
    ss_tot = float(np.sum((observed - np.mean(observed)) ** 2))
    if ss_tot == 0.0:
        # all points equal: a perfect fit explains them, any other explains nothing
        return 1.0 if ss_res == 0.0 else 0.0
    return 1.0 - ss_res / ss_tot


def fit_power_regression(segments: Sequence[SteadySegment], *, axis: str,
                         options: SteadyOptions = SteadyOptions()) -> LossFit:
    """Fit ``y = a·x**b`` to the used segments (least squares in log-log space).

    Parameters
    ----------
    segments
        Steady segments of one axis (excluded ones are carried along, not fitted).
    axis
        Axis name.
    options
        ``min_feeds`` and ``feed_rel_tol`` decide whether there are enough feeds.

    Returns
    -------
    LossFit
        Status ``'ok'``, ``'insufficient'`` or ``'out_of_range'``.
    """
    segments = tuple(segments)
    used = [s for s in segments if s.used]
    x = np.array([s.feed_mm_s for s in used])
    y = np.array([s.coefficient for s in used])
    feeds = tuple(_feed_groups(x, options.feed_rel_tol)) if used else ()
    excluded = len(segments) - len(used)
    if len(feeds) < options.min_feeds:
        shown = ', '.join(f'{f:.3g}' for f in feeds) or 'none'
        msg = (f'{len(feeds)} distinct feed(s) ({shown} mm/s) in {len(used)} usable steady '
               f'segment(s) ({excluded} excluded); need at least {options.min_feeds}')
        return LossFit(axis=axis, status='insufficient', message=msg, feeds_mm_s=feeds,
                       segments=segments)
    lx, ly = np.log(x), np.log(y)
    b, ln_a = np.polyfit(lx, ly, 1)
    a = math.exp(ln_a)
    r2_log = _r2(ly, ln_a + b * lx)
    r2_lin = _r2(y, a * np.power(x, b))
    base = dict(axis=axis, a=float(a), b=float(b), r2_log=r2_log, r2_linear=r2_lin,
                feeds_mm_s=feeds, segments=segments)
    if b < 0.0:
        msg = (f'b = {b:.4g} < 0: the loss coefficient falls with the feed; '
               'PowerRegressionLoss needs b >= 0')
        return LossFit(status='out_of_range', message=msg, **base)
    msg = (f'{len(used)} segments at {len(feeds)} feeds, {excluded} excluded; '
           f'R^2 = {r2_log:.4f} in log-log space')
    return LossFit(status='ok', message=msg, **base)


def fit_loss(runs: Sequence[MeasuredRun], *, machine: Machine | None = None,
             axes: Sequence[str] | None = None,
             options: SteadyOptions = SteadyOptions()) -> dict[str, LossFit]:
    """Fit the loss function of every axis with measured power over several runs.

    Parameters
    ----------
    runs
        No-load runs at several feeds (any load is accounted for only through the weight on
        inclined axes; the loss itself is assumed load independent, as in the paper).
    machine
        Machine model (efficiency, inclination, masses); axes it lacks are skipped.
    axes
        Axes to fit; default every axis with power in any run (and in the machine).
    options
        Thresholds.

    Returns
    -------
    dict
        Axis name -> :class:`LossFit`, in the order the axes first appear.
    """
    if axes is None:
        names: list[str] = []
        for run in runs:
            names.extend(a for a in run.power_axes if a not in names)
        if machine is not None:
            names = [a for a in names if a in machine.axis_names]
    else:
        names = list(axes)
    out = {}
    for axis in names:
        segments: list[SteadySegment] = []
        for run in runs:
            if axis in run.power_axes:
                segments.extend(run_segments(run, axis, machine=machine, options=options))
        out[axis] = fit_power_regression(segments, axis=axis, options=options)
    return out


def machine_with_losses(machine: Machine, fits: dict[str, LossFit]) -> Machine:
    """Return ``machine`` with the loss of every axis that has an ``'ok'`` fit replaced.

    Parameters
    ----------
    machine
        The machine.
    fits
        Axis name -> fit; fits with another status leave the axis unchanged.

    Returns
    -------
    Machine
        A new machine.
    """
    axes = tuple(replace(a, loss=fits[a.name].loss()) if a.name in fits and fits[a.name].ok
                 else a for a in machine.axes)
    return replace(machine, axes=axes)
