"""Pure helpers of the node graph: batching, flow control, pacing and crash-safe recording.

Nothing here imports rclpy: every piece is tested without DDS. The nodes in
:mod:`feed_axis_energy.nodes` are thin shells that call these helpers and the physics core.

Time is integer nanoseconds at this boundary (message stamps, bag log times); the physics
core sees float seconds rebuilt from those integers.
"""
from __future__ import annotations

from collections import deque
import math
from pathlib import Path
import struct
from typing import cast, Sequence

import numpy as np

from ..physics import (apply_braking, compute_dynamics, compute_power, electrical_power,
                       ElectricalAccumulator, ElectricalPower, EnergyIntegrator)
from ..errors import ConfigError, DataError
from .end import ProgramEnd
from ..machine import Machine
from ..plan import Motion
from ..sim import declared_effects_power_w

__all__ = ['NS_PER_S', 'seconds_to_ns', 'batch_bounds', 'FlowWindow', 'pacing_delay_s',
           'block_starts', 'lines_at', 'StreamingPower', 'header_stamp_ns', 'latency_stats',
           'read_raw', 'recording_gaps']

NS_PER_S = 1_000_000_000


def seconds_to_ns(t_s: np.ndarray) -> np.ndarray:
    """Round float seconds to integer nanoseconds (the rounding :mod:`.bagio` uses)."""
    return np.rint(np.asarray(t_s, dtype=np.float64) * NS_PER_S).astype(np.int64)


def batch_bounds(n: int, batch: int) -> list[tuple[int, int]]:
    """Cut ``n`` samples into ``[i0, i1)`` ranges of at most ``batch`` samples."""
    if batch < 1:
        msg = f'batch must be >= 1, got {batch}'
        raise ValueError(msg)
    return [(i0, min(i0 + batch, n)) for i0 in range(0, n, batch)]


class FlowWindow:
    """At most ``window`` batches in flight between a producer and its slowest consumer.

    The producer calls :meth:`sent` with each batch's stamp; every consumer (a named
    acknowledgement source) reports the newest stamp it has fully handled with :meth:`ack`.
    A batch counts as done once every source has acknowledged a stamp at or after it.

    Parameters
    ----------
    window
        Maximum number of unacknowledged batches (``>= 1``).
    sources
        Names of the acknowledgement sources that must all catch up.
    """

    def __init__(self, window: int, sources: Sequence[str]) -> None:
        if window < 1:
            msg = f'flow window must be >= 1 batch, got {window}'
            raise ValueError(msg)
        if not sources:
            msg = 'flow window needs at least one acknowledgement source'
            raise ValueError(msg)
        self.window = int(window)
        self._acked = {s: -1 for s in sources}
        self._in_flight: deque[int] = deque()
        self._last_sent = -1

    @property
    def acked_ns(self) -> int:
        """Newest stamp every source has acknowledged (-1 before the first)."""
        return min(self._acked.values())

    @property
    def in_flight(self) -> int:
        """Number of sent batches not yet acknowledged by every source."""
        return len(self._in_flight)

    def can_send(self) -> bool:
        """Whether another batch may be sent now."""
        return len(self._in_flight) < self.window

    def sent(self, stamp_ns: int) -> None:
        """Record a batch sent with header stamp ``stamp_ns`` (stamps increase)."""
        if stamp_ns <= self._last_sent:
            msg = f'batch stamps must increase: {stamp_ns} after {self._last_sent}'
            raise ValueError(msg)
        self._last_sent = int(stamp_ns)
        self._in_flight.append(int(stamp_ns))

    def ack(self, source: str, stamp_ns: int) -> int:
        """Record that ``source`` handled everything up to ``stamp_ns``; returns batches freed."""
        if source not in self._acked:
            return 0
        self._acked[source] = max(self._acked[source], int(stamp_ns))
        done = self.acked_ns
        freed = 0
        while self._in_flight and self._in_flight[0] <= done:
            self._in_flight.popleft()
            freed += 1
        return freed


