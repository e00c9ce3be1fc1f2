"""Benchmark of the whole offline pipeline: G-code text -> parse -> plan -> dynamics + power.

Run by hand from the repository root: ``.venv/bin/python bench/bench_simulate.py``
(options: ``--repeat R``, ``--seconds S``, ``--rate HZ``).

(a) ``config/demonstrator.yaml``: a reciprocating program of about 10 minutes, G61 exact stop,
    ``G1 X400`` / ``G4 P1`` / ``G1 X0`` / ``G4 P1`` at feeds 100..500 mm/s (seeded choice).
(b) ``config/three_axis_mill.yaml``: a dense contour of short G1/G2/G3 blocks (about 20 blocks
    per second of nominal program time, seeded) wandering in XY with a slow Z wave, G64.
(c) ``config/three_axis_mill.yaml``: CAM-style circles of R 100 mm as 720 G1 chords of
    0.87 mm (0.5 deg corners) at F18000 (300 mm/s, about 340 blocks per second), G64, with a
    50 ms dwell after every quarter circle.

The stages are the ones :func:`feed_axis_energy.sim.simulate.simulate_program` runs (the plan
uses the machine's own planner settings, sampled at ``--rate``). Each stage is timed on its
own, best of ``--repeat`` (the machine is shared); the total is the sum of the best stage
times. Printed per program and stage: wall time, samples per second and real-time factor
(planned program duration / wall time).
"""
from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path
import random
import sys
import time
from typing import Callable

from feed_axis_energy.physics.dynamics import compute_dynamics
from feed_axis_energy.physics.energy import compute_power
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.machine.spec import Machine
from feed_axis_energy.plan.trajectory import plan

CONFIG = Path(__file__).resolve().parents[1] / 'config'


def reciprocating_gcode(seconds: float, *, seed: int = 1) -> str:
    """Strokes of 400 mm with 1 s dwells until the nominal time reaches ``seconds``."""
    rng = random.Random(seed)
    out = ['(bench: reciprocating demonstrator program)', 'G21 G90 G94 G61', 'G0 X0']
    x, t = 0, 0.0
    while t < seconds:
        feed = rng.choice((100, 200, 300, 400, 500))        # mm/s
        x = 400 if x == 0 else 0
        out.append(f'G1 X{x} F{feed * 60}')
        out.append('G4 P1')
        t += 400.0 / feed + 1.0 + 0.25                      # + rough ramp time
    out.append('M30')
    return '\n'.join(out) + '\n'


def contour_gcode(seconds: float, *, seed: int = 2, blocks_per_s: float = 20.0) -> str:
    """Short lines and tangent arcs (2 mm, F2400 = 40 mm/s) with small heading changes."""
    rng = random.Random(seed)
    feed_mm_s = 40.0
    step = feed_mm_s / blocks_per_s                          # mm per block
    out = ['(bench: dense contour)', 'G21 G90 G94 G17 G64', 'G0 X100 Y100 Z50',
           f'G1 X100 Y100 Z50 F{feed_mm_s * 60:.0f}']
    x, y, heading = 100.0, 100.0, 0.0
    for i in range(int(seconds * blocks_per_s)):
        if rng.random() < 0.5:
            heading += rng.gauss(0.0, 0.3)
            nx = min(max(x + step * math.cos(heading), 0.0), 200.0)
            ny = min(max(y + step * math.sin(heading), 0.0), 200.0)
            nz = 50.0 + 10.0 * math.sin(i / 50.0)
            out.append(f'G1 X{nx:.4f} Y{ny:.4f} Z{nz:.4f}')
            x, y = nx, ny
        else:
            ccw = rng.random() < 0.5
            sign = 1.0 if ccw else -1.0
            turn = rng.uniform(0.3, 1.2)
            r = step / turn                                  # arc length = step
            cx = x - sign * r * math.sin(heading)
            cy = y + sign * r * math.cos(heading)
            a1 = math.atan2(y - cy, x - cx) + sign * turn
            nx, ny = cx + r * math.cos(a1), cy + r * math.sin(a1)
            out.append(f'{"G3" if ccw else "G2"} X{nx:.4f} Y{ny:.4f} '
                       f'I{cx - x:.4f} J{cy - y:.4f}')
            x, y = nx, ny
            heading += sign * turn
            # the end point was rounded to 0.1 um: continue along the exact end tangent
    out.append('M30')
    return '\n'.join(out) + '\n'


