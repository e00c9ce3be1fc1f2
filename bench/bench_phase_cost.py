"""Issue 23's measures: the cost of a simulation against its moves and its samples.

Usage: python bench/bench_phase_cost.py [--case demonstrator,contour,sweep,help]
                                        [--hours H] [--runs N] [--variants N] [--jobs N]

Cases (each a ``python -m feed_axis_energy`` child, reaped with ``os.wait4`` for its own CPU
time and peak RSS; process start included; bytecode cache on, as an installed package):

* ``demonstrator``: ``simulate --json --quiet`` of H hours (default 8) of the paper's
  reciprocating strokes (``bench_scale.demonstrator_program``: 400 mm at 100..500 mm/s, 1 s
  dwells) on ``config/demonstrator.yaml`` at its 1 kHz. **The per-sample floor is measured in
  the same run**: a bare numpy evaluation of a minimal per-sample model over the same number
  of samples, one million at a time (each sample's stroke by ``searchsorted``, its trapezoid
  speed and acceleration, force ``m a + F_c sign(v) + d v``, ``P = F v``, ``sum P dt``): what
  any per-sample tool pays at least. Printed: the tool's wall and CPU time, the floor's, and
  their ratio (target <= 1.0 x and <= 1 s).
* ``contour``: the dense 3-axis contour of H hours (``bench_scale.contour_program``, about 20
  blocks/s) on ``config/three_axis_mill.yaml``: wall time per source line (target <= 10 us).
* ``sweep``: ``sweep`` of the contour (``--hours`` as given) over N variants (default 100:
  ``load_kg`` x ``feed_override``, 10 x 10) with ``--jobs`` workers (default 2) (target <= 60 s
  on 2 cores for 8 hours; a shorter program gives the cost per variant-hour).
* ``help``: ``--help`` start-up, best of N (target <= 0.25 s).

Every figure is printed with its unit; ``--runs`` repeats each case (minimum, median and
maximum printed). Memory: peak RSS of the child (target <= 250 MB in every case).
"""
from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_scale import contour_program, demonstrator_program  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ENV = {k: v for k, v in os.environ.items() if k != 'PYTHONDONTWRITEBYTECODE'}
ENV['PYTHONPATH'] = str(ROOT) + (os.pathsep + ENV['PYTHONPATH'] if ENV.get('PYTHONPATH')
                                 else '')


def child_usage(argv: list[str]) -> tuple[float, float, int, bytes]:
    """Run ``python -m feed_axis_energy ARGV``, reaped with ``os.wait4``: wall [s], the
    child's own CPU time [s] and peak RSS [bytes], its stdout."""
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as out_f, tempfile.TemporaryFile() as err_f:
        proc = subprocess.Popen([sys.executable, '-m', 'feed_axis_energy', *argv], cwd=ROOT,
                                env=ENV, stdout=out_f, stderr=err_f)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        code = os.waitstatus_to_exitcode(status)
        proc.returncode = code
        out_f.seek(0)
        err_f.seek(0)
        out, err = out_f.read(), err_f.read()
    if code != 0:
        sys.exit(f'{" ".join(argv)}: exit {code}: {err.decode()[-800:]}')
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss * 1024, out


def strokes(text: str) -> tuple[np.ndarray, np.ndarray]:
    """Feed [m/s] and signed length [m] of every G1 stroke of a demonstrator program."""
    feed, length = [], []
    x, f = 0.0, 0.0
    for line in text.splitlines():
        words = {w[0]: float(w[1:]) for w in line.split() if w[0] in 'XF' and len(w) > 1}
        if 'F' in words:
            f = words['F'] / 60e3
        if 'X' in words and not line.startswith('G0'):
            new = words['X'] / 1e3
            feed.append(f)
            length.append(new - x)
            x = new
    return np.array(feed), np.array(length)


