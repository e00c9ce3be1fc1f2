"""The graph's job topics as a :class:`~.service.JobService`, without ROS.

The ``opcua_bridge`` node (:mod:`feed_axis_energy.nodes.opcua_bridge`) is a thin shell: it
hands every message of ``job/reply``, ``job/state``, ``job/result`` and ``job/live`` (the
text of a ``std_msgs/String``, docs/nodes.md "Jobs") to :class:`GraphJobService` and sends
what the service gives to its ``send`` callable on ``job/command``. Everything else is here:

* ``start_job``/``abort_job`` send a command with a fresh ``request_id`` and wait for the
  ``job/reply`` that echoes it (at most ``reply_timeout_s``; the OPC UA server calls them in
  a worker thread, so the caller's loop is not held);
* ``state``, ``active_job``, ``active_line``, ``progress`` follow ``job/state`` (newest
  ``sequence`` wins: the latched history a late reader gets is not replayed as news) and
  ``job/live`` (``line``; ``samples`` of ``planned_samples``);
* results come from ``job/result`` (the last ``keep`` kept; an older one is asked of the
  graph with the ``result`` command) and are shown in the bridges' form (:func:`service_result`);
* ``subscribe`` listeners get a :class:`~.service.LiveSample` per ``job/live`` message and a
  :class:`~.service.StateChange` per new state. DDS does not order topics: a final state
  whose result has not arrived yet is held until it has (at most ``result_wait_s``, see
  :meth:`GraphJobService.tick`), so a bridge that reads the result on the final state (MQTT
  publishes ``job/result`` before ``job/state``) finds it.

Malformed messages from the topics are counted (:attr:`GraphJobService.bad_messages`) and
dropped; nothing a topic carries raises out of the ``on_*`` methods.
"""
from __future__ import annotations

from collections import OrderedDict
import itertools
import json
import math
import threading
import time
from typing import Any, Callable, Mapping, Sequence

from ..cell import dumps
from .measured import MeasuredSample
from .service import (AxisPower, FINAL_STATES, JOB_STATES, Listener, LiveSample,
                      ServiceEvent, StateChange)

__all__ = ['GraphJobService', 'measured_live_payload', 'MEASURED_LIVE_KEYS', 'service_result']

MEASURED_LIVE_KEYS = ('axis', 'stamp', 'quantity', 'value')
"""Keys of a ``measured/live`` message (docs/nodes.md)."""


def measured_live_payload(sample: MeasuredSample) -> str:
    """The ``measured/live`` JSON text of one accepted measured sample.

    ``{"axis": "X", "stamp": <s since the UNIX epoch>, "quantity": "power_w", "value": ...}``;
    ``stamp`` is the sample's own time (never the time it arrived).
    """
    return dumps({'axis': sample.axis, 'stamp': sample.stamp_ns / 1e9,
                  'quantity': sample.quantity, 'value': float(sample.value)})


def _total(value: Any) -> float:
    """``{'X': .., 'total': t}`` -> t (0.0 for ``{}``: nothing ran)."""
    if isinstance(value, Mapping):
        value = value.get('total', 0.0)
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value):
        raise ValueError(f'expected a finite number, got {value!r}')
    return float(value)


def service_result(graph: Mapping[str, Any]) -> dict[str, Any]:
    """A ``job/result`` object in the bridges' form (docs/cell.md, "The job service").

    ``energy_j`` and ``peak_power_w`` become the totals [J, W] (the figures of
    ``simulate``'s ``energy_j.total`` and ``peak_power_w.total``; 0 for a job in which
    nothing ran), their per-axis values move to ``energy_by_axis_j`` and
    ``peak_power_by_axis_w``; every other key is kept as the graph wrote it.

    Raises
    ------
    ValueError
        Not a result: no text ``job_id``, a status that is not final, a total not finite.
    """
    job_id, status = graph.get('job_id'), graph.get('status')
    if not isinstance(job_id, str) or status not in FINAL_STATES:
        raise ValueError(f'not a job result: job_id {job_id!r}, status {status!r}')
    out = dict(graph)
    energy, peak = graph.get('energy_j', {}), graph.get('peak_power_w', {})
    out['energy_j'], out['peak_power_w'] = _total(energy), _total(peak)
    out['energy_by_axis_j'] = {k: v for k, v in energy.items() if k != 'total'} \
        if isinstance(energy, Mapping) else {}
    out['peak_power_by_axis_w'] = {k: v for k, v in peak.items() if k != 'total'} \
        if isinstance(peak, Mapping) else {}
    out['duration_s'] = _total(graph.get('duration_s', 0.0))
    return out


