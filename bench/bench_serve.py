"""``feed-axis-energy serve`` as a cell client sees it: OPC UA and MQTT latencies of jobs.

Starts mosquitto (free loopback port), ``serve`` (free OPC UA port, ``--mqtt``) and, in this
process, an OPC UA client subscribed to ``Energy/Total/AcActivePowerTotal`` and
``Results/LastJob/JobId`` (publishing interval ``--publish-ms``), an MQTT subscriber of
``job/result`` and a ROS subscriber of the graph's own ``job/result``. Then N jobs in a row
through ``StartJob``; per job:

* ``StartJob`` -> first power sample: from just before the method call to the arrival of the
  first ``AcActivePowerTotal`` data change after it (includes the call, planning, the graph's
  start and the bridge);
* job end -> result visible: from the arrival of the graph's ``job/result`` at the ROS
  subscriber here (the moment the job has ended in the graph) to the arrival of the
  ``LastJob/JobId`` data change naming the job (OPC UA) and of the MQTT ``job/result``
  message naming it.

Every time is ``time.time_ns()`` at arrival in this process. Prints per-job lines and
p50 / p90 / max; each job's ``energy_j`` is checked against ``simulate --json`` of the same
program once (relative difference printed); the RSS of ``serve`` and each of its nodes after
job 10 and after the last job. Figures: README "Benchmarks", docs/cell.md.

    PYTHONPATH=. .venv/bin/python bench/bench_serve.py [--jobs 10] [--mode realtime|fast]
        [--publish-ms 10] [--domain-id 209]
"""
from __future__ import annotations

import argparse
import asyncio
import json
import os
from pathlib import Path
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'test' / 'bridge'))
from brokers import mosquitto, mosquitto_binary  # noqa: E402

PROGRAM = 'G21 G90 G94 G61\nG0 X0\nG1 X100 F3000\nG4 P0.2\nG1 X80 F3000\n'
MACHINE = 'three_axis_mill_drives.yaml'
BASE = 'feed_axis_energy/machine'


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def _stats(name: str, values_ms: list[float]) -> str:
    if not values_ms:
        return f'{name}: no values'
    values = sorted(values_ms)
    p90 = values[min(len(values) - 1, int(round(0.9 * (len(values) - 1))))]
    return (f'{name}: p50 {statistics.median(values):.1f} ms, p90 {p90:.1f} ms, '
            f'max {values[-1]:.1f} ms (n={len(values)})')


class _RosResults:
    """The graph's own job/result, arrival time per job (a spinning thread)."""

    def __init__(self, domain_id: int) -> None:
        import rclpy
        from rclpy.context import Context
        from std_msgs.msg import String
        from feed_axis_energy.nodes.qos import job_qos
        from feed_axis_energy.nodes.runner import make_executor
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node('bench_serve', context=self.context)
        self.arrived: dict[str, int] = {}
        self.node.create_subscription(String, 'job/result', self._on_result, job_qos())
        self.ex = make_executor(context=self.context)
        self.ex.add_node(self.node)
        self.stop = False
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _on_result(self, msg) -> None:
        t = time.time_ns()
        self.arrived.setdefault(json.loads(msg.data)['job_id'], t)

    def _spin(self) -> None:
        while not self.stop:
            self.ex.spin_once(timeout_sec=0.02)

    def close(self) -> None:
        import rclpy
        self.stop = True
        self.thread.join(5)
        self.ex.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


class _MqttResults:
    def __init__(self, port: int) -> None:
        import paho.mqtt.client as paho
        self.arrived: dict[str, int] = {}
        ready = threading.Event()
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id='bench-serve')
        self.client.on_connect = lambda c, *a: c.subscribe(f'{BASE}/job/result', qos=1)
        self.client.on_subscribe = lambda *a: ready.set()
        self.client.on_message = self._on_message
        self.client.connect('127.0.0.1', port)
        self.client.loop_start()
        assert ready.wait(10), 'no SUBACK from mosquitto'

    def _on_message(self, client, userdata, message) -> None:
        t = time.time_ns()
        self.arrived.setdefault(json.loads(message.payload)['job_id'], t)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