def pacing_delay_s(sample_time_s: float, start_sample_s: float, wall_elapsed_s: float, *,
                   speed: float = 1.0) -> float:
    """Seconds to wait before a sample at ``sample_time_s`` is due (<= 0: due now).

    Real-time pacing: the sample at simulation time ``t`` is due ``(t - t0) / speed`` seconds
    of wall-clock time after streaming started.
    """
    return (sample_time_s - start_sample_s) / speed - wall_elapsed_s


def block_starts(t_ns: np.ndarray, line: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Run-length code of the source line of every sample.

    Returns
    -------
    (starts_ns, lines)
        Stamp of the first sample of each run and the run's line number.
    """
    line = np.asarray(line, dtype=np.int64)
    if line.shape[0] == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    change = np.flatnonzero(np.diff(line)) + 1
    idx = np.concatenate(([0], change))
    return np.asarray(t_ns, dtype=np.int64)[idx], line[idx]


def lines_at(t_ns: np.ndarray, starts_ns: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """Source line of each stamp, from the run-length code of :func:`block_starts`."""
    if starts_ns.shape[0] == 0:
        return np.zeros(np.shape(t_ns), dtype=np.int64)
    idx = np.searchsorted(starts_ns, np.asarray(t_ns, dtype=np.int64), side='right') - 1
    return np.where(idx >= 0, lines[np.clip(idx, 0, None)], 0).astype(np.int64)


class StreamingPower:
    """Actual power and cumulative energy from screw torque and speed, batch after batch.

    Applies the same operations as :func:`.energy.compute_power` in the same order
    (``M·omega``, braking rule, sum over axes, :class:`.energy.EnergyIntegrator` over axes +
    total), so the numbers equal the offline result for the same samples. Memory is bounded:
    no batch is kept. The energy and time per source line (:func:`.energy.energy_by_line`'s
    rule: an interval counts for the line of its end sample) are summed as batches come, once
    the program's line table (``program/lines``) is known (:meth:`set_lines`); the few
    batches that arrive before it keep only their times and total power until then.

    With a ``machine`` that declares effects (``effects:`` in its YAML, e.g. written by
    ``analyze``), their extra power is added after the braking rule, as
    :func:`.simulate.apply_declared_effects` does offline; the batch's dynamics are rebuilt
    from its carriage motion with the core (:func:`.dynamics.compute_dynamics`), and every
    declarable effect is sample-local, so batches give the offline numbers.

    With a ``machine`` that declares drives (``axes.<A>.drive``), the electrical side is
    computed too (:func:`.electrical.electrical_power` on the same rebuilt dynamics; motor
    terminals, supply side, what the drives return): :attr:`last_electrical` holds the
    newest batch's, :meth:`electrical_summary` the energies so far
    (:class:`.electrical.ElectricalAccumulator`, the offline summary's ``electrical``).
    Peak power per axis and total (:attr:`peak_w`) and the energy returned while braking
    (:attr:`regenerated_j`) follow the offline summary's rules.

    Parameters
    ----------
    axes
        Axis names (column order of ``torque_nm`` and ``omega_rad_s``).
    braking
        ``'regenerative'`` or ``'dissipated'``.
    machine
        The machine model, needed only for declared effects.
    load_kg
        Workpiece mass [kg] (declared effects such as load-dependent friction use it).
    """

    def __init__(self, axes: Sequence[str], *, braking: str, machine: Machine | None = None,
                 load_kg: float = 0.0) -> None:
        apply_braking(np.zeros((0, len(axes))), braking=braking)  # validate early
        self.axes = tuple(axes)
        self.braking = braking
        self.machine = machine if machine is not None and machine.effects else None
        self.electrical_machine = (machine if machine is not None and machine.electrical
                                   else None)
        self.load_kg = float(load_kg)
        self._electrical = (ElectricalAccumulator() if self.electrical_machine is not None
                            else None)
        self.last_electrical: ElectricalPower | None = None
        self._peak: np.ndarray | None = None
        self._last_power = np.zeros(len(self.axes) + 1)
        self._regenerated = 0.0
        self._neg_last: float | None = None
        self._t_first: float | None = None
        self._prev_t: float | None = None
        if self.machine is not None:
            from ..effects import get_effect
            local = [e.id for e in self.machine.effects if not get_effect(e.id).sample_local]
            if local:
                msg = f'declared effects {local} need whole records; the graph cannot stream them'
                raise ConfigError(msg, file=self.machine.name, key='effects')
        self._integrator = EnergyIntegrator(len(self.axes) + 1)
        # the negative part of the drawn power (after the braking rule): what flows back
        self._returned = EnergyIntegrator(len(self.axes) + 1)
        self._n = 0
        self._energy_last = np.zeros(len(self.axes) + 1)
        self._prev: tuple[float, float] | None = None        # (t, total power) of the last
        self._table: tuple[np.ndarray, np.ndarray] | None = None   # (starts_ns, lines)
        self._waiting: list[tuple[np.ndarray, np.ndarray]] = []    # (t, total) before it
        self._by_line: dict[int, list[float]] = {}            # line -> [energy J, time s]

    @property
    def last_time_s(self) -> float | None:
        """Time of the newest sample integrated, or ``None``."""
        return self._integrator.last_time_s

    @property
    def n_samples(self) -> int:
        """Samples integrated so far."""
        return self._n

    @property
    def energy_j(self) -> np.ndarray:
        """Cumulative energy so far [J]: per axis, then the total (``k + 1`` values)."""
        return self._energy_last.copy()

    @property
    def last_power_w(self) -> np.ndarray:
        """Power of the newest sample [W]: per axis, then the total (zeros before any)."""
        return self._last_power.copy()

    @property
    def peak_w(self) -> np.ndarray:
        """Largest power so far [W]: per axis, then the total (zeros before any sample)."""
        if self._peak is None:
            return np.zeros(len(self.axes) + 1)
        return self._peak.copy()

    @property
    def energy_export_j(self) -> np.ndarray:
        """Energy returned so far [J], per axis then the total (``k + 1`` values, >= 0).

        The trapezoid integral of ``-min(P, 0)`` of the power after the braking rule (and
        declared effects), per axis; the total is the sum over the axes' negative parts (the
        offline summary's rule for the energy returned). Zero with ``'dissipated'``
        braking. :attr:`energy_import_j` ``-`` this equals :attr:`energy_j`.
        """
        return np.maximum(-self._returned.energy_j, 0.0)

    @property
    def energy_import_j(self) -> np.ndarray:
        """Energy drawn so far [J], per axis then the total: :attr:`energy_j` plus
        :attr:`energy_export_j`."""
        return self._energy_last + self.energy_export_j

    @property
    def regenerated_j(self) -> float:
        """Energy returned while braking so far, ``-integral sum min(M·omega, 0) dt`` [J]."""
        return max(0.0, -self._regenerated)

    @property
    def duration_s(self) -> float:
        """Time from the first to the newest sample integrated [s]."""
        last = self._integrator.last_time_s
        if self._t_first is None or last is None:
            return 0.0
        return float(last) - self._t_first

    def electrical_summary(self) -> dict | None:
        """The electrical energies so far (the offline summary's ``electrical`` object),
        ``None`` when the machine declares no drive, ``{}`` before any sample."""
        return None if self._electrical is None else self._electrical.summary()

    def update(self, t_s: np.ndarray, torque_nm: np.ndarray, omega_rad_s: np.ndarray, *,
               motion: Motion | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Integrate one batch.

        ``motion`` (the batch's carriage positions, velocities, accelerations) is required
        when the machine declares effects.

        Returns
        -------
        (power_w, energy_j)
            Both ``(m, k + 1)``: per axis then total; power [W], cumulative energy [J].
        """
        mechanical = np.asarray(torque_nm, dtype=float) * np.asarray(omega_rad_s, dtype=float)
        power = apply_braking(mechanical, braking=self.braking)
        extra = None
        dyn = None
        if self.machine is not None or self.electrical_machine is not None:
            if motion is None:
                msg = 'the machine declares effects or drives: update() needs the motion'
                raise ValueError(msg)
            model = cast(Machine, self.machine or self.electrical_machine)
            dyn = compute_dynamics(motion, model, load_kg=self.load_kg)
        if self.machine is not None and dyn is not None:
            extra = declared_effects_power_w(
                dyn, compute_power(dyn, braking=self.braking), self.machine)
            if extra is not None:
                power = power + extra
        total = power.sum(axis=1)
        both = np.column_stack((power, total))
        t = np.asarray(t_s, dtype=float)
        energy = self._integrator.update(t, both)
        negative = np.minimum(power, 0.0)
        self._returned.update(t, np.column_stack((negative, negative.sum(axis=1))))
        self.last_electrical = None
        if dyn is not None and self.electrical_machine is not None and t.shape[0]:
            elec = electrical_power(dyn, mechanical, self.electrical_machine, effects_w=extra)
            if elec is not None and self._electrical is not None:
                self._electrical.add(dyn, mechanical, elec, braking=self.braking)
            self.last_electrical = elec
        if t.shape[0]:
            self._last_power = both[-1].copy()
            self._track_peak_and_braking(t, mechanical, both)
            self._n += t.shape[0]
            self._energy_last = energy[-1].copy()
            if self._table is None:
                self._waiting.append((t.copy(), total.copy()))
            else:
                self._add_lines(t, total)
        return both, energy

    def _track_peak_and_braking(self, t: np.ndarray, mechanical: np.ndarray,
                                both: np.ndarray) -> None:
        # the offline summary's rules (sim/summary.py): column maxima; the braking power
        # summed over the axes first, one trapezoid, the gap from the last batch included
        peak = np.array([both[:, j].max() for j in range(both.shape[1])])
        self._peak = peak if self._peak is None else np.maximum(self._peak, peak)
        neg = np.minimum(mechanical, 0.0).sum(axis=1)
        if self._t_first is None:
            self._t_first = float(t[0])
        else:
            d0 = float(t[0]) - float(cast(float, self._prev_t))
            self._regenerated += 0.5 * (float(neg[0]) + cast(float, self._neg_last)) * d0
        if t.shape[0] > 1:
            self._regenerated += float(np.sum(0.5 * (neg[1:] + neg[:-1]) * np.diff(t)))
        self._neg_last = float(neg[-1])
        self._prev_t = float(t[-1])

    def set_lines(self, starts_ns: np.ndarray, lines: np.ndarray) -> None:
        """The program's line table (:func:`block_starts`); batches that waited for it are
        attributed now."""
        if self._table is not None:
            return
        self._table = (np.asarray(starts_ns, dtype=np.int64), np.asarray(lines, dtype=np.int64))
        waiting, self._waiting = self._waiting, []
        for t, total in waiting:
            self._add_lines(t, total)

    def _add_lines(self, t: np.ndarray, total: np.ndarray) -> None:
        # called only once the table is set (set_lines, or a batch after it)
        line = lines_at(seconds_to_ns(t), *cast('tuple[np.ndarray, np.ndarray]', self._table))
        if self._prev is not None:          # the interval from the previous batch's last sample
            t0, p0 = self._prev
            t = np.concatenate(([t0], t))
            total = np.concatenate(([p0], total))
            line = np.concatenate(([0], line))
        self._prev = (float(t[-1]), float(total[-1]))
        if t.shape[0] < 2:
            return
        dt = np.diff(t)
        de = 0.5 * (total[1:] + total[:-1]) * dt
        keys, inverse = np.unique(line[1:], return_inverse=True)
        energy = np.bincount(inverse, weights=de, minlength=keys.shape[0])
        duration = np.bincount(inverse, weights=dt, minlength=keys.shape[0])
        by_line = self._by_line
        for k, e, d in zip(keys.tolist(), energy.tolist(), duration.tolist()):
            acc = by_line.get(k)
            if acc is None:
                by_line[k] = [e, d]
            else:
                acc[0] += e
                acc[1] += d

    def block_energy(self, starts_ns: np.ndarray | None = None,
                     lines: np.ndarray | None = None) -> list[tuple[int, float, float]]:
        """Per-line ``(line, energy_j, duration_s)`` sorted by line (the rule of
        :func:`.energy.energy_by_line`); the line table may be given here if
        :meth:`set_lines` was not called."""
        if self._table is None:
            if starts_ns is None or lines is None:
                raise ValueError('the line table (program/lines) is not known yet')
            self.set_lines(starts_ns, lines)
        return [(k, float(v[0]), float(v[1])) for k, v in sorted(self._by_line.items())]


_STAMP = struct.Struct('<iI')


def header_stamp_ns(cdr: bytes | memoryview) -> int:
    """Header stamp of a serialized message whose first field is a ``std_msgs/Header``.

    Also right for ``rosgraph_msgs/Clock`` (first field ``builtin_interfaces/Time``). CDR
    data starts with a 4-byte encapsulation header, then ``int32 sec``, ``uint32 nanosec``.
    """
    if len(cdr) < 12:
        msg = f'serialized message of {len(cdr)} bytes is too short for a header stamp'
        raise DataError(msg, file='<cdr>')
    if cdr[1] != 1:
        msg = 'only little-endian CDR is supported'
        raise DataError(msg, file='<cdr>')
    sec, nsec = _STAMP.unpack_from(cdr, 4)
    return sec * NS_PER_S + nsec


def latency_stats(latencies_s: Sequence[float]) -> dict[str, float]:
    """Median, 99th percentile and maximum of latencies [s] (NaN when empty)."""
    arr = np.asarray(latencies_s, dtype=float)
    if arr.shape[0] == 0:
        return {'median_s': math.nan, 'p99_s': math.nan, 'max_s': math.nan, 'n': 0}
    return {'median_s': float(np.median(arr)), 'p99_s': float(np.percentile(arr, 99)),
            'max_s': float(arr.max()), 'n': int(arr.shape[0])}


def read_raw(path: str | Path, topics: Sequence[str]) -> list[tuple[str, int, bytes]]:
    """Serialized messages of ``topics`` in a bag, by log time: ``[(topic, log_ns, cdr)]``.

    Topics missing from the bag are skipped; ``DataError`` if none of them is present.
    """
    from rosbags.rosbag2 import Reader
    path = Path(path)
    if not (path / 'metadata.yaml').is_file():
        msg = 'not a rosbag2 directory (no metadata.yaml)'
        raise DataError(msg, file=str(path))
    with Reader(path) as reader:
        conns = [c for c in reader.connections if c.topic in topics]
        if not conns:
            have = ', '.join(sorted(c.topic for c in reader.connections)) or 'none'
            msg = f'none of the topics {list(topics)} is in the bag (topics: {have})'
            raise DataError(msg, file=str(path))
        out = [(c.topic, int(t), bytes(raw)) for c, t, raw in reader.messages(connections=conns)]
    out.sort(key=lambda m: m[1])
    return out


def recording_gaps(path: str | Path, streams: Sequence[str] = (
        '/setpoints', '/axis_state', '/power')) -> list[str]:
    """What a graph recording lacks against its own end-of-program marker (empty: complete).

    The marker (``/program/end``) says how many batches each stream sent and the last stamp;
    a recorder stopped before the end (a signal to it alone) leaves a bag that reads well but
    holds fewer. Used by ``feed-axis-energy launch`` before it reports success.
    """
    from ..record import bag_topics, DIAGNOSTIC_ARRAY, typestore
    # Counts from the metadata and only the marker read: bounded memory for any length.
    counts = {topic: n for topic, (_, n) in bag_topics(path).items()}
    if not counts.get('/program/end'):
        return ['no /program/end marker: the recording stopped before the program ended']
    ends = [cdr for _, _, cdr in read_raw(path, ['/program/end'])]
    msg = typestore().deserialize_cdr(ends[-1], DIAGNOSTIC_ARRAY)
    end = ProgramEnd.from_pairs((kv.key, kv.value) for st in msg.status for kv in st.values)
    return [f'{stream}: {counts.get(stream, 0)} of {end.batches} batches'
            for stream in streams if counts.get(stream, 0) != end.batches]
