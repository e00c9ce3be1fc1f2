"""The setpoint source of the node graph: a program's planned samples as batches, streamed.

``gcode_trajectory`` publishes the planned motion in messages of ``batch`` samples. Here the
samples come from the streaming planner (:func:`feed_axis_energy.plan.stream.iter_motion` over
:func:`.gcode.iter_moves`), the same code ``simulate`` runs, so the node holds one planner
chunk and one batch at a time, never every sample of a program.

Two passes over the program, as ``simulate --out`` does: :meth:`SetpointSource.survey` plans
it once for what must be known before streaming starts (number of samples and batches,
duration, the first and the last batch's stamps, and the run-length table of source lines that
the node publishes on ``program/lines``: one entry per change of line, so its size grows with
the program's blocks, not with its samples); :meth:`SetpointSource.batches` plans it again and
hands on the batches. Batches are cut at multiples of ``batch`` samples from the program start
(:func:`.graph.batch_bounds`), whatever the planner's chunk size.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from .flow import block_starts, seconds_to_ns
from ..plan import Motion

__all__ = ['SetpointBatch', 'ProgramSurvey', 'SetpointSource']


@dataclass(frozen=True)
class SetpointBatch:
    """One message's worth of setpoints.

    Attributes
    ----------
    index
        Batch number from 0.
    t_ns
        Sample stamps [ns], shape ``(n,)``.
    pos, vel, acc
        Commanded positions [m], velocities [m/s], accelerations [m/s^2], shape ``(n, k)``.
    """

    index: int
    t_ns: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray


@dataclass(frozen=True)
class ProgramSurvey:
    """What the first pass over a program found.

    Attributes
    ----------
    axes
        Axis names (``Motion.axes``).
    n_samples, n_batches
        Samples of the program and messages of ``batch`` samples.
    duration_s
        Time of the last sample minus time of the first [s].
    first_ns, last_batch_ns
        Stamps of the first sample and of the last batch's first sample [ns].
    starts_ns, lines
        Run-length table of the samples' source lines (:func:`.graph.block_starts`).
    """

    axes: tuple[str, ...]
    n_samples: int
    n_batches: int
    duration_s: float
    first_ns: int
    last_batch_ns: int
    starts_ns: np.ndarray
    lines: np.ndarray


class SetpointSource:
    """Batches of a program's planned samples in bounded memory.

    Parameters
    ----------
    open_motion
        Returns a new iterator over the program's motion chunks each time it is called
        (typically ``iter_motion(iter_moves(path, ...), limits, ...)``).
    batch
        Samples per batch (``>= 1``).
    """

    def __init__(self, open_motion: Callable[[], Iterable[Motion]], *, batch: int) -> None:
        if batch < 1:
            msg = f'batch must be >= 1, got {batch}'
            raise ValueError(msg)
        self._open = open_motion
        self.batch = int(batch)

    def survey(self) -> ProgramSurvey:
        """Plan the program once and keep only what streaming needs to know first."""
        batch = self.batch
        n = 0
        axes: tuple[str, ...] = ()
        first_ns = last_batch_ns = 0
        t_first = t_last = 0.0
        starts: list[np.ndarray] = []
        lines: list[np.ndarray] = []
        last_line = None
        for chunk in self._open():
            m = chunk.t.shape[0]
            if m == 0:
                continue
            t_ns = seconds_to_ns(chunk.t)
            if n == 0:
                axes = tuple(chunk.axes)
                first_ns = int(t_ns[0])
                t_first = float(chunk.t[0])
            # the last batch start in this chunk: the largest multiple of batch in [n, n + m)
            top = ((n + m - 1) // batch) * batch
            if top >= n:
                last_batch_ns = int(t_ns[top - n])
            s, ln = block_starts(t_ns, chunk.line)
            if last_line is not None and ln.shape[0] and ln[0] == last_line:
                s, ln = s[1:], ln[1:]     # the run goes on from the previous chunk
            if ln.shape[0]:
                starts.append(s)
                lines.append(ln)
                last_line = int(ln[-1])
            t_last = float(chunk.t[-1])
            n += m
        empty = np.zeros(0, dtype=np.int64)
        return ProgramSurvey(
            axes=axes, n_samples=n, n_batches=-(-n // batch), duration_s=t_last - t_first,
            first_ns=first_ns, last_batch_ns=last_batch_ns,
            starts_ns=np.concatenate(starts) if starts else empty,
            lines=np.concatenate(lines) if lines else empty)

    def batches(self) -> Iterator[SetpointBatch]:
        """Plan the program again and yield its batches in order (all of ``batch`` samples
        but the last)."""
        batch = self.batch
        parts: list[tuple[np.ndarray, ...]] = []
        held = 0
        index = 0
        for chunk in self._open():
            if chunk.t.shape[0] == 0:
                continue
            arrays = (seconds_to_ns(chunk.t), chunk.pos, chunk.vel, chunk.acc)
            off = 0
            m = chunk.t.shape[0]
            while off < m:
                take = min(batch - held, m - off)
                parts.append(tuple(a[off:off + take] for a in arrays))
                held += take
                off += take
                if held == batch:
                    yield self._join(index, parts)
                    index += 1
                    parts = []
                    held = 0
        if held:
            yield self._join(index, parts)

    @staticmethod
    def _join(index: int, parts: list[tuple[np.ndarray, ...]]) -> SetpointBatch:
        if len(parts) == 1:
            t_ns, pos, vel, acc = parts[0]
        else:
            t_ns, pos, vel, acc = (np.concatenate(col) for col in zip(*parts))
        return SetpointBatch(index=index, t_ns=t_ns, pos=pos, vel=vel, acc=acc)
