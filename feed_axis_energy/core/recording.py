"""The recorded form of a simulation: which series go on which topic, in which units.

Offline ``simulate --out`` and the node graph both build their messages from these functions,
so a recording made by either has the same layout (see the topic table in README).
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from feed_axis_energy.core import bagio
from feed_axis_energy.core.motion import Motion

__all__ = ['setpoint_series', 'axis_state_series', 'power_series', 'simulation_series',
           'write_simulation_bag', 'SUMMARY_KEY', 'screw_joint']

SUMMARY_KEY = 'feed_axis_energy/summary'


def screw_joint(axis: str) -> str:
    """Return the joint name of an axis's ball screw (``X`` -> ``X_screw``)."""
    return f'{axis}_screw'


def setpoint_series(motion: Motion) -> bagio.Series:
    """Commanded positions [m], velocities [m/s] and accelerations [m/s^2] per axis."""
    return bagio.Series(t=motion.t, names=tuple(motion.axes), positions=motion.pos,
                        velocities=motion.vel, accelerations=motion.acc)


def axis_state_series(motion: Motion, dyn) -> bagio.Series:
    """Carriage joints (m, m/s, m/s^2, load force N) and screw joints (rad, rad/s, rad/s^2, N·m).

    Columns: all carriage joints in axis order, then all screw joints in axis order.
    """
    axes = tuple(motion.axes)
    names = axes + tuple(screw_joint(a) for a in axes)
    return bagio.Series(
        t=motion.t, names=names,
        positions=np.hstack([motion.pos, dyn.angle_rad]),
        velocities=np.hstack([motion.vel, dyn.omega_rad_s]),
        accelerations=np.hstack([motion.acc, dyn.alpha_rad_s2]),
        effort=np.hstack([dyn.force_n, dyn.torque_nm]))


def power_series(power) -> bagio.Series:
    """Per-axis and total actual power [W] (as velocities) and energy [J] (as positions)."""
    names = tuple(power.axes) + ('total',)
    return bagio.Series(
        t=power.t, names=names,
        positions=np.hstack([power.energy_j, power.total_energy_j[:, None]]),
        velocities=np.hstack([power.power_w, power.total_w[:, None]]))


def simulation_series(result) -> dict[str, bagio.Series]:
    """Return ``{topic: Series}`` for a ``simulate.SimulationResult``."""
    return {
        bagio.TOPIC_SETPOINTS: setpoint_series(result.motion),
        bagio.TOPIC_AXIS_STATE: axis_state_series(result.motion, result.dynamics),
        bagio.TOPIC_POWER: power_series(result.power),
    }


def write_simulation_bag(path: str | Path, result, *, summary: dict, batch: int = 100,
                         progress: Callable[[float], None] | None = None) -> None:
    """Write a whole simulation as a rosbag2/MCAP directory (topics in README)."""
    from feed_axis_energy.core.energy import energy_by_line
    series = simulation_series(result)
    with bagio.BagWriter(path) as writer:
        for i, (topic, s) in enumerate(series.items()):
            writer.write_series(topic, s, batch=batch)
            if progress is not None:
                progress((i + 1) / (len(series) + 1))
        writer.write_block_energy(energy_by_line(result.power), stamp_s=float(result.power.t[-1]),
                                  program=str(summary.get('program', '')))
        writer.set_custom_data(SUMMARY_KEY, summary)
    if progress is not None:
        progress(1.0)