class _Changes:
    """asyncua data-change handler: (arrival ns, value) per node."""

    def __init__(self) -> None:
        self.power: list[tuple[int, float]] = []
        self.last_id: list[tuple[int, str]] = []
        self.nodes: dict[str, object] = {}

    def datachange_notification(self, node, value, data) -> None:
        t = time.time_ns()
        if node == self.nodes['power']:
            self.power.append((t, value))
        else:
            self.last_id.append((t, value))


def _rss_mib(serve_pid: int) -> dict[str, float]:
    """Resident memory of serve's processes [MiB], by node name ('serve' for itself)."""
    from feed_axis_energy.lifeline import child_processes
    out = {}
    for pid, cmd in [(serve_pid, 'serve')] + child_processes(serve_pid):
        name = cmd.split('feed_axis_energy.nodes.')[-1].split()[0] if 'nodes.' in cmd \
            else 'serve'
        try:
            for line in Path(f'/proc/{pid}/status').read_text().splitlines():
                if line.startswith('VmRSS:'):
                    out[name] = int(line.split()[1]) / 1024
        except OSError:
            pass
    return out


async def _jobs(endpoint: str, n: int, publish_ms: float, ros: _RosResults,
                mqtt: _MqttResults, timeout_s: float, serve_pid: int) -> list[dict]:
    from asyncua import Client
    client = Client(endpoint, timeout=30)
    client.session_timeout = 600_000
    await client.connect()
    rows = []
    try:
        idx = await client.get_namespace_index('urn:feed-axis-energy:cell')
        root = await client.nodes.objects.get_child([f'{idx}:FeedAxisEnergy'])
        jobs = await root.get_child(f'{idx}:Jobs')
        results = await root.get_child(f'{idx}:Results')
        power = await root.get_child([f'{idx}:Energy', f'{idx}:Total',
                                      f'{idx}:AcActivePowerTotal'])
        last_id = await results.get_child([f'{idx}:LastJob', f'{idx}:JobId'])
        changes = _Changes()
        changes.nodes = {'power': power, 'last_id': last_id}
        sub = await client.create_subscription(publish_ms, changes)
        await sub.subscribe_data_change([power, last_id])
        await asyncio.sleep(1.0)
        prefix = f'b{os.getpid()}'
        for k in range(1, n + 1):
            job = f'{prefix}-{k}'
            t_call = time.time_ns()
            accepted, message = await jobs.call_method(f'{idx}:StartJob', job, 'short.nc', 0.0)
            assert accepted, message
            end = time.monotonic() + timeout_s
            while not any(j == job for _, j in changes.last_id) \
                    or job not in mqtt.arrived or job not in ros.arrived:
                if time.monotonic() > end:
                    raise SystemExit(f'job {job}: no result within {timeout_s:g} s')
                await asyncio.sleep(0.01)
            first_power = next(t for t, _ in changes.power if t > t_call)
            t_ros = ros.arrived[job]
            t_ua = next(t for t, j in changes.last_id if j == job)
            found, text, _ = await results.call_method(f'{idx}:GetResult', job)
            result = json.loads(text)
            rows.append({'job': job, 'start_to_power_ms': (first_power - t_call) / 1e6,
                         'end_to_opcua_ms': (t_ua - t_ros) / 1e6,
                         'end_to_mqtt_ms': (mqtt.arrived[job] - t_ros) / 1e6,
                         'energy_j': result['energy_j'], 'status': result['status']})
            if k == min(10, n) or k == n:
                rows[-1]['rss_mib'] = _rss_mib(serve_pid)
            r = rows[-1]
            print(f"{job}: {r['status']}, {r['energy_j']:.6f} J; StartJob -> first power "
                  f"{r['start_to_power_ms']:.1f} ms; job end -> OPC UA LastJob "
                  f"{r['end_to_opcua_ms']:.1f} ms, -> MQTT job/result "
                  f"{r['end_to_mqtt_ms']:.1f} ms", flush=True)
            await asyncio.sleep(0.2)
    finally:
        await client.disconnect()
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--jobs', type=int, default=10)
    parser.add_argument('--mode', choices=('realtime', 'fast'), default='realtime')
    parser.add_argument('--publish-ms', type=float, default=10.0,
                        help='OPC UA publishing interval of the client subscription')
    parser.add_argument('--domain-id', type=int, default=209)
    args = parser.parse_args()
    if mosquitto_binary() is None:
        raise SystemExit('mosquitto is not installed (apt-get install mosquitto)')
    from feed_axis_energy.paths import config_dir
    machine = config_dir() / MACHINE
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED='1')
    with tempfile.TemporaryDirectory() as tmp_text:
        tmp = Path(tmp_text)
        root = tmp / 'programs'
        root.mkdir()
        (root / 'short.nc').write_text(PROGRAM)
        mqtt_port, opcua_port = _free_port(), _free_port()
        with mosquitto(tmp / 'broker', mqtt_port):
            serve = subprocess.Popen(
                [sys.executable, '-m', 'feed_axis_energy', 'serve', '--program-root', str(root),
                 '--machine', str(machine), '--mode', args.mode, '--opcua-port',
                 str(opcua_port), '--mqtt', f'127.0.0.1:{mqtt_port}', '--domain-id',
                 str(args.domain_id)], env=env, stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT, text=True)
            try:
                for line in serve.stdout:
                    print(line, end='')
                    if line.startswith('Ctrl-C'):
                        break
                else:
                    raise SystemExit('serve ended before it was ready')
                threading.Thread(target=lambda: [None for _ in serve.stdout],
                                 daemon=True).start()
                ros = _RosResults(args.domain_id)
                mqtt = _MqttResults(mqtt_port)
                try:
                    rows = asyncio.run(_jobs(f'opc.tcp://127.0.0.1:{opcua_port}/'
                                             'feed_axis_energy/', args.jobs, args.publish_ms,
                                             ros, mqtt, 120.0, serve.pid))
                finally:
                    mqtt.close()
                    ros.close()
            finally:
                serve.send_signal(signal.SIGINT)
                serve.wait(60)
        ref = subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'simulate',
                              str(root / 'short.nc'), '--json', '--machine', str(machine)],
                             env=env, capture_output=True, text=True, check=True)
    total = json.loads(ref.stdout)['energy_j']['total']
    worst = max(abs(r['energy_j'] / total - 1) for r in rows)
    load = os.getloadavg()
    print(f'\n{len(rows)} jobs, {args.mode} mode, OPC UA publishing interval '
          f'{args.publish_ms:g} ms, load average {load[0]:.1f} {load[1]:.1f}, '
          f'{time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}')
    print(_stats('StartJob -> first power sample (OPC UA data change)',
                 [r['start_to_power_ms'] for r in rows]))
    print(_stats('job end (graph job/result) -> OPC UA LastJob/JobId',
                 [r['end_to_opcua_ms'] for r in rows]))
    print(_stats('job end (graph job/result) -> MQTT job/result',
                 [r['end_to_mqtt_ms'] for r in rows]))
    print(f'energy_j against simulate --json: largest relative difference {worst:.1e}; '
          f"statuses {sorted({r['status'] for r in rows})}")
    marks = [r for r in rows if 'rss_mib' in r]
    if len(marks) == 2:
        first, last = marks
        print(f"RSS after job {rows.index(first) + 1} -> after job {len(rows)}: " + ', '.join(
            f"{name} {first['rss_mib'][name]:.1f} -> {last['rss_mib'].get(name, 0.0):.1f} MiB"
            for name in sorted(first['rss_mib'])))


if __name__ == '__main__':
    main()
