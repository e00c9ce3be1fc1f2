"""measured_live on a UMich run replayed over MQTT in real time, against offline ``compare``.

    PYTHONPATH=. .venv/bin/python bench/bench_measured_live.py [--runs exp08] [--speed 1]
        [--broker auto|mosquitto|amqtt] [--freeze-count 0] [--path core|ros]
        [--lag inline|thread] [--domain-id N]

For each run of ``config/campaigns/umich_mill.yaml`` (data in ../shared/data/umich-cnc-mill):
a publisher sends the run's rows in real time (``--speed`` N: N times faster; the figures
say which), one MQTT message per axis and quantity on ``<prefix>/<machine>/measured/<axis>``
(``position_m``, ``velocity_m_s``, ``acceleration_m_s2`` of X, Y, Z from the actual columns,
``power_w`` of X and Y in W), stamped with the wall clock at the row's due time. The MQTT
bridge (``MqttBridge``, mosquitto on a loopback port) checks every message and hands the
accepted samples through its ``on_measured`` callback to the ``measured_live`` core
(``LiveMonitor``, source ``live_motion``: the prediction from the stream's own kinematics),
the path the node takes minus DDS. At the end of the run the final comparison is compared
with offline ``compare`` of the same run (``compare_campaign``). Prints per run: the live
and offline energy error [%] and their difference [percentage points], the lags [ms],
messages sent/accepted/dropped, the counters, the core's CPU time, and the largest
delay between a sample's stamp and its arrival in the core. ``--lag thread`` (as the node
does) runs the core's lag estimates on a worker thread (``ThreadedLag``), ``inline`` (the
default here, the figures before the worker existed) in the delivering thread.

``--path ros``: the full path of the cell instead, MQTT (mosquitto) -> the ``opcua_bridge``
node (MQTT bridge) -> ROS ``measured/live`` -> the ``measured_live`` node (``source:
live_motion``, its lag estimates on the worker thread) -> ROS ``measured/comparison``,
collected here; nodes started as ``serve`` starts them, on ROS domain ``--domain-id``
(default: the first of ``FAE_DOMAIN_IDS``, else 0). The node's final comparison (after
``end_after_s`` = 5 s without samples) is compared with offline ``compare``; instead of the
core's CPU, it prints how stale the running comparisons are on arrival (arrival minus the
stamp of their newest row: the reorder wait, the 2 Hz publishing and the transport).
"""
from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
import shutil
import socket
import sys
import tempfile
import threading
import time


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'test' / 'bridge'))

from brokers import amqtt_broker, mosquitto, mosquitto_binary  # noqa: E402

from feed_axis_energy.bridge import MqttBridge, MqttSettings, TopicTree  # noqa: E402
from feed_axis_energy.machine import load_machine  # noqa: E402
from feed_axis_energy.measured import (compare_campaign, LiveMonitor,  # noqa: E402
                                       LiveMotionPredictor, LiveSettings, load_campaign,
                                       load_run, measured_signal, ThreadedLag)

MANIFEST = ROOT / 'config' / 'campaigns' / 'umich_mill.yaml'


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return int(sock.getsockname()[1])


class _Core:
    """The measured_live core behind the bridge's callback (the MQTT network thread)."""

    def __init__(self, monitor: LiveMonitor):
        self.monitor = monitor
        self.lock = threading.Lock()
        self.cpu_s = 0.0
        self.received = 0
        self.max_delay_s = 0.0

    def on_measured(self, sample) -> None:
        now = time.time()
        start = time.thread_time()
        with self.lock:
            self.monitor.add_sample(sample.axis, sample.quantity, sample.stamp_ns, sample.value)
            self.received += 1
        self.cpu_s += time.thread_time() - start
        self.max_delay_s = max(self.max_delay_s, now - sample.stamp_ns * 1e-9)


