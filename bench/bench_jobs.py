"""Jobs in a row in one graph: every result against offline ``simulate --json``, memory, latency.

Starts ``feed-axis-energy launch --program-root DIR --machine-root config`` (fast mode; with
``--record``, ``--record OUT`` too: one recording per job), submits
N jobs one after another over ``job/command`` (three generated programs, loads 0..10 kg; the
1-axis program on the demonstrator, the 3-axis ones on the 3-axis mill with or without
drives), and prints the largest relative difference of a job's ``energy_j`` (every axis and
``total``) to ``simulate --json`` of the same program, machine and load (each combination
simulated once, as a child process), the time from the start command to the
job's first ``job/live`` message and from its last ``job/live`` message to its result, and the
RSS of every node process (the recorder too with ``--record``) after job 10 and after job N.
With ``--record`` every job's recording ``OUT/<job_id>/`` is then checked: marked complete
with the job's status, and its ``/power`` totals equal to the job's result.

    PYTHONPATH=. .venv/bin/python bench/bench_jobs.py --jobs 100 --domain-id 231 [--record]
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from feed_axis_energy import lifeline  # noqa: E402
from feed_axis_energy.paths import config_dir  # noqa: E402

PROGRAMS = {
    'stroke.nc': 'G21 G90 G94 G61\nG0 X0\nG1 X100 F3000\nG4 P0.2\nG1 X80 F3000\n',
    'xyz.nc': 'G21 G90 G94 G61\nG1 X120 Y40 Z-20 F6000\nG4 P0.1\nG1 X0 Y0 Z0 F9000\n',
    'zigzag.nc': 'G21 G90 G94 G64\n' + ''.join(
        f'G1 X{20 * (i % 2) + 5 * i} Y{10 * (i % 3)} F4800\n' for i in range(12)),
}
NODES = ('gcode_trajectory', 'axis_dynamics', 'energy_estimator', 'mcap_recorder')
MACHINES = {'plain': None, 'mill': 'three_axis_mill.yaml',
            'drives': 'three_axis_mill_drives.yaml'}


def _job(i: int) -> tuple[str, str, float]:
    names = sorted(PROGRAMS)
    program = names[i % len(names)]
    if program == 'stroke.nc':
        return program, 'plain', 2.5 * (i % 5)
    return program, ('drives' if i % 2 else 'mill'), 2.5 * (i % 5)


def _rss_mib(pid: int) -> float:
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024
    return float('nan')


def _nodes(launcher: int) -> dict[str, int]:
    out = {}
    for pid, cmd in lifeline.child_processes(launcher):
        for name in NODES:
            if f'nodes.{name}' in cmd:
                out[name] = pid
    return out


def _offline(path: Path, machine: str | None, load: float, env: dict) -> dict:
    args = [sys.executable, '-m', 'feed_axis_energy', 'simulate', str(path), '--json',
            '--load-kg', repr(load)]
    if machine:
        args += ['--machine', str(config_dir() / machine)]
    out = subprocess.run(args, env=env, capture_output=True, text=True, timeout=300)
    if out.returncode:
        raise SystemExit(f'simulate failed: {out.stderr}')
    return json.loads(out.stdout)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--jobs', type=int, default=100)
    p.add_argument('--domain-id', type=int, default=231)
    p.add_argument('--log', type=Path, default=None,
                   help='write the launcher\'s output (every node\'s log) to this file')
    p.add_argument('--record', action='store_true',
                   help='record every job (launch --record OUT): OUT/<job_id>/')
    args = p.parse_args()
    env = dict(os.environ, PYTHONPATH=str(ROOT), ROS_DOMAIN_ID=str(args.domain_id))
    import rclpy
    from rclpy.context import Context
    from std_msgs.msg import String
    from feed_axis_energy.nodes.qos import command_qos, job_qos
    from feed_axis_energy.nodes.runner import make_executor

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for name, text in PROGRAMS.items():
            (root / name).write_text(text)
        refs = {}
        for i in range(args.jobs):
            program, machine, load = _job(i)
            key = (program, machine, load)
            if key not in refs:
                refs[key] = _offline(root / program, MACHINES[machine], load, env)
        record = ['--record', str(root / 'rec')] if args.record else []
        log = open(args.log, 'w') if args.log else subprocess.DEVNULL
        launcher = subprocess.Popen(
            [sys.executable, '-m', 'feed_axis_energy', 'launch', '--program-root', str(root),
             '--machine-root', str(config_dir()), '--domain-id', str(args.domain_id), *record],
            env=env, stdout=log, stderr=subprocess.STDOUT)
        n_nodes = 4 if args.record else 3
        ctx = Context()
        rclpy.init(context=ctx, domain_id=args.domain_id)
        node = rclpy.create_node('bench_jobs', context=ctx)
        ex = make_executor(context=ctx)
        ex.add_node(node)
        results: dict[str, dict] = {}
        first_live: dict[str, float] = {}
        last_live: dict[str, float] = {}
        result_at: dict[str, float] = {}
        result_wall: dict[str, float] = {}

        def on_result(msg):
            d = json.loads(msg.data)
            results[d['job_id']] = d
            result_at[d['job_id']] = time.monotonic()
            result_wall[d['job_id']] = time.time()

        def on_live(msg):
            d = json.loads(msg.data)
            now = time.monotonic()
            first_live.setdefault(d['job_id'], now)
            last_live[d['job_id']] = now

        pub = node.create_publisher(String, 'job/command', command_qos())
        node.create_subscription(String, 'job/result', on_result, job_qos())
        node.create_subscription(String, 'job/live', on_live, command_qos())

        def spin_until(cond, timeout_s):
            end = time.monotonic() + timeout_s
            while not cond():
                if time.monotonic() > end:
                    raise SystemExit('timed out')
                ex.spin_once(timeout_sec=0.01)

        rows, rss = [], {}
        try:
            spin_until(lambda: pub.get_subscription_count() >= 1
                       and node.count_publishers('job/live') >= 1
                       and len(_nodes(launcher.pid)) == n_nodes, 60)
            settle = time.monotonic() + 1.0     # the estimator sees our job/live reader too
            spin_until(lambda: time.monotonic() > settle, 5)
            t_all = time.monotonic()
            for i in range(args.jobs):
                program, machine, load = _job(i)
                job = f'b{i:04d}'
                body = {'command': 'start', 'job_id': job, 'program': program, 'load_kg': load}
                if MACHINES[machine]:
                    body['machine'] = MACHINES[machine]
                t0 = time.monotonic()
                pub.publish(String(data=json.dumps(body)))
                spin_until(lambda: job in results, 120)
                res = results[job]
                ref = refs[(program, machine, load)]
                rel = max(abs(res['energy_j'][k] / v - 1) if v else abs(res['energy_j'][k])
                          for k, v in ref['energy_j'].items())
                rows.append((job, program, machine, load, res['status'], rel,
                             first_live.get(job, np.nan) - t0,
                             result_at[job] - last_live.get(job, np.nan)))
                if i + 1 in (10, args.jobs):
                    rss[i + 1] = {n: _rss_mib(pid) for n, pid in _nodes(launcher.pid).items()}
            wall = time.monotonic() - t_all
            if args.record:
                checked = _check_recordings(root / 'rec', results, rows, result_wall)
        finally:
            ex.shutdown()
            node.destroy_node()
            rclpy.shutdown(context=ctx)
            launcher.send_signal(signal.SIGINT)
            launcher.wait(timeout=30)

    rel = np.array([r[5] for r in rows])
    start = np.array([r[6] for r in rows]) * 1e3
    end = np.array([r[7] for r in rows]) * 1e3
    statuses = {s: sum(1 for r in rows if r[4] == s) for s in {r[4] for r in rows}}
    print(f'{len(rows)} jobs in {wall:.1f} s; statuses {statuses}')
    print(f'energy_j (every axis and total) vs simulate --json: worst relative difference '
          f'{rel.max():.2e} (median of the per-job worst {np.median(rel):.2e}); jobs above '
          f'1e-9: {int((rel > 1e-9).sum())}')
    for what, ms in (('start command -> first job/live', start),
                     ('last job/live -> job/result', end)):
        seen = ms[np.isfinite(ms)]
        print(f'{what}: median {np.median(seen):.1f} ms, p99 {np.percentile(seen, 99):.1f} ms, '
              f'max {seen.max():.1f} ms ({ms.shape[0] - seen.shape[0]} jobs without job/live)')
    print(f'load average after: {os.getloadavg()[0]:.1f}')
    if args.record:
        print(checked)
    for name in NODES:
        a, b = rss.get(10, {}).get(name), rss.get(args.jobs, {}).get(name)
        if a is not None and b is not None:
            print(f'RSS {name}: {a:.1f} MiB after job 10, {b:.1f} MiB after job {args.jobs} '
                  f'({b - a:+.1f} MiB)')


def _check_recordings(out: Path, results: dict[str, dict], rows: list,
                      result_wall: dict[str, float]) -> str:
    """Wait for every job's recording, then check its mark and its /power totals; how long
    after the job's result (as the bench received it) its metadata was last written."""
    from feed_axis_energy.graph import JOB_KEY, recording_gaps
    from feed_axis_energy.record import bagio
    jobs = [r[0] for r in rows]
    t0 = time.monotonic()
    while not all((out / j / 'metadata.yaml').exists() for j in jobs):
        if time.monotonic() - t0 > 60:
            missing = [j for j in jobs if not (out / j / 'metadata.yaml').exists()]
            raise SystemExit(f'recordings missing after 60 s: {missing[:5]}')
        time.sleep(0.1)
    waited = time.monotonic() - t0
    lag_ms = np.array([(out / j / 'metadata.yaml').stat().st_mtime - result_wall[j]
                       for j in jobs]) * 1e3
    worst, bad = 0.0, []
    for job in jobs:
        res = results[job]
        mark = bagio.read_custom_data(out / job, JOB_KEY)
        power = bagio.read_series(out / job, bagio.TOPIC_POWER)
        if (not mark['complete'] or mark['status'] != res['status'] or recording_gaps(out / job)
                or power.t.shape[0] != res['samples']):
            bad.append(f"{job} ({mark['status']}: {'; '.join(mark['gaps'])}; "
                       f"{power.t.shape[0]} of {res['samples']} samples)")
            continue
        for name, value in zip(power.names, power.positions[-1].tolist()):
            ref = res['energy_j'][name]
            worst = max(worst, abs(value / ref - 1) if ref else abs(value))
    hidden = [p.name for p in out.iterdir() if p.name.startswith('.')]
    return (f'recordings: {len(jobs) - len(bad)} of {len(jobs)} complete, marked with the '
            f'job\'s status and holding its samples (bad: {bad[:5]}); /power totals vs the '
            f'results: worst relative difference {worst:.2e}; hidden temporaries left: '
            f'{len(hidden)}; waited {waited:.2f} s for them after the RSS figures; job/result '
            f'-> its recording\'s metadata written: median {np.median(lag_ms):.1f} ms, p99 '
            f'{np.percentile(lag_ms, 99):.1f} ms, max {lag_ms.max():.1f} ms')


if __name__ == '__main__':
    main()
