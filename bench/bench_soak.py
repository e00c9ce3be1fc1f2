"""Real-time soak of the job graph with and without the cell bridges: live latency, lost samples.

    PYTHONPATH=. .venv/bin/python bench/bench_soak.py [--seconds 600] [--subscribers 1,5,20]
        [--publish-ms 10] [--domain-ids 180-189] [--no-baseline | --interleave PAIRS]

One long real-time job per round: a reciprocating program (X 0 <-> 100 mm at 3 m/min, generated
into a temporary folder, as many strokes as last ``--seconds``) on the 3-axis mill with
drives. Rounds, one after another in the same sitting:

(a) the graph alone: ``feed-axis-energy launch --program-root DIR --mode realtime``;
(b..) ``feed-axis-energy serve --mqtt`` (graph + ``opcua_bridge`` with the MQTT bridge, mosquitto
    on a free loopback port) with an MQTT subscriber of ``<base>/power`` and N OPC UA
    subscribers (``--subscribers``), each its own asyncua client session; the sessions run in
    child processes of at most 5 sessions each, and each child reports its own event-loop lag
    and CPU time so that a slow client side shows up as such.

With ``--interleave PAIRS`` the rounds alternate instead: a1, b1, a2, b2, ... (a: the graph
alone; b: with the bridges, taking the ``--subscribers`` counts in turn), so that a load that
drifts over the sitting falls on both kinds alike; the 1-minute load average is sampled every
5 s during each job, and a summary at the end gives per round and pooled (a rounds, b rounds)
p50 / p99 / max of the graph's own latency, raw and centred on each round's median (each
round's stamps carry its first batch's delay), lost samples and missing ``job/live``
messages, and the paired difference of the spread p99 - p50.

Every round starts its job over ``job/command`` from this process (the same way in every
round) and measures, per sample, on this machine's wall clock:

* graph: ``job/live`` ``stamp_ns`` -> arrival at a ROS subscriber in this process (the graph's
  own latency; ``job/live`` is sent only while it has a subscriber, and this one exists in
  every round), the ``job/live`` messages missing (gaps in ``samples``) and the result's
  ``samples``/``lost_samples``/``status``;
* OPC UA: ``SourceTimestamp`` of each ``Energy/Total/AcActivePowerTotal`` data change -> its
  arrival (monitored item with trigger StatusValueTimestamp, so a repeated value is a change);
* MQTT: ``stamp`` of each ``power`` message -> its arrival.

Latencies go into log-spaced histograms (1.2 % wide bins, 10 us to 1000 s; percentiles are
the bin's upper edge), so memory does not grow with ``--seconds``. Prints per round p50 / p99
/ max and counts, the RSS of every process of the graph (and of mosquitto) at the job's start
and end, and the load average. Figures: docs/cell.md ("Soak"), README "In the machine cell".
"""
from __future__ import annotations

import argparse
import asyncio
from datetime import timezone
import json
import logging
import math
import multiprocessing as mp
import os
from pathlib import Path
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'test' / 'bridge'))

from brokers import mosquitto, mosquitto_binary  # noqa: E402

MACHINE = 'three_axis_mill_drives.yaml'
BASE = 'feed_axis_energy/machine'
NAMESPACE = 'urn:feed-axis-energy:cell'
HEADER = 'G21 G90 G94 G61\nG0 X0\n'
STROKES = 'G1 X100 F3000\nG1 X0 F3000\n'
CLIENTS_PER_PROCESS = 5
# raw job/live latencies kept per round for the interleaved summary (one per 0.1 s batch:
# 10 000 cover 16 minutes); beyond, only the histogram
RAW_CAP = 10_000


