"""The recorded form of a simulation: which series go on which topic, in which units.

Offline ``simulate --out`` and the node graph both build their messages from these functions,
so a recording made by either has the same layout (see the topic table in README).
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from . import bagio
from feed_axis_energy.record.bagwrite import StreamBagWriter
from feed_axis_energy.record.cdr import (BLOCK_ENERGY_PER_MESSAGE, joint_trajectory_rows,
                                         MessageRows)
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.plan import Motion
from feed_axis_energy.record.plottopics import (block_energy_joint_state, DEFAULT_PLOT_RATE_HZ,
                                                JOINT_STATE, TOPIC_PLOT_AXES,
                                                TOPIC_PLOT_BLOCK_ENERGY, TOPIC_PLOT_POWER)
from feed_axis_energy.record.recplot import RecordingPlots
from feed_axis_energy.record.thinning import STANDSTILL_PERIOD_S, StandstillThinner
from feed_axis_energy.record.starttime import check_end, MAX_STAMP_NS

__all__ = ['axis_state_series', 'simulation_series', 'write_simulation_bag',
           'SimulationBagWriter', 'SUMMARY_KEY', 'screw_joint']

SUMMARY_KEY = 'feed_axis_energy/summary'


def screw_joint(axis: str) -> str:
    """Return the joint name of an axis's ball screw (``X`` -> ``X_screw``)."""
    return f'{axis}_screw'


# A topic's columns: joint names, then per JointTrajectoryPoint field (positions,
# velocities, accelerations, effort) None or a tuple of (n, k_i) arrays whose columns follow
# one another. Series for the node graph join the blocks; the bag writer copies them
# straight into the messages.
Columns = tuple[tuple[str, ...], list[tuple[np.ndarray, ...] | None]]


def setpoint_columns(motion: Motion) -> Columns:
    """Commanded positions [m], velocities [m/s] and accelerations [m/s^2] per axis."""
    return tuple(motion.axes), [(motion.pos,), (motion.vel,), (motion.acc,), None]


def axis_state_columns(motion: Motion, dyn) -> Columns:
    """Carriage joints (m, m/s, m/s^2, load force N) and screw joints (rad, rad/s, rad/s^2, N·m).

    Columns: all carriage joints in axis order, then all screw joints in axis order.
    """
    axes = tuple(motion.axes)
    return axes + tuple(screw_joint(a) for a in axes), [
        (motion.pos, dyn.angle_rad), (motion.vel, dyn.omega_rad_s),
        (motion.acc, dyn.alpha_rad_s2), (dyn.force_n, dyn.torque_nm)]


def power_columns(power) -> Columns:
    """Per-axis and total actual power [W] (as velocities) and energy [J] (as positions)."""
    return tuple(power.axes) + ('total',), [
        (power.energy_j, power.total_energy_j[:, None]),
        (power.power_w, power.total_w[:, None]), None, None]


def simulation_columns(result) -> dict[str, Columns]:
    """Return ``{topic: Columns}`` for a ``simulate.SimulationResult`` (README topic table)."""
    return {
        bagio.TOPIC_SETPOINTS: setpoint_columns(result.motion),
        bagio.TOPIC_AXIS_STATE: axis_state_columns(result.motion, result.dynamics),
        bagio.TOPIC_POWER: power_columns(result.power),
    }


def _series(t: np.ndarray, columns: Columns) -> bagio.Series:
    names, fields = columns
    joined = [None if f is None else (f[0] if len(f) == 1 else np.hstack(f)) for f in fields]
    return bagio.Series(t, names, *joined)


def axis_state_series(motion: Motion, dyn) -> bagio.Series:
    """:func:`axis_state_columns` as one :class:`.bagio.Series`."""
    return _series(motion.t, axis_state_columns(motion, dyn))


def simulation_series(result) -> dict[str, bagio.Series]:
    """Return ``{topic: Series}`` for a ``simulate.SimulationResult``."""
    return {topic: _series(result.power.t if topic == bagio.TOPIC_POWER else result.motion.t,
                           columns)
            for topic, columns in simulation_columns(result).items()}


def _t_ns(t: np.ndarray) -> np.ndarray:
    if t.shape[0] and float(t.min()) < 0:
        msg = 'bag time series must not have negative times'
        raise ValueError(msg)
    return np.rint(t * 1e9).astype(np.int64)