class _Prepared:
    """One UMich run: its data as the publisher streams them, and offline ``compare``'s."""

    def __init__(self, name: str):
        campaign = load_campaign(MANIFEST)
        self.name = name
        self.machine = load_machine(campaign.machine)
        self.spec = spec = campaign.run(name)
        self.run = run = load_run(spec)
        self.offline = compare_campaign(campaign, machine=self.machine, runs=[name]).runs[0]
        self.vel, self.acc = run.derivatives('actual')
        self.pos = run.positions('actual')
        self.power = measured_signal(run, measures='shaft', axes=spec.measured_axes,
                                     invert=spec.instrument.invert)

    def stream(self, pub, base: str, speed: float) -> tuple[int, float]:
        """Publish every row at its due time; (messages sent, wall time of the first row)."""
        run, spec = self.run, self.spec
        sent = 0
        t_wall0 = time.time() + 0.5
        for i, t in enumerate(run.t):
            due = t_wall0 + float(t - run.t[0]) / speed
            pause = due - time.time()
            if pause > 0:
                time.sleep(pause)
            stamp = t_wall0 + float(t - run.t[0])     # the run's own spacing, in wall time
            msgs = []
            for j, axis in enumerate(run.axes):
                msgs += [(axis, 'position_m', self.pos[i, j]),
                         (axis, 'velocity_m_s', self.vel[i, j]),
                         (axis, 'acceleration_m_s2', self.acc[i, j])]
            msgs += [(a, 'power_w', self.power[i, j]) for j, a in enumerate(spec.measured_axes)]
            for axis, quantity, value in msgs:
                body = f'{{"stamp": {stamp!r}, "value": {float(value)!r}, ' \
                       f'"quantity": "{quantity}"}}'
                pub.publish(f'{base}/{axis}', body.encode(), qos=1)
                sent += 1
        return sent, t_wall0

    def figures(self, final: dict, **extra) -> dict:
        """The final comparison against offline ``compare``."""
        run, offline = self.run, self.offline
        live_pct = final['energy_error_pct']['total']
        off_pct = offline.metrics.energy_error_pct
        return {'run': self.name, 'rows': int(run.t.size),
                'duration_s': float(run.t[-1] - run.t[0]), 'live_pct': live_pct,
                'offline_pct': off_pct, 'diff_pt': live_pct - off_pct,
                'live_j': (final['measured_energy_j']['total'],
                           final['predicted_energy_j']['total']),
                'offline_j': (offline.metrics.energy_meas_j, offline.metrics.energy_sim_j),
                'lag_ms': 1e3 * final['lag']['lag_s'],
                'offline_lag_ms': 1e3 * offline.offset_used_s,
                'lag_status': final['lag']['status'], 'estimates': final['lag']['estimates'],
                'frozen': final['lag']['frozen'], 'alarms': final['alarm']['count'],
                'counters': final['counters'], **extra}


def _publisher(port: int, name: str):
    import paho.mqtt.client as paho
    pub = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id=f'bench-{name}')
    pub.connect('127.0.0.1', port)
    pub.loop_start()
    return pub


def replay(name: str, *, port: int, speed: float, freeze_count: int,
           lag_thread: bool) -> dict:
    """The direct path: MQTT bridge callback -> ``LiveMonitor`` in this process."""
    data = _Prepared(name)
    spec, run = data.spec, data.run
    predictor = LiveMotionPredictor(data.machine, axes=run.axes,
                                    measured_axes=spec.measured_axes, load_kg=spec.load_kg)
    settings = LiveSettings(window_s=data.offline.window_s, stamp=data.offline.stamp,
                            freeze_count=freeze_count)
    runner = ThreadedLag() if lag_thread else None
    core = _Core(LiveMonitor(spec.measured_axes, source='live_motion', predictor=predictor,
                             settings=settings, job_id=name, lag_runner=runner))
    tree = TopicTree(machine='umich_mill')
    bridge = MqttBridge(None, MqttSettings(port=port, topics=tree, axes=run.axes),
                        on_measured=core.on_measured)
    bridge.start()
    pub = _publisher(port, name)
    try:
        sent, t_wall0 = data.stream(pub, f'{tree.prefix}/{tree.machine}/measured', speed)
        end = time.monotonic() + 30.0
        while time.monotonic() < end and core.received + bridge.measured.dropped < sent:
            time.sleep(0.05)
        wall = time.time() - t_wall0
        with core.lock:
            start = time.thread_time()
            final = core.monitor.finish()
            core.cpu_s += time.thread_time() - start
    finally:
        pub.loop_stop()
        pub.disconnect()
        bridge.stop()
    return data.figures(final, wall_s=wall, speed=speed, sent=sent,
                        accepted=bridge.measured.accepted, dropped=bridge.measured.dropped,
                        cpu_s=core.cpu_s, max_delay_ms=1e3 * core.max_delay_s,
                        path='bridge callback -> core')


