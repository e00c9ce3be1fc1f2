"""Sparkplug B: the payload codec by hand-made bytes, the edge node against mosquitto.

The codec is checked against bytes written down from the protobuf wire rules (not produced by
the encoder), then by round trips and hostile input. The edge node runs beside the plain JSON
bridge on one fake job service and one real broker; a second client decodes what arrives
under ``spBv1.0/#`` and compares it with the JSON topics.
"""
from __future__ import annotations

from pathlib import Path
import queue
import socket
import struct
import threading
import time
from typing import Any, Iterator

from brokers import mosquitto, mosquitto_binary
from conftest import mqtt_port
from fake_service import FakeJobService
import must_run
import paho.mqtt.client as paho
import pytest

from feed_axis_energy.bridge import (decode_sparkplug, device_metrics, encode_sparkplug,
                                     MAX_DECODED_BYTES, MqttBridge, MqttSettings,
                                     REBIRTH_METRIC, SparkplugBridge, SparkplugSettings,
                                     SparkplugTopics, SpDataType, SpMetric, SpPayload,
                                     TopicTree)
from feed_axis_energy.errors import ConfigError, FeedAxisError, RequestError

# --- the payload codec -------------------------------------------------------------------


def test_encoding_matches_bytes_written_from_the_wire_rules() -> None:
    metric = SpMetric(name='a', alias=None, datatype=SpDataType.DOUBLE, value=1.5)
    got = encode_sparkplug(SpPayload(timestamp_ms=300, metrics=(metric,), seq=0))
    want = (b'\x08\xac\x02'                       # field 1 varint: 300 = 0b10_0101100
            + b'\x12\x0e'                         # field 2, 14 bytes: the metric
            + b'\x0a\x01a'                        # name (1, length-delimited) 'a'
            + b'\x20\x0a'                         # datatype (4, varint) 10 = Double
            + b'\x69' + struct.pack('<d', 1.5)    # double_value (13, 64-bit)
            + b'\x18\x00')                        # seq (3, varint) 0
    assert got == want
    # alias only, Int64 -1 as two's complement in long_value (11): ten varint bytes
    data = encode_sparkplug(SpPayload(timestamp_ms=None, seq=None, metrics=(
        SpMetric(name=None, alias=5, datatype=SpDataType.INT64, value=-1),)))
    assert data == b'\x12\x0f' + b'\x10\x05' + b'\x20\x04' + b'\x58' + b'\xff' * 9 + b'\x01'


@pytest.mark.parametrize('datatype, value', [
    (SpDataType.INT8, -128), (SpDataType.INT16, -2), (SpDataType.INT32, -2_000_000_000),
    (SpDataType.INT64, -(1 << 63)), (SpDataType.UINT32, (1 << 32) - 1),
    (SpDataType.UINT64, (1 << 64) - 1), (SpDataType.DOUBLE, -0.1),
    (SpDataType.FLOAT, 0.5), (SpDataType.BOOLEAN, True), (SpDataType.BOOLEAN, False),
    (SpDataType.STRING, 'Ä/€ job'), (SpDataType.STRING, ''),
])
def test_values_round_trip_with_their_datatype(datatype: int, value: Any) -> None:
    metric = SpMetric(name='m', alias=7, datatype=datatype, value=value, timestamp_ms=123,
                      properties={'engUnit': (SpDataType.STRING, 'W'),
                                  'scale': (SpDataType.INT32, -3)})
    back = decode_sparkplug(encode_sparkplug(SpPayload(timestamp_ms=9, metrics=(metric,),
                                                       seq=255)))
    assert back.seq == 255 and back.timestamp_ms == 9
    assert back.metrics == (metric,)
    assert type(back.metrics[0].value) is type(value)


def test_a_value_that_is_not_finite_goes_out_as_null() -> None:
    for value in (float('nan'), float('inf'), None):
        data = encode_sparkplug(SpPayload(timestamp_ms=1, seq=1, metrics=(
            SpMetric(name='p', alias=1, datatype=SpDataType.DOUBLE, value=value),)))
        metric = decode_sparkplug(data).metrics[0]
        assert metric.is_null and metric.value is None and metric.datatype == SpDataType.DOUBLE


