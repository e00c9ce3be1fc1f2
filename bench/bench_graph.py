"""Benchmarks of the node graph (run by hand; needs rclpy).

    .venv/bin/python bench/bench_graph.py fast --minutes 10      # real-time factor, fast mode
    .venv/bin/python bench/bench_graph.py realtime --seconds 60  # latency setpoint -> power
    .venv/bin/python bench/bench_graph.py recorder --messages 20000 [--window 90]
    .venv/bin/python bench/bench_graph.py all

fast: a reciprocating 400 mm program at 100 mm/s with 1 s dwells, sampled at 1 kHz, through
``feed-axis-energy launch --record``; prints the trajectory node's streaming factor and the
whole run's wall time (process start-up and discovery included).
realtime: the same graph paced by the wall clock; a listener in this process stamps the
arrival of every ``setpoints`` and ``power`` batch and reports the latency per batch
(median, p99, max) and batches that never arrived.
recorder: publishes 1-sample ``power`` messages to a recorder process as fast as its
``recorder/progress`` acks allow (``--window`` in flight), counts what the bag holds and the CPU
time per message of both processes; also the bag writer alone (no DDS).
``--recorder-param ack_every:=40`` passes a parameter to the recorder.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from feed_axis_energy.record import bagio  # noqa: E402
from feed_axis_energy.record.crashsafe import ChunkedBagWriter  # noqa: E402
from feed_axis_energy.graph.flow import latency_stats  # noqa: E402


def _env(domain: int) -> dict[str, str]:
    env = dict(os.environ)
    env['PYTHONPATH'] = str(ROOT)
    env['ROS_DOMAIN_ID'] = str(domain)
    return env


def _program(path: Path, seconds: float) -> Path:
    """Reciprocating 400 mm strokes at 100 mm/s with 1 s dwells: about 5.2 s per stroke."""
    strokes = max(1, int(round(seconds / 5.2)))
    lines = ['G21 G90 G94 G61', 'G0 X0']
    for i in range(strokes):
        lines += [f'G1 X{400 if i % 2 == 0 else 0} F6000', 'G4 P1']
    path.write_text('\n'.join(lines) + '\n')
    return path


def bench_fast(minutes: float, domain: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        prog = _program(Path(tmp) / 'long.nc', minutes * 60)
        t0 = time.monotonic()
        out = subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'launch', '--program',
                              str(prog), '--record', f'{tmp}/bag', '--domain-id', str(domain)],
                             env=_env(domain), capture_output=True, text=True)
        wall = time.monotonic() - t0
        if out.returncode != 0:
            print(out.stdout[-3000:], out.stderr[-2000:])
            raise SystemExit('fast run failed')
        m = re.search(r'program done: (\d+) samples, ([\d.]+) s simulated in ([\d.]+) s wall',
                      out.stdout)
        n, sim, stream = int(m.group(1)), float(m.group(2)), float(m.group(3))
        counts = bagio.bag_topics(f'{tmp}/bag')
        print(f'fast: {n} samples = {sim:.1f} s simulated; streaming {stream:.2f} s wall '
              f'(x{sim / stream:.1f}); whole launch incl. start-up and bag close {wall:.2f} s '
              f'(x{sim / wall:.1f}); bag: {dict((k, v[1]) for k, v in counts.items())}')


def bench_realtime(seconds: float, domain: int) -> None:
    import rclpy
    from rclpy.context import Context
    from trajectory_msgs.msg import JointTrajectory
    from feed_axis_energy.graph.flow import header_stamp_ns
    from feed_axis_energy.nodes.qos import stream_qos
    from feed_axis_energy.nodes.runner import make_executor
    with tempfile.TemporaryDirectory() as tmp:
        prog = _program(Path(tmp) / 'rt.nc', seconds)
        ctx = Context()
        rclpy.init(context=ctx, domain_id=domain)
        node = rclpy.create_node('latency_probe', context=ctx)
        sent: dict[int, float] = {}
        got: dict[int, float] = {}
        node.create_subscription(JointTrajectory, 'setpoints', lambda d: sent.setdefault(
            header_stamp_ns(d), time.monotonic()), stream_qos(), raw=True)
        node.create_subscription(JointTrajectory, 'power', lambda d: got.setdefault(
            header_stamp_ns(d), time.monotonic()), stream_qos(), raw=True)
        ex = make_executor(context=ctx)
        ex.add_node(node)
        launcher = subprocess.Popen(
            [sys.executable, '-m', 'feed_axis_energy', 'launch', '--program', str(prog),
             '--mode', 'realtime', '--domain-id', str(domain)], env=_env(domain),
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        while launcher.poll() is None:
            ex.spin_once(timeout_sec=0.01)
        log = launcher.stdout.read()
        ex.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
        m = re.search(r'program done: (\d+) samples', log)
        if m is None:
            print(log[-3000:])
        batches = -(-int(m.group(1)) // 100) if m else None
        lat = [got[s] - sent[s] for s in sent if s in got]
        e = re.search(r'energy_estimator\]: program end: (\d+) samples', log)
        lost = (int(m.group(1)) - int(e.group(1))) if m and e else None
        st = latency_stats(lat)
        print(f'realtime ({seconds:g} s program): probe saw {len(sent)} setpoint and '
              f'{len(got)} power batches of {batches}; samples lost in the graph: {lost}; '
              f'latency setpoints->power median {st["median_s"] * 1e3:.2f} ms, '
              f'p99 {st["p99_s"] * 1e3:.2f} ms, max {st["max_s"] * 1e3:.2f} ms')


def _cpu_s(pid: int) -> float:
    """User + system CPU time of a process [s] (Linux /proc)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def bench_recorder(messages: int, domain: int, window: int = 90,
                   params: list[str] | None = None) -> None:
    import rclpy
    from rclpy.context import Context
    from feed_axis_energy.nodes.runner import make_executor
    from std_msgs.msg import Header
    from trajectory_msgs.msg import JointTrajectory
    from feed_axis_energy.nodes import convert
    from feed_axis_energy.nodes.qos import stream_qos
    data = []
    for i in range(messages):
        s = bagio.Series(t=np.array([i * 1e-3]), names=('X', 'total'),
                         positions=np.ones((1, 2)), velocities=np.ones((1, 2)))
        data.append(convert.series_to_cdr(s)[0])
    with tempfile.TemporaryDirectory() as tmp:
        bag = ChunkedBagWriter(f'{tmp}/direct', typestore=bagio.typestore())
        bag.add_topic('/power', bagio.JOINT_TRAJECTORY)
        t0 = time.perf_counter()
        for stamp, cdr in data:
            bag.write('/power', stamp, cdr)
            if bag.buffered >= 5000:
                bag.flush()
        bag.close()
        direct = messages / (time.perf_counter() - t0)
        rec = subprocess.Popen(
            [sys.executable, '-m', 'feed_axis_energy.nodes.mcap_recorder', '--ros-args', '-p',
             f'output:={tmp}/bag', '-p', 'topics:=[power]']
            + [a for p in params or [] for a in ('-p', p)], env=_env(domain),
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        ctx = Context()
        rclpy.init(context=ctx, domain_id=domain)
        node = rclpy.create_node('blaster', context=ctx)
        pub = node.create_publisher(JointTrajectory, 'power', stream_qos())
        acked = [-1]
        node.create_subscription(Header, 'recorder/progress', lambda m: m.frame_id or (
            acked.__setitem__(0, convert.time_to_ns(m.stamp))), stream_qos())
        ex = make_executor(context=ctx)
        ex.add_node(node)
        while pub.get_subscription_count() < 1 or node.count_publishers(
                '/recorder/progress') < 1:
            ex.spin_once(timeout_sec=0.05)
        time.sleep(0.5)
        # Pre-serialized bytes straight to rcl (Publisher.publish's type checks skipped), so
        # the bench measures the recorder rather than the publisher.
        publish_raw = pub.handle.publish_raw
        stamps = [stamp for stamp, _ in data]
        t0 = time.perf_counter()
        cpu0 = _cpu_s(rec.pid), time.process_time()
        for i, (_, cdr) in enumerate(data):
            # the recorder's own acks, same flow control as the graph (window < depth 100)
            if i >= window and acked[0] < stamps[i - window]:
                while acked[0] < stamps[i - window]:
                    ex.spin_once(timeout_sec=0.01)
            publish_raw(cdr)
        while acked[0] < data[-1][0]:
            ex.spin_once(timeout_sec=0.01)
        sent_s = time.perf_counter() - t0
        rec_cpu, own_cpu = _cpu_s(rec.pid) - cpu0[0], time.process_time() - cpu0[1]
        rec.send_signal(2)
        rec.wait(timeout=30)
        ex.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
        n = bagio.bag_topics(f'{tmp}/bag').get('/power', ('', 0))[1]
        print(f'recorder: bag writer alone {direct:,.0f} msgs/s; over DDS {messages} messages '
              f'recorded in {sent_s:.2f} s ({messages / sent_s:,.0f} msgs/s, window {window} on '
              f'recorder/progress acks), {n} in the bag; CPU per message: recorder process '
              f'{rec_cpu / messages * 1e6:.1f} us (one core: {messages / rec_cpu:,.0f} msgs/s), '
              f'publisher process {own_cpu / messages * 1e6:.1f} us')


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('which', choices=('fast', 'realtime', 'recorder', 'all'))
    p.add_argument('--minutes', type=float, default=10.0)
    p.add_argument('--seconds', type=float, default=60.0)
    p.add_argument('--messages', type=int, default=50000)
    p.add_argument('--window', type=int, default=90,
                   help='recorder bench: messages in flight (< stream depth 100)')
    p.add_argument('--recorder-param', action='append', default=[], metavar='NAME:=VALUE',
                   help='recorder bench: extra mcap_recorder parameter (repeatable)')
    p.add_argument('--domain-id', type=int, default=97)
    a = p.parse_args()
    if a.which in ('fast', 'all'):
        bench_fast(a.minutes, a.domain_id)
    if a.which in ('realtime', 'all'):
        bench_realtime(a.seconds, a.domain_id)
    if a.which in ('recorder', 'all'):
        bench_recorder(a.messages, a.domain_id, a.window, a.recorder_param)


if __name__ == '__main__':
    main()
