"""The Sparkplug B edge node: a job service's state, live power and results as metrics.

A paho-mqtt client of its own (the death certificate must be this session's last will, so
it cannot share the plain bridge's connection, whose will is ``status``). Topics and
session rules after Eclipse Sparkplug 3.0 (docs/cell.md, "Sparkplug B"):

* the edge node ``spBv1.0/<group>/{NBIRTH,NDEATH,NCMD}/<edge_node>`` carries ``bdSeq`` and
  ``Node Control/Rebirth``; the machine is its device ``spBv1.0/<group>/{DBIRTH,DDATA}/
  <edge_node>/<device>`` with the job, live and result metrics (:func:`device_metrics`);
* every CONNECT carries the will NDEATH with ``bdSeq`` (0 on the first connection, one more
  on each following one, after 255 back to 0); once connected the node subscribes to its
  NCMD (QoS 1), then publishes NBIRTH (``seq`` 0, the same ``bdSeq``) and DBIRTH (``seq``
  1, every metric with its name, alias, datatype, current value and ``engUnit``);
* DDATA messages carry aliases only and ``seq`` one more than the message before, 255
  wrapping to 0; a live sample is one DDATA (every live metric, stamped with the sample's
  wall-clock time), a state change one DDATA (with the result metrics first when it ends a
  job);
* an NCMD with ``Node Control/Rebirth`` = true makes the node publish NBIRTH and DBIRTH again
  (``seq`` from 0, the same ``bdSeq``) before any further data; a clean stop publishes
  NDEATH before DISCONNECT; malformed commands, and rebirth requests sooner than
  ``min_rebirth_interval_s`` after the last one, are dropped and counted
  (:attr:`SparkplugBridge.drops`).

Not built: waiting for a primary host application's STATE before the births, DCMD, NDATA
(the node itself has no data), store and forward while the broker is away.
"""
from __future__ import annotations

from dataclasses import dataclass
import logging
import math
import threading
import time
from typing import Any, Callable, Mapping, Sequence

import paho.mqtt.client as paho

from ..errors import ConfigError, describe, FeedAxisError, RequestError
from .logbound import BoundedLog
from .mqtt import new_client
from .service import FINAL_STATES, JobService, LiveSample, ServiceEvent, StateChange
from .sparkplug_payload import (decode_sparkplug, encode_sparkplug, SpDataType, SpMetric,
                                SpPayload)

__all__ = ['device_metrics', 'REBIRTH_METRIC', 'SPARKPLUG_NAMESPACE', 'SparkplugBridge',
           'SparkplugSettings', 'SparkplugTopics']

_log = logging.getLogger(__name__)

SPARKPLUG_NAMESPACE = 'spBv1.0'
REBIRTH_METRIC = 'Node Control/Rebirth'
BDSEQ = 'bdSeq'
_LIVE_QUANTITIES = (('power_w', 'W'), ('energy_j', 'J'), ('energy_import_j', 'J'),
                    ('energy_export_j', 'J'))


def _check_id(value: str, key: str) -> str:
    if (not isinstance(value, str) or not value or len(value) > 64 or not value.isprintable()
            or any(c in '/+#' for c in value)):
        msg = (f'expected a Sparkplug id of 1 to 64 printable characters without "/", "+" '
               f'or "#", got {describe(value)}')
        raise ConfigError(msg, file='<sparkplug>', key=key)
    return value


