"""The recorded form of a simulation: which series go on which topic, in which units.

Offline ``simulate --out`` and the node graph both build their messages from these functions,
so a recording made by either has the same layout (see the topic table in README).
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from feed_axis_energy.core import bagio
from feed_axis_energy.core.motion import Motion

__all__ = ['setpoint_series', 'axis_state_series', 'power_series', 'simulation_series',
           'write_simulation_bag', 'SimulationBagWriter', 'SUMMARY_KEY', 'screw_joint']

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


def _join(head: bagio.Series | None, tail: bagio.Series) -> bagio.Series:
    if head is None or head.t.shape[0] == 0:
        return tail
    fields = {}
    for name in ('positions', 'velocities', 'accelerations', 'effort'):
        a, b = getattr(head, name), getattr(tail, name)
        fields[name] = None if a is None else np.concatenate((a, b))
    return bagio.Series(t=np.concatenate((head.t, tail.t)), names=tail.names, **fields)


def _rows(series: bagio.Series, i0: int, i1: int) -> bagio.Series:
    fields = {name: None if getattr(series, name) is None else getattr(series, name)[i0:i1]
              for name in ('positions', 'velocities', 'accelerations', 'effort')}
    return bagio.Series(t=series.t[i0:i1], names=series.names, **fields)


class SimulationBagWriter:
    """Write a simulation to a rosbag2/MCAP directory chunk by chunk (context manager).

    Each chunk's messages are built and written as the chunk arrives; samples that do not fill
    a message of ``batch`` points wait for the next chunk, so the messages are the ones a
    whole-record write produces (topics interleave in time order). Memory: one chunk.

    Parameters
    ----------
    path
        Bag directory to create; it must not exist yet.
    batch
        Samples per JointTrajectory message.
    compression
        ``'none'`` or ``'zstd'`` (MCAP chunk compression, see :class:`.bagio.BagWriter`).
    """

    def __init__(self, path: str | Path, *, batch: int = 100, compression: str = 'none') -> None:
        self._bag = bagio.BagWriter(path, compression=compression)
        self.batch = int(batch)
        self._rest: dict[str, bagio.Series | None] = {}
        self.messages = 0

    def __enter__(self) -> 'SimulationBagWriter':
        self._bag.__enter__()
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self._bag.__exit__(exc_type, exc, tb)

    def write(self, chunk) -> None:
        """Write the series of one ``SimulationResult`` chunk (whole messages only)."""
        for topic, series in simulation_series(chunk).items():
            joined = _join(self._rest.get(topic), series)
            full = (joined.t.shape[0] // self.batch) * self.batch
            if full:
                self.messages += self._bag.write_series(topic, _rows(joined, 0, full),
                                                        batch=self.batch)
            self._rest[topic] = _rows(joined, full, joined.t.shape[0])

    def finish(self, blocks: Sequence[tuple[int, float, float]], *, summary: dict,
               stamp_s: float) -> None:
        """Write the samples still waiting, the per-block energy and the summary."""
        for topic, rest in self._rest.items():
            if rest is not None and rest.t.shape[0]:
                self.messages += self._bag.write_series(topic, rest, batch=self.batch)
        self._rest = {}
        self._bag.write_block_energy(blocks, stamp_s=stamp_s,
                                     program=str(summary.get('program', '')))
        self._bag.set_custom_data(SUMMARY_KEY, summary)


def write_simulation_bag(path: str | Path, result, *, summary: dict, batch: int = 100,
                         progress: Callable[[float], None] | None = None,
                         compression: str = 'none') -> None:
    """Write a whole simulation as a rosbag2/MCAP directory (topics in README)."""
    from feed_axis_energy.core.energy import energy_by_line
    with SimulationBagWriter(path, batch=batch, compression=compression) as writer:
        writer.write(result)
        if progress is not None:
            progress(0.9)
        writer.finish(energy_by_line(result.power), summary=summary,
                      stamp_s=float(result.power.t[-1]))
    if progress is not None:
        progress(1.0)
