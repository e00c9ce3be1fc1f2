"""A campaign of 100 programs: ``batch`` with 1 and with 2 worker processes, speed-up.

Usage: python bench/bench_batch.py [--programs N] [--minutes M] [--workers W] [--repeat R]

Writes N (default 100) generated 3-axis programs of about M minutes each (default 4; dense
1 mm G1 chords with G2/G3 turns at F1200, each program with its own seed so no two are
alike) to a temporary directory and runs
``python -m feed_axis_energy batch DIR --machine config/three_axis_mill.yaml --json --quiet``
as a child process with ``--jobs 1`` and with ``--jobs W`` (default 2), best of R (default 2)
runs each, process start included. Prints the wall times, the speed-up, samples per second
and whether the two JSON outputs are equal, with the load average of the machine before and
after (the machine is shared: a load above 0 makes the speed-up smaller than on an idle one).
"""
import argparse
import json
import math
import os
from pathlib import Path
import random
import subprocess
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parents[1]


def program(seed: int, minutes: float) -> str:
    """Rows of 1 mm chords with a Z wave, joined by half circles, about ``minutes`` long."""
    rng = random.Random(seed)
    lines = [f'( bench_batch program {seed} )', 'G21 G90 G94 G17 G64', 'G0 X0 Y0 Z5',
             'G1 Z-1 F600']
    feed = 1200.0                                # mm/min: 20 mm/s, 20 blocks/s of 1 mm
    n_blocks = int(minutes * 60.0 * 20.0)
    amp = rng.uniform(0.5, 3.0)
    row = rng.randint(60, 200)
    x = y = 0.0
    k = 0
    direction = 1.0
    while k < n_blocks:
        for j in range(row):
            x += direction
            z = -1.0 + 0.5 * math.sin(0.05 * (k + j))
            lines.append(f'G1 X{x:.4f} Y{y + amp * math.sin(0.1 * j):.4f} Z{z:.4f} F{feed:g}')
        k += row
        lines.append(f'G1 Y{y + 2.0:.4f}')
        arc = 'G3' if direction > 0 else 'G2'
        lines.append(f'{arc} X{x:.4f} Y{y + 6.0:.4f} I0 J2.0')
        y += 6.0
        direction = -direction
        if y > 250.0:
            lines += ['G0 Z5', 'G0 X0 Y0', 'G1 Z-1 F600']
            x = y = 0.0
            direction = 1.0
    lines.append('M30')
    return '\n'.join(lines) + '\n'


def run(directory: Path, workers: int) -> tuple[float, dict]:
    """Wall time and JSON of one ``batch`` run as a child process."""
    argv = [sys.executable, '-m', 'feed_axis_energy', 'batch', str(directory), '--machine',
            str(ROOT / 'config' / 'three_axis_mill.yaml'), '--jobs', str(workers), '--json',
            '--quiet']
    t0 = time.perf_counter()
    proc = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f'batch --jobs {workers}: exit {proc.returncode}: {proc.stderr[-500:]}')
    return wall, json.loads(proc.stdout)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--programs', type=int, default=100)
    ap.add_argument('--minutes', type=float, default=4.0)
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--repeat', type=int, default=2)
    args = ap.parse_args()
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        for i in range(args.programs):
            (d / f'p{i:04d}.nc').write_text(program(i, args.minutes))
        walls: dict[int, float] = {}
        docs: dict[int, dict] = {}
        for _ in range(args.repeat):
            for w in (1, args.workers):
                wall, doc = run(d, w)
                walls[w] = min(walls.get(w, math.inf), wall)
                docs[w] = doc
    samples = sum(r['summary']['samples'] for r in docs[1]['results'])
    hours = sum(r['summary']['duration_s'] for r in docs[1]['results']) / 3600.0
    print(f'{args.programs} programs, {hours:.2f} h of program, {samples:,} samples at 1 kHz '
          f'(three_axis_mill), best of {args.repeat}')
    for w in (1, args.workers):
        print(f'--jobs {w}: wall {walls[w]:.2f} s  {samples / walls[w]:,.0f} samples/s  '
              f'{hours * 3600.0 / walls[w]:,.0f}x real time')
    print(f'speed-up {args.workers} workers over 1: {walls[1] / walls[args.workers]:.2f}x '
          f'(on {os.cpu_count()} cores)')
    print(f'results equal: {docs[1] == docs[args.workers]}')
    load_after = os.getloadavg()
    print(f'load average (1 min) before {load_before[0]:.2f}, after {load_after[0]:.2f}')


if __name__ == '__main__':
    main()