@dataclass(frozen=True)
class SparkplugTopics:
    """The Sparkplug topics of one edge node and its one device (the machine)."""

    group_id: str
    edge_node_id: str
    device_id: str = 'machine'

    def __post_init__(self) -> None:
        _check_id(self.group_id, 'group_id')
        _check_id(self.edge_node_id, 'edge_node_id')
        _check_id(self.device_id, 'device_id')

    def node(self, verb: str) -> str:
        """``spBv1.0/<group>/<verb>/<edge_node>`` (NBIRTH, NDEATH, NCMD)."""
        return f'{SPARKPLUG_NAMESPACE}/{self.group_id}/{verb}/{self.edge_node_id}'

    def device(self, verb: str) -> str:
        """``spBv1.0/<group>/<verb>/<edge_node>/<device>`` (DBIRTH, DDATA)."""
        return f'{SPARKPLUG_NAMESPACE}/{self.group_id}/{verb}/{self.edge_node_id}/{self.device_id}'

    @classmethod
    def parse(cls, text: str, *, device_id: str = 'machine') -> SparkplugTopics:
        """``GROUP_ID/EDGE_NODE_ID`` (as ``serve --mqtt-sparkplug`` takes it)."""
        group, slash, edge = str(text).partition('/')
        if not slash:
            msg = f'expected GROUP_ID/EDGE_NODE_ID, got {describe(text)}'
            raise ConfigError(msg, file='<sparkplug>', key='sparkplug')
        return cls(group_id=group, edge_node_id=edge, device_id=device_id)


@dataclass(frozen=True)
class SparkplugSettings:
    """Broker, identities and limits of the Sparkplug edge node.

    Attributes
    ----------
    host, port
        The broker.
    topics
        Group, edge node and device ids.
    client_id
        MQTT client id; '' makes one from the ids.
    username, password
        Broker credentials, if it asks for them.
    keepalive_s
        MQTT keep-alive [s]: the broker sends the NDEATH after 1.5 times this without a
        packet from a node that vanished without closing its connection.
    max_queued
        Outgoing messages held while the broker is away.
    min_rebirth_interval_s
        A rebirth request sooner than this after the last one honoured is dropped
        (``rate_limited``): a flood of NCMDs cannot turn into a flood of births.
    """

    host: str
    port: int
    topics: SparkplugTopics
    client_id: str = ''
    username: str | None = None
    password: str | None = None
    keepalive_s: int = 30
    max_queued: int = 1000
    min_rebirth_interval_s: float = 0.5

    def __post_init__(self) -> None:
        if isinstance(self.port, bool) or not isinstance(self.port, int) \
                or not 1 <= self.port <= 65535:
            raise ConfigError(f'expected a TCP port 1...65535, got {describe(self.port)}',
                              file='<sparkplug>', key='port')
        interval = self.min_rebirth_interval_s
        if isinstance(interval, bool) or not isinstance(interval, (int, float)) \
                or not math.isfinite(interval) or interval < 0:
            raise ConfigError(f'expected a finite number >= 0, got {describe(interval)}',
                              file='<sparkplug>', key='min_rebirth_interval_s')
        for key in ('keepalive_s', 'max_queued'):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError(f'expected a positive integer, got {describe(value)}',
                                  file='<sparkplug>', key=key)


@dataclass(frozen=True)
class _Spec:
    name: str
    datatype: int
    unit: str = ''


def device_metrics(axes: Sequence[str]) -> tuple[tuple[str, int, str], ...]:
    """The device's metrics in birth order: ``(name, datatype, unit)``; alias = index + 1.

    ``Job/JobId``, ``Job/State``; ``Live/JobId`` and ``Live/<part>/<quantity>`` for every
    axis and ``total`` (quantities ``power_w`` [W], ``energy_j``, ``energy_import_j``,
    ``energy_export_j`` [J], as the JSON ``power`` topic); ``Result/JobId``, ``Result/Status``,
    ``Result/Message``, ``Result/Program``, ``Result/energy_j`` [J], ``Result/duration_s``
    [s], ``Result/peak_power_w`` [W] and ``Result/<axis>/energy_j``, ``.../peak_power_w``.
    """
    out: list[tuple[str, int, str]] = [('Job/JobId', SpDataType.STRING, ''),
                                       ('Job/State', SpDataType.STRING, ''),
                                       ('Live/JobId', SpDataType.STRING, '')]
    for part in (*axes, 'total'):
        out += [(f'Live/{part}/{q}', SpDataType.DOUBLE, unit) for q, unit in _LIVE_QUANTITIES]
    out += [('Result/JobId', SpDataType.STRING, ''), ('Result/Status', SpDataType.STRING, ''),
            ('Result/Message', SpDataType.STRING, ''), ('Result/Program', SpDataType.STRING, ''),
            ('Result/energy_j', SpDataType.DOUBLE, 'J'),
            ('Result/duration_s', SpDataType.DOUBLE, 's'),
            ('Result/peak_power_w', SpDataType.DOUBLE, 'W')]
    for axis in axes:
        out += [(f'Result/{axis}/energy_j', SpDataType.DOUBLE, 'J'),
                (f'Result/{axis}/peak_power_w', SpDataType.DOUBLE, 'W')]
    return tuple(out)


