"""Time ``load_gcode`` against ``gcodeparser`` on a generated 100 000-line contour program.

Run by hand from the repository root:
``PYTHONPATH=. .venv/bin/python bench/bench_gcode.py [--lines N] [--repeat R]``.
The program is deterministic (seeded): G1 and G2/G3 (I/J and R forms) contour moves with
F words and comments. Both parsers get the same text and run in turn, ``repeat`` times each
in the same process; the figures are the best wall (and CPU) times.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import random
import tempfile
import time
import warnings

from feed_axis_energy.gcode.load import load_gcode


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


def time_both(ours, theirs, repeat: int) -> tuple[list[float], list[float]]:
    """Best wall and CPU time [s] of ``ours`` and ``theirs`` (``None``: not run), called in
    turn ``repeat`` times so that a change in the load of a shared machine falls on both."""
    best = [math.inf] * 4
    for _ in range(repeat):
        for k, fn in enumerate((ours, theirs)):
            if fn is None:
                continue
            w0, c0 = time.perf_counter(), time.process_time()
            fn()
            w1, c1 = time.perf_counter(), time.process_time()
            best[k] = min(best[k], w1 - w0)
            best[2 + k] = min(best[2 + k], c1 - c0)
    return best[:2], best[2:]


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
        try:
            from gcodeparser import GcodeParser
        except ImportError:
            print('gcodeparser not installed')
            theirs = None
        else:
            def theirs():
                with warnings.catch_warnings():
                    warnings.simplefilter('ignore', DeprecationWarning)
                    GcodeParser(path.read_text())
        wall, cpu = time_both(lambda: load_gcode(path), theirs, args.repeat)
    print(f'lines: {n}, moves: {len(prog.moves)}, path length: '
          f'{sum(m.length_m for m in prog.moves):.3f} m')
    print(f'feed_axis_energy load_gcode: {wall[0]:.3f} s  {n / wall[0]:,.0f} lines/s  '
          f'(CPU {cpu[0]:.3f} s)')
    if theirs is None:
        return
    print(f'gcodeparser GcodeParser:     {wall[1]:.3f} s  {n / wall[1]:,.0f} lines/s  '
          f'(CPU {cpu[1]:.3f} s)')
    print(f'speed ratio (ours / gcodeparser): {wall[1] / wall[0]:.2f}x '
          f'(CPU time: {cpu[1] / cpu[0]:.2f}x)')


if __name__ == '__main__':
    main()