def _slice(fields: list, lo: int, hi: int) -> list:
    return [None if f is None else tuple(a[lo:hi] for a in f) for f in fields]


def _prepend(head: list, fields: list, count: int) -> list:
    """The rows of ``head`` (joined fields) followed by the first ``count`` rows of ``fields``."""
    return [None if f is None else
            (np.concatenate((h, np.hstack([a[:count] for a in f]))),) for h, f in
            zip(head, fields)]


def _compared(result) -> list[np.ndarray]:
    """The recorded arrays that are constant during a standstill (all but time and energy)."""
    mo, dyn, pw = result.motion, result.dynamics, result.power
    return [mo.pos, mo.vel, mo.acc, dyn.angle_rad, dyn.omega_rad_s, dyn.alpha_rad_s2,
            dyn.force_n, dyn.torque_nm, pw.power_w, pw.total_w[:, None]]


class SimulationBagWriter:
    """Write a simulation to a rosbag2/MCAP directory chunk by chunk (context manager).

    Each chunk's messages are built and written as the chunk arrives; samples that do not fill
    a message of ``batch`` points wait for the next chunk, so the messages are the ones a
    whole-record write produces. The messages of a topic are built with numpy as one byte
    array (:func:`.cdr.joint_trajectory_rows`) straight from the simulation's arrays, and
    written in MCAP chunks that each hold the same stretch of time on every topic
    (:class:`.bagwrite.StreamBagWriter`). Memory: one chunk of samples and its messages.

    Parameters
    ----------
    path
        Bag directory to create; it must not exist yet.
    batch
        Samples per JointTrajectory message.
    compression
        ``'zstd'``, ``'lz4'`` or ``'none'`` (MCAP chunk compression, :mod:`.mcapstream`).
    standstill_period_s
        During a standstill keep the first and last sample and one per this period
        (:mod:`.thinning`); ``None`` records every sample.
    rate_hz
        Sample rate of the grid: needed for chunks with left-out samples (``Motion.gaps``).
    background
        Compress and write the MCAP chunks in a second thread (same file; see
        :class:`.mcapstream.McapStream`).
    plot_rate_hz
        Display rate of the plot-ready topics (:mod:`.plottopics`; 0: every recorded
        sample; ``None``: no plot topics).
    start_ns
        Added to every stamp [ns]: the wall-clock time of the program start (0: stamps
        are simulation time).
    """

    def __init__(self, path: str | Path, *, batch: int = 100, compression: str = 'none',
                 standstill_period_s: float | None = STANDSTILL_PERIOD_S,
                 rate_hz: float | None = None, background: bool = False,
                 plot_rate_hz: float | None = DEFAULT_PLOT_RATE_HZ, start_ns: int = 0) -> None:
        if int(start_ns) < 0:
            msg = f'start_ns must be >= 0, got {start_ns}'
            raise ValueError(msg)
        self.start_ns = int(start_ns)
        self.plot_messages = 0
        self._pending: dict[str, MessageRows] = {}      # plot messages after the JT ones
        self._bag = StreamBagWriter(path, compression=compression, background=background)
        self._plot = (None if plot_rate_hz is None else
                      RecordingPlots(rate_hz=plot_rate_hz, stamps=self._stamps,
                                     lead=self._bag.lead))
        self.batch = int(batch)
        self._thin = (None if standstill_period_s is None else
                      StandstillThinner(period_s=standstill_period_s, rate_hz=rate_hz))
        self._last: list[np.ndarray] | None = None      # last row of the compared arrays
        self._held: tuple[float, dict] | None = None    # the row the thinner holds back
        self.samples = 0                                # samples recorded (per topic)
        # samples waiting for a full message: times [ns] and per topic the joined fields
        self._rest_t = np.zeros(0, np.int64)
        self._rest: dict[str, tuple[tuple[str, ...], list]] = {}
        self.messages = 0

    def __enter__(self) -> 'SimulationBagWriter':
        self._bag.__enter__()
        try:
            # declared up front: a declaration ends the open MCAP chunk
            for topic in (bagio.TOPIC_SETPOINTS, bagio.TOPIC_AXIS_STATE, bagio.TOPIC_POWER):
                self._bag.channel(topic, bagio.JOINT_TRAJECTORY)
            self._bag.channel(bagio.TOPIC_BLOCK_ENERGY, bagio.DIAGNOSTIC_ARRAY)
            if self._plot is not None:
                for topic in (TOPIC_PLOT_POWER, TOPIC_PLOT_AXES, TOPIC_PLOT_BLOCK_ENERGY):
                    self._bag.channel(topic, JOINT_STATE)
        except BaseException as err:
            self._bag.__exit__(type(err), err, err.__traceback__)
            raise
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self._bag.__exit__(exc_type, exc, tb)

    def write(self, chunk) -> None:
        """Write the series of one ``SimulationResult`` chunk (whole messages only)."""
        columns = simulation_columns(chunk)
        t = chunk.motion.t
        if self._thin is not None and t.shape[0]:
            t, columns = self._thinned(chunk, t, columns)
        plots = self._merge_pending(self._plot_rows(t, columns))
        t_ns = self._stamps(t)
        n, r, batch = int(t_ns.shape[0]), int(self._rest_t.shape[0]), self.batch
        lead = self._bag.lead
        first: dict[str, MessageRows] = {}
        start = 0
        if r:
            start = min(batch - r, n)
            t_head = np.concatenate((self._rest_t, t_ns[:start]))
            heads = {topic: (names, _prepend(self._rest[topic][1], fields, start))
                     for topic, (names, fields) in columns.items()}
            if t_head.shape[0] < batch:          # still not a whole message
                self._keep(t_head, heads, 0, t_head.shape[0])
                self._pending = plots
                return
            first = {topic: joint_trajectory_rows(t_head, names, fields, points=batch,
                                                  lead=lead)
                     for topic, (names, fields) in heads.items()}
        full = (n - start) // batch * batch
        self.samples += full + (batch if first else 0)
        blocks = {}
        if full:
            blocks = {topic: joint_trajectory_rows(t_ns[start:start + full], names,
                                                   _slice(fields, start, start + full),
                                                   points=batch, lead=lead)
                      for topic, (names, fields) in columns.items()}
        self._keep(t_ns, columns, start + full, n)
        for topic, block in first.items():     # joins the first chunk of the slices below
            self.messages += self._bag.write_rows(topic, block)
        self._write_interleaved(blocks, plots)

    def _stamps(self, t: np.ndarray) -> np.ndarray:
        t_ns = _t_ns(t)
        if self.start_ns:
            t_ns += self.start_ns
            if t_ns.shape[0] and int(t_ns[-1]) > MAX_STAMP_NS:
                msg = check_end(self.start_ns, float(t[-1]))
                raise ConfigError(msg, file='command line', key='start-time')
        return t_ns

    def _plot_rows(self, t: np.ndarray, columns: dict) -> dict[str, MessageRows]:
        """The plot topics' messages of the display intervals completed by these samples."""
        return {} if self._plot is None else self._plot.rows(t, columns)

    def _write_plots(self, plots: dict[str, MessageRows]) -> None:
        for topic, block in plots.items():
            self.plot_messages += self._bag.write_rows(topic, block, msgtype=JOINT_STATE)

    def _merge_pending(self, plots: dict[str, MessageRows]) -> dict[str, MessageRows]:
        """The plot messages held back by the last write, followed by ``plots``."""
        pending, self._pending = self._pending, {}
        for topic, old in pending.items():
            new = plots.get(topic)
            if new is None or new.rows.shape[0] == 0:
                plots[topic] = old
            elif old.rows.shape[0]:
                plots[topic] = MessageRows(stamps=np.concatenate((old.stamps, new.stamps)),
                                           rows=np.concatenate((old.rows, new.rows)),
                                           start=new.start, length=new.length)
        return plots

    def _thinned(self, chunk, t: np.ndarray, columns: dict) -> tuple[np.ndarray, dict]:
        """The chunk's samples the recording keeps (:mod:`.thinning`), as times and columns."""
        compared = _compared(chunk)
        still = np.ones(t.shape[0], bool)
        for j, a in enumerate(compared):
            for c in range(a.shape[1]):
                col = a[:, c]
                still[1:] &= col[1:] == col[:-1]
                still[0] &= self._last is not None and bool(col[0] == self._last[j][c])
        self._last = [a[-1].copy() for a in compared]
        sel = self._thin.select(t, still, getattr(chunk.motion, 'gaps', ()))
        if sel is None:
            return t, columns
        held = self._held
        self._held = None
        if sel.hold_last:
            last = {topic: [None if f is None else tuple(a[-1:].copy() for a in f)
                            for f in fields] for topic, (_, fields) in columns.items()}
            self._held = (float(t[-1]), last)
        shift = 1 if held is not None and bool((sel.src < 0).any()) else 0
        idx = sel.src + shift
        t_src = t[np.maximum(sel.src, 0)]
        back = (t_src - sel.t)[sel.filled]
        out = {}
        gathered: dict[int, np.ndarray] = {}     # an array on two topics is taken once
        for topic, (names, fields) in columns.items():
            taken = []
            for i, f in enumerate(fields):
                if f is None:
                    taken.append(None)
                    continue
                parts = []
                for k, a in enumerate(f):
                    if shift:
                        parts.append(np.concatenate((held[1][topic][i][k], a))[idx])
                        continue
                    got = gathered.get(id(a))
                    if got is None:
                        got = gathered[id(a)] = a[idx]
                    parts.append(got)
                taken.append(tuple(parts))
            if topic == bagio.TOPIC_POWER and back.size:
                # energy (positions) of a left-out sample: E_row - P_row (t_row - t)
                for energy, power in zip(taken[0], taken[1]):
                    energy[sel.filled] -= power[sel.filled] * back[:, None]
            out[topic] = (names, taken)
        return sel.t, out

    def _keep(self, t_ns: np.ndarray, columns: dict, lo: int, hi: int) -> None:
        """Keep samples ``lo:hi`` (fewer than a message) for the next chunk, as copies."""
        self._rest_t = t_ns[lo:hi].copy()
        self._rest = {topic: (names, [None if f is None else np.hstack([a[lo:hi] for a in f])
                                      for f in fields])
                      for topic, (names, fields) in columns.items()}

    def _append_rest(self, t_ns: np.ndarray, columns: dict) -> None:
        """Add samples (a few) to those waiting for a message."""
        self._rest_t = np.concatenate((self._rest_t, t_ns))
        self._rest = {topic: (names, [None if f is None else
                                      np.concatenate((old, np.hstack(f)))
                                      for old, f in zip(self._rest[topic][1], fields)])
                      for topic, (names, fields) in columns.items()}

    def _write_interleaved(self, blocks: dict[str, MessageRows],
                           plots: dict[str, MessageRows] | None = None) -> None:
        """Write the topics' messages in slices of time, one MCAP chunk per slice.

        The plot topics' messages go into the slice of their stamps; those later than the
        samples written so far wait for the next write (:attr:`_pending`), so that chunks
        do not overlap in time.
        """
        plots = plots or {}
        # samples from here on wait for a whole message: so do the plot messages
        limit = int(self._rest_t[0]) if self._rest_t.shape[0] else None
        if not blocks:
            self._hold_plots(plots, limit)
            return
        m = next(iter(blocks.values())).rows.shape[0]
        per_message = sum(b.length + self._bag.lead for b in blocks.values())
        stamps = next(iter(blocks.values())).stamps
        if plots:
            # plot messages per JointTrajectory message, on average
            per_message += sum((b.length + self._bag.lead) * b.rows.shape[0]
                               for b in plots.values()) // max(m, 1)
        # a slice fills 7/8 of a chunk: the plot messages vary about their average, and a
        # slice over the limit would close the chunk inside it and leave a small one behind
        step = max(1, self._bag.chunk_bytes * 7 // 8 // per_message)
        taken = dict.fromkeys(plots, 0)
        for lo in range(0, m, step):
            for topic, b in blocks.items():
                part = MessageRows(stamps=b.stamps[lo:lo + step], rows=b.rows[lo:lo + step],
                                   start=b.start, length=b.length)
                self.messages += self._bag.write_rows(topic, part)
            if lo + step < m:
                for topic, b in plots.items():
                    a = taken[topic]
                    z = int(np.searchsorted(b.stamps, stamps[lo + step], side='left'))
                    if z > a:
                        self._write_plots({topic: _rows(b, a, z)})
                        taken[topic] = z
            else:
                self._hold_plots({topic: _rows(b, taken[topic], b.stamps.shape[0])
                                  for topic, b in plots.items()}, limit)
            self._bag.close_chunk()

    def _hold_plots(self, plots: dict[str, MessageRows], limit: int | None) -> None:
        """Write the plot messages stamped before ``limit``, keep the others pending."""
        for topic, b in plots.items():
            z = b.stamps.shape[0] if limit is None else int(
                np.searchsorted(b.stamps, limit, side='left'))
            if z:
                self._write_plots({topic: _rows(b, 0, z)})
            if z < b.stamps.shape[0]:
                self._pending[topic] = _rows(b, z, b.stamps.shape[0])

    def finish(self, blocks: Sequence[tuple[int, float, float]], *, summary: dict,
               stamp_s: float) -> None:
        """Write the samples still waiting, the per-block energy and the summary."""
        if self._held is not None:         # the program ends in a standstill: its last sample
            t_held, fields = self._held
            self._held = None
            columns = {topic: (names, fields[topic]) for topic, (names, _) in self._rest.items()}
            self._pending = self._merge_pending(self._plot_rows(np.array([t_held]), columns))
            self._append_rest(self._stamps(np.array([t_held])), columns)
        r = int(self._rest_t.shape[0])
        if r:
            for topic, (names, fields) in self._rest.items():
                block = joint_trajectory_rows(self._rest_t, names, fields, points=r,
                                              lead=self._bag.lead)
                self.messages += self._bag.write_rows(topic, block)
            self.samples += r
        self._rest_t = np.zeros(0, np.int64)
        self._rest = {}
        self._write_plots(self._merge_pending({}))
        if self._plot is not None:
            self._write_plots(self._plot.finish())
        end_ns = int(round(stamp_s * 1e9)) + self.start_ns
        self._bag.write_block_energy(blocks, stamp_ns=end_ns,
                                     program=str(summary.get('program', '')))
        if self._plot is not None:
            self._write_block_plot(blocks, end_ns)
        self._bag.set_custom_data(SUMMARY_KEY, summary)

    def _write_block_plot(self, blocks, stamp_ns: int) -> None:
        """``/plot/block_energy``: the per-line energy as numbers (:mod:`.plottopics`)."""
        if getattr(blocks, 'lines', None) is not None:
            lines, energy, duration = blocks.lines, blocks.energy_j, blocks.duration_s
        else:
            rows = np.array([(int(a), float(b), float(c)) for a, b, c in blocks],
                            dtype=[('l', np.int64), ('e', float), ('d', float)])
            lines, energy, duration = rows['l'], rows['e'], rows['d']
        for data in block_energy_joint_state(stamp_ns, lines, energy, duration,
                                             per_message=BLOCK_ENERGY_PER_MESSAGE):
            self._bag.write_raw(TOPIC_PLOT_BLOCK_ENERGY, JOINT_STATE, stamp_ns, data)
            self.plot_messages += 1


def _rows(block: MessageRows, lo: int, hi: int) -> MessageRows:
    """Messages ``lo:hi`` of a block."""
    return MessageRows(stamps=block.stamps[lo:hi], rows=block.rows[lo:hi], start=block.start,
                       length=block.length)


def write_simulation_bag(path: str | Path, result, *, summary: dict, batch: int = 100,
                         progress: Callable[[float], None] | None = None,
                         compression: str = 'none',
                         plot_rate_hz: float | None = DEFAULT_PLOT_RATE_HZ,
                         start_ns: int = 0) -> None:
    """Write a whole simulation as a rosbag2/MCAP directory (topics in README)."""
    from feed_axis_energy.physics import energy_by_line
    with SimulationBagWriter(path, batch=batch, compression=compression,
                             plot_rate_hz=plot_rate_hz, start_ns=start_ns) as writer:
        writer.write(result)
        if progress is not None:
            progress(0.9)
        writer.finish(energy_by_line(result.power), summary=summary,
                      stamp_s=float(result.power.t[-1]))
    if progress is not None:
        progress(1.0)