def test_fields_the_bridge_does_not_use_are_skipped() -> None:
    metric = (b'\x0a\x01x' + b'\x20\x0b' + b'\x70\x01'          # name x, Boolean, true
              + b'\x42\x02\x10\x01'                              # metadata (8): skipped
              + b'\x8a\x01\x00')                                 # a data set (17): skipped
    data = (b'\x08\x01' + b'\x12' + bytes([len(metric)]) + metric
            + b'\x22\x03abc' + b'\x2a\x00' + b'\x18\x05')        # uuid (4), body (5)
    payload = decode_sparkplug(data)
    assert payload.seq == 5
    assert payload.metrics[0].name == 'x' and payload.metrics[0].value is True


@pytest.mark.parametrize('data, code', [
    (b'\x08', 'bad_protobuf'),                      # varint runs past the end
    (b'\x08' + b'\xff' * 11, 'bad_protobuf'),       # varint longer than 10 bytes
    (b'\x12\x05\x0a', 'bad_protobuf'),              # length past the end
    (b'\x0b', 'bad_protobuf'),                      # wire type 3 (groups)
    (b'\x00\x00', 'bad_protobuf'),                  # field number 0
    (b'\x12\x03\x0a\x01\xff', 'bad_protobuf'),      # a name that is not UTF-8
    (b'\x10\x01', 'bad_protobuf'),                  # metrics (2) as a varint
    (b'\x12\x02\x68\x00', 'bad_protobuf'),      # double_value (13) as a varint
    (b'\x00' * (MAX_DECODED_BYTES + 1), 'too_large'),
])
def test_malformed_payloads_are_refused_with_our_error(data: bytes, code: str) -> None:
    with pytest.raises(RequestError) as err:
        decode_sparkplug(data, where='spBv1.0/g/NCMD/e')
    assert err.value.code == code and 'spBv1.0/g/NCMD/e' in str(err.value)


def test_sparkplug_ids_are_checked() -> None:
    topics = SparkplugTopics.parse('plant1/cell3', device_id='dmc60h')
    assert topics.node('NBIRTH') == 'spBv1.0/plant1/NBIRTH/cell3'
    assert topics.device('DDATA') == 'spBv1.0/plant1/DDATA/cell3/dmc60h'
    for bad in ('nogroup', 'a/b/c', 'a+/b', '/b', 'a/', 'a/#'):
        with pytest.raises(ConfigError):
            SparkplugTopics.parse(bad)


def test_device_metrics_carry_units_and_unique_names() -> None:
    metrics = device_metrics(('X', 'Y'))
    names = [name for name, _, _ in metrics]
    assert len(names) == len(set(names))
    units = {name: unit for name, _, unit in metrics}
    assert units['Live/total/power_w'] == 'W' and units['Live/X/energy_export_j'] == 'J'
    assert units['Result/duration_s'] == 's' and units['Result/Y/peak_power_w'] == 'W'
    assert all(unit for name, datatype, unit in metrics if datatype == SpDataType.DOUBLE)


# --- the edge node against a real broker ---------------------------------------------------

@pytest.fixture
def broker_port(tmp_path: Path) -> Iterator[int]:
    """mosquitto on a free loopback port (the real broker; must run on CI)."""
    if mosquitto_binary() is None:
        must_run.skip('mosquitto', 'mosquitto is not installed (apt-get install mosquitto)')
    port = mqtt_port()
    with mosquitto(tmp_path / 'broker', port):
        yield port


