"""What the machine lets the planner do: kinematic limits per axis, and the planner's options.

The values a machine file declares (:mod:`.spec`'s ``LimitSpec`` and ``PlannerSettings``) in the
form the planner (:mod:`feed_axis_energy.plan`) takes them; here, below the planner, so that the
machine data does not import the planner.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

__all__ = ['AxisLimits', 'PlannerOptions']


@dataclass(frozen=True)
class AxisLimits:
    """Kinematic limits of one machine axis.

    Attributes
    ----------
    velocity_m_s, acceleration_m_s2, jerk_m_s3
        Maximum speed [m/s], acceleration [m/s^2] and jerk [m/s^3]; all must be > 0.
    """

    velocity_m_s: float
    acceleration_m_s2: float
    jerk_m_s3: float

    def __post_init__(self) -> None:
        for name in ('velocity_m_s', 'acceleration_m_s2', 'jerk_m_s3'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and value > 0.0 and math.isfinite(value)):
                msg = f'AxisLimits.{name} must be a finite number > 0, got {value!r}'
                raise ValueError(msg)


@dataclass(frozen=True)
class PlannerOptions:
    """Options of the planner (:func:`feed_axis_energy.plan.trajectory.plan`, ``iter_motion``).

    Attributes
    ----------
    rate_hz
        Sample rate of the output [Hz]; default 1000 (1 ms, a typical interpolation cycle).
    profile
        ``'jerk'`` (default; seven-phase S-curve, jerk-limited) or ``'trapezoid'``
        (constant acceleration phases, jerk limit ignored).
    corner_tolerance_m
        Path deviation allowed at a non-tangent corner for the junction-deviation rule [m];
        default 1e-4 (0.1 mm). 0 makes every non-tangent corner an exact stop.
    cycle_s
        Interpolation cycle of the control [s], default 1 ms: a corner's per-axis velocity
        step must fit into one cycle (``v |du_k| <= a_k cycle_s``). A property of the
        control, not of the output, so the planned motion does not depend on ``rate_hz``.
    """

    rate_hz: float = 1000.0
    profile: str = 'jerk'
    corner_tolerance_m: float = 0.0001
    cycle_s: float = 0.001

    def __post_init__(self) -> None:
        if not (self.rate_hz > 0.0 and math.isfinite(self.rate_hz)):
            msg = f'PlannerOptions.rate_hz must be > 0, got {self.rate_hz!r}'
            raise ValueError(msg)
        if self.profile not in ('jerk', 'trapezoid'):
            msg = f"PlannerOptions.profile must be 'jerk' or 'trapezoid', got {self.profile!r}"
            raise ValueError(msg)
        if not (self.cycle_s > 0.0 and math.isfinite(self.cycle_s)):
            msg = f'PlannerOptions.cycle_s must be > 0, got {self.cycle_s!r}'
            raise ValueError(msg)
        if not self.corner_tolerance_m >= 0.0:
            value = self.corner_tolerance_m
            msg = f'PlannerOptions.corner_tolerance_m must be >= 0, got {value!r}'
            raise ValueError(msg)