def _load(text: str | bytes) -> dict[str, Any]:
    data = json.loads(text)
    if not isinstance(data, dict):
        raise ValueError('not a JSON object')
    return data


class GraphJobService:
    """A job service on the graph's job topics (see the module docstring).

    Parameters
    ----------
    axes
        The machine's feed axes (fixed for the service's life).
    send
        Sends one ``job/command`` text (the node's publisher); may be called from any thread.
    reply_timeout_s
        Longest wait for the reply to a command [s].
    keep
        Results kept for :meth:`result`.
    result_wait_s
        Longest hold of a final state whose result has not arrived [s].
    """

    def __init__(self, axes: Sequence[str], send: Callable[[str], None], *,
                 reply_timeout_s: float = 10.0, keep: int = 100,
                 result_wait_s: float = 2.0) -> None:
        self._axes = tuple(axes)
        self._send = send
        self.reply_timeout_s = reply_timeout_s
        self.result_wait_s = result_wait_s
        self._keep = keep
        self._lock = threading.Lock()
        self._replied = threading.Condition(self._lock)
        self._replies: dict[str, dict[str, Any]] = {}
        self._waiting: set[str] = set()
        self._ids = itertools.count(1)
        self._prefix = f'bridge-{time.time_ns() % 10**9}-'
        self._listeners: list[Listener] = []
        self._state = 'idle'
        self._job = ''
        self._sequence = -1
        self._planned = 0
        self._line = 0
        self._samples = 0
        self._results: OrderedDict[str, dict[str, Any]] = OrderedDict()
        self._last: dict[str, Any] | None = None
        self._held: tuple[StateChange, float] | None = None
        self.bad_messages = 0
        """Messages from the job topics that were not what docs/nodes.md says (dropped)."""
        self.listener_errors = 0
        """Events a listener raised on (the bridges catch and log their own faults)."""

    # -- the JobService protocol --------------------------------------------------------

    def axes(self) -> Sequence[str]:
        """The machine's feed axes."""
        return self._axes

    def start_job(self, job_id: str, program: str, load_kg: float) -> tuple[bool, str]:
        """Send ``start`` and answer the graph's reply."""
        return self._command({'command': 'start', 'job_id': job_id, 'program': program,
                              'load_kg': float(load_kg)})

    def abort_job(self, job_id: str) -> tuple[bool, str]:
        """Send ``abort`` and answer the graph's reply."""
        return self._command({'command': 'abort', 'job_id': job_id})

    def state(self) -> str:
        """The newest job state."""
        return self._state

    def active_job(self) -> str:
        """The job of the newest state ('' before any)."""
        return self._job

    def active_line(self) -> int:
        """The line of the newest ``job/live`` message of the running job (0: none)."""
        return self._line if self._state == 'running' else 0

    def progress(self) -> float:
        """Samples integrated / samples planned of the running job (1 once it ended)."""
        if self._state == 'ended':
            return 1.0
        if self._state != 'running' or self._planned <= 0:
            return 0.0
        return min(1.0, self._samples / self._planned)

    def last_result(self) -> Mapping[str, Any] | None:
        """The result of the last job that ended, in the bridges' form."""
        return self._last

    def result(self, job_id: str) -> Mapping[str, Any] | None:
        """A kept result; else the graph's answer to the ``result`` command (or None)."""
        with self._lock:
            found = self._results.get(job_id)
        if found is not None:
            return found
        reply = self._request({'command': 'result', 'job_id': job_id})
        graph = reply.get('result') if reply is not None and reply.get('accepted') else None
        if not isinstance(graph, Mapping):
            return None
        try:
            return service_result(graph)
        except ValueError:
            self.bad_messages += 1
            return None

    def subscribe(self, listener: Listener) -> Callable[[], None]:
        """Hand every later event to ``listener``; returns the call that unsubscribes."""
        with self._lock:
            self._listeners.append(listener)

        def unsubscribe() -> None:
            with self._lock:
                if listener in self._listeners:
                    self._listeners.remove(listener)
        return unsubscribe

    # -- commands -------------------------------------------------------------------------

    def _request(self, body: dict[str, Any]) -> dict[str, Any] | None:
        request_id = f'{self._prefix}{next(self._ids)}'
        with self._lock:
            self._waiting.add(request_id)
        try:
            self._send(dumps({**body, 'request_id': request_id}))
            end = time.monotonic() + self.reply_timeout_s
            with self._replied:
                while request_id not in self._replies:
                    left = end - time.monotonic()
                    if left <= 0:
                        return None
                    self._replied.wait(left)
                return self._replies.pop(request_id)
        finally:
            with self._lock:
                self._waiting.discard(request_id)
                self._replies.pop(request_id, None)

    def _command(self, body: dict[str, Any]) -> tuple[bool, str]:
        reply = self._request(body)
        if reply is None:
            return False, (f'the graph did not answer the {body["command"]} command within '
                           f'{self.reply_timeout_s:g} s (is it running?)')
        accepted = reply.get('accepted') is True
        message = reply.get('message')
        return accepted, message if isinstance(message, str) else ''

    # -- messages from the topics (the node's executor thread) -------------------------------

    def on_reply(self, text: str | bytes) -> None:
        """A ``job/reply`` message: wakes the command waiting for it."""
        try:
            data = _load(text)
        except ValueError:
            self.bad_messages += 1
            return
        request_id = data.get('request_id')
        with self._replied:
            if isinstance(request_id, str) and request_id in self._waiting:
                self._replies[request_id] = data
                self._replied.notify_all()

    def on_state(self, text: str | bytes) -> None:
        """A ``job/state`` message: a newer ``sequence`` becomes the state."""
        try:
            data = _load(text)
            state, job_id, sequence = data['state'], data['job_id'], data['sequence']
            if state not in JOB_STATES or not isinstance(job_id, str) \
                    or isinstance(sequence, bool) or not isinstance(sequence, int):
                raise ValueError(f'bad state {state!r}')
            planned = data.get('planned_samples', 0)
            planned = planned if isinstance(planned, int) and planned > 0 else 0
        except (ValueError, KeyError):
            self.bad_messages += 1
            return
        with self._lock:
            if sequence <= self._sequence:
                return
            self._sequence = sequence
            if job_id != self._job or state == 'planning':
                self._line = self._samples = 0
            self._state, self._job, self._planned = state, job_id, planned
            event = StateChange(job_id=job_id, state=state, stamp_ns=time.time_ns())
            if state in FINAL_STATES and job_id not in self._results:
                self._held = (event, time.monotonic())
                return
        self._emit(event)

    def on_result(self, text: str | bytes) -> None:
        """A ``job/result`` message: kept (the last ``keep``); releases a held final state."""
        try:
            result = service_result(_load(text))
        except ValueError:
            self.bad_messages += 1
            return
        job_id = result['job_id']
        release = None
        with self._lock:
            self._results[job_id] = result
            self._results.move_to_end(job_id)
            while len(self._results) > self._keep:
                self._results.popitem(last=False)
            self._last = result
            if self._held is not None and self._held[0].job_id == job_id:
                release, self._held = self._held[0], None
        if release is not None:
            self._emit(release)

    def on_live(self, text: str | bytes) -> None:
        """A ``job/live`` message: line, progress and a :class:`LiveSample` to listeners."""
        try:
            sample, line, samples = self._live_sample(_load(text))
        except (ValueError, KeyError, TypeError):
            self.bad_messages += 1
            return
        with self._lock:
            if sample.job_id == self._job:
                self._line, self._samples = line, samples
        self._emit(sample)

    def tick(self) -> None:
        """Release a final state held longer than ``result_wait_s`` (call it periodically)."""
        with self._lock:
            held = self._held
            if held is None or time.monotonic() - held[1] < self.result_wait_s:
                return
            self._held = None
        self._emit(held[0])

    @staticmethod
    def _live_sample(data: dict[str, Any]) -> tuple[LiveSample, int, int]:
        job_id = data['job_id']
        power, energy = data['power_w'], data['energy_j']
        if not isinstance(job_id, str) or not isinstance(power, dict) \
                or not isinstance(energy, dict):
            raise ValueError('bad job/live message')
        # job/live carries the net mechanical energy after the braking rule: it is what the
        # axes drew; the energy returned while braking is not in it (export 0 here)
        axes = {name: AxisPower(float(power[name]), max(0.0, float(energy.get(name, 0.0))),
                                0.0) for name in power if name != 'total'}
        total = AxisPower(float(power['total']), max(0.0, float(energy['total'])), 0.0)
        if data.get('clock') == 'wall' and isinstance(data.get('stamp_ns'), int):
            stamp_ns = int(data['stamp_ns'])
        else:   # simulation time from 0 (fast mode): the bridges show wall-clock time
            stamp_ns = time.time_ns()
        line = data.get('line')
        samples = data.get('samples')
        return (LiveSample(job_id=job_id, stamp_ns=stamp_ns, axes=axes, total=total),
                line if isinstance(line, int) and line > 0 else 0,
                samples if isinstance(samples, int) and samples > 0 else 0)

    def _emit(self, event: ServiceEvent) -> None:
        with self._lock:
            listeners = list(self._listeners)
        for listener in listeners:
            try:
                listener(event)
            except Exception:   # noqa: B902 - one listener's fault must not stop the others
                self.listener_errors += 1
