"""The MQTT bridge against a real broker: mosquitto in a child process, amqtt in-process.

The topic tree and JSON keys of docs/cell.md are asserted here as a contract; the measured
input's checks are driven by a second client publishing hostile payloads through the broker.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
import queue
import resource
import threading
import time
from typing import Any, Iterator

from brokers import amqtt_broker, mosquitto, mosquitto_binary
from conftest import mqtt_port
from fake_service import FakeJobService
import must_run
import paho.mqtt.client as paho
import pytest

from feed_axis_energy.bridge import (MAX_PAYLOAD_BYTES, MeasuredSample, MqttBridge,
                                     MqttSettings, POWER_KEYS, RESULT_KEYS, STATE_KEYS,
                                     STATUS_KEYS, TopicTree)
from feed_axis_energy.errors import FeedAxisError


def _start_broker(kind: str, tmp: Path) -> Any:
    port = mqtt_port()
    if kind == 'mosquitto':
        if mosquitto_binary() is None:
            must_run.skip('mosquitto', 'mosquitto is not installed (apt-get install mosquitto)')
        return port, mosquitto(tmp / 'broker', port)
    return port, amqtt_broker(port)


@pytest.fixture(params=['mosquitto', 'amqtt'])
def any_broker(request, tmp_path: Path) -> Iterator[tuple[str, int]]:
    """Each broker in turn: mosquitto (must run on CI) and the amqtt fallback."""
    port, context = _start_broker(request.param, tmp_path)
    with context as kind:
        yield kind, port


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[tuple[str, int]]:
    """mosquitto where installed, else the in-process amqtt broker (the fallback)."""
    kind = 'mosquitto' if mosquitto_binary() is not None else 'amqtt'
    port, context = _start_broker(kind, tmp_path)
    with context as name:
        yield name, port


class Listener:
    """A plain paho client that records what arrives on a topic filter."""

    def __init__(self, port: int, topic: str):
        self.messages: queue.Queue[tuple[str, bytes, bool, float]] = queue.Queue()
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id='')
        self.client.on_message = self._on_message
        subscribed = threading.Event()
        self.client.on_subscribe = lambda *args: subscribed.set()
        self.client.connect('127.0.0.1', port)
        self.client.loop_start()
        self.client.subscribe(topic, qos=1)
        assert subscribed.wait(10), 'the broker did not confirm the subscription'

    def _on_message(self, client, userdata, message) -> None:
        self.messages.put((message.topic, message.payload, bool(message.retain),
                           time.time()))

    def take(self, topic: str, timeout: float = 10.0,
             until: Any = None) -> tuple[dict[str, Any], bool]:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                got, payload, retained, _ = self.messages.get(timeout=0.1)
            except queue.Empty:
                continue
            if got == topic:
                data = json.loads(payload)
                if until is None or until(data):
                    return data, retained
        pytest.fail(f'nothing (wanted) on {topic} within {timeout} s')

    def collect(self, topics: set[str], timeout: float = 10.0) -> dict[str, tuple[Any, bool]]:
        """The first message on each of ``topics`` (decoded, retained flag)."""
        found: dict[str, tuple[Any, bool]] = {}
        end = time.monotonic() + timeout
        while not topics <= set(found) and time.monotonic() < end:
            try:
                topic, payload, retained, _ = self.messages.get(timeout=0.1)
            except queue.Empty:
                continue
            found.setdefault(topic, (json.loads(payload), retained))
        missing = topics - set(found)
        assert not missing, f'nothing on {sorted(missing)} within {timeout} s'
        return found

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def _publisher(port: int) -> paho.Client:
    client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id='')
    client.max_queued_messages_set(0)
    client.connect('127.0.0.1', port)
    client.loop_start()
    return client


def _wait(condition, timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.02)
    return condition()


def test_the_topic_tree_is_the_documented_one() -> None:
    tree = TopicTree(prefix='plant/cell3', machine='dmc60h')
    assert tree.status == 'plant/cell3/dmc60h/status'
    assert tree.job_state == 'plant/cell3/dmc60h/job/state'
    assert tree.job_result == 'plant/cell3/dmc60h/job/result'
    assert tree.power == 'plant/cell3/dmc60h/power'
    assert tree.measured('X') == 'plant/cell3/dmc60h/measured/X'
    assert tree.measured_filter == 'plant/cell3/dmc60h/measured/+'
    assert tree.axis_of('plant/cell3/dmc60h/measured/Y') == 'Y'
    assert tree.axis_of('plant/cell3/dmc60h/measured/Y/z') is None
    assert tree.axis_of('plant/cell3/dmc60h/power') is None
    assert TopicTree().base == 'feed_axis_energy/machine'


def test_a_job_is_published_on_the_documented_topics_and_keys(any_broker, program_root):
    kind, port = any_broker
    service = FakeJobService(program_root, samples=10, period_s=0.01)
    tree = TopicTree(machine='m1')
    sink = Listener(port, f'{tree.base}/#')
    try:
        with MqttBridge(service, MqttSettings(port=port, topics=tree)) as bridge:
            status, _ = sink.take(tree.status, until=lambda d: d['online'])
            assert tuple(status) == STATUS_KEYS
            assert service.start_job('job-1', 'a.ngc', 1.5) == (True, "job 'job-1' started")
            power, _ = sink.take(tree.power)
            assert tuple(power) == POWER_KEYS
            assert power['predicted'] is True and power['job_id'] == 'job-1'
            assert set(power['power_w']) == {'X', 'Y', 'Z', 'total'}
            assert abs(power['stamp'] - time.time()) < 60    # wall clock, seconds
            assert math.isclose(power['power_w']['total'],
                                sum(power['power_w'][a] for a in 'XYZ'), rel_tol=1e-12)
            for part in ('X', 'total'):
                assert math.isclose(power['energy_j'][part],
                                    power['energy_import_j'][part]
                                    - power['energy_export_j'][part], abs_tol=1e-12)
            service.wait()
            # the result is published before the state that announces it
            result, _ = sink.take(tree.job_result)
            assert set(RESULT_KEYS) <= set(result) and 'stamp' in result
            assert result['job_id'] == 'job-1' and result['status'] == 'ended'
            assert result['energy_j'] == service.result('job-1')['energy_j']
            state, _ = sink.take(tree.job_state, until=lambda d: d['state'] == 'ended')
            assert tuple(state) == STATE_KEYS and state['job_id'] == 'job-1'
            assert bridge.publish_failures == 0
        # a late subscriber finds state, result and status (offline now) retained
        late = Listener(port, f'{tree.base}/#')
        try:
            found = late.collect({tree.job_state, tree.job_result, tree.status})
            assert all(retained for _, retained in found.values()), found
            assert found[tree.job_state][0]['state'] == 'ended'
            assert found[tree.job_result][0]['job_id'] == 'job-1'
            assert found[tree.status][0]['online'] is False
        finally:
            late.close()
    finally:
        sink.close()


def test_measured_data_reach_the_callback_and_bad_ones_are_counted(any_broker):
    kind, port = any_broker
    got: list[MeasuredSample] = []
    tree = TopicTree(machine='m2')
    settings = MqttSettings(port=port, topics=tree, axes=('X', 'Y'))
    hostile = [
        ('X', b'{"stamp": 1.7e9, "value": 1.0}', 'missing_key'),
        ('X', b'not json', 'bad_json'),
        ('X', b'\xff\xfe', 'not_utf8'),
        ('X', b'[1, 2]', 'not_object'),
        ('X', b'{"stamp": 1.7e9, "value": "3", "quantity": "power_w"}', 'wrong_type'),
        ('X', b'{"stamp": 1.7e9, "value": true, "quantity": "power_w"}', 'wrong_type'),
        ('X', b'{"stamp": 1.7e9, "value": NaN, "quantity": "power_w"}', 'non_finite'),
        ('X', b'{"stamp": 1.7e9, "value": 1e400, "quantity": "power_w"}', 'non_finite'),
        ('X', b'{"stamp": 1.7e9, "value": 1, "quantity": "volts"}', 'unknown_quantity'),
        ('X', b'{"stamp": -5, "value": 1, "quantity": "power_w"}', 'bad_stamp'),
        ('Q', b'{"stamp": 1.7e9, "value": 1, "quantity": "power_w"}', 'unknown_axis'),
        ('X', b'[' * 50000, 'bad_json'),
        ('X', b' ' * (MAX_PAYLOAD_BYTES + 1), 'too_large'),
        ('Y', b'x' * (10 * 1024 * 1024), 'too_large'),
    ]
    with MqttBridge(None, settings, on_measured=got.append) as bridge:
        pub = _publisher(port)
        try:
            for axis, payload, _ in hostile:
                pub.publish(tree.measured(axis), payload, qos=1).wait_for_publish(10)
            good = {'stamp': 1764280000.25, 'value': 41.5, 'quantity': 'power_w'}
            pub.publish(tree.measured('Y'), json.dumps(good), qos=1).wait_for_publish(10)
            assert _wait(lambda: bridge.measured.accepted == 1
                         and bridge.measured.dropped == len(hostile), 30), \
                (bridge.measured.accepted, bridge.measured.drops)
        finally:
            pub.disconnect()
            pub.loop_stop()
        assert got == [MeasuredSample(axis='Y', quantity='power_w', value=41.5,
                                      stamp_ns=1764280000250000000)]
        want: dict[str, int] = {}
        for _, _, reason in hostile:
            want[reason] = want.get(reason, 0) + 1
        assert {k: v for k, v in bridge.measured.drops.items() if v} == want


def test_a_flood_is_dropped_and_counted_and_the_bridge_goes_on(broker):
    """10 000 messages as fast as one client sends them (100/s allowed): the rate limit drops
    most, memory stays flat, and a message after the flood still arrives."""
    kind, port = broker
    tree = TopicTree(machine='m3')
    got: list[MeasuredSample] = []
    settings = MqttSettings(port=port, topics=tree, axes=('X',), max_rate_hz=100.0)
    payload = json.dumps({'stamp': 1.7e9, 'value': 1.0, 'quantity': 'power_w'}).encode()
    with MqttBridge(None, settings, on_measured=got.append) as bridge:
        rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        pub = _publisher(port)
        try:
            start = time.monotonic()
            for _ in range(10_000):
                pub.publish(tree.measured('X'), payload, qos=0)
            sent_s = time.monotonic() - start
            seen = lambda: bridge.measured.accepted + bridge.measured.dropped  # noqa: E731
            _wait(lambda: seen() >= 10_000, 60)
            received = seen()
            assert bridge.measured.drops['rate_limited'] > 0
            # QoS 0 through a broker may lose some under a flood; none may be mishandled
            assert bridge.measured.dropped == bridge.measured.drops['rate_limited']
            time.sleep(1.1)    # the bucket refills
            before = bridge.measured.accepted
            pub.publish(tree.measured('X'), payload, qos=1).wait_for_publish(10)
            assert _wait(lambda: bridge.measured.accepted > before, 10)
        finally:
            pub.disconnect()
            pub.loop_stop()
        rss_after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        print(f'{kind}: 10000 messages sent in {sent_s:.2f} s, {received} received, accepted '
              f'{bridge.measured.accepted}, dropped {bridge.measured.drops["rate_limited"]}, '
              f'max RSS {rss_before / 1024:.0f} -> {rss_after / 1024:.0f} MiB')
        assert len(got) == bridge.measured.accepted
        assert rss_after - rss_before < 50 * 1024     # ru_maxrss is in KiB


def test_a_callback_that_raises_is_counted_not_fatal(broker):
    kind, port = broker
    tree = TopicTree(machine='m4')

    def bad(sample: MeasuredSample) -> None:
        raise RuntimeError('consumer broke')

    payload = json.dumps({'stamp': 1.7e9, 'value': 2.0, 'quantity': 'current_a'})
    with MqttBridge(None, MqttSettings(port=port, topics=tree), on_measured=bad) as bridge:
        pub = _publisher(port)
        try:
            for _ in range(3):
                pub.publish(tree.measured('X'), payload, qos=1).wait_for_publish(10)
            assert _wait(lambda: bridge.measured.drops['callback_error'] == 3)
        finally:
            pub.disconnect()
            pub.loop_stop()
        assert 'consumer broke' in bridge.measured.last_error


def test_no_broker_is_a_clear_error() -> None:
    port = mqtt_port()   # nothing listens there
    bridge = MqttBridge(None, MqttSettings(port=port))
    with pytest.raises(FeedAxisError, match=f'cannot connect to the MQTT broker at '
                                            f'127.0.0.1:{port}'):
        bridge.start(timeout_s=2)


def test_a_service_event_that_cannot_be_json_is_not_published(broker, program_root):
    """A result with NaN is refused (never NaN on the wire), the bridge goes on."""
    kind, port = broker
    service = FakeJobService(program_root, samples=3)
    tree = TopicTree(machine='m5')
    with MqttBridge(service, MqttSettings(port=port, topics=tree)) as bridge:
        failures = bridge.publish_failures
        service.inject_result({'job_id': 'j', 'status': 'ended', 'energy_j': float('nan'),
                               'duration_s': 1.0, 'peak_power_w': 1.0})
        assert _wait(lambda: bridge.publish_failures == failures + 1)
        assert service.start_job('ok', 'a.ngc', 0.0)[0]
        service.wait()
        assert _wait(lambda: bridge.published >= 4)


def test_the_bridge_comes_back_after_the_broker_restarts(tmp_path, program_root):
    """mosquitto stopped and started again on the same port: paho reconnects, the bridge
    says online again and republishes state and result (the restarted broker kept nothing)."""
    if mosquitto_binary() is None:
        must_run.skip('mosquitto', 'mosquitto is not installed (apt-get install mosquitto)')
    port = mqtt_port()
    service = FakeJobService(program_root, samples=3)
    tree = TopicTree(machine='m6')
    with mosquitto(tmp_path / 'first', port):
        bridge = MqttBridge(service, MqttSettings(port=port, topics=tree, keepalive_s=2))
        bridge.start()
        assert service.start_job('before', 'a.ngc', 0.0)[0]
        service.wait()
    try:
        assert _wait(lambda: not bridge.connected, 10)
        with mosquitto(tmp_path / 'second', port):
            assert _wait(lambda: bridge.connected, 30), 'paho did not reconnect'
            late = Listener(port, f'{tree.base}/#')
            try:
                found = late.collect({tree.job_result, tree.job_state, tree.status})
                assert found[tree.job_result] == (found[tree.job_result][0], True)
                assert found[tree.job_result][0]['job_id'] == 'before'
                assert found[tree.job_state][0]['state'] == 'ended'
                assert found[tree.status][0]['online'] is True
            finally:
                late.close()
    finally:
        bridge.stop()


def test_bad_settings_are_config_errors() -> None:
    from feed_axis_energy.errors import ConfigError
    for key, value in (('port', 0), ('max_queued', 0), ('max_rate_hz', math.inf),
                       ('keepalive_s', 1.5)):
        with pytest.raises(ConfigError, match=f'<mqtt>: {key}: expected'):
            MqttSettings(**{key: value})


def test_the_bridge_socket_does_not_wait_for_nagle(broker) -> None:
    """TCP_NODELAY on the bridge's socket: small messages leave at once (with the broker's
    ``set_tcp_nodelay``, MQTT p99 7.5 ms instead of 37 ms in bench/bench_bridges.py)."""
    import socket
    kind, port = broker
    with MqttBridge(None, MqttSettings(port=port, topics=TopicTree(machine='m7'))) as bridge:
        sock = bridge._client.socket()
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) != 0
