"""Alignment study: ``PYTHONPATH=. .venv/bin/python bench/bench_align.py [--seeds N]``.

Campaigns like issue 11's hidden rig: the demonstrator's single X axis, reciprocating 400 mm
strokes (3 cycles, 1 s dwells), 15 runs per seed (100 ... 500 mm/s x 0, 17.336, 22.711 kg),
load-dependent friction (mu = 0.1) in the truth that the declared model lacks, a 50 ms
averaging meter stamped at the window's end, 1.5 W noise, 1 W quantisation and a random
start offset per run drawn uniformly from +-``--spread-s`` (default 4 s: one to two stroke
cycles at the higher feeds). The declared model is simulated from the same program, as
``compare`` does, and :func:`estimate_offset` searches +-5 s (compare's default).

A run is *misaligned* when the offset found differs from the true one by more than a quarter
of the measured period (12.5 ms). Prints, per feed and in total: runs, misaligned runs, the
largest offset error of the others, the statuses, and the CPU time per estimate.
"""
from __future__ import annotations

import argparse
from collections import Counter
import time

import numpy as np

from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.align import estimate_offset
from feed_axis_energy.identify.rig import (instrument_record, Instrument, OUTSIDE_KINDS,
                                                parse_effects, simulate_run)
from feed_axis_energy.identify.rig import PAPER_FEEDS_MM_S, PAPER_LOADS_KG, stroke_program
from feed_axis_energy.sim.simulate import simulate_program
from feed_axis_energy.paths import config_dir

MAX_LAG_S = 5.0


def main(argv: list[str] | None = None) -> int:
    """Run the study and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seeds', type=int, default=20, help='seeds (15 runs each)')
    parser.add_argument('--spread-s', type=float, default=4.0,
                        help='true offsets are uniform in +-this [s] (default: 4)')
    parser.add_argument('--noise-w', type=float, default=1.5, help='meter noise [W]')
    parser.add_argument('--effects', default='load_friction=mu:0.1',
                        help='truth effects, rig syntax (default: load_friction=mu:0.1)')
    parser.add_argument('--outside', choices=sorted(OUTSIDE_KINDS),
                        help='an effect outside the catalog in the truth')
    parser.add_argument('--machine', default='demonstrator.yaml',
                        help='machine config (file in config/ or a path)')
    args = parser.parse_args(argv)
    machine = load_machine(config_dir() / args.machine)

    meter = Instrument(window_s=0.05, period_s=0.05, noise_w=args.noise_w, quantum_w=1.0)
    truth_effects = parse_effects(args.effects)
    tol = 0.25 * meter.period_s
    cases = []
    for feed in PAPER_FEEDS_MM_S:
        text = stroke_program(feed, axis=machine.load_axis, cycles=3, dwell_s=1.0)
        for load in PAPER_LOADS_KG:
            # the truth once per case, padded for the largest offset; the declared model
            # as compare simulates it (the program alone)
            truth = simulate_run(machine, text, load_kg=load, effects=truth_effects,
                                 instrument=Instrument(noise_w=0.0), offset_s=args.spread_s,
                                 outside=args.outside)
            declared = simulate_program(parse_gcode(text), machine, load_kg=load)
            end = float(declared.power.t[-1]) + 1.0
            cases.append((feed, load, truth, declared, end))
    errors: dict[float, list[float]] = {f: [] for f in PAPER_FEEDS_MM_S}
    statuses: Counter = Counter()
    cpu = 0.0
    worst = []
    for seed in range(args.seeds):
        rng = np.random.default_rng(seed)
        for feed, load, truth, declared, end in cases:
            offset = float(rng.uniform(-args.spread_s, args.spread_s))
            stamps, rec = instrument_record(truth.result.power.t, truth.truth_w.sum(axis=1),
                                            instrument=meter, offset_s=offset, end_s=end,
                                            rng=rng)
            c0 = time.process_time()
            res = estimate_offset(stamps, rec, declared.power.t,
                                  declared.power.power_w.sum(axis=1), max_lag_s=MAX_LAG_S,
                                  window_s=meter.window_s)
            cpu += time.process_time() - c0
            err = res.offset_s - offset
            errors[feed].append(err)
            statuses[res.status] += 1
            if abs(err) > tol:
                worst.append((seed, feed, load, offset, res.offset_s, res.message))
    total = sum(len(v) for v in errors.values())
    print(f'{args.seeds} seeds x {len(cases)} runs = {total} runs; offsets uniform in '
          f'+-{args.spread_s:g} s, search +-{MAX_LAG_S:g} s, 50 ms meter, '
          f'{args.noise_w:g} W noise')
    print(f'{"feed [mm/s]":>12} {"runs":>5} {"misaligned":>10} {"max |err| of the rest [ms]":>27}')
    for feed, errs in errors.items():
        e = np.abs(np.array(errs))
        ok = e[e <= tol]
        print(f'{feed:12g} {e.size:5d} {int((e > tol).sum()):10d} '
              f'{1e3 * ok.max() if ok.size else float("nan"):27.2f}')
    n_bad = len(worst)
    print(f'misaligned (|error| > {1e3 * tol:g} ms): {n_bad} of {total} '
          f'({100.0 * n_bad / total:.1f} %)')
    print('statuses: ' + ', '.join(f'{k} {v}' for k, v in sorted(statuses.items())))
    print(f'CPU time per estimate: {1e3 * cpu / total:.1f} ms')
    for seed, feed, load, offset, found, message in worst[:10]:
        print(f'  seed {seed} f{feed:g} load {load:g} kg: true {offset:+.4f} s, found '
              f'{found:+.4f} s ({message[:120]})')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