def polyline_gcode(seconds: float, *, feed_mm_s: float = 300.0, chords: int = 720,
                   radius_mm: float = 100.0) -> str:
    """CAM-style quarter circles of short G1 chords (0.87 mm, 0.5 deg corners) at F18000.

    Each quarter (180 chords) ends with a 50 ms dwell, so the speed starts from rest 4 times
    per circle; repeated until the nominal time reaches ``seconds``.
    """
    out = ['(bench: G1 polyline circles)', 'G21 G90 G94 G17 G64',
           f'G0 X{radius_mm:.4f} Y0 Z50', f'G1 F{feed_mm_s * 60:.0f}']
    circ = 2 * chords * radius_mm * math.sin(math.pi / chords)
    for _ in range(max(1, int(seconds * feed_mm_s / circ))):
        for i in range(1, chords + 1):
            a = 2 * math.pi * i / chords
            out.append(f'G1 X{radius_mm * math.cos(a):.4f} Y{radius_mm * math.sin(a):.4f}')
            if i % (chords // 4) == 0:
                out.append('G4 P0.05')
    out.append('M30')
    return '\n'.join(out) + '\n'


def _best(fn: Callable[[], object], repeat: int) -> tuple[float, object]:
    best, out = math.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def run(name: str, text: str, machine: Machine, *, rate_hz: float, repeat: int) -> dict:
    """Time the stages on one program and print one line per stage."""
    options = dataclasses.replace(machine.planner.options(), rate_hz=rate_hz)
    limits = machine.limits()
    t_parse, program = _best(lambda: parse_gcode(text, file=name), repeat)
    t_plan, motion = _best(lambda: plan(program, limits, options=options), repeat)
    t_dyn, power = _best(lambda: compute_power(compute_dynamics(motion, machine),
                                               braking=machine.braking), repeat)
    n, dur = motion.n_samples, motion.duration_s
    total = t_parse + t_plan + t_dyn
    print(f'{name}: {text.count(chr(10))} lines, {len(program.moves)} moves, program '
          f'{dur:.1f} s, {n} samples at {rate_hz:g} Hz, energy '
          f'{float(power.total_energy_j[-1]):.1f} J')
    for stage, dt in (('parse', t_parse), ('plan', t_plan), ('dynamics+power', t_dyn),
                      ('total', total)):
        print(f'  {stage:15s} {dt:8.4f} s  {n / dt:10.3g} samples/s  '
              f'real-time factor {dur / dt:9.0f}x')
    return {'duration_s': dur, 'total_s': total}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeat', type=int, default=3)
    ap.add_argument('--seconds', type=float, default=600.0, help='nominal program time [s]')
    ap.add_argument('--rate', type=float, default=1000.0, help='sample rate [Hz]')
    args = ap.parse_args(argv)
    demo = load_machine(CONFIG / 'demonstrator.yaml')
    mill = load_machine(CONFIG / 'three_axis_mill.yaml')
    a = run('(a) reciprocating/demonstrator', reciprocating_gcode(args.seconds), demo,
            rate_hz=args.rate, repeat=args.repeat)
    b = run('(b) dense contour/three_axis_mill', contour_gcode(args.seconds), mill,
            rate_hz=args.rate, repeat=args.repeat)
    c = run('(c) G1 polyline circles/three_axis_mill', polyline_gcode(args.seconds), mill,
            rate_hz=args.rate, repeat=args.repeat)
    print(f'(c) total real-time factor {c["duration_s"] / c["total_s"]:.0f}x (no target)')
    for label, res, target in (('(a)', a, 5000.0), ('(b)', b, 500.0)):
        factor = res['duration_s'] / res['total_s']
        verdict = 'meets' if factor >= target else 'MISSES'
        print(f'{label} total real-time factor {factor:.0f}x {verdict} the target {target:.0f}x')
    return 0


if __name__ == '__main__':
    sys.exit(main())
