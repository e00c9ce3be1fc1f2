"""Cost of the electrical side: ``simulate_stream`` with and without declared drives.

Run by hand from the repository root:
``PYTHONPATH=. .venv/bin/python bench/bench_electrical.py [--minutes M] [--repeat R]``.

The dense 3-axis contour of ``bench_simulate.py`` (seeded) is simulated chunk by chunk on
``config/three_axis_mill_drives.yaml`` and on the same machine without its ``drive`` and
``supply`` blocks (same braking rule, so the mechanical work is identical). Printed: samples,
CPU time (``time.process_time``, best of ``--repeat``) of each, the extra CPU time of the
electrical model, and the peak of Python heap allocations (``tracemalloc``) of each, to show
that the electrical side adds memory per chunk, not per sample of the program.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys
import time
import tracemalloc

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_simulate import contour_gcode  # noqa: E402

from feed_axis_energy.gcode.load import parse_gcode  # noqa: E402
from feed_axis_energy.machine.file import (load_machine, machine_from_dict,  # noqa: E402
                                           machine_to_dict)
from feed_axis_energy.sim.stream import simulate_stream  # noqa: E402

CONFIG = Path(__file__).resolve().parents[1] / 'config'


def _without_drives():
    data = machine_to_dict(load_machine(CONFIG / 'three_axis_mill_drives.yaml'))
    data.pop('supply')
    for axis in data['axes'].values():
        axis.pop('drive')
    return machine_from_dict(data)


def _run(prog, machine) -> tuple[float, int]:
    start = time.process_time()
    summary, _ = simulate_stream(prog.moves, machine, file=prog.file, load_kg=50.0)
    return time.process_time() - start, summary['samples']


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--minutes', type=float, default=5.0)
    parser.add_argument('--repeat', type=int, default=3)
    args = parser.parse_args(argv)
    with_drives = load_machine(CONFIG / 'three_axis_mill_drives.yaml')
    plain = _without_drives()
    prog = parse_gcode(contour_gcode(60.0 * args.minutes), file='contour.nc',
                       home=plain.home_point())
    rows = []
    for name, machine in (('without drives', plain), ('with drives', with_drives)):
        best = min(_run(prog, machine) for _ in range(max(1, args.repeat)))
        tracemalloc.start()
        _run(prog, machine)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        rows.append((name, best[0], best[1], peak))
        print(f'{name:15s} {best[1]:>10d} samples  CPU {best[0]:7.3f} s  '
              f'peak heap {peak / 2 ** 20:6.1f} MiB', flush=True)
    extra = rows[1][1] - rows[0][1]
    print(f'electrical model: +{extra:.3f} s CPU ({100.0 * extra / rows[0][1]:+.1f} %), '
          f'+{(rows[1][3] - rows[0][3]) / 2 ** 20:.1f} MiB peak heap')
    return 0


if __name__ == '__main__':
    sys.exit(main())