def floor_seconds(text: str, samples: int, *, rate_hz: float, amax: float, mass_kg: float,
                  coulomb_n: float, viscous_ns_m: float, dwell_s: float = 1.0,
                  block: int = 1_000_000) -> tuple[float, float]:
    """The per-sample floor: wall time [s] of a minimal per-sample model over ``samples``
    samples of the program's strokes (trapezoid profiles at ``amax``, a dwell after each),
    and the energy it sums [J] (printed, so the work cannot be skipped)."""
    t0 = time.perf_counter()
    feed, length = strokes(text)
    dist = np.abs(length)
    v_top = np.minimum(feed, np.sqrt(dist * amax))          # triangle when too short
    ramp = v_top / amax
    move = dist / v_top + ramp                              # trapezoid duration
    period = move + dwell_s
    start = np.concatenate(([dwell_s], dwell_s + np.cumsum(period)[:-1]))
    sign = np.sign(length)
    dt = 1.0 / rate_hz
    energy = 0.0
    for lo in range(0, samples, block):
        t = np.arange(lo, min(lo + block, samples)) * dt
        k = np.clip(np.searchsorted(start, t, side='right') - 1, 0, start.size - 1)
        tau = t - np.take(start, k)
        a_k, top, dur = amax, np.take(v_top, k), np.take(move, k)
        v = np.clip(np.minimum(np.minimum(a_k * tau, top), a_k * (dur - tau)), 0.0, None)
        r_k = np.take(ramp, k)
        acc = np.where(tau < r_k, a_k, np.where(tau > dur - r_k, -a_k, 0.0))
        acc = np.where(v > 0.0, acc, 0.0)
        v = v * np.take(sign, k)
        acc = acc * np.take(sign, k)
        force = mass_kg * acc + coulomb_n * np.sign(v) + viscous_ns_m * v
        energy += float(np.sum(force * v)) * dt
    return time.perf_counter() - t0, energy


def spread(values: list[float], unit: str, fmt: str = '.2f') -> str:
    if len(values) == 1:
        return f'{values[0]:{fmt}} {unit}'
    return (f'{min(values):{fmt}} / {statistics.median(values):{fmt}} / '
            f'{max(values):{fmt}} {unit} (min / median / max of {len(values)})')


Runs = tuple[dict, list[float], list[float], list[float]]


def simulated(prog: Path, machine: Path, runs: int) -> Runs:
    """``simulate --json`` of ``prog`` ``runs`` times: the summary, walls [s], CPU times [s]
    and peak RSS [MiB]."""
    walls, cpus, rss = [], [], []
    summary: dict = {}
    for _ in range(runs):
        wall, cpu, peak, out = child_usage(['simulate', str(prog), '--machine', str(machine),
                                            '--json', '--quiet'])
        summary = json.loads(out)
        walls.append(wall)
        cpus.append(cpu)
        rss.append(peak / 2 ** 20)
    return summary, walls, cpus, rss


def demonstrator(tmp: Path, hours: float, runs: int) -> None:
    text = demonstrator_program(hours)
    prog = tmp / 'demonstrator.nc'
    prog.write_text(text)
    summary, walls, cpus, rss = simulated(prog, ROOT / 'config' / 'demonstrator.yaml', runs)
    floors = []
    for _ in range(runs):
        f, e = floor_seconds(text, int(summary['samples']), rate_hz=1000.0, amax=2.5,
                             mass_kg=40.0, coulomb_n=20.0, viscous_ns_m=200.0)
        floors.append(f)
    ratio = [w / f for w, f in zip(walls, floors)]
    print(f'demonstrator  {len(text.splitlines()):,} lines, {summary["duration_s"] / 3600:.2f} h, '
          f'{summary["samples"]:,} samples at 1 kHz, energy {summary["energy_j"]["total"]:.6g} J')
    print(f'  tool end to end: wall {spread(walls, "s")}, CPU {spread(cpus, "s")}, '
          f'peak RSS {spread(rss, "MiB", ".0f")}')
    print(f'  per-sample numpy floor, same samples: {spread(floors, "s")} '
          f'(floor energy {e:.6g} J, a different model: printed so the work is done)')
    print(f'  tool / floor: {spread(ratio, "x")}   (target <= 1.0 x and <= 1 s)')


