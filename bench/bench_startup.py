"""Start-up time of the command: wall and CPU time of N process starts (best and median).

Usage: python bench/bench_startup.py [N]   (default 10)

Measures ``feed-axis-energy --help`` and ``simulate`` of a 10-line program (``--json``),
each as a fresh ``python -m feed_axis_energy`` process, and prints best / median wall time
and best / median CPU time of the child (user + system, from ``os.wait4``: steadier than the
wall time while other work shares the machine) in seconds.
Target (issue 10): <= 0.25 s. The children run with the bytecode cache on, as an installed
package does (``PYTHONDONTWRITEBYTECODE``, which this workplace sets, is removed from their
environment; the first, discarded start fills the cache).
"""
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROGRAM = '\n'.join(['G21 G90 G17', 'G0 X0 Y0 Z5', 'G1 Z0 F300', 'G1 X20 F1200', 'G1 Y20',
                     'G2 X30 Y10 I0 J-10', 'G1 X0 Y0', 'G4 P0.5', 'G0 Z5', 'M2']) + '\n'


ENV = {k: v for k, v in os.environ.items() if k != 'PYTHONDONTWRITEBYTECODE'}


def _time(argv: list[str], n: int) -> tuple[list[float], list[float]]:
    """Wall times [s] and CPU times (user + system of the child, ``os.wait4``) [s]."""
    wall, cpu = [], []
    subprocess.run([sys.executable, '-m', 'feed_axis_energy', *argv], cwd=ROOT, env=ENV,
                   capture_output=True)            # fills the bytecode cache
    for _ in range(n):
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, '-m', 'feed_axis_energy', *argv], cwd=ROOT,
                                env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        err = proc.stderr.read()
        _, status, usage = os.wait4(proc.pid, 0)
        wall.append(time.perf_counter() - t0)
        cpu.append(usage.ru_utime + usage.ru_stime)
        code = os.waitstatus_to_exitcode(status)
        if code != 0:
            sys.exit(f'{argv}: exit {code}: {err.decode()[-300:]}')
    return wall, cpu


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    with tempfile.TemporaryDirectory() as tmp:
        prog = Path(tmp) / 'ten_lines.nc'
        prog.write_text(PROGRAM)
        cases = {'--help': ['--help'],
                 'simulate 10-line program (3-axis mill)':
                     ['simulate', str(prog), '--machine',
                      str(ROOT / 'config' / 'three_axis_mill.yaml'), '--json', '--quiet']}
        print(f'{"command":44s} {"best [s]":>9s} {"median [s]":>11s} {"CPU best [s]":>13s} '
              f'{"CPU median [s]":>15s}  ({n} starts)')
        for label, argv in cases.items():
            wall, cpu = _time(argv, n)
            print(f'{label:44s} {min(wall):9.3f} {statistics.median(wall):11.3f} '
                  f'{min(cpu):13.3f} {statistics.median(cpu):15.3f}')


if __name__ == '__main__':
    main()
