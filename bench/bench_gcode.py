"""Time ``load_gcode`` against ``gcodeparser`` on a generated 100 000-line contour program.

Run by hand from the repository root:
``PYTHONPATH=. .venv/bin/python bench/bench_gcode.py [--lines N] [--repeat R]``.
The program is deterministic (seeded): G1 and G2/G3 (I/J and R forms) contour moves with
F words and comments. Both parsers get the same text; best of ``repeat`` wall times.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import random
import tempfile
import time
import warnings

from feed_axis_energy.core.gcode import load_gcode


def make_program(n_lines: int, *, seed: int = 1) -> str:
    """Return a valid program of ``n_lines`` lines (header and footer included)."""
    rng = random.Random(seed)
    out = ['%', 'O1000 (BENCH CONTOUR)', 'G21 G90 G94 G17 G40 G49 G80 G64', 'G0 X0 Y0 Z5',
           'G1 Z-1 F300 (PLUNGE)']
    x = y = 0.0
    z = -1.0
    while len(out) < n_lines - 2:
        r = rng.random()
        if r < 0.5:
            x = round(x + rng.uniform(-20.0, 20.0), 3)
            y = round(y + rng.uniform(-20.0, 20.0), 3)
            feed = f' F{rng.choice((600, 800, 1200, 2400))}' if rng.random() < 0.3 else ''
            out.append(f'N{len(out)} G1 X{x:.3f} Y{y:.3f}{feed}')
        elif r < 0.8:
            # Centre form: pick a centre, rotate the current point about it by < 180 degrees.
            cx = round(x + rng.uniform(-10.0, 10.0), 3)
            cy = round(y + rng.uniform(-10.0, 10.0), 3)
            ang = rng.uniform(0.1, 3.0) * (1 if rng.random() < 0.5 else -1)
            dx, dy = x - cx, y - cy
            c, s = math.cos(ang), math.sin(ang)
            nx = round(cx + c * dx - s * dy, 3)
            ny = round(cy + s * dx + c * dy, 3)
            g = 'G3' if ang > 0 else 'G2'
            dz = round(rng.uniform(-0.5, 0.5), 3) if rng.random() < 0.1 else 0.0
            zw = f' Z{z + dz:.3f}' if dz else ''
            z += dz
            out.append(f'{g} X{nx:.3f} Y{ny:.3f}{zw} I{cx - x:.3f} J{cy - y:.3f}')
            x, y = nx, ny
        elif r < 0.95:
            nx = round(x + rng.uniform(-10.0, 10.0), 3)
            ny = round(y + rng.uniform(-10.0, 10.0), 3)
            half = math.hypot(nx - x, ny - y) / 2.0
            rad = half * rng.uniform(1.05, 3.0)
            g = rng.choice(('G2', 'G3'))
            out.append(f'{g} X{nx:.3f} Y{ny:.3f} R{rad:.4f} ; radius form')
            x, y = nx, ny
        else:
            out.append(f'(CONTOUR SEGMENT {len(out)})')
    out.extend(['G0 Z5', 'M30'])
    return '\n'.join(out) + '\n'


def best_of(fn, repeat: int) -> float:
    """Best wall time [s] of ``repeat`` calls."""
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    """Generate, parse with both, print lines/s and the ratio."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--lines', type=int, default=100_000)
    ap.add_argument('--repeat', type=int, default=3)
    args = ap.parse_args()
    text = make_program(args.lines)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'bench.nc'
        path.write_text(text)
        n = text.count('\n')
        prog = load_gcode(path)
        ours = best_of(lambda: load_gcode(path), args.repeat)
        try:
            from gcodeparser import GcodeParser
        except ImportError:
            print('gcodeparser not installed')
            theirs = math.nan
        else:
            with warnings.catch_warnings():
                warnings.simplefilter('ignore', DeprecationWarning)
                theirs = best_of(lambda: GcodeParser(path.read_text()), args.repeat)
    print(f'lines: {n}, moves: {len(prog.moves)}, path length: '
          f'{sum(m.length_m for m in prog.moves):.3f} m')
    print(f'feed_axis_energy load_gcode: {ours:.3f} s  {n / ours:,.0f} lines/s')
    print(f'gcodeparser GcodeParser:     {theirs:.3f} s  {n / theirs:,.0f} lines/s')
    print(f'speed ratio (ours / gcodeparser): {theirs / ours:.2f}x')


if __name__ == '__main__':
    main()