class _RosPath:
    """``opcua_bridge`` and ``measured_live`` as node processes, a listener in this one.

    The nodes run as ``serve`` runs them (``launch.node_command`` with a parameter file,
    ``launch.Supervisor``): ``opcua_bridge`` with the MQTT bridge republishes each accepted
    sample on ``measured/live``; ``measured_live`` (``source: live_motion``, the UMich
    machine) publishes ``measured/comparison``, which this process collects.
    """

    def __init__(self, *, port: int, domain_id: int, freeze_count: int, window_s: float,
                 stamp: str, load_kg: float, end_after_s: float):
        import rclpy
        from std_msgs.msg import String
        from feed_axis_energy.cli.launch import (node_command, node_environment,
                                                 private_parameter_dir, Supervisor,
                                                 write_params_file)
        from feed_axis_energy.nodes.qos import command_qos
        from feed_axis_energy.nodes.runner import make_executor
        machine = str(ROOT / 'config' / 'umich_mill.yaml')
        with socket.socket() as sock:
            sock.bind(('127.0.0.1', 0))
            opcua_port = int(sock.getsockname()[1])
        params = {
            'opcua_bridge': {'machine': machine, 'opcua_port': opcua_port,
                             'mqtt_host': '127.0.0.1', 'mqtt_port': port,
                             'mqtt_machine': 'umich_mill'},
            'measured_live': {'machine': machine, 'source': 'live_motion',
                              'measured_axes': 'X,Y', 'load_kg': float(load_kg),
                              'window_s': float(window_s), 'stamp': stamp,
                              'freeze_count': int(freeze_count),
                              'end_after_s': float(end_after_s)},
        }
        self.private = private_parameter_dir()
        overrides = write_params_file(self.private, params)
        graph = ROOT / 'config' / 'graph.yaml'
        self.sup = Supervisor({n: node_command(n, params_files=[graph, overrides])
                               for n in params}, finishers=set(),
                              env=node_environment(domain_id), echo=False)
        os.environ['ROS_DOMAIN_ID'] = str(domain_id)
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node('bench_measured_live', context=self.context)
        self.executor = make_executor(context=self.context)
        self.executor.add_node(self.node)
        self.lock = threading.Lock()
        self.messages: list[tuple[float, dict]] = []
        self.node.create_subscription(String, 'measured/comparison', self._on_comparison,
                                      command_qos())
        self._stop = threading.Event()
        self._spinner = threading.Thread(target=self._spin, daemon=True)

    def _on_comparison(self, msg) -> None:
        with self.lock:
            self.messages.append((time.time(), json.loads(msg.data)))

    def _spin(self) -> None:
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def start(self, timeout_s: float = 90.0) -> None:
        """Start the nodes; return once both are up and matched with this listener."""
        self.sup.start()
        self._spinner.start()
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            state, reason = self.sup.poll()
            if state != 'running':
                raise RuntimeError(f'a node stopped: {reason}')
            if (self.node.count_publishers('measured/comparison') >= 1
                    and self.node.count_publishers('measured/live') >= 1
                    and self.node.count_subscribers('measured/live') >= 1):
                time.sleep(2.0)     # discovery is per direction; the MQTT bridge subscribes
                return
            time.sleep(0.1)
        raise RuntimeError('the nodes did not come up in time')

    def warm_up(self, port: int, wait_s: float, tries: int = 6) -> float:
        """One sample through the whole path before the runs: discovery and subscriptions
        settled once its comparison comes back final (``wait_s``: the node's ``end_after_s``
        and some). Seconds it took."""
        tree = TopicTree(machine='umich_mill')
        pub = _publisher(port, 'warm-up')
        start = time.time()
        try:
            for _ in range(tries):
                body = json.dumps({'stamp': time.time(), 'value': 0.0, 'quantity': 'energy_j'})
                pub.publish(f'{tree.prefix}/{tree.machine}/measured/X', body.encode(), qos=1)
                final, _ = self.final(start, timeout_s=wait_s)
                if final is not None:
                    return time.time() - start
        finally:
            pub.loop_stop()
            pub.disconnect()
        raise RuntimeError('no comparison came back through MQTT -> ROS in time')

    def final(self, job_after: float, timeout_s: float) -> tuple[dict | None, list]:
        """The first final comparison received after ``job_after`` (wall clock) and the
        running ones of the same stream."""
        end = time.monotonic() + timeout_s
        while True:
            with self.lock:
                mine = [(r, m) for r, m in self.messages if r >= job_after]
            finals = [m for _, m in mine if m['final']]
            if finals:
                return finals[0], mine
            if time.monotonic() >= end:
                return None, []
            time.sleep(0.1)
            state, reason = self.sup.poll()
            if state != 'running':
                raise RuntimeError(f'a node stopped: {reason}')

    def close(self) -> None:
        """Stop the listener and the nodes."""
        self._stop.set()
        if self._spinner.is_alive():
            self._spinner.join(timeout=5.0)
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()
        self.sup.stop(timeout_s=10.0)
        shutil.rmtree(self.private, ignore_errors=True)


