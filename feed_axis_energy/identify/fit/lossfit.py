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
from typing import Any, cast, Sequence

import numpy as np

from ...machine import CalibratedRange, LossCovariance, Machine, PowerRegressionLoss
from ...measured import MeasuredRun
from .steady import run_segments, SteadyOptions, SteadySegment

__all__ = ['LossFit', 'fit_power_regression', 'fit_loss', 'machine_with_losses']


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
    a_se, b_se
        Standard errors of ``a`` and ``b`` from the covariance of the log-log fit
        (``a_se = a·se(ln a)``, first order); ``None`` with fewer than 3 segments.
    cov_ln_a_b
        Covariance matrix of ``(ln a, b)``: ``s²·(X'X)^-1`` with ``s²`` the residual variance
        of ``ln y`` (``n - 2`` degrees of freedom); ``None`` with fewer than 3 segments.
    calibrated
        Steady feeds of the used segments and loads of the fitted runs: where the fit holds.
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
    a_se: float | None = None
    b_se: float | None = None
    cov_ln_a_b: tuple[tuple[float, float], tuple[float, float]] | None = None
    calibrated: CalibratedRange | None = None

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
        # the casts: an ok fit has both values
        return PowerRegressionLoss(a=float(cast(float, self.a)), b=float(cast(float, self.b)),
                                   x_unit='mm/s',
                                   y_unit='W/(mm/s)')

    def covariance(self) -> LossCovariance | None:
        """Covariance of ``(a, b)`` in the units of :meth:`loss` (``None`` when not known).

        The fit's covariance of ``(ln a, b)`` taken to ``(a, b)`` to first order
        (``d a = a·d ln a``): ``[[a²·C00, a·C01], [a·C01, C11]]``.
        """
        if not self.ok or self.cov_ln_a_b is None:
            return None
        a = float(cast(float, self.a))
        (c00, c01), (_, c11) = self.cov_ln_a_b
        units = self.loss().param_units()
        return LossCovariance.of(('a', 'b'), (units['a'], units['b']),
                                 [[a * a * c00, a * c01], [a * c01, c11]])

    def to_dict(self, *, segments: bool = True) -> dict[str, Any]:
        """Plain-type form (for JSON); ``segments=False`` leaves the segment list out."""
        out: dict[str, Any]
        out = {'axis': self.axis, 'status': self.status, 'message': self.message,
               'a': self.a, 'b': self.b, 'x_unit': 'mm/s', 'y_unit': 'W/(mm/s)',
               'r2_log': self.r2_log, 'r2_space': 'log-log (ln y vs ln x)',
               'r2_linear': self.r2_linear, 'segments_used': len(self.used),
               'segments_excluded': self.excluded, 'feeds_mm_s': list(self.feeds_mm_s),
               'a_se': self.a_se, 'b_se': self.b_se,
               'cov_ln_a_b': None if self.cov_ln_a_b is None else [list(r)
                                                                   for r in self.cov_ln_a_b],
               'calibrated': None if self.calibrated is None else self.calibrated.to_dict()}
        if segments:
            out['segments'] = [s.to_dict() for s in self.segments]
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


def _covariance(lx: np.ndarray, res: np.ndarray):
    """Covariance of ``(ln a, b)`` of the straight-line fit (``None``: no dof left)."""
    n = lx.shape[0]
    if n < 3:
        return None
    xtx = np.array([[n, float(lx.sum())], [float(lx.sum()), float(lx @ lx)]])
    det = float(np.linalg.det(xtx))
    if not det > 0.0:
        return None
    cov = float(res @ res) / (n - 2) * np.linalg.inv(xtx)
    return ((float(cov[0, 0]), float(cov[0, 1])), (float(cov[1, 0]), float(cov[1, 1])))


def fit_power_regression(segments: Sequence[SteadySegment], *, axis: str,
                         options: SteadyOptions = SteadyOptions(),
                         loads_kg: Sequence[float] = ()) -> LossFit:
    """Fit ``y = a·x**b`` to the used segments (least squares in log-log space).

    Parameters
    ----------
    segments
        Steady segments of one axis (excluded ones are carried along, not fitted).
    axis
        Axis name.
    options
        ``min_feeds`` and ``feed_rel_tol`` decide whether there are enough feeds.
    loads_kg
        Loads of the runs the segments come from (recorded in ``calibrated``).

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
    cov = _covariance(lx, ly - (ln_a + b * lx))
    calibrated = CalibratedRange(
        feed_mm_s=(float(x.min()), float(x.max())),
        load_kg=(float(min(loads_kg)), float(max(loads_kg))) if len(loads_kg) else None)
    base = dict(axis=axis, a=float(a), b=float(b), r2_log=r2_log, r2_linear=r2_lin,
                feeds_mm_s=feeds, segments=segments, calibrated=calibrated,
                a_se=None if cov is None else float(a * math.sqrt(cov[0][0])),
                b_se=None if cov is None else float(math.sqrt(cov[1][1])), cov_ln_a_b=cov)
    if b < 0.0:
        msg = (f'b = {b:.4g} < 0: the loss coefficient falls with the feed; '
               'PowerRegressionLoss needs b >= 0')
        return LossFit(status='out_of_range', message=msg, **base)
    msg = (f'{len(used)} segments at {len(feeds)} feeds ({x.min():.3g}-{x.max():.3g} mm/s), '
           f'{excluded} excluded; R^2 = {r2_log:.4f} in log-log space')
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
        loads = []
        for run in runs:
            if axis in run.power_axes:
                segments.extend(run_segments(run, axis, machine=machine, options=options))
                loads.append(run.load_kg)
        out[axis] = fit_power_regression(segments, axis=axis, options=options, loads_kg=loads)
    return out


def machine_with_losses(machine: Machine, fits: dict[str, LossFit]) -> Machine:
    """Return ``machine`` with the loss of every axis that has an ``'ok'`` fit replaced.

    The axis also gets the fit's calibrated range (``loss_calibrated``) and the covariance
    of ``(a, b)`` (``loss_covariance``; ``None`` with fewer than 3 segments).

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
    axes = tuple(replace(a, loss=fits[a.name].loss(), loss_calibrated=fits[a.name].calibrated,
                         loss_covariance=fits[a.name].covariance())
                 if a.name in fits and fits[a.name].ok else a for a in machine.axes)
    return replace(machine, axes=axes)
