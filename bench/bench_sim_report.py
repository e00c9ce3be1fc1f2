"""``simulate --report``: memory and CPU time against program length, with and without it.

Usage: python bench/bench_sim_report.py [--hours 0.25,1,4] [--repeat 1]

Writes bench_scale's dense 3-axis contour (about 20 blocks/s, config/three_axis_mill.yaml) of
each length to a temporary directory and runs ``simulate PROGRAM --json --quiet`` as a child
process, once without and once with ``--report DIR``. Prints per length: samples, CPU time
(user + system of the child, ``os.wait4``) and peak RSS of both runs, and the report's size.
The report keeps a fixed number of time columns (``report/decimate.py``), so its extra peak
RSS must not grow with the program (the target: flat within a few MiB from 15 min to 4 h);
the extra CPU time is the decimation per chunk plus a fixed cost for the plots.
"""
import argparse
import os
from pathlib import Path
import sys
import tempfile

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_scale  # noqa: E402  (a sibling script, not a package)

ROOT = bench_scale.ROOT
MACHINE = ROOT / 'config' / 'three_axis_mill.yaml'


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--hours', default='0.25,1,4',
                   help='program lengths [h], comma-separated (default 0.25,1,4)')
    p.add_argument('--repeat', type=int, default=1, help='runs of each, best CPU time kept')
    args = p.parse_args()
    try:
        hours = [float(h) for h in args.hours.split(',')]
    except ValueError:
        p.error(f'--hours: numbers separated by commas, got {args.hours[:60]!r}')
    bench_scale.use_bytecode_cache()
    load = os.getloadavg()
    print(f'load average before: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}')
    print(f'{"program":>9} {"samples":>12} {"CPU plain":>10} {"CPU report":>10} '
          f'{"RSS plain":>10} {"RSS report":>10} {"extra RSS":>10} {"report":>9}')
    with tempfile.TemporaryDirectory(prefix='bench-sim-report-') as tmp:
        for h in hours:
            prog = Path(tmp) / f'contour_{h:g}h.nc'
            prog.write_text(bench_scale.contour_program(h))
            base = ['simulate', str(prog), '--machine', str(MACHINE), '--json', '--quiet']
            plain, with_report = [], []
            for i in range(args.repeat):
                _, rss, summary, cpu = bench_scale._wait_run(base)
                plain.append((cpu, rss))
                rep = Path(tmp) / f'report_{h:g}_{i}'
                _, rss_r, _, cpu_r = bench_scale._wait_run(base + ['--report', str(rep)])
                with_report.append((cpu_r, rss_r))
                size = sum(f.stat().st_size for f in rep.iterdir())
            cpu_p, rss_p = min(plain)
            cpu_r, rss_r = min(with_report)
            mib = 1024.0 * 1024.0
            print(f'{h:>7g} h {summary["samples"]:>12,} {cpu_p:>8.2f} s {cpu_r:>8.2f} s '
                  f'{rss_p / mib:>6.1f} MiB {rss_r / mib:>6.1f} MiB '
                  f'{(rss_r - rss_p) / mib:>+6.1f} MiB {size / 1e6:>5.2f} MB')
    load = os.getloadavg()
    print(f'load average after: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