class Sink:
    """Records every message under the filters, in arrival order, Sparkplug ones decoded."""

    def __init__(self, port: int, *filters: str):
        self.messages: queue.Queue[tuple[str, Any, int, bool]] = queue.Queue()
        self.seen: list[tuple[str, Any, int, bool]] = []
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id='')
        self.client.on_message = self._on_message
        subscribed = threading.Event()
        self.client.on_subscribe = lambda *args: subscribed.set()
        self.client.connect('127.0.0.1', port)
        self.client.loop_start()
        self.client.subscribe([(f, 1) for f in filters])
        assert subscribed.wait(10), 'the broker did not confirm the subscription'

    def _on_message(self, client, userdata, message) -> None:
        body: Any = message.payload
        if message.topic.startswith('spBv1.0/'):
            try:
                body = decode_sparkplug(message.payload)
            except RequestError:     # the hostile commands the tests send
                pass
        self.messages.put((message.topic, body, message.qos, bool(message.retain)))

    def until(self, predicate, timeout: float = 15.0) -> tuple[str, Any, int, bool]:
        """Read on until a message satisfies ``predicate(topic, body)``; returns it."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                item = self.messages.get(timeout=0.1)
            except queue.Empty:
                continue
            self.seen.append(item)
            if predicate(item[0], item[1]):
                return item
        pytest.fail(f'not seen within {timeout} s; last: {[m[0] for m in self.seen[-5:]]}')

    def publish(self, topic: str, payload: bytes) -> None:
        self.client.publish(topic, payload, qos=0).wait_for_publish(5)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def _values(metric_list, names: dict[int, str]) -> dict[str, Any]:
    return {names[m.alias]: m.value for m in metric_list}


def test_births_come_first_then_data_with_seq_and_values_of_the_json_topics(
        broker_port, program_root):
    import json
    service = FakeJobService(program_root, samples=300, period_s=0.001)
    tree = TopicTree(machine='m1')
    topics = SparkplugTopics(group_id='g1', edge_node_id='e1', device_id='m1')
    sink = Sink(broker_port, 'spBv1.0/#', f'{tree.base}/#')
    settings = SparkplugSettings(host='127.0.0.1', port=broker_port, topics=topics)
    try:
        with MqttBridge(service, MqttSettings(port=broker_port, topics=tree)), \
                SparkplugBridge(service, settings) as edge:
            topic, nbirth, qos, retain = sink.until(lambda t, b: t.startswith('spBv1.0/'))
            assert topic == 'spBv1.0/g1/NBIRTH/e1' and nbirth.seq == 0 and not retain
            node = {m.name: m for m in nbirth.metrics}
            assert node['bdSeq'].datatype == SpDataType.INT64 and node['bdSeq'].value == 0
            rebirth = node[REBIRTH_METRIC]
            assert rebirth.datatype == SpDataType.BOOLEAN and rebirth.value is False
            assert rebirth.alias is None and nbirth.timestamp_ms is not None
            topic, dbirth, _, _ = sink.until(lambda t, b: t.startswith('spBv1.0/'))
            assert topic == 'spBv1.0/g1/DBIRTH/e1/m1' and dbirth.seq == 1
            names = {m.alias: m.name for m in dbirth.metrics}
            assert sorted(names.values()) == sorted(n for n, _, _ in device_metrics('XYZ'))
            birth = {m.name: m for m in dbirth.metrics}
            assert birth['Job/State'].value == 'idle'
            assert birth['Live/total/power_w'].properties == {
                'engUnit': (SpDataType.STRING, 'W')}
            assert birth['Result/JobId'].is_null

            assert service.start_job('job-1', 'a.ngc', 0.0)[0]
            service.wait()
            sink.until(_state_of('e1', 'ended'))
            if not any(t == tree.job_result for t, _, _, _ in sink.seen):
                sink.until(lambda t, b: t == tree.job_result)     # its own connection
            assert edge.publish_failures == 0
    finally:
        sink.close()
    spb = [(t, b) for t, b, _, _ in sink.seen if t.startswith('spBv1.0/')]
    seqs = [b.seq for _, b in spb]
    # every message after the NBIRTH is one more than the one before, 255 wrapping to 0
    assert all(b == (a + 1) % 256 for a, b in zip(seqs, seqs[1:])), seqs
    assert 255 in seqs and seqs.count(0) >= 2     # wrapped at least once
    data = [b for t, b in spb if t == 'spBv1.0/g1/DDATA/e1/m1']
    assert all(m.name is None and m.alias in names for b in data for m in b.metrics)
    live = [_values(b.metrics, names) for b in data
            if any(names[m.alias] == 'Live/JobId' for m in b.metrics)]
    power = [json.loads(body) for t, body, _, _ in sink.seen if t == tree.power]
    assert len(live) == len(power) == 300
    for spb_values, js in zip(live, power):
        assert spb_values['Live/JobId'] == js['job_id']
        for part in ('X', 'Y', 'Z', 'total'):
            for quantity in ('power_w', 'energy_j', 'energy_import_j', 'energy_export_j'):
                assert spb_values[f'Live/{part}/{quantity}'] == js[quantity][part]
    stamps = [m.timestamp_ms for b in data for m in b.metrics
              if names[m.alias] == 'Live/total/power_w']
    assert all(abs(ms / 1e3 - js['stamp']) <= 1e-3 for ms, js in zip(stamps, power))
    states = [m.value for b in data for m in b.metrics if names[m.alias] == 'Job/State']
    assert states == ['planning', 'running', 'ended']
    result_json = next(json.loads(body) for t, body, _, _ in sink.seen if t == tree.job_result)
    final = _values(data[-1].metrics, names)
    assert final['Result/JobId'] == result_json['job_id'] == 'job-1'
    assert final['Result/Status'] == result_json['status'] == 'ended'
    assert final['Result/Program'] == result_json['program']
    for key in ('energy_j', 'duration_s', 'peak_power_w'):
        assert final[f'Result/{key}'] == result_json[key]
    for axis in 'XYZ':
        assert final[f'Result/{axis}/energy_j'] == result_json['energy_by_axis_j'][axis]
        assert final[f'Result/{axis}/peak_power_w'] is None     # not in the fake's result


def test_death_certificate_when_the_connection_drops_then_a_new_birth(
        broker_port, program_root):
    service = FakeJobService(program_root)
    topics = SparkplugTopics(group_id='g1', edge_node_id='e2', device_id='m1')
    sink = Sink(broker_port, 'spBv1.0/#')
    edge = SparkplugBridge(service, SparkplugSettings(host='127.0.0.1', port=broker_port,
                                                      topics=topics, keepalive_s=5))
    try:
        edge.start()
        sink.until(lambda t, b: t == 'spBv1.0/g1/DBIRTH/e2/m1')
        # the TCP connection breaks without an MQTT DISCONNECT: the broker sends the will
        edge._client.socket().shutdown(socket.SHUT_RDWR)
        topic, death, qos, retain = sink.until(lambda t, b: 'NDEATH' in t)
        assert topic == 'spBv1.0/g1/NDEATH/e2' and qos == 1 and not retain
        assert death.seq is None
        assert [(m.name, m.datatype, m.value) for m in death.metrics] == [
            ('bdSeq', SpDataType.INT64, 0)]
        # paho reconnects: a new session, bdSeq one more, births again from seq 0
        _, birth, _, _ = sink.until(lambda t, b: t == 'spBv1.0/g1/NBIRTH/e2', timeout=30)
        assert birth.seq == 0
        assert {m.name: m.value for m in birth.metrics}['bdSeq'] == 1
        _, dbirth, _, _ = sink.until(lambda t, b: t == 'spBv1.0/g1/DBIRTH/e2/m1')
        assert dbirth.seq == 1
        # a clean stop publishes the NDEATH of the current session before disconnecting
        edge.stop()
        _, death, _, _ = sink.until(lambda t, b: 'NDEATH' in t)
        assert {m.name: m.value for m in death.metrics} == {'bdSeq': 1}
    finally:
        edge.stop()
        sink.close()


def test_rebirth_on_ncmd_and_bad_commands_counted(broker_port, program_root):
    service = FakeJobService(program_root, samples=5)
    topics = SparkplugTopics(group_id='g1', edge_node_id='e3', device_id='m1')
    sink = Sink(broker_port, 'spBv1.0/#')
    ncmd = 'spBv1.0/g1/NCMD/e3'

    def command(name: str, datatype: int, value: Any) -> bytes:
        return encode_sparkplug(SpPayload(timestamp_ms=int(time.time() * 1e3), metrics=(
            SpMetric(name=name, alias=None, datatype=datatype, value=value),)))

    try:
        with SparkplugBridge(service, SparkplugSettings(host='127.0.0.1', port=broker_port,
                                                        topics=topics)) as edge:
            sink.until(lambda t, b: t == 'spBv1.0/g1/DBIRTH/e3/m1')
            assert service.start_job('job-r', 'b.ngc', 0.0)[0]
            service.wait()
            sink.until(_state_of('e3', 'ended'))
            # hostile and useless commands: counted, nothing else happens
            sink.publish(ncmd, b'\xff\xff\xff')
            sink.publish(ncmd, command(REBIRTH_METRIC, SpDataType.BOOLEAN, False))
            sink.publish(ncmd, command(REBIRTH_METRIC, SpDataType.STRING, 'yes'))
            sink.publish(ncmd, command('Node Control/Reboot', SpDataType.BOOLEAN, True))
            sink.publish(ncmd, command(REBIRTH_METRIC, SpDataType.BOOLEAN, True))
            for _ in range(50):   # a flood of requests right after: not a flood of births
                sink.publish(ncmd, command(REBIRTH_METRIC, SpDataType.BOOLEAN, True))
            _, nbirth, _, _ = sink.until(lambda t, b: t == 'spBv1.0/g1/NBIRTH/e3')
            assert nbirth.seq == 0
            assert {m.name: m.value for m in nbirth.metrics}['bdSeq'] == 0   # same session
            _, dbirth, _, _ = sink.until(lambda t, b: t == 'spBv1.0/g1/DBIRTH/e3/m1')
            assert dbirth.seq == 1
            values = {m.name: m.value for m in dbirth.metrics}
            assert values['Job/State'] == 'ended' and values['Result/JobId'] == 'job-r'
            assert values['Result/energy_j'] == service.result('job-r')['energy_j']
            assert _wait_for(lambda: sum(edge.drops.values()) == 54)
            assert edge.drops == {'bad_protobuf': 1, 'wrong_type': 2, 'unknown_metric': 1,
                                  'rate_limited': 50}
            assert edge.births == 2
            # data go on after the rebirth, counting from the DBIRTH
            assert service.start_job('job-s', 'a.ngc', 0.0)[0]
            _, first, _, _ = sink.until(lambda t, b: t == 'spBv1.0/g1/DDATA/e3/m1')
            assert first.seq == 2
            service.wait()
    finally:
        sink.close()


def _wait_for(condition, timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end and not condition():
        time.sleep(0.02)
    return condition()


def _state_of(edge: str, name: str):
    return lambda topic, body: (topic == f'spBv1.0/g1/DDATA/{edge}/m1' and any(
        m.value == name for m in body.metrics if m.datatype == SpDataType.STRING))


def test_an_unreachable_broker_is_our_error(program_root) -> None:
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        port = sock.getsockname()[1]
    edge = SparkplugBridge(FakeJobService(program_root), SparkplugSettings(
        host='127.0.0.1', port=port, topics=SparkplugTopics('g', 'e')))
    with pytest.raises(FeedAxisError, match='MQTT broker'):
        edge.start(timeout_s=2.0)
    with pytest.raises(ConfigError):
        SparkplugSettings(host='127.0.0.1', port=0, topics=SparkplugTopics('g', 'e'))


def test_docs_list_every_device_metric_with_its_unit() -> None:
    """docs/cell.md, "Sparkplug B": the metric table is the contract of device_metrics."""
    import re
    text = (Path(__file__).resolve().parents[2] / 'docs' / 'cell.md').read_text()
    section = text.split('### Sparkplug B', 1)[1].split('\n## ', 1)[0]
    rows = [line for line in section.splitlines()
            if line.startswith('| `Job/') or line.startswith('| `Live/')
            or line.startswith('| `Result/')]
    documented: dict[str, str] = {}
    for row in rows:
        cells = [c.strip() for c in row.strip('|').split('|')]
        names, last = [], ''
        for token in re.findall(r'`([^`]+)`', cells[0]):
            if token.startswith('.../'):
                token = last.rsplit('/', 1)[0] + token[3:]
            names.append(token)
            last = token
        units = [u.strip() for u in cells[2].split(',')] if cells[2] else ['']
        for k, name in enumerate(names):
            documented[name] = units[min(k, len(units) - 1)]
    generic = {}
    for name, _, unit in device_metrics(('X',)):
        if name.startswith('Live/'):
            name = name.replace('/X/', '/<part>/').replace('/total/', '/<part>/')
        name = name.replace('/X/', '/<axis>/')
        generic[name] = unit
    assert documented == generic
