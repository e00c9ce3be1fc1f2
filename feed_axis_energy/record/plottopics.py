"""Plot-ready topics: one sample per ``sensor_msgs/JointState`` message, at a display rate.

The batched ``JointTrajectory`` streams (:mod:`.recording`) are compact, but a viewer plots
one value per field per message (Foxglove's Plot panel, PlotJuggler), so a batch of 100
samples shows as one point or as hundreds of separate series. The plot topics carry one
sample per message, its time in ``header.stamp`` (= the bag's log time):

* ``/plot/power``: one entry per axis and ``total``; ``position`` = cumulative energy [J],
  ``velocity`` = actual power [W] (power is the time derivative of energy, as velocity is of
  position), ``effort`` empty;
* ``/plot/axes``: one entry per axis (its ball screw): ``position`` = screw angle [rad],
  ``velocity`` = screw speed [rad/s], ``effort`` = screw torque [N·m];
* ``/plot/block_energy``: once at the program end, one entry per source line (name = the
  line number), ``position`` = energy [J], ``velocity`` = mean power [W] (energy / duration,
  0 for a line of no duration), ``effort`` = duration [s].

**Display rate without losing the peaks** (:class:`PlotDecimator`). With a display rate
``r`` the time axis is cut into intervals ``[k/r, (k+1)/r)``; of the samples in an interval
the topic keeps the first one and, for every key column (each power column on
``/plot/power``, each torque column on ``/plot/axes``), the first sample where it is
largest and the first where it is smallest. So every plotted value is the simulated value at
its stamp, and the minimum and maximum of every key column over any stretch of whole
intervals - the peak power in particular - are among the plotted samples. A rate of 0 keeps
every sample. The selection does not depend on how the samples are chunked: the rows of an
interval that continues into the next chunk are held back until it is complete.
"""
from __future__ import annotations

from typing import Iterator, Sequence

import numpy as np

from .bagio import typestore
from .cdr import MessageRows

__all__ = ['PlotDecimator', 'held_then', 'held_tail', 'joint_state_rows',
           'block_energy_joint_state',
           'TOPIC_PLOT_POWER', 'TOPIC_PLOT_AXES', 'TOPIC_PLOT_BLOCK_ENERGY', 'JOINT_STATE',
           'DEFAULT_PLOT_RATE_HZ']

TOPIC_PLOT_POWER = '/plot/power'
TOPIC_PLOT_AXES = '/plot/axes'
TOPIC_PLOT_BLOCK_ENERGY = '/plot/block_energy'
JOINT_STATE = 'sensor_msgs/msg/JointState'
DEFAULT_PLOT_RATE_HZ = 20.0
_NS = 1_000_000_000
_EPS = 1e-9                 # relative slack of an interval boundary (grid times are rounded)
_ENCAPSULATION = np.frombuffer(b'\x00\x01\x00\x00', np.uint8)


def _string(text: str, offset: int) -> bytes:
    """A CDR string at payload ``offset`` (4-aligned), padded to the next multiple of 4."""
    raw = text.encode('utf-8') + b'\x00'
    out = len(raw).to_bytes(4, 'little') + raw
    return out + b'\x00' * (-(offset + len(out)) % 4)


def joint_state_rows(t_ns: np.ndarray, names: Sequence[str],
                     fields: Sequence[np.ndarray | None], *, frame_id: str = '',
                     lead: int = 0) -> MessageRows:
    """``sensor_msgs/JointState`` messages, one per row of the field arrays, as byte rows.

    Parameters
    ----------
    t_ns
        Header stamp of every message [ns], ``(m,)``, non-negative.
    names
        Joint names (``name``).
    fields
        ``position``, ``velocity``, ``effort``: arrays ``(m, len(names))`` or ``None``
        (empty in every message).
    frame_id
        ``header.frame_id``.
    lead
        Spare bytes before each message (a container's record header goes there).

    Returns
    -------
    MessageRows
        Message ``i`` is ``rows[i, start:start + length]``; its bytes equal rosbags'
        ``serialize_cdr`` of the message (a test compares them).
    """
    t_ns = np.asarray(t_ns, np.int64)
    m, k = int(t_ns.shape[0]), len(names)
    head = bytearray(8)                              # stamp, filled per message
    head += _string(frame_id, len(head))
    head += k.to_bytes(4, 'little')
    for name in names:
        head += _string(name, len(head))
    at = []
    o = len(head)
    for value in fields:
        o += -o % 4
        count_at = o
        o += 4
        if value is None or k == 0:               # an empty sequence: no alignment
            at.append((count_at, -1, 0))
            continue
        o += -o % 8
        at.append((count_at, o, k))
        o += 8 * k
    payload = lead + 4
    template = np.zeros(payload + o, np.uint8)
    template[lead:payload] = _ENCAPSULATION
    template[payload:payload + len(head)] = np.frombuffer(bytes(head), np.uint8)
    for count_at, _, width in at:
        template[payload + count_at:payload + count_at + 4] = np.frombuffer(
            width.to_bytes(4, 'little'), np.uint8)
    rows = np.empty((m, template.shape[0]), np.uint8)
    rows[:] = template
    stamp = np.empty((m, 2), '<u4')
    stamp[:, 0] = t_ns // _NS
    stamp[:, 1] = t_ns % _NS
    rows[:, payload:payload + 8] = stamp.view(np.uint8)
    for (_, value_at, width), value in zip(at, fields):
        if value_at < 0:
            continue
        values = np.ascontiguousarray(value, '<f8')
        if values.shape != (m, width):
            msg = f'joint_state_rows: a field has shape {values.shape}, expected {(m, width)}'
            raise ValueError(msg)
        c = payload + value_at
        rows[:, c:c + 8 * width] = values.view(np.uint8).reshape(m, 8 * width)
    return MessageRows(stamps=t_ns, rows=rows, start=lead, length=4 + o)


