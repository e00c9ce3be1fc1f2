"""Peak memory and time of reading damaged measured-run bags (the bag boundary, issue 9).

Builds one small measured-run bag, then for each seed flips 1..50 random bytes of a copy of
its MCAP file and reads both measured topics through ``bagio.read_series``. Prints how the
reads ended (read, or the kind of DataError) and the peak Python heap of the worst read
(``tracemalloc``), with and without the MCAP framing check (``--no-check`` shows what
``rosbags`` alone allocates: a damaged 64-bit length field is allocated as it stands).

Usage: ``PYTHONPATH=. .venv/bin/python bench/bench_damaged_bags.py [--bags N] [--no-check]``
"""
from __future__ import annotations

import argparse
from collections import Counter
import contextlib
import shutil
import sys
import tempfile
import time
from pathlib import Path
import tracemalloc

import numpy as np

from feed_axis_energy.record import bagio
from feed_axis_energy.errors import DataError
from feed_axis_energy.measured.importer import import_campaign
from feed_axis_energy.measured.manifest import load_campaign

TOPICS = (bagio.TOPIC_MEASURED_POWER, bagio.TOPIC_MEASURED_KINEMATICS)


def build(root: Path) -> Path:
    """A 200-sample measured run (X power and position), imported with 10 samples/message."""
    lines = ['t,P,X'] + [f'{i * 0.1:.2f},{0.05 + 0.01 * (i % 7):.4f},{(i % 40) * 1.5:.2f}'
                         for i in range(200)]
    (root / 'r0.csv').write_text('\n'.join(lines) + '\n')
    (root / 'm.yaml').write_text(
        'machine: ' + str(Path('config/demonstrator.yaml').resolve()) + '\n'
        'runs:\n  - name: r0\n    data: r0.csv\n    load_kg: 0\n'
        '    motion: {from_data: actual}\n    time: {column: t, unit: s}\n'
        '    axes: {X: {power: {column: P, unit: kW}, position: {column: X, unit: mm}}}\n')
    import_campaign(load_campaign(root / 'm.yaml'), root / 'bags', batch=10)
    return root / 'bags' / 'r0'


def main() -> int:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--bags', type=int, default=200, help='damaged copies (default 200)')
    parser.add_argument('--no-check', action='store_true',
                        help='skip the MCAP framing check (shows what rosbags allocates)')
    args = parser.parse_args()
    if args.no_check:
        bagio.check_mcap = lambda *a, **k: None
    root = Path(tempfile.mkdtemp(prefix='fae-bench-bags-'))
    outcomes: Counter[str] = Counter()
    worst_bytes, worst_s, total_s = 0, 0.0, 0.0
    try:
        bag = build(root)
        mcap = next(bag.glob('*.mcap'))
        print(f'bag: {mcap.stat().st_size} bytes of MCAP, {len(TOPICS)} topics read per copy',
              file=sys.stderr)
        for seed in range(args.bags):
            copy = root / f'copy{seed}'
            shutil.copytree(bag, copy)
            target = copy / mcap.name
            data = bytearray(target.read_bytes())
            rng = np.random.default_rng(seed)
            for i in rng.integers(0, len(data), size=1 + seed % 50):
                data[i] ^= int(rng.integers(1, 256))
            target.write_bytes(bytes(data))
            tracemalloc.start()
            t0 = time.perf_counter()
            try:
                for topic in TOPICS:
                    bagio.read_series(copy, topic)
                outcomes['read (damage in values or padding)'] += 1
            except DataError as err:
                reason = err.reason.split(':')[0]
                outcomes['DataError: ' + ('framing check' if 'truncated or damaged' in
                                          str(err) else reason)] += 1
            except MemoryError:
                outcomes['MemoryError (escaped)'] += 1
            except Exception as err:  # noqa: B902 - counted, this is what the bench looks for
                outcomes[f'escaped: {type(err).__name__}'] += 1
            finally:
                dt = time.perf_counter() - t0
                _, peak = tracemalloc.get_traced_memory()
                tracemalloc.stop()
            worst_bytes, worst_s, total_s = max(worst_bytes, peak), max(worst_s, dt), total_s + dt
            with contextlib.suppress(OSError):
                shutil.rmtree(copy)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    print(f'{args.bags} damaged copies, framing check {"off" if args.no_check else "on"}:')
    for what, n in outcomes.most_common():
        print(f'  {n:5d}  {what}')
    print(f'peak Python heap of the worst read: {worst_bytes / 1e6:.1f} MB')
    print(f'read time: worst {worst_s * 1e3:.1f} ms, mean {total_s / args.bags * 1e3:.1f} ms')
    return 0


if __name__ == '__main__':
    sys.exit(main())
