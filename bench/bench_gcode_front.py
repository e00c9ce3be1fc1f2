"""Time the front end of the G-code reader (text -> blocks) on the 100 000-line program.

Run by hand from the repository root:
``PYTHONPATH=. .venv/bin/python bench/bench_gcode_front.py [--lines N] [--repeat R]``.
Prints, for the program of ``bench_gcode.py``: the CPU time of ``flow.read_blocks`` (lexing,
values as floats, flow control; no interpretation), the time of the whole ``load_gcode``,
``gcodeparser`` if installed, and the peak memory [MiB] of reading a program of
``--big`` lines (default 1 000 000) through ``read_blocks`` (tracemalloc; the program text
and its list of lines included).
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys
import tempfile
import time
import tracemalloc
import warnings

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_gcode import make_program  # noqa: E402
from feed_axis_energy.gcode.load import load_gcode  # noqa: E402
from feed_axis_energy.gcode.read.flow import read_blocks  # noqa: E402


def best_of(fn, repeat: int) -> float:
    """Best CPU time [s] of ``repeat`` calls (CPU time: the machine is shared)."""
    best = math.inf
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def drain(text: str) -> int:
    """Read every block; return how many there were."""
    n = 0
    for _ in read_blocks(text, file='bench.nc'):
        n += 1
    return n


def main() -> None:
    """Print the timings and the memory figure."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--lines', type=int, default=100_000)
    ap.add_argument('--repeat', type=int, default=3)
    ap.add_argument('--big', type=int, default=1_000_000)
    args = ap.parse_args()
    text = make_program(args.lines)
    n = text.count('\n')
    blocks = drain(text)
    front = best_of(lambda: drain(text), args.repeat)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'bench.nc'
        path.write_text(text)
        whole = best_of(lambda: load_gcode(path), args.repeat)
    try:
        from gcodeparser import GcodeParser
    except ImportError:
        theirs = math.nan
    else:
        with warnings.catch_warnings():
            warnings.simplefilter('ignore', DeprecationWarning)
            theirs = best_of(lambda: GcodeParser(text), args.repeat)
    print(f'lines: {n}, blocks: {blocks}')
    print(f'read_blocks (front only): {front:.3f} s CPU  {n / front:,.0f} lines/s')
    print(f'load_gcode (whole parse): {whole:.3f} s CPU  {n / whole:,.0f} lines/s')
    print(f'gcodeparser:              {theirs:.3f} s CPU  {n / theirs:,.0f} lines/s')
    print(f'ratio gcodeparser / load_gcode: {theirs / whole:.2f}x')
    if args.big:
        big = make_program(args.big)
        size = len(big) / 2 ** 20
        tracemalloc.start()
        drain(big)
        peak = tracemalloc.get_traced_memory()[1] / 2 ** 10
        tracemalloc.stop()
        print(f'{args.big:,} lines ({size:.1f} MiB of text): read_blocks peak memory '
              f'{peak:,.0f} KiB above the text')


if __name__ == '__main__':
    main()