def replay_ros(name: str, ros: _RosPath, *, port: int, speed: float,
               end_after_s: float) -> dict:
    """The full path: MQTT -> opcua_bridge -> ROS measured/live -> measured_live -> ROS."""
    data = _Prepared(name)
    tree = TopicTree(machine='umich_mill')
    pub = _publisher(port, name)
    try:
        start = time.time()
        sent, t_wall0 = data.stream(pub, f'{tree.prefix}/{tree.machine}/measured', speed)
        final, mine = ros.final(start, timeout_s=end_after_s + 120.0)
        wall = time.time() - t_wall0
    finally:
        pub.loop_stop()
        pub.disconnect()
    if final is None:
        raise RuntimeError(f'{name}: no final comparison within {end_after_s + 120:.0f} s')
    # staleness: a running comparison's arrival here minus the stamp of its newest row
    stale = sorted(r - m['stamp'] for r, m in mine if not m['final'] and m['stamp'])
    pick = (lambda q: 1e3 * stale[min(int(q * len(stale)), len(stale) - 1)]) if stale \
        else (lambda q: math.nan)
    return data.figures(final, wall_s=wall, speed=speed, sent=sent,
                        accepted=final['counters']['samples'], dropped=sent - final[
                            'counters']['samples'], cpu_s=math.nan, max_delay_ms=math.nan,
                        stale_p50_ms=pick(0.5), stale_max_ms=pick(1.0),
                        running_msgs=len(stale), path='MQTT -> ROS nodes')


def _default_domain() -> int:
    text = os.environ.get('FAE_DOMAIN_IDS', '')
    lo = text.split('-', 1)[0].strip()
    return int(lo) if lo.isdigit() else int(os.environ.get('ROS_DOMAIN_ID', '0') or 0)