class Hist:
    """Signed latency histogram [s]: log-spaced bins of |x| on each side, exact count and max.

    Bins are 1.2 % wide from 1 us to 1000 s; a quantile is reported as the bin's edge farther
    from -inf (so the figure is never earlier than the samples it stands for).
    """

    EDGES = np.geomspace(1e-6, 1e3, 1801)

    def __init__(self) -> None:
        self.pos = np.zeros(self.EDGES.size + 1, dtype=np.int64)
        self.neg = np.zeros(self.EDGES.size + 1, dtype=np.int64)
        self.n = 0
        self.max = -math.inf
        self.min = math.inf

    def add(self, latency_s: float) -> None:
        self.n += 1
        self.max = max(self.max, latency_s)
        self.min = min(self.min, latency_s)
        side = self.pos if latency_s >= 0 else self.neg
        side[int(np.searchsorted(self.EDGES, abs(latency_s)))] += 1

    def merge(self, other: 'Hist') -> None:
        self.pos += other.pos
        self.neg += other.neg
        self.n += other.n
        self.max = max(self.max, other.max)
        self.min = min(self.min, other.min)

    def quantile(self, q: float) -> float:
        """The q-quantile [s], to a bin (its edge towards +inf)."""
        if self.n == 0:
            return math.nan
        target = q * self.n
        # negative side first, from the largest magnitude down
        below = np.cumsum(self.neg[::-1])
        if below[-1] >= target and below[-1] > 0:
            k = self.neg.size - 1 - int(np.searchsorted(below, target, side='left'))
            return -float(self.EDGES[k - 1]) if k > 0 else 0.0
        above = np.cumsum(self.pos)
        k = int(np.searchsorted(above, target - below[-1], side='left'))
        return float(self.EDGES[min(k, self.EDGES.size - 1)])

    def text(self, shift_s: float = 0.0) -> str:
        """p50 / p99 / max of (x + shift_s) and the count."""
        if self.n == 0:
            return 'nothing arrived'
        return (f'p50 {_ms(self.quantile(0.5) + shift_s)}  '
                f'p99 {_ms(self.quantile(0.99) + shift_s)}  max {_ms(self.max + shift_s)}')

    def state(self) -> dict[str, Any]:
        return {'pos': self.pos.tolist(), 'neg': self.neg.tolist(), 'n': self.n,
                'max': self.max, 'min': self.min}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> 'Hist':
        h = cls()
        h.pos = np.asarray(state['pos'], dtype=np.int64)
        h.neg = np.asarray(state['neg'], dtype=np.int64)
        h.n, h.max, h.min = state['n'], state['max'], state['min']
        return h


def _ms(seconds: float) -> str:
    ms = seconds * 1e3
    return f'{ms:.0f} ms' if abs(ms) >= 100 else f'{ms:.1f} ms'


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def _rss_mib(pid: int) -> float | None:
    try:
        for line in Path(f'/proc/{pid}/status').read_text().splitlines():
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024
    except OSError:
        return None
    return None


