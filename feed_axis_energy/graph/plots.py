"""The plot-ready topics (:mod:`.plottopics`) from the node graph's batched streams.

The recorder (``nodes/mcap_recorder.py``) hands every ``power`` and ``axis_state`` batch it
records to :class:`GraphPlotter` and writes the JointState messages it returns beside the
batches, so a graph recording has the same plot topics as ``simulate --out``: the same
display-rate rule (first sample and every power / torque extreme per interval), one
decimator per stream. Pure: arrays in, serialized messages out.
"""
from __future__ import annotations

from typing import cast, Mapping, Sequence

import numpy as np

from ..errors import DataError, shorten
from ..record import (block_energy_joint_state, joint_state_rows, PlotDecimator, TOPIC_PLOT_AXES,
                      TOPIC_PLOT_BLOCK_ENERGY, TOPIC_PLOT_POWER)

__all__ = ['GraphPlotter', 'PLOT_SOURCES']

# logical stream -> the plot topic made from it
PLOT_SOURCES = {'power': TOPIC_PLOT_POWER, 'axis_state': TOPIC_PLOT_AXES}
_NS = 1_000_000_000

Message = tuple[str, int, bytes]          # (bag topic, log time [ns], CDR)


class GraphPlotter:
    """Plot-topic messages from JointTrajectory batches.

    Parameters
    ----------
    rate_hz
        Display rate [Hz] (0: every sample).
    start_ns
        Added to every stamp [ns] (wall-clock start; 0: simulation time).
    per_message
        Source lines per ``/plot/block_energy`` message.
    """

    def __init__(self, *, rate_hz: float, start_ns: int = 0, per_message: int = 10_000) -> None:
        # the decimators work on integer nanoseconds: exact stamps, interval 1e9 / rate
        self._dec = {topic: PlotDecimator(rate_hz=float(rate_hz) / _NS, keys=())
                     for topic in PLOT_SOURCES}
        self._names: dict[str, tuple[str, ...]] = {}
        self._source: dict[str, tuple[str, ...]] = {}
        self.start_ns = int(start_ns)
        self.per_message = int(per_message)

    def add(self, topic: str, t_ns: np.ndarray, names: Sequence[str],
            fields: Mapping[str, np.ndarray | None]) -> list[Message]:
        """Take one batch of ``topic`` (``power`` or ``axis_state``); return the messages
        of the display intervals it completes.

        Raises
        ------
        DataError
            A batch whose joint names differ from the stream's first batch, or that lacks a
            field the plot needs (naming the topic).
        """
        names = tuple(names)
        known = self._source.setdefault(topic, names)
        if names != known:
            msg = (f'joint names {shorten(", ".join(names), limit=60)} differ from the first '
                   f'batch\'s; no plot samples from this batch')
            raise DataError(msg, file='<graph>', topic=topic)
        need: tuple[str, ...]
        if topic == 'power':
            need = ('positions', 'velocities')
            k = len(names)
        else:
            need = ('positions', 'velocities', 'effort')
            k = len(names) // 2                          # carriage joints, then screw joints
        missing = [f for f in need if fields.get(f) is None]
        if missing:
            msg = f'batch without {", ".join(missing)}; no plot samples from it'
            raise DataError(msg, file='<graph>', topic=topic)
        dec = self._dec[topic]
        if topic not in self._names:
            if topic == 'power':
                self._names[topic] = names
                dec.keys = list(range(k, 2 * k))              # the power columns
            else:
                self._names[topic] = names[:k]
                dec.keys = list(range(2 * k, 3 * k))          # the torque columns
        if topic == 'power':           # the casts: none of them is None (checked above)
            values = np.hstack([cast(np.ndarray, fields[f]) for f in need])
        else:
            values = np.hstack([cast(np.ndarray, fields[f])[:, k:] for f in need])
        t, kept = dec.push(np.asarray(t_ns, np.int64), values)
        return self._messages(topic, t, kept)

    def finish(self) -> list[Message]:
        """The messages of the last (open) display intervals."""
        out = []
        for topic, dec in self._dec.items():
            t, kept = dec.finish()
            if t.shape[0]:
                out += self._messages(topic, t.astype(np.int64), kept)
        return out

    def block_energy(self, blocks: Sequence[tuple[int, float, float]],
                     stamp_ns: int) -> list[Message]:
        """``/plot/block_energy`` from the ``block_energy`` statuses, at ``stamp_ns``
        (already shifted to the recording's start)."""
        rows = np.array([(int(a), float(b), float(c)) for a, b, c in blocks],
                        dtype=[('l', np.int64), ('e', float), ('d', float)])
        return [(TOPIC_PLOT_BLOCK_ENERGY, int(stamp_ns), data) for data in
                block_energy_joint_state(int(stamp_ns), rows['l'], rows['e'], rows['d'],
                                         per_message=self.per_message)]

    def _messages(self, topic: str, t_ns: np.ndarray, values: np.ndarray) -> list[Message]:
        if t_ns.shape[0] == 0:
            return []
        names = self._names[topic]
        k = len(names)
        if topic == 'power':
            fields = [values[:, :k], values[:, k:], None]
        else:
            fields = [values[:, :k], values[:, k:2 * k], values[:, 2 * k:]]
        block = joint_state_rows(t_ns + self.start_ns, names, fields)
        stop = block.start + block.length
        bag_topic = PLOT_SOURCES[topic]
        return [(bag_topic, int(s), block.rows[i, block.start:stop].tobytes())
                for i, s in enumerate(block.stamps.tolist())]