def _print(rows: list[dict]) -> None:
    for r in rows:
        m = r['counters']['measured']
        k = r['counters']['kinematics']
        print(f"{r['run']} ({r['path']}): {r['rows']} rows, {r['duration_s']:.1f} s of data "
              f"replayed in {r['wall_s']:.1f} s; MQTT messages sent {r['sent']}, "
              f"reached the comparison {r['accepted']}, lost {r['dropped']}")
        print(f"  energy error at program end: live {r['live_pct']:+.4f} %, offline compare "
              f"{r['offline_pct']:+.4f} %, difference {r['diff_pt']:+.5f} percentage points")
        print(f"  energies measured/predicted: live {r['live_j'][0]:.4f} J / "
              f"{r['live_j'][1]:.4f} J, offline {r['offline_j'][0]:.4f} J / "
              f"{r['offline_j'][1]:.4f} J")
        print(f"  lag: live {r['lag_ms']:+.3f} ms ({r['lag_status']}, {r['estimates']} "
              f"estimates, frozen {r['frozen']}), offline {r['offline_lag_ms']:+.3f} ms; "
              f"alarms {r['alarms']}")
        rows_line = (f"  rows power/kinematics {m['rows']}/{k['rows']}; late "
                     f"{m['late'] + k['late']}, duplicate {m['duplicate'] + k['duplicate']}, "
                     f"out of order {m['out_of_order'] + k['out_of_order']}, gaps "
                     f"{m['gaps'] + k['gaps']}, incomplete {m['incomplete'] + k['incomplete']}")
        if 'stale_p50_ms' in r:
            print(f"{rows_line}; {r['running_msgs']} running comparisons, stale on arrival "
                  f"p50 {r['stale_p50_ms']:.0f} ms, max {r['stale_max_ms']:.0f} ms")
        else:
            print(f"{rows_line}; core CPU {r['cpu_s']:.2f} s "
                  f"({100 * r['cpu_s'] / max(r['wall_s'], 1e-9):.1f} % of the wall time); "
                  f"largest stamp-to-core delay {r['max_delay_ms']:.1f} ms")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', default='exp08',
                        help='comma-separated runs of the UMich campaign (default exp08)')
    parser.add_argument('--speed', type=float, default=1.0,
                        help='replay speed factor (1: real time, the reported figure)')
    parser.add_argument('--broker', choices=('auto', 'mosquitto', 'amqtt'), default='auto')
    parser.add_argument('--freeze-count', type=int, default=0,
                        help='LiveSettings.freeze_count (0: the lag is never frozen)')
    parser.add_argument('--path', choices=('core', 'ros'), default='core',
                        help='core: MQTT bridge callback -> core in this process; ros: '
                             'MQTT -> opcua_bridge -> measured/live -> measured_live node')
    parser.add_argument('--lag', choices=('inline', 'thread'), default='inline',
                        help='core path: lag estimates in the delivering thread or on a '
                             'worker (the node always uses the worker)')
    parser.add_argument('--domain-id', type=int, default=None,
                        help='ROS domain of --path ros (default: first of FAE_DOMAIN_IDS)')
    args = parser.parse_args()
    if not args.speed > 0:
        parser.error('--speed must be > 0')
    if not (ROOT.parent / 'shared' / 'data' / 'umich-cnc-mill').is_dir():
        print('UMich data not found at ../shared/data/umich-cnc-mill', file=sys.stderr)
        return 1
    broker = args.broker
    if broker == 'auto':
        broker = 'mosquitto' if mosquitto_binary() else 'amqtt'
    port = _free_port()
    names = [r.strip() for r in args.runs.split(',') if r.strip()]
    rows = []
    end_after_s = 5.0
    with tempfile.TemporaryDirectory() as tmp:
        ctx = mosquitto(Path(tmp), port) if broker == 'mosquitto' else amqtt_broker(port)
        with ctx:
            if args.path == 'core':
                for name in names:
                    rows.append(replay(name, port=port, speed=args.speed,
                                       freeze_count=args.freeze_count,
                                       lag_thread=args.lag == 'thread'))
            else:
                first = _Prepared(names[0])
                domain = args.domain_id if args.domain_id is not None else _default_domain()
                ros = _RosPath(port=port, domain_id=domain, freeze_count=args.freeze_count,
                               window_s=first.offline.window_s, stamp=first.offline.stamp,
                               load_kg=first.spec.load_kg, end_after_s=end_after_s)
                try:
                    ros.start()
                    warm = ros.warm_up(port, end_after_s + 5.0)
                    print(f'path ready: one sample through MQTT -> ROS -> comparison in '
                          f'{warm:.1f} s (end_after_s {end_after_s:g} s)')
                    for name in names:
                        rows.append(replay_ros(name, ros, port=port, speed=args.speed,
                                               end_after_s=end_after_s))
                finally:
                    ros.close()
    print(f'broker {broker} on 127.0.0.1:{port}; replay speed x{args.speed:g} '
          f'({"real time" if args.speed == 1 else "NOT real time"}); '
          f'freeze_count {args.freeze_count}; path {args.path}'
          + (f', lag estimates {args.lag}' if args.path == 'core' else
             f', ROS domain {domain}'))
    _print(rows)
    worst = max(abs(r['diff_pt']) for r in rows)
    print(f'largest |live - offline| energy error: {worst:.5f} percentage points '
          f'(target 0.5)')
    return 0 if worst <= 0.5 else 1


if __name__ == '__main__':
    sys.exit(main())