def _cpu_s(pid: int) -> float | None:
    """User + system CPU time of a process so far [s] (/proc/PID/stat), or None."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def _processes(top: int, label: str) -> dict[str, int]:
    """``label`` (launch or serve) and each node process below it, by node name."""
    from feed_axis_energy.lifeline import child_processes
    out = {label: top}
    for pid, cmd in child_processes(top):
        if 'feed_axis_energy.nodes.' in cmd:
            out[cmd.split('feed_axis_energy.nodes.')[-1].split()[0]] = pid
    return out


# --- OPC UA subscribers (child processes) ---------------------------------------------------

def _ua_clients(endpoint: str, n: int, publish_ms: float, ready: Any, stop: Any,
                out: Any) -> None:
    """Child process: n asyncua sessions on AcActivePowerTotal; sends histograms back."""
    logging.getLogger('asyncua').setLevel(logging.CRITICAL)
    from asyncua import Client, ua

    class Handler:
        def __init__(self) -> None:
            self.hist = Hist()

        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            now = time.time()
            stamp = data.monitored_item.Value.SourceTimestamp
            if stamp is None:
                return
            if stamp.tzinfo is None:
                stamp = stamp.replace(tzinfo=timezone.utc)
            self.hist.add(now - stamp.timestamp())

    async def lag_probe(hist: Hist) -> None:
        # the loop's own lateness: a client side that cannot keep up shows here
        while not stop.is_set():
            t0 = time.monotonic()
            await asyncio.sleep(0.05)
            hist.add(time.monotonic() - t0 - 0.05)

    async def main() -> dict[str, Any]:
        clients, handlers = [], []
        for k in range(n):
            client = Client(endpoint, timeout=60)
            client.session_timeout = 3_600_000
            await client.connect()
            idx = await client.get_namespace_index(NAMESPACE)
            node = await client.nodes.objects.get_child(
                [f'{idx}:FeedAxisEnergy', f'{idx}:Energy', f'{idx}:Total',
                 f'{idx}:AcActivePowerTotal'])
            handler = Handler()
            sub = await client.create_subscription(publish_ms, handler)
            params = ua.MonitoringParameters(
                ClientHandle=1000 + k, SamplingInterval=0.0, QueueSize=1000,
                DiscardOldest=True,
                Filter=ua.DataChangeFilter(Trigger=ua.DataChangeTrigger.StatusValueTimestamp))
            request = ua.MonitoredItemCreateRequest(
                ItemToMonitor=ua.ReadValueId(NodeId=node.nodeid,
                                             AttributeId=ua.AttributeIds.Value),
                MonitoringMode=ua.MonitoringMode.Reporting, RequestedParameters=params)
            results = await sub.create_monitored_items([request])
            assert isinstance(results[0], int), results
            clients.append(client)
            handlers.append(handler)
        await asyncio.sleep(1.0)
        for handler in handlers:     # the value present at subscription time
            handler.hist = Hist()
        lag = Hist()
        probe = asyncio.create_task(lag_probe(lag))
        cpu0 = time.process_time()
        t0 = time.monotonic()
        ready.set()
        while not stop.is_set():
            await asyncio.sleep(0.1)
        cpu = time.process_time() - cpu0
        wall = time.monotonic() - t0
        await probe
        lost = 0
        for client in clients:
            try:
                await client.disconnect()
            except Exception:   # a session the server dropped under load
                lost += 1
        return {'hists': [h.hist.state() for h in handlers], 'lag': lag.state(),
                'cpu_s': cpu, 'wall_s': wall, 'disconnect_failed': lost,
                'rss_mib': _rss_mib(os.getpid())}

    try:
        out.send(asyncio.run(main()))
    except Exception as exc:   # reported by the parent, which then stops
        out.send({'error': repr(exc)})


class UaSubscribers:
    """N sessions in ceil(N/5) child processes."""

    def __init__(self, endpoint: str, n: int, publish_ms: float) -> None:
        ctx = mp.get_context('spawn')
        self.stop = ctx.Event()
        self.children = []
        left = n
        while left > 0:
            k = min(CLIENTS_PER_PROCESS, left)
            left -= k
            ready = ctx.Event()
            recv, send = ctx.Pipe(duplex=False)
            proc = ctx.Process(target=_ua_clients,
                               args=(endpoint, k, publish_ms, ready, self.stop, send))
            proc.start()
            self.children.append((proc, ready, recv))
        for proc, ready, recv in self.children:
            end = time.monotonic() + 300
            while not ready.wait(0.5):
                if recv.poll():
                    raise SystemExit(f'OPC UA clients failed: {recv.recv()}')
                if time.monotonic() > end or not proc.is_alive():
                    raise SystemExit('the OPC UA clients did not connect')

    def pids(self) -> list[int]:
        return [p.pid for p, _, _ in self.children if p.pid is not None]

    def finish(self) -> list[dict[str, Any]]:
        self.stop.set()
        out = []
        for proc, _, recv in self.children:
            if recv.poll(120):
                out.append(recv.recv())
            proc.join(30)
            if proc.is_alive():
                proc.kill()
        return out


# --- the ROS side: job/live, job/result, job/command ------------------------------------------

class RosSide:
    """A node in this process: job/live histogram and gaps, job/result, start command."""

    def __init__(self, domain_id: int) -> None:
        import rclpy
        from rclpy.context import Context
        from std_msgs.msg import String
        from feed_axis_energy.nodes.qos import command_qos, job_qos
        from feed_axis_energy.nodes.runner import make_executor
        self.String = String
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node('bench_soak', context=self.context)
        self.hist = Hist()
        self.raw: list[float] = []
        self.job = ''
        self.messages = 0
        self.increments: dict[int, int] = {}
        self.last_samples = 0
        self.last_time_s = 0.0
        self.dt_s = 0.0
        self.results: dict[str, dict] = {}
        self.pub = self.node.create_publisher(String, 'job/command', command_qos())
        self.node.create_subscription(String, 'job/live', self._on_live, command_qos())
        self.node.create_subscription(String, 'job/result', self._on_result, job_qos())
        self.ex = make_executor(context=self.context)
        self.ex.add_node(self.node)
        self.stopped = False
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _on_live(self, msg: Any) -> None:
        now = time.time_ns()
        d = json.loads(msg.data)
        if d['job_id'] != self.job:
            return
        latency_s = (now - d['stamp_ns']) * 1e-9
        self.hist.add(latency_s)
        if len(self.raw) < RAW_CAP:
            self.raw.append(latency_s)
        self.messages += 1
        step = d['samples'] - self.last_samples
        if step > 0 and self.last_samples > 0:
            self.dt_s = (d['time_s'] - self.last_time_s) / step
        self.last_samples, self.last_time_s = d['samples'], d['time_s']
        if len(self.increments) < 1000 or step in self.increments:
            self.increments[step] = self.increments.get(step, 0) + 1

    def _on_result(self, msg: Any) -> None:
        d = json.loads(msg.data)
        self.results[d['job_id']] = d

    def _spin(self) -> None:
        while not self.stopped:
            self.ex.spin_once(timeout_sec=0.02)

    def graph_ready(self) -> bool:
        return (self.pub.get_subscription_count() >= 1
                and self.node.count_publishers('job/live') >= 1
                and self.node.count_publishers('job/result') >= 1)

    def start(self, job: str, program: str) -> None:
        self.job = job
        body = {'command': 'start', 'job_id': job, 'program': program, 'load_kg': 0.0}
        self.pub.publish(self.String(data=json.dumps(body)))

    def missing(self) -> tuple[int, int]:
        """(job/live messages missing by gaps in ``samples``, the usual batch size)."""
        if not self.increments:
            return 0, 0
        batch = max(self.increments, key=lambda k: self.increments[k])
        gone = sum(count * (math.ceil(step / batch) - 1)
                   for step, count in self.increments.items() if step > batch)
        return gone, batch

    def close(self) -> None:
        import rclpy
        self.stopped = True
        self.thread.join(5)
        self.ex.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


class MqttPower:
    """paho subscriber of ``<base>/power``: stamp -> arrival histogram."""

    def __init__(self, port: int) -> None:
        import paho.mqtt.client as paho
        self.hist = Hist()
        self.job = ''
        ready = threading.Event()
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id='bench-soak')
        self.client.on_connect = lambda c, *a: c.subscribe(f'{BASE}/power', qos=0)
        self.client.on_subscribe = lambda *a: ready.set()
        self.client.on_message = self._on_message
        self.client.connect('127.0.0.1', port)
        self.client.loop_start()
        if not ready.wait(20):
            raise SystemExit('no SUBACK from mosquitto')

    def _on_message(self, client: Any, userdata: Any, message: Any) -> None:
        now = time.time()
        d = json.loads(message.payload)
        if d.get('job_id') == self.job:
            self.hist.add(now - d['stamp'])

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


# --- one round --------------------------------------------------------------------------------

def _drain(proc: subprocess.Popen) -> None:
    assert proc.stdout is not None
    threading.Thread(target=lambda: [None for _ in proc.stdout], daemon=True).start()


def _round(label: str, n_ua: int | None, args: argparse.Namespace, root: Path, machine: Path,
           domain_id: int, mqtt_port: int, broker_pid: int | None,
           duration_s: float) -> dict[str, Any]:
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED='1')
    base = [sys.executable, '-m', 'feed_axis_energy']
    common = ['--program-root', str(root), '--machine', str(machine), '--mode', 'realtime',
              '--domain-id', str(domain_id)]
    if n_ua is None:
        cmd, top = base + ['launch'] + common, 'launch'
    else:
        cmd = base + ['serve'] + common + ['--opcua-port', str(_free_port()),
                                           '--mqtt', f'127.0.0.1:{mqtt_port}']
        if args.bridge_nice is not None:
            cmd += ['--bridge-nice', str(args.bridge_nice)]
        top = 'serve'
    extra = '' if n_ua is None else f' + MQTT subscriber + {n_ua} OPC UA subscriber(s)'
    print(f'\n== round {label}: {top}{extra} (domain {domain_id}; '
          f'{time.strftime("%H:%M:%S UTC", time.gmtime())})', flush=True)
    t_launch = time.monotonic()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    ros: RosSide | None = None
    mqtt: MqttPower | None = None
    ua_subs: UaSubscribers | None = None
    ua_out: list[dict[str, Any]] = []
    try:
        endpoint = ''
        if n_ua is not None:
            assert proc.stdout is not None
            for line in proc.stdout:
                if 'OPC UA opc.tcp://' in line:
                    endpoint = line.split('OPC UA ')[1].split()[0]
                if line.startswith('Ctrl-C'):
                    break
            else:
                raise SystemExit(f'serve ended before it was ready (exit {proc.wait()})')
        _drain(proc)
        ros = RosSide(domain_id)
        end = time.monotonic() + 180
        while not (ros.graph_ready() and len(_processes(proc.pid, top)) >= 4):
            if time.monotonic() > end or proc.poll() is not None:
                raise SystemExit(f'{top} not ready (exit {proc.poll()})')
            time.sleep(0.1)
        if n_ua is not None:
            mqtt = MqttPower(mqtt_port)
            ua_subs = UaSubscribers(endpoint, n_ua, args.publish_ms)
        time.sleep(1.0)      # the estimator sees our job/live reader
        ready_s = time.monotonic() - t_launch
        procs = _processes(proc.pid, top)
        procs['bench'] = os.getpid()
        if broker_pid is not None and n_ua is not None:
            procs['mosquitto'] = broker_pid
        if ua_subs is not None:
            procs.update({f'ua_clients[{i}]': pid for i, pid in enumerate(ua_subs.pids())})
        rss0 = {name: _rss_mib(pid) for name, pid in procs.items()}
        cpu0 = {name: _cpu_s(pid) for name, pid in procs.items()}
        load0 = os.getloadavg()
        job = f'soak-{label}-{os.getpid()}'
        if mqtt is not None:
            mqtt.job = job
        t0 = time.monotonic()
        ros.start(job, 'soak.nc')
        deadline = t0 + duration_s * 1.5 + 120
        loads: list[float] = []
        next_load = t0
        while job not in ros.results:
            if time.monotonic() >= next_load:     # the 1-minute load average every 5 s
                loads.append(os.getloadavg()[0])
                next_load += 5.0
            if time.monotonic() > deadline:
                raise SystemExit(f'round {label}: no result within {deadline - t0:.0f} s')
            if proc.poll() is not None:
                raise SystemExit(f'round {label}: {top} died (exit {proc.returncode})')
            time.sleep(0.2)
        wall = time.monotonic() - t0
        time.sleep(1.0)      # data changes and MQTT messages still under way
        rss1 = {name: _rss_mib(pid) for name, pid in procs.items()}
        cpu1 = {name: _cpu_s(pid) for name, pid in procs.items()}
        load1 = os.getloadavg()
        if ua_subs is not None:
            ua_out = ua_subs.finish()
            ua_subs = None
    finally:
        if ua_subs is not None:
            ua_subs.finish()
        if mqtt is not None:
            mqtt.close()
        if ros is not None:
            ros.close()
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)
    res = ros.results[job]
    gone, batch = ros.missing()
    print(f'job {res["status"]} ({res["message"]}): {res["duration_s"]:.1f} s of samples in '
          f'{wall:.1f} s wall, {res["samples"]} samples, lost_samples {res["lost_samples"]}, '
          f'energy {res["energy_j"].get("total", math.nan):.3f} J; ready {ready_s:.1f} s after '
          f'start; load average {load0[0]:.1f} at the start, {load1[0]:.1f} at the end '
          f'(5-min {load1[1]:.1f}; 1-min every 5 s during the job: mean '
          f'{np.mean(loads) if loads else math.nan:.1f}, '
          f'{min(loads, default=math.nan):.1f}-{max(loads, default=math.nan):.1f})')
    expected = math.ceil(res['samples'] / batch) if batch else 0
    # stamps: the job's first batch anchors simulation time 0 to the wall clock when it reaches
    # energy_estimator, and a message carries its batch's last sample: raw figures are
    # relative to that first batch, about -(batch - 1) samples when every batch is as fast
    print(f'  graph  job/live -> ROS subscriber:  {ros.hist.text()}; {ros.messages} of '
          f'~{expected} messages ({batch} samples each, span {_ms((batch - 1) * ros.dt_s)}), '
          f'{gone} missing by gaps in samples')
    if mqtt is not None:
        print(f'  MQTT   power -> arrival:            {mqtt.hist.text()}; '
              f'{mqtt.hist.n} of {ros.messages} job/live messages')
    if n_ua is not None:
        errors = [o['error'] for o in ua_out if 'error' in o]
        if errors:
            print(f'  OPC UA client process errors: {errors}')
        ok = [o for o in ua_out if 'error' not in o]
        total, lag = Hist(), Hist()
        per = []
        for o in ok:
            for state in o['hists']:
                h = Hist.from_state(state)
                per.append(h.n)
                total.merge(h)
            lag.merge(Hist.from_state(o['lag']))
        cpu = sum(o['cpu_s'] for o in ok)
        wall_c = max((o['wall_s'] for o in ok), default=math.nan)
        print(f'  OPC UA SourceTimestamp -> data change: {total.text()}; '
              f'{total.n} in all, per session '
              f'{min(per, default=0)}-{max(per, default=0)} of {ros.messages}')
        print(f'  OPC UA client side: {len(ok)} process(es), CPU {cpu:.1f} s in {wall_c:.0f} s '
              f'({100 * cpu / wall_c:.1f} % of one core), event-loop lag p99 '
              f'{_ms(lag.quantile(0.99))} max {_ms(lag.max)}; failed disconnects '
              f'{sum(o["disconnect_failed"] for o in ok)}')
    print('  RSS start -> end: ' + ', '.join(
        f'{name} {_fmt(rss0.get(name))} -> {_fmt(rss1.get(name))} MiB' for name in rss0))
    print('  CPU during the job: ' + ', '.join(
        f'{name} {_cpu_pct(cpu0.get(name), cpu1.get(name), wall)}' for name in cpu0)
        + ' (% of one core)', flush=True)
    return {'label': label, 'subscribers': n_ua, 'hist': ros.hist, 'raw': ros.raw,
            'missing': gone,
            'messages': ros.messages, 'expected': expected, 'lost_samples': res['lost_samples'],
            'samples': res['samples'], 'status': res['status'],
            'load': (load0[0], load1[0], load1[1]),
            'load_mean': float(np.mean(loads)) if loads else load0[0],
            'load_range': (min(loads, default=load0[0]), max(loads, default=load0[0]))}


def _cpu_pct(start: float | None, end: float | None, wall_s: float) -> str:
    return '?' if start is None or end is None else f'{100 * (end - start) / wall_s:.1f}'


def _fmt(value: float | None) -> str:
    return '?' if value is None else f'{value:.1f}'


def _program(root: Path, seconds: float, machine: Path) -> float:
    """Write ``soak.nc`` lasting >= seconds; returns its duration from ``simulate --json``."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))

    def duration(pairs: int) -> float:
        path = root / 'soak.nc'
        path.write_text(HEADER + STROKES * pairs + 'M2\n')
        out = subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'simulate', str(path),
                              '--json', '--machine', str(machine)], env=env,
                             capture_output=True, text=True, timeout=600)
        if out.returncode:
            raise SystemExit(f'simulate failed: {out.stderr}')
        return float(json.loads(out.stdout)['duration_s'])

    per_pair = duration(4) / 4
    pairs = max(1, math.ceil(seconds / per_pair))
    return duration(pairs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--seconds', type=float, default=600.0,
                        help='length of each round\'s real-time job [s] (default 600)')
    parser.add_argument('--subscribers', default='1,5,20',
                        help='OPC UA subscribers per bridge round (default 1,5,20)')
    parser.add_argument('--publish-ms', type=float, default=10.0,
                        help='requested OPC UA publishing interval [ms] (default 10)')
    parser.add_argument('--domain-ids', default='180-189', metavar='LO-HI',
                        help='ROS domain ids, one per round (default 180-189)')
    parser.add_argument('--bridge-nice', type=int, default=None, metavar='N',
                        help="serve's --bridge-nice for the b rounds (default: serve's own)")
    parser.add_argument('--no-baseline', action='store_true',
                        help='skip round (a), the graph without bridges')
    parser.add_argument('--interleave', type=int, default=0, metavar='PAIRS',
                        help='PAIRS x (a, b) alternated: a the graph alone, b the graph with '
                        'the bridges, b taking the --subscribers counts in turn; prints a '
                        'per-round and pooled summary of the graph\'s own latency')
    args = parser.parse_args()
    try:
        counts = [int(x) for x in args.subscribers.split(',') if x]
        lo, hi = (int(x) for x in args.domain_ids.split('-'))
    except ValueError:
        parser.error('--subscribers takes numbers like 1,5,20; --domain-ids LO-HI')
    if args.seconds <= 0 or any(n < 1 for n in counts) or not counts:
        parser.error('--seconds must be > 0 and every subscriber count >= 1')
    if args.interleave < 0 or (args.interleave and args.no_baseline):
        parser.error('--interleave takes a number of pairs >= 1, without --no-baseline')
    rounds: list[tuple[str, int | None]]
    if args.interleave:
        rounds = []
        for i in range(args.interleave):
            rounds += [(f'a{i + 1}', None), (f'b{i + 1}', counts[i % len(counts)])]
    else:
        rounds = [] if args.no_baseline else [('a', None)]
        rounds += [(chr(ord('b') + i), n) for i, n in enumerate(counts)]
    if hi - lo + 1 < len(rounds):
        parser.error(f'{len(rounds)} rounds need {len(rounds)} domain ids')
    if mosquitto_binary() is None:
        raise SystemExit('mosquitto is not installed (apt-get install mosquitto)')
    from feed_axis_energy.paths import config_dir
    machine = config_dir() / MACHINE
    with tempfile.TemporaryDirectory(prefix='fae-bench-soak-') as tmp_text:
        tmp = Path(tmp_text)
        root = tmp / 'programs'
        root.mkdir()
        duration_s = _program(root, args.seconds, machine)
        mqtt_port = _free_port()
        print(f'soak: {duration_s:.1f} s real-time job per round ({machine.name}, X 0 <-> 100 '
              f'mm at 3 m/min), OPC UA publishing interval {args.publish_ms:g} ms, '
              f'{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}; '
              f'{time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}', flush=True)
        figures = []
        with mosquitto(tmp / 'broker', mqtt_port):
            broker_pid = _broker_pid(mqtt_port)
            for k, (label, n) in enumerate(rounds):
                figures.append(_round(label, n, args, root, machine, lo + k, mqtt_port,
                                      broker_pid, duration_s))
        if args.interleave:
            _summary(figures)
    print(f'\ndone {time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}, load average '
          + ' '.join(f'{x:.1f}' for x in os.getloadavg()))