def contour(tmp: Path, hours: float, runs: int) -> None:
    text = contour_program(hours)
    prog = tmp / 'contour.nc'
    prog.write_text(text)
    lines = len(text.splitlines())
    summary, walls, cpus, rss = simulated(prog, ROOT / 'config' / 'three_axis_mill.yaml', runs)
    per_line = [w / lines * 1e6 for w in walls]
    print(f'contour       {lines:,} lines, {summary["duration_s"] / 3600:.2f} h, '
          f'{summary["samples"]:,} samples, energy {summary["energy_j"]["total"]:.6g} J')
    print(f'  tool end to end: wall {spread(walls, "s")}, CPU {spread(cpus, "s")}, '
          f'peak RSS {spread(rss, "MiB", ".0f")}')
    print(f'  per line: {spread(per_line, "us", ".1f")}   (target <= 10 us)')


def sweep(tmp: Path, hours: float, runs: int, variants: int, jobs: int) -> None:
    text = contour_program(hours)
    prog = tmp / 'contour.nc'
    prog.write_text(text)
    side = max(int(round(math.sqrt(variants))), 1)
    other = max(variants // side, 1)
    machine = ROOT / 'config' / 'three_axis_mill.yaml'
    argv = ['sweep', str(prog), '--machine', str(machine), '--json', '--quiet',
            '--jobs', str(jobs), '--vary', f'load_kg=0:90:{side}',
            '--vary', f'feed_override=0.5:1.4:{other}']
    walls, cpus, rss = [], [], []
    for _ in range(runs):
        wall, cpu, peak, out = child_usage(argv)
        json.loads(out)
        walls.append(wall)
        cpus.append(cpu)
        rss.append(peak / 2 ** 20)
    print(f'sweep         {side * other} variants + baseline of the {hours:g} h contour '
          f'({len(text.splitlines()):,} lines), --jobs {jobs}')
    print(f'  wall {spread(walls, "s")}, CPU {spread(cpus, "s")} (its workers included), '
          f'peak RSS of one process {spread(rss, "MiB", ".0f")}   '
          f'(target <= 60 s on 2 cores for 100 variants of 8 h)')


def startup(runs: int) -> None:
    child_usage(['--help'])                  # fills the bytecode cache
    walls = [child_usage(['--help'])[0] for _ in range(max(runs, 5))]
    print(f'--help        wall {spread(walls, "s", ".3f")}, best {min(walls):.3f} s   '
          '(target <= 0.25 s)')


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--case', default='demonstrator,contour,help',
                    help='comma-separated: demonstrator, contour, sweep, help')
    ap.add_argument('--hours', type=float, default=8.0, help='program length [h]')
    ap.add_argument('--runs', type=int, default=1, help='repeats of each case')
    ap.add_argument('--variants', type=int, default=100, help='sweep variants')
    ap.add_argument('--jobs', type=int, default=2, help='sweep worker processes')
    args = ap.parse_args()
    cases = [c.strip() for c in args.case.split(',') if c.strip()]
    bad = [c for c in cases if c not in ('demonstrator', 'contour', 'sweep', 'help')]
    if bad:
        ap.error(f'unknown case {bad[0]!r}')
    print(f'{time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())}, load average '
          f'{os.getloadavg()[0]:.2f}, {os.cpu_count()} CPUs', flush=True)
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        for case in cases:
            if case == 'demonstrator':
                demonstrator(tmp, args.hours, args.runs)
            elif case == 'contour':
                contour(tmp, args.hours, args.runs)
            elif case == 'sweep':
                sweep(tmp, args.hours, args.runs, args.variants, args.jobs)
            else:
                startup(args.runs)
            sys.stdout.flush()


if __name__ == '__main__':
    main()
