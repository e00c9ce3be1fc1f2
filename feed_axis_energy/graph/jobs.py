"""Jobs on the graph's streams (no rclpy): which job a message belongs to, and what it needs.

Every per-job stream message carries its job id in ``header.frame_id`` (``''``: the graph
was started on one program, the behaviour before jobs). :func:`header_frame_id` reads it
from the serialized message without decoding the rest. A node downstream of
``gcode_trajectory`` needs the job's spec (machine, load) before it can compute; the spec
comes on the latched ``job/state`` topic, which DDS may deliver after the job's first
batches (no order between topics): :class:`JobRouter` holds those batches, bounded, until the
spec arrives, and remembers the specs of the last few jobs. :func:`live_payload` is one
message of the live stream ``job/live`` (power, energy so far and the electrical side, with a
wall-clock stamp in real-time mode).
"""
from __future__ import annotations

from collections import OrderedDict, deque
import json
import struct
from typing import Any, Generic, TypeVar

import numpy as np

from ..cell import JobSpec
from ..errors import DataError, FeedAxisError
from .flow import StreamingPower

__all__ = ['header_frame_id', 'JobRouter', 'live_payload', 'LIVE_CLOCKS', 'parse_state_text']

LIVE_CLOCKS = ('simulation', 'wall')

_U32 = struct.Struct('<I')
_MAX_FRAME_ID = 256
Item = TypeVar('Item')


def header_frame_id(cdr: bytes | memoryview) -> str:
    """``header.frame_id`` of a serialized message whose first field is a ``std_msgs/Header``
    (little-endian CDR: encapsulation, ``sec``, ``nanosec``, then the string).

    Raises
    ------
    DataError
        Truncated, big-endian, or a string longer than 256 bytes or not UTF-8.
    """
    if len(cdr) < 16 or cdr[1] != 1:
        msg = f'serialized message of {len(cdr)} bytes has no little-endian header'
        raise DataError(msg, file='<cdr>')
    (length,) = _U32.unpack_from(cdr, 12)
    if length == 0 or length > _MAX_FRAME_ID or 16 + length > len(cdr):
        msg = f'header.frame_id of {length} bytes does not fit the message'
        raise DataError(msg, file='<cdr>')
    try:
        return bytes(cdr[16:16 + length - 1]).decode('utf-8')
    except UnicodeDecodeError:
        msg = 'header.frame_id is not UTF-8'
        raise DataError(msg, file='<cdr>') from None


def parse_state_text(text: str) -> tuple[str, str, JobSpec | None]:
    """``(state, job_id, spec)`` from the JSON of a ``job/state`` message.

    Raises
    ------
    DataError
        Not the JSON object ``gcode_trajectory`` publishes.
    """
    try:
        d = json.loads(text)
        state, job_id = d['state'], d['job_id']
        spec = None if d.get('spec') is None else JobSpec.from_dict(d['spec'])
    except (ValueError, KeyError, TypeError, FeedAxisError) as err:
        msg = f'not a job state message: {type(err).__name__}: {str(err)[:80]}'
        raise DataError(msg, file='job/state') from None
    if not isinstance(state, str) or not isinstance(job_id, str):
        msg = 'state and job_id must be text'
        raise DataError(msg, file='job/state')
    return state, job_id, spec


class JobRouter(Generic[Item]):
    """The specs of the last ``keep`` jobs, and messages held until their job's spec is known.

    Parameters
    ----------
    keep
        Specs remembered (the current job and a few before it).
    max_held
        Messages held in all; beyond it the oldest is dropped and counted in
        :attr:`dropped` (``gcode_trajectory`` keeps at most ``flow_window`` batches in
        flight, so a healthy graph never gets close).
    """

    def __init__(self, *, keep: int = 8, max_held: int = 256) -> None:
        self._specs: OrderedDict[str, JobSpec] = OrderedDict()
        self._held: deque[tuple[str, Any]] = deque()
        self.keep = keep
        self.max_held = max_held
        self.dropped = 0

    def spec(self, job_id: str) -> JobSpec | None:
        """The spec of ``job_id`` if known."""
        return self._specs.get(job_id)

    def note(self, spec: JobSpec) -> list[tuple[JobSpec, Item]]:
        """Learn ``spec``; returns the messages held for its job, oldest first."""
        self._specs[spec.job_id] = spec
        self._specs.move_to_end(spec.job_id)
        while len(self._specs) > self.keep:
            self._specs.popitem(last=False)
        ready = [item for job_id, item in self._held if job_id == spec.job_id]
        if ready:
            self._held = deque((j, i) for j, i in self._held if j != spec.job_id)
        return [(spec, item) for item in ready]

    def hold(self, job_id: str, item: Item) -> None:
        """Keep ``item`` until the spec of ``job_id`` arrives (bounded)."""
        self._held.append((job_id, item))
        while len(self._held) > self.max_held:
            self._held.popleft()
            self.dropped += 1

    @property
    def held(self) -> int:
        """Messages waiting for their job's spec."""
        return len(self._held)


def _named(names: list[str], values: np.ndarray) -> dict[str, float]:
    return {n: float(v) for n, v in zip(names, values)}


def live_payload(power: StreamingPower, *, job_id: str, stamp_ns: int, clock: str,
                 line: int | None = None) -> dict[str, Any]:
    """One ``job/live`` message after a batch (docs/nodes.md, "Jobs": the keys).

    Parameters
    ----------
    power
        The job's integrator, after :meth:`StreamingPower.update` of the batch.
    job_id
        The job ('' for a graph on one program).
    stamp_ns
        Time of the batch's last sample: simulation time, or wall-clock time in real-time
        mode (``clock``).
    clock
        ``'simulation'`` or ``'wall'``.
    line
        Source line of the batch's last sample, when the line table is known.

    Returns
    -------
    dict
        ``power_w`` (the last sample's power after the braking rule per axis and ``total``
        [W]), ``energy_j`` (so far [J]), ``energy_import_j`` and ``energy_export_j`` (drawn
        and returned so far, ``energy_j`` = import - export [J]); with declared drives
        ``electrical``: the last sample's ``motor_w`` and ``supply_w`` (per axis, ``total``;
        the supply with ``cabinet``) [W] and ``motor_energy_j``, ``supply_energy_j``,
        ``returned_j`` so far [J].
    """
    if clock not in LIVE_CLOCKS:
        msg = f'clock must be one of {LIVE_CLOCKS}, got {clock!r}'
        raise ValueError(msg)
    names = list(power.axes) + ['total']
    last = power.last_power_w
    out: dict[str, Any] = {
        'job_id': job_id, 'stamp_ns': int(stamp_ns), 'clock': clock,
        'time_s': float(power.last_time_s or 0.0), 'samples': power.n_samples,
        'line': line, 'power_w': _named(names, last), 'energy_j': _named(names, power.energy_j),
        'energy_import_j': _named(names, power.energy_import_j),
        'energy_export_j': _named(names, power.energy_export_j),
        'electrical': None}
    elec = power.last_electrical
    summary = power.electrical_summary()
    if elec is not None and summary:
        motor = elec.motor_w[-1]
        supply = elec.supply_w[-1]
        out['electrical'] = {
            'motor_w': {**_named(list(power.axes), motor), 'total': float(motor.sum())},
            'supply_w': {**_named(list(power.axes), supply), 'cabinet': elec.cabinet_w,
                         'total': float(supply.sum() + elec.cabinet_w)},
            'motor_energy_j': summary['motor_energy_j'],
            'supply_energy_j': summary['supply_energy_j'],
            'returned_j': summary['returned_j']}
    return out
