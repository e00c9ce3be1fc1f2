"""Long programs end to end: wall time and peak RSS of ``simulate`` as a child process.

Usage: python bench/bench_scale.py [--hours H] [--case demonstrator|contour|dwell|both] [--out]

Writes two programs of H hours (default 8) to a temporary directory:
* demonstrator: the paper's reciprocating 400 mm strokes at 100..500 mm/s with a 1 s dwell
  after every stroke (as config/programs/demonstrator_f*.nc), repeated; 1 axis.
* contour: a dense 3-axis contour of short G1/G2/G3 blocks (about 20 blocks/s), on
  config/three_axis_mill.yaml.
* dwell (only with ``--case dwell``): ``G4 P604800``, one week of dwell between two short
  moves, on config/demonstrator.yaml (``--hours`` is ignored).
Each is run as ``python -m feed_axis_energy simulate PROGRAM --json --quiet`` (and with
``--out BAG`` when asked); process start is included. Prints program duration, wall time,
real-time factor, samples/s, peak RSS (``ru_maxrss`` of the child via ``os.wait4``) and, with
``--out``, bag bytes per sample.

The child runs with Python's bytecode cache on, as an installed package (or a checkout run
before) does: ``PYTHONDONTWRITEBYTECODE`` is removed from its environment and one
``--help`` run warms the cache first. Pass ``--no-bytecode-cache`` to keep the caller's
environment (this workplace sets the variable; every start then compiles the package,
about 0.1-0.2 s).
"""
import argparse
import json
import math
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parents[1]


def demonstrator_program(hours: float) -> str:
    """Reciprocating strokes cycling through the five feeds until ``hours`` are filled."""
    lines = ['( bench: repeated demonstrator strokes )', 'G21 G90 G94 G61', 'G0 X0', 'G4 P1']
    t = 1.0
    feeds = (100, 200, 300, 400, 500)
    i = 0
    while t < hours * 3600.0:
        f = feeds[i % len(feeds)]
        lines += [f'G1 X400 F{f * 60}', 'G4 P1', 'X0', 'G4 P1']
        t += 2 * (400.0 / f + 1.0)           # ramps make it a little longer
        i += 1
    lines.append('M30')
    return '\n'.join(lines) + '\n'


def contour_program(hours: float) -> str:
    """Short chords and arcs at about 20 blocks/s (feed 1200 mm/min, ~1 mm blocks)."""
    lines = ['( bench: dense 3-axis contour )', 'G21 G90 G94 G17 G64', 'G0 X0 Y0 Z5',
             'G1 Z-1 F600']
    n_blocks = int(hours * 3600.0 * 20)
    x = y = 0.0
    k = 0
    while k < n_blocks:
        for j in range(200):                        # a wavy line of 1 mm chords
            x += 1.0
            z = -1.0 + 0.5 * math.sin(0.05 * (k + j))
            lines.append(f'G1 X{x:.4f} Y{y + 2.0 * math.sin(0.1 * j):.4f} Z{z:.4f} F1200')
        k += 200
        y_new = y + 4.0
        lines.append(f'G1 Y{y_new - 2.0:.4f}')     # arc turn back
        lines.append(f'G3 X{x:.4f} Y{y_new + 2.0:.4f} I0 J2.0')
        y = y_new + 2.0
        for j in range(200):
            x -= 1.0
            lines.append(f'G1 X{x:.4f} Y{y:.4f}')
        k += 202
        lines.append(f'G2 X{x:.4f} Y{y + 4.0:.4f} I0 J2.0')
        y += 4.0
        if y > 300.0:
            lines.append('G0 Z5')
            lines.append('G0 X0 Y0')
            lines.append('G1 Z-1 F600')
            x = y = 0.0
    lines.append('M30')
    return '\n'.join(lines) + '\n'


def dwell_program(hours: float) -> str:
    """One week of dwell (``hours`` is ignored): 11 bytes of G-code, 605 million samples."""
    return 'G21 G90\nG1 X10 F600\nG4 P604800\nG1 X0\nM30\n'


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--hours', type=float, default=8.0)
    ap.add_argument('--case', choices=('demonstrator', 'contour', 'dwell', 'both'),
                    default='both')
    ap.add_argument('--out', action='store_true', help='also write the bag (--out)')
    ap.add_argument('--no-bytecode-cache', action='store_true',
                    help='keep the caller\'s PYTHONDONTWRITEBYTECODE (every start compiles)')
    args = ap.parse_args()
    if not args.no_bytecode_cache:
        use_bytecode_cache()
    cases = ('demonstrator', 'contour') if args.case == 'both' else (args.case,)
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases:
            make = {'demonstrator': demonstrator_program, 'contour': contour_program,
                    'dwell': dwell_program}[case]
            text = make(args.hours)
            prog = Path(tmp) / f'{case}.nc'
            prog.write_text(text)
            machine = ROOT / 'config' / ('three_axis_mill.yaml' if case == 'contour'
                                         else 'demonstrator.yaml')
            argv = ['simulate', str(prog), '--machine', str(machine), '--json', '--quiet']
            bag = Path(tmp) / f'{case}.bag'
            if args.out:
                argv += ['--out', str(bag)]
            wall, rss, summary, cpu = _wait_run(argv)
            dur, n = summary['duration_s'], summary['samples']
            line = (f'{case:12s} {len(text.splitlines()):8d} lines  program {dur / 3600:.2f} h  '
                    f'{n:,} samples  wall {wall:.1f} s  {dur / wall:,.0f}x real time  '
                    f'{n / wall:,.0f} samples/s  CPU {cpu:.1f} s  peak RSS {rss / 2**20:.0f} MiB')
            if args.out:
                size = sum(f.stat().st_size for f in bag.rglob('*') if f.is_file())
                line += f'  bag {size / 1e9:.2f} GB ({size / n:.0f} B/sample)'
                shutil.rmtree(bag)
            print(line, flush=True)


CHILD_ENV = dict(os.environ)


def use_bytecode_cache() -> None:
    """Let the children cache bytecode, as an installed package does, and warm the cache."""
    CHILD_ENV.pop('PYTHONDONTWRITEBYTECODE', None)
    subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'simulate', '--help'], cwd=ROOT,
                   env=CHILD_ENV, stdout=subprocess.DEVNULL, check=True)


def _wait_run(argv: list[str]) -> tuple[float, int, dict, float]:
    """Run the child; reap it with ``os.wait4`` for its own rusage: wall [s], peak RSS
    [bytes], the JSON summary, CPU time (user + system) [s]."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, '-m', 'feed_axis_energy', *argv], cwd=ROOT,
                            env=CHILD_ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out = proc.stdout.read()
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        sys.exit(f'{argv}: exit {proc.returncode}: {err.decode()[-500:]}')
    return (wall, usage.ru_maxrss * 1024, json.loads(out),
            usage.ru_utime + usage.ru_stime)


if __name__ == '__main__':
    main()
