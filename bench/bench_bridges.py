"""Latency of the cell bridges: live power -> OPC UA data change and -> MQTT message.

    PYTHONPATH=. .venv/bin/python bench/bench_bridges.py [--seconds 60] [--rate-hz 100]
        [--subscribers 1,5,20] [--broker auto|mosquitto|amqtt]

This process runs the job service's test double (``test/bridge/fake_service.py``: one live
sample per ``1/rate`` s, each stamped with the wall clock when it is emitted), the OPC UA
server (``OpcUaThread``: its own thread and event loop) and the MQTT bridge, with mosquitto
(or amqtt) on a loopback port. A child process holds the clients: N asyncua clients, each
subscribed to ``Energy/Total/AcActivePowerTotal`` (sampling interval 0, publishing interval
``--publish-ms``), and one paho subscriber of ``<base>/power``. Each client's latency is its
arrival time minus the sample's stamp (the data change's ``SourceTimestamp``, the JSON's
``stamp``), on the same machine's wall clock. Prints p50/p99/max per transport and N, and
how many of the samples arrived (OPC UA may merge changes within one publishing interval).
A 10-minute soak is ``--seconds 600``.
"""
from __future__ import annotations

import argparse
import asyncio
import json
import logging
import multiprocessing as mp
from pathlib import Path
import socket
import sys
import tempfile
import time
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'test' / 'bridge'))

from brokers import amqtt_broker, mosquitto, mosquitto_binary  # noqa: E402
from fake_service import FakeJobService  # noqa: E402

from feed_axis_energy.bridge import (MqttBridge, MqttSettings, NAMESPACE_URI,  # noqa: E402
                                     OpcUaSettings, OpcUaThread, TopicTree)


def _free_port(low: int, high: int) -> int:
    for port in range(low, high + 1):
        with socket.socket() as sock:
            try:
                sock.bind(('127.0.0.1', port))
            except OSError:
                continue
            return port
    raise SystemExit(f'no free port in {low}-{high}')


def _clients(endpoint: str, n: int, mqtt_port: int, topic: str, publish_ms: float,
             ready: Any, stop: Any, out: Any) -> None:
    """Child process: n OPC UA subscribers and one MQTT subscriber; sends latencies back."""
    # a client whose server stops answering logs every publish retry; counted, not shown
    logging.getLogger('asyncua').setLevel(logging.CRITICAL)
    import paho.mqtt.client as paho
    from asyncua import Client

    mqtt_lat: list[float] = []

    def on_message(client: Any, userdata: Any, message: Any) -> None:
        now = time.time()
        mqtt_lat.append(now - json.loads(message.payload)['stamp'])

    sub = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id='')
    sub.on_message = on_message
    sub.connect('127.0.0.1', mqtt_port)
    sub.subscribe(topic, qos=0)
    sub.loop_start()

    class Handler:
        def __init__(self) -> None:
            self.lat: list[float] = []

        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            now = time.time()
            stamp = data.monitored_item.Value.SourceTimestamp
            if stamp is not None:
                self.lat.append(now - stamp.timestamp())

    async def main() -> list[list[float]]:
        clients, handlers = [], []
        for _ in range(n):
            client = Client(endpoint)
            await client.connect()
            idx = await client.get_namespace_index(NAMESPACE_URI)
            node = await client.nodes.objects.get_child(
                [f'{idx}:FeedAxisEnergy', f'{idx}:Energy', f'{idx}:Total',
                 f'{idx}:AcActivePowerTotal'])
            handler = Handler()
            subscription = await client.create_subscription(publish_ms, handler)
            await subscription.subscribe_data_change(node, sampling_interval=0,
                                                     queuesize=1000)
            clients.append(client)
            handlers.append(handler)
        ready.set()
        while not stop.is_set():
            await asyncio.sleep(0.1)
        await asyncio.sleep(0.5)
        for handler in handlers:
            handler.lat = handler.lat[1:]    # the value present at subscription time
        for client in clients:
            try:
                await client.disconnect()
            except Exception:   # a client the server dropped under load
                pass
        return [h.lat for h in handlers]

    opcua = asyncio.run(main())
    sub.loop_stop()
    sub.disconnect()
    out.send({'opcua': opcua, 'mqtt': mqtt_lat})