def _live_values(sample: LiveSample) -> dict[str, Any]:
    values: dict[str, Any] = {'Live/JobId': sample.job_id}
    for part, p in (*sample.axes.items(), ('total', sample.total)):
        values[f'Live/{part}/power_w'] = float(p.power_w)
        values[f'Live/{part}/energy_j'] = float(p.energy_import_j - p.energy_export_j)
        values[f'Live/{part}/energy_import_j'] = float(p.energy_import_j)
        values[f'Live/{part}/energy_export_j'] = float(p.energy_export_j)
    return values


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None


def _result_values(result: Mapping[str, Any], axes: Sequence[str]) -> dict[str, Any]:
    def text(key: str) -> str | None:
        value = result.get(key)
        return value if isinstance(value, str) else None

    values: dict[str, Any] = {
        'Result/JobId': text('job_id'), 'Result/Status': text('status'),
        'Result/Message': text('message'), 'Result/Program': text('program'),
        'Result/energy_j': _number(result.get('energy_j')),
        'Result/duration_s': _number(result.get('duration_s')),
        'Result/peak_power_w': _number(result.get('peak_power_w'))}
    for key, quantity in (('energy_by_axis_j', 'energy_j'),
                          ('peak_power_by_axis_w', 'peak_power_w')):
        by_axis = result.get(key)
        by_axis = by_axis if isinstance(by_axis, Mapping) else {}
        for axis in axes:
            values[f'Result/{axis}/{quantity}'] = _number(by_axis.get(axis))
    return values


def _now_ms() -> int:
    return time.time_ns() // 1_000_000


