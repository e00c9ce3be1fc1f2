"""The MQTT bridge: a job service's state, live power and results out, measured data in.

A paho-mqtt 2.x client with its own network thread. What it publishes and where is
:mod:`.topics` (docs/cell.md); what it accepts on ``measured/<axis>`` is :mod:`.measured`.
The job service's listener publishes from the service's thread (paho's ``publish`` may be
called from any thread); the outgoing queue is bounded (``max_queued``), so a broker that is
away costs memory up to that bound, not more. On (re)connection the bridge publishes
``status`` online and the current state and last result, retained; the broker publishes
the last will, ``status`` offline, when the bridge disappears without saying goodbye.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import logging
import math
import socket
import threading
import time
from typing import Any, Callable, Mapping

import paho.mqtt.client as paho

from ..errors import ConfigError, describe, FeedAxisError, RequestError
from .logbound import BoundedLog
from .measured import MeasuredInput, MeasuredSample
from .service import FINAL_STATES, JobService, LiveSample, ServiceEvent, StateChange
from .topics import (power_payload, result_payload, state_payload, status_payload,
                     TopicTree)

__all__ = ['MqttBridge', 'MqttSettings', 'new_client', 'tcp_no_delay']

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class MqttSettings:
    """Where the broker is and how the bridge uses it.

    Attributes
    ----------
    host, port
        The broker.
    topics
        The topic tree (prefix and machine name).
    client_id
        MQTT client id; '' lets the bridge make one from the machine name.
    username, password
        Broker credentials, if it asks for them.
    keepalive_s
        MQTT keep-alive [s].
    max_queued
        Outgoing messages held while the broker is away; beyond, publishing drops.
    max_rate_hz
        Measured-data messages accepted per second (:class:`~.measured.MeasuredInput`).
    axes
        Axes whose measured data are accepted; empty: the service's axes, or any.
    """

    host: str = '127.0.0.1'
    port: int = 1883
    topics: TopicTree = field(default_factory=TopicTree)
    client_id: str = ''
    username: str | None = None
    password: str | None = None
    keepalive_s: int = 30
    max_queued: int = 1000
    max_rate_hz: float = 2000.0
    axes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if isinstance(self.port, bool) or not isinstance(self.port, int) \
                or not 1 <= self.port <= 65535:
            raise ConfigError(f'expected a TCP port 1...65535, got {describe(self.port)}',
                              file='<mqtt>', key='port')
        for key in ('keepalive_s', 'max_queued'):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError(f'expected a positive integer, got {describe(value)}',
                                  file='<mqtt>', key=key)
        if isinstance(self.max_rate_hz, bool) or not isinstance(self.max_rate_hz, (int, float)) \
                or not math.isfinite(self.max_rate_hz) or self.max_rate_hz <= 0:
            raise ConfigError(f'expected a positive finite number, got '
                              f'{describe(self.max_rate_hz)}', file='<mqtt>', key='max_rate_hz')


def new_client(client_id: str, *, max_queued: int, username: str | None,
               password: str | None) -> paho.Client:
    """A paho client (MQTT 3.1.1): its outgoing queue bounded by ``max_queued`` messages, the
    credentials when ``username`` is given, Nagle's algorithm off (:func:`tcp_no_delay`);
    the caller sets its will and callbacks."""
    client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id=client_id,
                         protocol=paho.MQTTv311)
    client.max_queued_messages_set(max_queued)
    if username is not None:
        client.username_pw_set(username, password)
    client.on_socket_open = tcp_no_delay
    return client


def tcp_no_delay(client: paho.Client, userdata: Any, sock: Any) -> None:
    """paho's ``on_socket_open``: Nagle's algorithm off on the broker connection."""
    # without it Nagle's algorithm holds a small message back until the broker's delayed
    # acknowledgement of the one before (up to 40 ms on Linux)
    try:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    except (OSError, AttributeError):   # not a TCP socket (a proxy, a unix socket)
        pass


class MqttBridge:
    """Publishes a job service on MQTT and hands measured drive data to a callback.

    Parameters
    ----------
    service
        The job service to publish, or None for a bridge that only receives measured data.
    settings
        Broker, topics, limits.
    on_measured
        Called with every accepted measured sample, in the MQTT network thread; None: the
        bridge does not subscribe.

    Use as a context manager or call :meth:`start` and :meth:`stop`.
    """

    def __init__(self, service: JobService | None, settings: MqttSettings | None = None, *,
                 on_measured: Callable[[MeasuredSample], None] | None = None):
        self.service = service
        self.settings = settings or MqttSettings()
        self.topics = self.settings.topics
        axes = self.settings.axes or (tuple(service.axes()) if service is not None else ())
        self.measured = MeasuredInput(on_measured or (lambda sample: None), axes=axes,
                                      max_rate_hz=self.settings.max_rate_hz)
        self._subscribe_measured = on_measured is not None
        self.published = 0
        """Messages handed to paho (QoS 0 ones may still be lost on the way)."""
        self.publish_failures = 0
        """Messages paho refused (queue full, not connected for QoS 0)."""
        self._log = BoundedLog(_log)
        self._connected = threading.Event()
        self._subscribed = threading.Event()    # the broker confirmed measured/# (SUBACK)
        self._connect_error = ''
        self._unsubscribe: Callable[[], None] | None = None
        client_id = self.settings.client_id or f'feed_axis_energy-{self.topics.machine}'
        client = new_client(client_id, max_queued=self.settings.max_queued,
                            username=self.settings.username, password=self.settings.password)
        client.will_set(self.topics.status, status_payload(online=False, stamp_ns=0), qos=1,
                        retain=True)
        client.on_connect = self._on_connect
        client.on_subscribe = self._on_subscribe
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        self._client = client

    def __enter__(self) -> MqttBridge:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def connected(self) -> bool:
        """Whether the broker has accepted the connection (and not lost it since)."""
        return self._connected.is_set()

    def start(self, *, timeout_s: float = 10.0) -> None:
        """Connect, start the network thread, follow the service.

        Raises
        ------
        FeedAxisError
            The broker cannot be reached or refuses the connection within ``timeout_s``.
        """
        where = f'{self.settings.host}:{self.settings.port}'
        try:
            self._client.connect(self.settings.host, self.settings.port,
                                 keepalive=self.settings.keepalive_s)
        except (OSError, ValueError) as exc:
            msg = f'cannot connect to the MQTT broker at {where}: {exc}'
            raise FeedAxisError(msg) from exc
        self._client.loop_start()
        if not self._connected.wait(timeout_s):
            self._client.loop_stop()
            reason = self._connect_error or f'no answer within {timeout_s:g} s'
            raise FeedAxisError(f'the MQTT broker at {where} did not accept the bridge: '
                                f'{reason}')
        # measured data published once start() has returned reach the callback: the broker
        # has confirmed the subscription (without it, the first messages could be lost)
        if self._subscribe_measured and not self._subscribed.wait(timeout_s):
            self._client.disconnect()
            self._client.loop_stop()
            raise FeedAxisError(f'the MQTT broker at {where} did not confirm the subscription '
                                f'to {self.topics.measured_filter} within {timeout_s:g} s')
        if self.service is not None:
            self._unsubscribe = self.service.subscribe(self._on_event)

    def stop(self) -> None:
        """Say offline (retained), disconnect, stop the network thread."""
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None
        if self._connected.is_set():
            info = self._client.publish(self.topics.status,
                                        status_payload(online=False, stamp_ns=time.time_ns()),
                                        qos=1, retain=True)
            try:
                info.wait_for_publish(timeout=2.0)
            except (RuntimeError, ValueError):
                pass
        self._client.disconnect()
        self._client.loop_stop()
        self._connected.clear()

    # -- paho's callbacks (network thread) ------------------------------------------------

    def _on_connect(self, client: paho.Client, userdata: Any, flags: Any, reason: Any,
                    properties: Any) -> None:
        if reason.is_failure:
            self._connect_error = str(reason)
            _log.error('the MQTT broker refused the bridge: %s', reason)
            return
        if self._subscribe_measured:
            client.subscribe(self.topics.measured_filter, qos=0)
        self._publish(self.topics.status, status_payload(online=True, stamp_ns=time.time_ns()),
                      qos=1, retain=True)
        self._publish_state()
        self._publish_result()
        self._connected.set()

    def _on_subscribe(self, client: paho.Client, userdata: Any, mid: int, reasons: Any,
                      properties: Any) -> None:
        if any(getattr(r, 'is_failure', False) for r in reasons):
            _log.error('the MQTT broker refused the subscription to %s: %s',
                       self.topics.measured_filter, reasons)
            return
        self._subscribed.set()

    def _on_disconnect(self, client: paho.Client, userdata: Any, flags: Any, reason: Any,
                       properties: Any) -> None:
        self._connected.clear()
        self._subscribed.clear()
        if reason.is_failure:
            _log.warning('lost the MQTT broker (%s); paho reconnects', reason)

    def _on_message(self, client: paho.Client, userdata: Any, message: Any) -> None:
        try:
            topic = message.topic
        except UnicodeDecodeError:   # a topic that is not UTF-8
            topic = repr(message._topic)   # paho keeps the raw bytes there
        self.measured.handle(self.topics.axis_of(topic), topic, message.payload)

    # -- publishing -----------------------------------------------------------------------

    def _publish(self, topic: str, payload: bytes, *, qos: int, retain: bool = False) -> None:
        try:
            info = self._client.publish(topic, payload, qos=qos, retain=retain)
        except (ValueError, RuntimeError) as exc:
            self.publish_failures += 1
            self._log.log(logging.WARNING, 'publish', f'cannot publish on {topic}: {exc}')
            return
        if info.rc == paho.MQTT_ERR_SUCCESS:
            self.published += 1
        else:
            self.publish_failures += 1

    def _publish_state(self, event: StateChange | None = None) -> None:
        if self.service is None:
            return
        if event is None:
            event = StateChange(job_id=str(self.service.active_job()),
                                state=str(self.service.state()), stamp_ns=time.time_ns())
        self._publish(self.topics.job_state, state_payload(job_id=event.job_id,
                                                           state=event.state,
                                                           stamp_ns=event.stamp_ns),
                      qos=1, retain=True)

    def _publish_result(self, job_id: str | None = None) -> None:
        if self.service is None:
            return
        result: Mapping[str, Any] | None
        result = self.service.last_result() if job_id is None else self.service.result(job_id)
        if result is None and job_id is not None:
            # a service that keeps no history still has its last result
            last = self.service.last_result()
            result = last if last is not None and last.get('job_id') == job_id else None
        if result is None:
            return
        try:
            payload = result_payload(result, stamp_ns=time.time_ns())
        except RequestError as exc:
            self.publish_failures += 1
            self._log.log(logging.ERROR, 'result', f'the result is not published: {exc}')
            return
        self._publish(self.topics.job_result, payload, qos=1, retain=True)

    def _on_event(self, event: ServiceEvent) -> None:
        """The service's listener (any thread): never raises into the service."""
        try:
            if isinstance(event, LiveSample):
                self._publish(self.topics.power, power_payload(event), qos=0)
            elif isinstance(event, StateChange):
                if event.state in FINAL_STATES:
                    # the result first: a client that reacts to the state finds it there
                    self._publish_result(event.job_id)
                self._publish_state(event)
        except Exception:
            self._log.log(logging.ERROR, 'event', 'cannot publish a job service event on MQTT',
                          exc_info=True)