class PlotDecimator:
    """Keep, per display interval, the first sample and each key column's extremes.

    Two ways to use it: :meth:`push` / :meth:`finish` take and return whole rows of values
    (the decimator holds the rows of the open interval); :meth:`select` /
    :meth:`finish_select` take only the key columns and return row indices, so a caller with
    many value columns gathers just the kept rows and holds the open interval's rows itself.

    Parameters
    ----------
    rate_hz
        Display rate [Hz]; 0 keeps every sample.
    keys
        Column indices (of the ``values`` passed to :meth:`push`) whose minimum and maximum
        per interval are kept.
    """

    def __init__(self, *, rate_hz: float, keys: Sequence[int]) -> None:
        rate = float(rate_hz)
        if not np.isfinite(rate) or rate < 0:
            msg = f'display rate must be a finite number >= 0 Hz, got {rate_hz!r}'
            raise ValueError(msg)
        self.rate_hz = rate
        self.keys = list(keys)
        self._held_t = np.zeros(0)                  # times and key values of the open
        self._held_v: np.ndarray | None = None      # interval's samples
        self._held_k = -1
        self._rows: np.ndarray | None = None        # push: the open interval's whole rows

    @property
    def held(self) -> int:
        """Samples of the open interval, held back until it is complete."""
        return int(self._held_t.shape[0])

    def intervals(self, t: np.ndarray) -> np.ndarray:
        """The display interval of every time ``t`` [s] (for :meth:`select`'s ``k``)."""
        x = t * self.rate_hz
        return np.floor(x + _EPS * np.maximum(1.0, np.abs(x))).astype(np.int64)

    def select(self, t: np.ndarray, keys: np.ndarray,
               k: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Take the next samples (times ``(n,)`` [s], key columns ``(n, c)``; ``k``: their
        :meth:`intervals` when already known); return the kept samples of the intervals that
        are complete as ``(t, rows)``: ``rows`` index the held samples followed by these
        (``held`` before the call, then ``0..n-1``). Afterwards the last :attr:`held` of
        those samples are held back."""
        n = int(t.shape[0])
        h = self.held
        if self.rate_hz == 0:
            return t, np.arange(n)
        if n == 0:
            return t[:0], np.zeros(0, np.int64)
        keys = keys.reshape(n, -1)
        k = self.intervals(t) if k is None else k
        out_t, out_i = [], []
        lo = 0
        if h:
            lo = int(np.searchsorted(k, self._held_k, side='right'))
            ht = np.concatenate((self._held_t, t[:lo]))
            hv = np.concatenate((self._held_v, keys[:lo]))
            if lo == n:                          # the interval goes on
                self._held_t, self._held_v = ht, hv
                return t[:0], np.zeros(0, np.int64)
            sel = self._select(hv, np.zeros(ht.shape[0], np.int64))
            out_t.append(ht[sel])
            out_i.append(sel)
        last = int(k[-1])
        hi = int(np.searchsorted(k, last, side='left'))
        if hi > lo:
            sel = self._select(keys[lo:hi], k[lo:hi]) + lo
            out_t.append(t[sel])
            out_i.append(sel + h)
        self._held_t, self._held_v = t[hi:].copy(), keys[hi:].copy()
        self._held_k = last
        if not out_t:
            return t[:0], np.zeros(0, np.int64)
        if len(out_t) == 1:
            return out_t[0], out_i[0]
        return np.concatenate(out_t), np.concatenate(out_i)

    def finish_select(self) -> tuple[np.ndarray, np.ndarray]:
        """The kept samples of the last (open) interval as ``(t, rows)``, ``rows`` indexing
        the held samples."""
        if not self.held:
            return np.zeros(0), np.zeros(0, np.int64)
        sel = self._select(self._held_v, np.zeros(self.held, np.int64))
        t = self._held_t[sel]
        self._held_t, self._held_v = np.zeros(0), None
        return t, sel

    def push(self, t: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Take the next samples (times ``(n,)`` [s], ``values`` ``(n, c)``); return the kept
        ones of the intervals that are complete, as ``(t, values)``."""
        if self.rate_hz == 0:
            return t, values
        keys = values[:, self.keys] if self.keys else values[:, :0]
        held = self._rows if self._rows is not None else values[:0]
        t_out, idx = self.select(t, keys)
        out = held_then(held, values, idx)
        self._rows = held_tail(held, values, self.held)
        return t_out, out

    def finish(self) -> tuple[np.ndarray, np.ndarray]:
        """The kept samples of the last (open) interval."""
        if not self.held:
            return np.zeros(0), np.zeros((0, 0))
        rows = self._rows
        t, idx = self.finish_select()
        self._rows = None
        return t, rows[idx]

    def _select(self, values: np.ndarray, k: np.ndarray) -> np.ndarray:
        """Row indices kept of whole intervals ``k`` (non-decreasing), sorted; ``values``:
        the key columns."""
        n = int(k.shape[0])
        if n == 0:
            return np.zeros(0, np.int64)
        new = np.empty(n, bool)
        new[0] = True
        np.not_equal(k[1:], k[:-1], out=new[1:])
        starts = np.flatnonzero(new)
        if values.shape[1] == 0:
            return starts
        keep = new.copy()
        sizes = np.diff(starts, append=n)
        size = int(sizes.max())
        full = sizes == size
        # intervals of the common length (motion at the full rate): one gather and one
        # argmax / argmin per key column
        rows = starts[full][:, None] + np.arange(size)
        for c in range(values.shape[1]):
            block = values[:, c][rows]
            keep[rows[:, 0] + block.argmax(axis=1)] = True
            keep[rows[:, 0] + block.argmin(axis=1)] = True
        if full.all():
            return np.flatnonzero(keep)
        # the other intervals (shorter: a standstill recorded at 1 Hz, the first ones)
        group = np.cumsum(new) - 1
        sub = np.flatnonzero(~full[group])
        g = group[sub]
        first_of = np.empty(sub.shape[0], bool)
        first_of[0] = True
        np.not_equal(g[1:], g[:-1], out=first_of[1:])
        sub_starts = np.flatnonzero(first_of)
        sub_group = np.cumsum(first_of) - 1
        for c in range(values.shape[1]):
            col = values[sub, c]
            for reduce in (np.maximum, np.minimum):
                hit = np.flatnonzero(col == reduce.reduceat(col, sub_starts)[sub_group])
                first = np.empty(hit.shape[0], bool)      # the first hit of each interval
                first[0] = True
                h = sub_group[hit]
                np.not_equal(h[1:], h[:-1], out=first[1:])
                keep[sub[hit[first]]] = True
        return np.flatnonzero(keep)


def held_tail(held: np.ndarray, rows: np.ndarray, count: int) -> np.ndarray:
    """The last ``count`` rows of ``held`` followed by ``rows`` (a copy)."""
    n = rows.shape[0]
    if count <= n:
        return rows[n - count:].copy()
    return np.concatenate((held[held.shape[0] - (count - n):], rows))


def held_then(held: np.ndarray, rows: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Rows ``idx`` of ``held`` followed by ``rows`` (both ``(., c)``), without joining them
    first (:meth:`PlotDecimator.select`'s indices)."""
    h = held.shape[0]
    if idx.shape[0] and int(idx[0]) >= h:            # sorted: none of the held rows
        return rows[idx - h]
    out = np.empty((idx.shape[0],) + rows.shape[1:], rows.dtype)
    old = idx < h
    out[old] = held[idx[old]]
    out[~old] = rows[idx[~old] - h]
    return out


def block_energy_joint_state(stamp_ns: int, lines: np.ndarray, energy_j: np.ndarray,
                             duration_s: np.ndarray, *, per_message: int,
                             frame_id: str = '') -> Iterator[bytes]:
    """CDR of the ``/plot/block_energy`` JointStates (module docstring), ``per_message``
    lines each (at least one message, empty for a program without lines)."""
    store = typestore()
    cls = store.types[JOINT_STATE]
    header = store.types['std_msgs/msg/Header']
    stamp = store.types['builtin_interfaces/msg/Time'](sec=int(stamp_ns // _NS),
                                                       nanosec=int(stamp_ns % _NS))
    lines = np.asarray(lines, np.int64)
    energy = np.asarray(energy_j, np.float64)
    duration = np.asarray(duration_s, np.float64)
    with np.errstate(divide='ignore', invalid='ignore'):
        mean = np.where(duration > 0, energy / np.where(duration > 0, duration, 1.0), 0.0)
    total = int(lines.shape[0])
    for lo in range(0, max(total, 1), per_message):
        hi = min(lo + per_message, total)
        msg = cls(header=header(stamp=stamp, frame_id=frame_id),
                  name=[str(v) for v in lines[lo:hi].tolist()],
                  position=np.ascontiguousarray(energy[lo:hi]),
                  velocity=np.ascontiguousarray(mean[lo:hi]),
                  effort=np.ascontiguousarray(duration[lo:hi]))
        yield bytes(store.serialize_cdr(msg, JOINT_STATE))