class SparkplugBridge:
    """Publishes a job service as a Sparkplug B edge node with the machine as its device.

    Parameters
    ----------
    service
        The job service to publish.
    settings
        Broker, ids, limits.

    Use as a context manager or call :meth:`start` and :meth:`stop`. Attributes for tests
    and benches: :attr:`bd_seq` (of the current session), :attr:`published`,
    :attr:`publish_failures`, :attr:`births` (NBIRTHs sent), :attr:`drops` (NCMD messages
    not acted on, by reason).
    """

    def __init__(self, service: JobService, settings: SparkplugSettings):
        self.service = service
        self.settings = settings
        self.topics = settings.topics
        self.axes = tuple(service.axes())
        self._specs = tuple(_Spec(n, d, u) for n, d, u in device_metrics(self.axes))
        self._alias = {spec.name: k + 1 for k, spec in enumerate(self._specs)}
        self._values: dict[str, Any] = {spec.name: None for spec in self._specs}
        self._stamps: dict[str, int] = {}
        self._lock = threading.RLock()
        self._seq = 0
        self._born = False
        self._connects = 0
        self.bd_seq = 0
        self.published = 0
        self.publish_failures = 0
        self.births = 0
        self.drops: dict[str, int] = {}
        self._last_rebirth = -math.inf
        self._log = BoundedLog(_log)
        self._connected = threading.Event()
        self._connect_error = ''
        self._unsubscribe: Callable[[], None] | None = None
        ids = f'{self.topics.group_id}-{self.topics.edge_node_id}'
        client = new_client(settings.client_id or f'spb-{ids}'[:64],
                            max_queued=settings.max_queued, username=settings.username,
                            password=settings.password)
        client.on_pre_connect = self._on_pre_connect
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        self._client = client

    def __enter__(self) -> SparkplugBridge:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def connected(self) -> bool:
        """Whether the births of the current session have been sent."""
        return self._connected.is_set()

    def start(self, *, timeout_s: float = 10.0) -> None:
        """Seed the values from the service, connect, publish the births, follow the service.

        Raises
        ------
        FeedAxisError
            The broker cannot be reached or refuses the connection within ``timeout_s``.
        """
        with self._lock:
            self._values['Job/JobId'] = str(self.service.active_job())
            self._values['Job/State'] = str(self.service.state())
            last = self.service.last_result()
            if last is not None:
                self._values.update(_result_values(last, self.axes))
        # follow before connecting: an event in between updates the values the births carry
        self._unsubscribe = self.service.subscribe(self._on_event)
        where = f'{self.settings.host}:{self.settings.port}'
        try:
            self._client.connect(self.settings.host, self.settings.port,
                                 keepalive=self.settings.keepalive_s)
        except (OSError, ValueError) as exc:
            self._stop_following()
            raise FeedAxisError(f'cannot connect to the MQTT broker at {where}: '
                                f'{exc}') from exc
        self._client.loop_start()
        if not self._connected.wait(timeout_s):
            self._client.loop_stop()
            self._stop_following()
            reason = self._connect_error or f'no answer within {timeout_s:g} s'
            raise FeedAxisError(f'the MQTT broker at {where} did not accept the Sparkplug '
                                f'edge node: {reason}')

    def _stop_following(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None

    def stop(self) -> None:
        """Publish NDEATH (the spec's intentional disconnect), disconnect, stop the thread."""
        self._stop_following()
        with self._lock:
            was_born, self._born = self._born, False
        if was_born and self._connected.is_set():
            info = self._client.publish(self.topics.node('NDEATH'), self._death(), qos=1)
            try:
                info.wait_for_publish(timeout=2.0)
            except (RuntimeError, ValueError):
                pass
        self._client.disconnect()
        self._client.loop_stop()
        self._connected.clear()

    # -- payloads -------------------------------------------------------------------------

    def _death(self) -> bytes:
        bd = SpMetric(name=BDSEQ, alias=None, datatype=SpDataType.INT64, value=self.bd_seq)
        return encode_sparkplug(SpPayload(timestamp_ms=_now_ms(), metrics=(bd,)))

    def _next_seq(self) -> int:
        seq = self._seq
        self._seq = (self._seq + 1) % 256
        return seq

    def _publish(self, topic: str, metrics: tuple[SpMetric, ...]) -> None:
        """One message with the next ``seq`` (QoS 0, not retained; caller holds the lock)."""
        payload = encode_sparkplug(SpPayload(timestamp_ms=_now_ms(), metrics=metrics,
                                             seq=self._next_seq()))
        try:
            info = self._client.publish(topic, payload, qos=0, retain=False)
        except (ValueError, RuntimeError) as exc:
            self.publish_failures += 1
            self._log.log(logging.WARNING, 'publish', f'cannot publish on {topic}: {exc}')
            return
        if info.rc == paho.MQTT_ERR_SUCCESS:
            self.published += 1
        else:
            self.publish_failures += 1

    def _births(self) -> None:
        """NBIRTH (seq 0) and DBIRTH with every metric's current value (holds the lock)."""
        with self._lock:
            self._seq = 0
            now = _now_ms()
            node = (SpMetric(name=BDSEQ, alias=None, datatype=SpDataType.INT64,
                             value=self.bd_seq, timestamp_ms=now),
                    SpMetric(name=REBIRTH_METRIC, alias=None, datatype=SpDataType.BOOLEAN,
                             value=False, timestamp_ms=now))
            self._publish(self.topics.node('NBIRTH'), node)
            device = tuple(
                SpMetric(name=spec.name, alias=self._alias[spec.name], datatype=spec.datatype,
                         value=self._values[spec.name],
                         timestamp_ms=self._stamps.get(spec.name, now),
                         properties={'engUnit': (SpDataType.STRING, spec.unit)} if spec.unit
                         else {})
                for spec in self._specs)
            self._publish(self.topics.device('DBIRTH'), device)
            self.births += 1
            self._born = True

    def _data(self, values: Mapping[str, Any], stamp_ns: int) -> None:
        """Update the values; one DDATA with them (aliases only) when born."""
        stamp_ms = stamp_ns // 1_000_000
        with self._lock:
            for name, value in values.items():
                self._values[name] = value
                self._stamps[name] = stamp_ms
            if not self._born:
                return
            metrics = tuple(SpMetric(name=None, alias=self._alias[name],
                                     datatype=self._specs[self._alias[name] - 1].datatype,
                                     value=value, timestamp_ms=stamp_ms)
                            for name, value in values.items())
            self._publish(self.topics.device('DDATA'), metrics)

    # -- paho's callbacks (network thread) ------------------------------------------------

    def _on_pre_connect(self, client: paho.Client, userdata: Any) -> None:
        # bdSeq: 0 on the first CONNECT, one more on every later one (255 -> 0)
        with self._lock:
            if self._connects:
                self.bd_seq = (self.bd_seq + 1) % 256
            self._connects += 1
            client.will_set(self.topics.node('NDEATH'), self._death(), qos=1, retain=False)

    def _on_connect(self, client: paho.Client, userdata: Any, flags: Any, reason: Any,
                    properties: Any) -> None:
        if reason.is_failure:
            self._connect_error = str(reason)
            _log.error('the MQTT broker refused the Sparkplug edge node: %s', reason)
            return
        # the subscription goes out before the births, so a rebirth request that answers
        # them finds it in place (packets of one session keep their order)
        client.subscribe(self.topics.node('NCMD'), qos=1)
        self._births()
        self._connected.set()

    def _on_disconnect(self, client: paho.Client, userdata: Any, flags: Any, reason: Any,
                       properties: Any) -> None:
        with self._lock:
            self._born = False
        self._connected.clear()
        if reason.is_failure:
            _log.warning('the Sparkplug edge node lost the MQTT broker (%s); paho reconnects',
                         reason)

    def _drop(self, code: str, message: str) -> None:
        self.drops[code] = self.drops.get(code, 0) + 1
        self._log.log(logging.WARNING, code, message)

    def _on_message(self, client: paho.Client, userdata: Any, message: Any) -> None:
        try:
            payload = decode_sparkplug(message.payload, where=self.topics.node('NCMD'))
        except RequestError as exc:
            self._drop(exc.code or 'bad_protobuf', str(exc))
            return
        rebirth = [m for m in payload.metrics if m.name == REBIRTH_METRIC]
        if not rebirth:
            self._drop('unknown_metric', f'NCMD without {REBIRTH_METRIC}: ignored')
            return
        if rebirth[0].datatype != SpDataType.BOOLEAN or rebirth[0].value is not True:
            self._drop('wrong_type', f'NCMD {REBIRTH_METRIC} must be Boolean true, got '
                       f'{describe(rebirth[0].value)}')
            return
        now = time.monotonic()
        if now - self._last_rebirth < self.settings.min_rebirth_interval_s:
            self._drop('rate_limited', f'a rebirth request within '
                       f'{self.settings.min_rebirth_interval_s:g} s of the last one: ignored')
            return
        self._last_rebirth = now
        self._births()

    # -- the service's listener -----------------------------------------------------------

    def _on_event(self, event: ServiceEvent) -> None:
        """Any thread; never raises into the service."""
        try:
            if isinstance(event, LiveSample):
                self._data(_live_values(event), event.stamp_ns)
            elif isinstance(event, StateChange):
                values: dict[str, Any] = {}
                if event.state in FINAL_STATES:
                    result = self.service.result(event.job_id) or self.service.last_result()
                    if result is not None and result.get('job_id') == event.job_id:
                        values.update(_result_values(result, self.axes))
                values.update({'Job/JobId': event.job_id, 'Job/State': event.state})
                self._data(values, event.stamp_ns)
        except Exception:
            self._log.log(logging.ERROR, 'event', 'cannot publish a job service event as '
                          'Sparkplug B', exc_info=True)