def _stats(values: list[float]) -> str:
    if not values:
        return 'nothing arrived'
    ms = np.asarray(values) * 1e3
    return (f'p50 {np.percentile(ms, 50):7.2f} ms  p99 {np.percentile(ms, 99):7.2f} ms  '
            f'max {ms.max():7.2f} ms')


def _round(n: int, args: argparse.Namespace, mqtt_port: int, programs: Path) -> None:
    samples = int(args.seconds * args.rate_hz)
    service = FakeJobService(programs, samples=samples, period_s=1.0 / args.rate_hz)
    server = OpcUaThread(service, OpcUaSettings(port=_free_port(48490, 48499)))
    server.start()
    bridge = server.bridge
    tree = TopicTree(machine='bench')
    ctx = mp.get_context('spawn')
    ready, stop = ctx.Event(), ctx.Event()
    recv, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=_clients, args=(bridge.endpoint, n, mqtt_port, tree.power,
                                               args.publish_ms, ready, stop, send))
    try:
        with MqttBridge(service, MqttSettings(port=mqtt_port, topics=tree)):
            child.start()
            if not ready.wait(300):
                raise SystemExit('the clients did not connect')
            time.sleep(0.5)
            start = time.monotonic()
            accepted, message = service.start_job('bench', 'a.ngc', 0.0)
            assert accepted, message
            service.wait(args.seconds * 3 + 60)
            wall = time.monotonic() - start
            time.sleep(1.0)
            stop.set()
            got = recv.recv()
            child.join(60)
    finally:
        server.stop()
    sent = service.result('bench')['samples']
    opcua = [x for lat in got['opcua'] for x in lat]
    per = [len(lat) for lat in got['opcua']]
    print(f'{n:2d} OPC UA subscriber(s), {sent} samples at {args.rate_hz:g} Hz in {wall:.1f} s '
          f'(dropped by the bridge: {bridge.dropped_events})')
    print(f'   OPC UA data change: {_stats(opcua)}  arrived {min(per)}-{max(per)} of {sent} '
          f'per subscriber')
    print(f'   MQTT message:       {_stats(got["mqtt"])}  arrived {len(got["mqtt"])} of {sent}')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--seconds', type=float, default=60.0, help='length of each round [s]')
    parser.add_argument('--rate-hz', type=float, default=100.0, help='live samples per second')
    parser.add_argument('--subscribers', default='1,5,20', help='OPC UA subscribers per round')
    parser.add_argument('--publish-ms', type=float, default=10.0,
                        help='requested OPC UA publishing interval [ms]')
    parser.add_argument('--broker', choices=('auto', 'mosquitto', 'amqtt'), default='auto')
    args = parser.parse_args()
    logging.getLogger('asyncua').setLevel(logging.ERROR)
    counts = [int(x) for x in args.subscribers.split(',') if x]
    kind = args.broker
    if kind == 'auto':
        kind = 'mosquitto' if mosquitto_binary() else 'amqtt'
    port = _free_port(18890, 18899)
    with tempfile.TemporaryDirectory(prefix='fae-bench-bridges-') as tmp:
        programs = Path(tmp) / 'programs'
        programs.mkdir()
        (programs / 'a.ngc').write_text('M2\n')
        broker = mosquitto(Path(tmp) / 'broker', port) if kind == 'mosquitto' \
            else amqtt_broker(port)
        with broker:
            print(f'broker: {kind} on 127.0.0.1:{port}; OPC UA publishing interval requested '
                  f'{args.publish_ms:g} ms; {time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}')
            for n in counts:
                _round(n, args, port, programs)


if __name__ == '__main__':
    main()
