"""The plot topics of a simulation recording (``/plot/power``, ``/plot/axes``), chunk by chunk.

Split from :mod:`.recording`, which hands it each chunk's recorded columns. The display-rate
selection (:class:`.plottopics.PlotDecimator`) looks at the key columns only (the power
columns for ``/plot/power``, the torque columns for ``/plot/axes``); the other columns are
gathered for the kept samples alone, and the samples of an interval that continues into the
next chunk are held here until it is complete. Memory: one display interval of samples.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from . import bagio
from .cdr import MessageRows
from .plottopics import (held_tail, held_then, joint_state_rows, PlotDecimator, TOPIC_PLOT_AXES,
                         TOPIC_PLOT_POWER)

__all__ = ['RecordingPlots']


def _blocks(topic: str, columns: dict) -> tuple[tuple[str, ...], list[np.ndarray], np.ndarray]:
    """``(joint names, value blocks, key columns)`` of a plot topic from the recorded columns
    (:func:`.recording.simulation_columns`): blocks in message field order (positions,
    velocities, effort), each ``(n, joints)`` or the per-axis and total parts of one."""
    if topic == TOPIC_PLOT_POWER:
        names, fields = columns[bagio.TOPIC_POWER]
        energy, watts = fields[0], fields[1]            # (per axis, total) each
        keys = watts[0] if len(watts) == 1 else np.hstack(watts)
        return names, list(energy) + list(watts), keys
    names, fields = columns[bagio.TOPIC_AXIS_STATE]
    angle, omega, torque = fields[0][-1], fields[1][-1], fields[3][-1]   # the screw joints
    return names[:angle.shape[1]], [angle, omega, torque], torque


class RecordingPlots:
    """Build the messages of ``/plot/power`` and ``/plot/axes`` (module docstring).

    Parameters
    ----------
    rate_hz
        Display rate [Hz] (0: every recorded sample).
    stamps
        Sample times [s] -> message stamps [ns] (the recording's start time added).
    lead
        Spare bytes before each message (:attr:`.bagwrite.StreamBagWriter.lead`).
    """

    def __init__(self, *, rate_hz: float, stamps: Callable[[np.ndarray], np.ndarray],
                 lead: int) -> None:
        self._dec = {topic: PlotDecimator(rate_hz=rate_hz, keys=())
                     for topic in (TOPIC_PLOT_POWER, TOPIC_PLOT_AXES)}
        self._stamps = stamps
        self._lead = lead
        self._names: dict[str, tuple[str, ...]] = {}
        self._held: dict[str, list[np.ndarray]] = {}    # the open interval's value blocks

    def rows(self, t: np.ndarray, columns: dict) -> dict[str, MessageRows]:
        """The messages of the display intervals these samples complete (times ``t`` [s],
        the chunk's recorded columns)."""
        out = {}
        k = None
        for topic, dec in self._dec.items():
            names, blocks, keys = _blocks(topic, columns)
            self._names.setdefault(topic, names)
            held = self._held.get(topic) or [b[:0] for b in blocks]
            if k is None and dec.rate_hz:
                k = dec.intervals(t)                # the same for both topics
            t_out, idx = dec.select(t, keys, k)
            kept = [held_then(h, b, idx) for h, b in zip(held, blocks)]
            self._held[topic] = [held_tail(h, b, dec.held) for h, b in zip(held, blocks)]
            out[topic] = self._message_rows(topic, t_out, kept)
        return out

    def finish(self) -> dict[str, MessageRows]:
        """The messages of the last (open) interval of each topic."""
        out = {}
        for topic, dec in self._dec.items():
            t_out, idx = dec.finish_select()
            if t_out.shape[0]:
                out[topic] = self._message_rows(topic, t_out,
                                                [h[idx] for h in self._held[topic]])
            self._held.pop(topic, None)
        return out

    def _message_rows(self, topic: str, t: np.ndarray, blocks: list[np.ndarray]) -> MessageRows:
        names = self._names[topic]
        if topic == TOPIC_PLOT_POWER:
            half = len(blocks) // 2
            fields = [np.hstack(blocks[:half]), np.hstack(blocks[half:]), None]
        else:
            fields = blocks
        return joint_state_rows(self._stamps(t), names, fields, lead=self._lead)
