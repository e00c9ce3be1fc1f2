"""Benchmark of the trajectory planner (run by hand: ``python bench/bench_plan.py``).

(a) the 10-minute reciprocating demonstrator program: 400 mm stroke along X, 1 s dwell at each
    end, feeds 100..500 mm/s, exact stop; X limits v = 0.6 m/s, a = 2.5 m/s^2, j = 50 m/s^3.
(b) a dense 10-minute contour of short G1/G2/G3 moves (~20 moves per second of program time)
    on X/Y/Z.
Prints planning+sampling time (best of 3), samples per second and the real-time factor at 1 kHz.
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np

from feed_axis_energy.gcode.program import Move, MoveKind, Program
from feed_axis_energy.machine.limits import AxisLimits, PlannerOptions
from feed_axis_energy.plan.trajectory import plan

PROGRAM_S = 600.0


def reciprocating(rng: np.random.Generator) -> Program:
    """Back-and-forth strokes with dwells until about 10 minutes of program time."""
    moves = []
    x, t, line = 0.0, 0.0, 1
    while t < PROGRAM_S:
        feed = float(rng.choice([0.1, 0.2, 0.3, 0.4, 0.5]))
        x1 = 0.4 if x == 0.0 else 0.0
        moves.append(Move(MoveKind.LINEAR, line, (x, 0.0, 0.0), (x1, 0.0, 0.0),
                          feed_m_s=feed, exact_stop=True, length_m=0.4))
        moves.append(Move(MoveKind.DWELL, line + 1, (x1, 0.0, 0.0), (x1, 0.0, 0.0),
                          dwell_s=1.0))
        t += 0.4 / feed + 1.0 + 0.3
        x, line = x1, line + 2
    return Program('reciprocating', tuple(moves))


def contour(rng: np.random.Generator) -> Program:
    """Short lines and arcs wandering around a box, ~20 moves per second."""
    moves = []
    p = np.array([0.1, 0.1, 0.05])
    heading = 0.0
    feed = 0.04
    n_moves = int(PROGRAM_S * 20)
    for i in range(n_moves):
        line = i + 1
        kind = rng.choice([MoveKind.LINEAR, MoveKind.ARC_CW, MoveKind.ARC_CCW])
        if kind == MoveKind.LINEAR:
            heading += rng.normal(0.0, 0.3)
            step = 0.002
            q = p + step * np.array([math.cos(heading), math.sin(heading), 0.0])
            q[2] = 0.05 + 0.01 * math.sin(i / 50.0)
            q[:2] = np.clip(q[:2], 0.0, 0.2)
            moves.append(Move(MoveKind.LINEAR, line, tuple(p), tuple(q), feed_m_s=feed))
        else:
            r = 0.002
            sign = 1.0 if kind == MoveKind.ARC_CCW else -1.0
            # centre to the left (CCW) or right (CW) of the heading: tangent continuation
            c = p + r * np.array([-math.sin(heading), math.cos(heading), 0.0]) * sign
            turn = rng.uniform(0.3, 1.2)
            a0 = math.atan2(p[1] - c[1], p[0] - c[0])
            a1 = a0 + sign * turn
            q = np.array([c[0] + r * math.cos(a1), c[1] + r * math.sin(a1), p[2]])
            heading += sign * turn
            moves.append(Move(kind, line, tuple(p), tuple(q), feed_m_s=feed,
                              center=(c[0], c[1], p[2]), plane=17))
        p = q
    return Program('contour', tuple(moves))


def run(name: str, program: Program, limits: dict, options: PlannerOptions) -> None:
    dt = math.inf
    for _ in range(3):      # best of three: the machine is shared
        t0 = time.perf_counter()
        motion = plan(program, limits, options=options)
        dt = min(dt, time.perf_counter() - t0)
    print(f'{name}: {len(program.moves)} moves, program {motion.duration_s:.1f} s, '
          f'{motion.n_samples} samples, plan+sample {dt:.3f} s, '
          f'{motion.n_samples / dt:.3g} samples/s, real-time factor {motion.duration_s / dt:.0f}x')


def main() -> int:
    rng = np.random.default_rng(12345)
    opts = PlannerOptions(rate_hz=1000.0)
    x_lim = {'X': AxisLimits(0.6, 2.5, 50.0)}
    xyz = {a: AxisLimits(0.5, 3.0, 60.0) for a in 'XYZ'}
    prog_a = reciprocating(rng)
    prog_b = contour(rng)
    for profile in ('jerk', 'trapezoid'):
        o = PlannerOptions(rate_hz=opts.rate_hz, profile=profile)
        run(f'(a) reciprocating [{profile}]', prog_a, x_lim, o)
        run(f'(b) contour       [{profile}]', prog_b, xyz, o)
    return 0


if __name__ == '__main__':
    sys.exit(main())
