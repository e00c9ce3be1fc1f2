"""measured_live on a UMich run replayed over MQTT in real time, against offline ``compare``.

    PYTHONPATH=. .venv/bin/python bench/bench_measured_live.py [--runs exp08] [--speed 1]
        [--broker auto|mosquitto|amqtt] [--freeze-count 0]

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
delay between a sample's stamp and its arrival in the core.
"""
from __future__ import annotations

import argparse
from pathlib import Path
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
                                       load_run, measured_signal)

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


def replay(name: str, *, port: int, speed: float, freeze_count: int) -> dict:
    import paho.mqtt.client as paho
    campaign = load_campaign(MANIFEST)
    machine = load_machine(campaign.machine)
    spec = campaign.run(name)
    run = load_run(spec)
    offline = compare_campaign(campaign, machine=machine, runs=[name]).runs[0]
    vel, acc = run.derivatives('actual')
    pos = run.positions('actual')
    power = measured_signal(run, measures='shaft', axes=spec.measured_axes,
                            invert=spec.instrument.invert)
    predictor = LiveMotionPredictor(machine, axes=run.axes, measured_axes=spec.measured_axes,
                                    load_kg=spec.load_kg)
    settings = LiveSettings(window_s=offline.window_s, stamp=offline.stamp,
                            freeze_count=freeze_count)
    core = _Core(LiveMonitor(spec.measured_axes, source='live_motion', predictor=predictor,
                             settings=settings, job_id=name))
    tree = TopicTree(machine='umich_mill')
    bridge = MqttBridge(None, MqttSettings(port=port, topics=tree, axes=run.axes),
                        on_measured=core.on_measured)
    bridge.start()
    pub = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id=f'bench-{name}')
    pub.connect('127.0.0.1', port)
    pub.loop_start()
    sent = 0
    base = f'{tree.prefix}/{tree.machine}/measured'
    try:
        t_wall0 = time.time() + 0.5
        for i, t in enumerate(run.t):
            due = t_wall0 + float(t - run.t[0]) / speed
            pause = due - time.time()
            if pause > 0:
                time.sleep(pause)
            stamp = t_wall0 + float(t - run.t[0])     # the run's own spacing, in wall time
            msgs = []
            for j, axis in enumerate(run.axes):
                msgs += [(axis, 'position_m', pos[i, j]), (axis, 'velocity_m_s', vel[i, j]),
                         (axis, 'acceleration_m_s2', acc[i, j])]
            msgs += [(a, 'power_w', power[i, j]) for j, a in enumerate(spec.measured_axes)]
            for axis, quantity, value in msgs:
                body = f'{{"stamp": {stamp!r}, "value": {float(value)!r}, ' \
                       f'"quantity": "{quantity}"}}'
                pub.publish(f'{base}/{axis}', body.encode(), qos=1)
                sent += 1
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
    live_pct = final['energy_error_pct']['total']
    off_pct = offline.metrics.energy_error_pct
    return {'run': name, 'rows': int(run.t.size), 'duration_s': float(run.t[-1] - run.t[0]),
            'wall_s': wall, 'speed': speed, 'sent': sent, 'accepted': bridge.measured.accepted,
            'dropped': bridge.measured.dropped, 'live_pct': live_pct, 'offline_pct': off_pct,
            'diff_pt': live_pct - off_pct,
            'live_j': (final['measured_energy_j']['total'], final['predicted_energy_j']['total']),
            'offline_j': (offline.metrics.energy_meas_j, offline.metrics.energy_sim_j),
            'lag_ms': 1e3 * final['lag']['lag_s'], 'offline_lag_ms': 1e3 * offline.offset_used_s,
            'lag_status': final['lag']['status'], 'estimates': final['lag']['estimates'],
            'frozen': final['lag']['frozen'], 'alarms': final['alarm']['count'],
            'counters': final['counters'], 'cpu_s': core.cpu_s,
            'max_delay_ms': 1e3 * core.max_delay_s}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', default='exp08',
                        help='comma-separated runs of the UMich campaign (default exp08)')
    parser.add_argument('--speed', type=float, default=1.0,
                        help='replay speed factor (1: real time, the reported figure)')
    parser.add_argument('--broker', choices=('auto', 'mosquitto', 'amqtt'), default='auto')
    parser.add_argument('--freeze-count', type=int, default=0,
                        help='LiveSettings.freeze_count (0: the lag is never frozen)')
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
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        ctx = mosquitto(Path(tmp), port) if broker == 'mosquitto' else amqtt_broker(port)
        with ctx:
            for name in [r.strip() for r in args.runs.split(',') if r.strip()]:
                rows.append(replay(name, port=port, speed=args.speed,
                                   freeze_count=args.freeze_count))
    print(f'broker {broker} on 127.0.0.1:{port}; replay speed x{args.speed:g} '
          f'({"real time" if args.speed == 1 else "NOT real time"}); '
          f'freeze_count {args.freeze_count}')
    for r in rows:
        m = r['counters']['measured']
        k = r['counters']['kinematics']
        print(f"{r['run']}: {r['rows']} rows, {r['duration_s']:.1f} s of data replayed in "
              f"{r['wall_s']:.1f} s; MQTT messages sent {r['sent']}, accepted {r['accepted']}, "
              f"dropped {r['dropped']}")
        print(f"  energy error at program end: live {r['live_pct']:+.4f} %, offline compare "
              f"{r['offline_pct']:+.4f} %, difference {r['diff_pt']:+.5f} percentage points")
        print(f"  energies measured/predicted: live {r['live_j'][0]:.4f} J / "
              f"{r['live_j'][1]:.4f} J, offline {r['offline_j'][0]:.4f} J / "
              f"{r['offline_j'][1]:.4f} J")
        print(f"  lag: live {r['lag_ms']:+.3f} ms ({r['lag_status']}, {r['estimates']} "
              f"estimates, frozen {r['frozen']}), offline {r['offline_lag_ms']:+.3f} ms; "
              f"alarms {r['alarms']}")
        print(f"  rows power/kinematics {m['rows']}/{k['rows']}; late {m['late'] + k['late']}, "
              f"duplicate {m['duplicate'] + k['duplicate']}, out of order "
              f"{m['out_of_order'] + k['out_of_order']}, gaps {m['gaps'] + k['gaps']}, "
              f"incomplete {m['incomplete'] + k['incomplete']}; core CPU {r['cpu_s']:.2f} s "
              f"({100 * r['cpu_s'] / max(r['wall_s'], 1e-9):.1f} % of the wall time); largest "
              f"stamp-to-core delay {r['max_delay_ms']:.1f} ms")
    worst = max(abs(r['diff_pt']) for r in rows)
    print(f'largest |live - offline| energy error: {worst:.5f} percentage points '
          f'(target 0.5)')
    return 0 if worst <= 0.5 else 1


if __name__ == '__main__':
    sys.exit(main())