def _pct(values: np.ndarray) -> str:
    """p50 / p99 / max [ms] of raw latencies."""
    if values.size == 0:
        return 'nothing arrived'
    p50, p99 = np.percentile(values, [50, 99])
    return f'{_ms(p50)} / {_ms(p99)} / {_ms(values.max())}'


def _summary(figures: list[dict[str, Any]]) -> None:
    """Interleaved rounds: one line per round, then a and b pooled, raw and centred.

    Each round's stamps are shifted by its first batch's delay (docs/cell.md, "Soak"), so the
    pooled figures are given twice: raw, and centred on each round's own median (the spread,
    which is what compares across rounds).
    """
    print('\n== interleaved summary: the graph\'s own latency, job/live -> ROS subscriber '
          '(p50 / p99 / max; spread = p99 - p50 and max - p50 of the round)')
    print('round  OPC UA  load 1-min mean (range)  p50 / p99 / max              '
          'spread p99 / max    lost_samples  missing job/live  samples')
    for f in figures:
        raw = np.asarray(f['raw'])
        med = float(np.median(raw)) if raw.size else math.nan
        p99 = float(np.percentile(raw, 99)) if raw.size else math.nan
        top = float(raw.max()) if raw.size else math.nan
        lo, hi = f['load_range']
        subs = '-' if f['subscribers'] is None else str(f['subscribers'])
        print(f'{f["label"]:<6} {subs:>6}  {f["load_mean"]:5.1f} ({lo:.1f}-{hi:.1f})'
              f'{"":10}{_pct(raw):<28} {_ms(p99 - med):>7} / {_ms(top - med):<9}'
              f' {f["lost_samples"]:>12}  {f["missing"]:>16}  {f["samples"]} {f["status"]}')
    for kind, name in (('a', 'graph alone'), ('b', 'graph + bridges')):
        group = [f for f in figures if f['label'].startswith(kind)]
        raw = np.concatenate([np.asarray(f['raw']) for f in group]) if group else np.zeros(0)
        centred = np.concatenate([np.asarray(f['raw']) - np.median(f['raw'])
                                  for f in group if f['raw']]) if group else np.zeros(0)
        loads = [f['load_mean'] for f in group]
        print(f'pooled {kind} ({name}, {len(group)} rounds, load means '
              f'{min(loads, default=math.nan):.1f}-{max(loads, default=math.nan):.1f}): '
              f'raw {_pct(raw)}; centred on each round\'s median {_pct(centred)}; '
              f'lost_samples {sum(f["lost_samples"] for f in group)}, missing job/live '
              f'{sum(f["missing"] for f in group)} of '
              f'{sum(f["messages"] + f["missing"] for f in group)}')
    pairs = [(a, b) for a, b in zip(figures[0::2], figures[1::2])]
    for a, b in pairs:
        spread = [float(np.percentile(f['raw'], 99) - np.median(f['raw'])) if f['raw']
                  else math.nan for f in (a, b)]
        print(f'pair {a["label"]}/{b["label"]}: spread p99 - p50 {_ms(spread[0])} alone, '
              f'{_ms(spread[1])} with the bridges ({b["subscribers"]} OPC UA), difference '
              f'{_ms(spread[1] - spread[0])}; load means {a["load_mean"]:.1f} / '
              f'{b["load_mean"]:.1f}')


def _broker_pid(port: int) -> int | None:
    """The mosquitto process listening on ``port`` (its RSS is reported), or None."""
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmd = (entry / 'cmdline').read_bytes().split(b'\0')
            if cmd and cmd[0].endswith(b'mosquitto') and len(cmd) > 2:
                if f'listener {port} ' in Path(cmd[2].decode()).read_text():
                    return int(entry.name)
        except OSError:
            continue
    return None


if __name__ == '__main__':
    main()
