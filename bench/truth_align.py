"""Alignment on hard cases of the independent truth rig (``bench/truth_model.py``).

``PYTHONPATH=. .venv/bin/python bench/truth_align.py [--seeds N] [--scenarios A,B]``

Scenarios built so that a lag one stroke (half a cycle) or one cycle away correlates nearly
as well as the true one: symmetric reciprocating strokes with many cycles, start offsets of
seconds in a +-5 s search (compare's default), records cut at both ends so that only the
periodic middle is seen, clock drift up to 500 ppm on records of 66-100 s, a meter lag, and
truths the declared model lacks large effects of (load friction, asymmetric Coulomb
friction, a pump). Every run is recorded by the 50 ms averaging meter (1.5 W noise, 1 W
quantisation) and the declared model is simulated from the program as ``compare`` does;
:func:`estimate_offset` then searches +-5 s.

A run is *misaligned* when the offset found differs from the true one (at the record's
middle, plus the meter lag's delay) by more than a quarter of the period (12.5 ms). Per
scenario the script prints runs, misaligned runs, runs whose runner-up correlates within
0.05 of the winner (the hard ones), the statuses, the largest error among the others and,
where the records are long enough for a drift estimate (60 s), its largest error.
"""
from __future__ import annotations

import argparse
from collections import Counter
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import truth_model as tm  # noqa: E402

from feed_axis_energy.gcode.load import parse_gcode  # noqa: E402,I100
from feed_axis_energy.machine.file import load_machine  # noqa: E402
from feed_axis_energy.measured.align import estimate_offset  # noqa: E402
from feed_axis_energy.sim.simulate import simulate_program  # noqa: E402
from feed_axis_energy.paths import config_dir  # noqa: E402

MACHINE = Path(config_dir()) / 'demonstrator.yaml'
MAX_LAG_S = 5.0
SCENARIOS = {
    # name: feeds [mm/s], stroke [mm], cycles, dwell [s], offsets (lo, hi) [s], drift [ppm],
    # cut (record ends this long before the program) [s], truth effects, meter lag [s]
    'symmetric': dict(feeds=(300.0, 400.0, 500.0), stroke=400.0, cycles=4, dwell=1.0,
                      offsets=(-4.5, 4.5)),
    'short_strokes': dict(feeds=(200.0, 350.0, 500.0), stroke=20.0, cycles=12, dwell=0.3,
                          offsets=(-4.5, 4.5)),
    'short_mismatch': dict(feeds=(200.0, 500.0), stroke=30.0, cycles=10, dwell=0.15,
                           offsets=(-4.5, 4.5), drift=200.0,
                           effects={'copper': 2.0, 'coulomb': 60.0, 'pump': 6.0}),
    'many_maxima': dict(feeds=(150.0, 300.0, 500.0), stroke=10.0, cycles=30, dwell=0.1,
                        offsets=(-4.5, 4.5), drift=200.0,
                        effects={'copper': 3.0, 'load_friction': 0.1, 'pump': 6.0}),
    'cut_ends': dict(feeds=(400.0, 500.0), stroke=400.0, cycles=6, dwell=0.5,
                     offsets=(-4.5, -0.5), cut=3.0),
    'drift': dict(feeds=(200.0, 500.0), stroke=400.0, cycles=16, dwell=1.0,
                  offsets=(-4.5, 4.5), drift=500.0),
    'mismatch': dict(feeds=(100.0, 300.0, 500.0), stroke=400.0, cycles=3, dwell=1.0,
                     offsets=(-4.5, 4.5), drift=100.0,
                     effects={'load_friction': 0.1, 'coulomb': 60.0, 'pump': 10.0}),
    'meter_lag': dict(feeds=(200.0, 500.0), stroke=400.0, cycles=3, dwell=0.2,
                      offsets=(-4.5, 4.5), lag=0.02),
    # the paper's program on an axis inclined by 15 deg that the declared model calls
    # horizontal: m*g*sin(15 deg) = 30-88 N, the up and down strokes differ only through it
    # (issue 24: 6 of 15 runs aligned a stroke off)
    'inclined_15deg': dict(feeds=(100.0, 200.0, 300.0, 400.0, 500.0), stroke=400.0,
                           cycles=3, dwell=1.0, offsets=(0.2, 1.2),
                           effects={'gravity': 0.2588}),
    # ... recorded only over the middle (the meter started 2.5 s late and stopped 3 s early):
    # no record edge tells the strokes apart, only the missing effect does
    'inclined_middle': dict(feeds=(100.0, 200.0, 300.0, 400.0, 500.0), stroke=400.0,
                            cycles=3, dwell=1.0, offsets=(0.2, 1.2), cut=3.0, head=2.5,
                            effects={'gravity': 0.2588}),
    # the same program with a large disturbance outside the catalog (a 2.3 Hz pump, 20 W)
    'large_outside': dict(feeds=(100.0, 200.0, 300.0, 400.0, 500.0), stroke=400.0,
                          cycles=3, dwell=1.0, offsets=(0.2, 1.2), effects={'pump': 20.0}),
}


def program_text(feed: float, stroke: float, cycles: int, dwell: float) -> str:
    """The reciprocating stroke as NC text."""
    lines = ['G21 G90 G94 G61', 'G0 X0', f'G4 P{dwell:g}']
    for _ in range(cycles):
        lines += [f'G1 X{stroke:g} F{feed * 60:g}', f'G4 P{dwell:g}', 'X0', f'G4 P{dwell:g}']
    return '\n'.join(lines + ['M30']) + '\n'


def scenario(name: str, seeds: range, *, machine, axis: tm.AxisData) -> dict:
    """Misaligned, hard and status counts of one scenario."""
    spec = SCENARIOS[name]
    feeds, stroke, cycles, dwell = spec['feeds'], spec['stroke'], spec['cycles'], spec['dwell']
    (lo, hi), drift, cut = spec['offsets'], spec.get('drift', 0.0), spec.get('cut', 0.0)
    head = spec.get('head', 0.0)
    effects, lag = spec.get('effects', {}), spec.get('lag', 0.0)
    tol = 0.25 * tm.Meter().period_s
    out = {'runs': 0, 'misaligned': 0, 'hard': 0, 'status': Counter(), 'worst_ok': 0.0,
           'cpu': 0.0, 'bad': [], 'drift': []}
    for feed in feeds:
        line = tm.stroke_timeline(feed / 1000.0, axis=axis, stroke_m=stroke / 1000.0,
                                  cycles=cycles, dwell_s=dwell)
        for load in (0.0, 22.711):
            state = tm.fine_state(line, axis=axis, load_kg=load, run_index=int(feed),
                                  before_s=abs(lo) + hi + 1.0, after_s=2.0)
            power = tm.true_power(state, axis, effects)
            declared = simulate_program(parse_gcode(program_text(feed, stroke, cycles, dwell)),
                                        machine, load_kg=load)
            for seed in seeds:
                rng = np.random.default_rng([seed, int(feed), int(load)])
                offset = float(rng.uniform(lo, hi))
                meter = tm.Meter(drift_ppm=float(rng.uniform(-drift, drift)), lag_s=lag)
                stamps, y = tm.record(state, power, meter=meter, offset_s=offset,
                                      end_s=line.duration + 1.0, rng=rng)
                if cut > 0.0:
                    # the meter ran only over the middle: drop `cut` s of the program's end
                    keep = stamps <= stamps[-1] - cut - 1.0
                    stamps, y = stamps[keep], y[keep]
                if head > 0.0:
                    # ... and started `head` s after the program (its clock still counts
                    # from the program's start: stamps keep their values)
                    keep = stamps >= offset + head
                    stamps, y = stamps[keep], y[keep]
                mid = 0.5 * stamps[-1]
                true = offset + mid * (1.0 - 1.0 / (1.0 + 1e-6 * meter.drift_ppm)) + lag
                c0 = time.process_time()
                res = estimate_offset(stamps, y, declared.power.t,
                                      declared.power.power_w.sum(axis=1),
                                      max_lag_s=MAX_LAG_S, window_s=meter.period_s)
                out['cpu'] += time.process_time() - c0
                err = res.offset_s - true
                out['runs'] += 1
                if math.isfinite(res.drift_ppm):
                    out['drift'].append(res.drift_ppm - meter.drift_ppm)
                out['status'][res.status] += 1
                out['hard'] += bool(np.isfinite(res.runner_up_correlation)
                                    and res.runner_up_correlation
                                    >= res.peak_correlation - 0.05)
                if abs(err) > tol:
                    out['misaligned'] += 1
                    out['bad'].append(f'f{feed:g} {load:g} kg seed {seed}: true {true:+.4f} s, '
                                      f'found {res.offset_s:+.4f} s ({res.status}; '
                                      f'{res.message[:110]})')
                else:
                    out['worst_ok'] = max(out['worst_ok'], abs(err))
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the scenarios and print the table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--seeds', type=int, default=10, help='seeds per run (default 10)')
    p.add_argument('--scenarios', default=','.join(SCENARIOS),
                   help='comma-separated scenarios (default: all)')
    args = p.parse_args(argv)
    names = [s.strip() for s in args.scenarios.split(',') if s.strip()]
    unknown = [s for s in names if s not in SCENARIOS]
    if unknown or args.seeds < 1:
        p.error(f'unknown scenario(s) {", ".join(unknown)}' if unknown
                else '--seeds must be >= 1')
    machine = load_machine(MACHINE)
    axis = tm.read_axis(MACHINE)
    print('| scenario | runs | misaligned | runner-up within 0.05 | statuses | largest error '
          'of the rest [ms] | drift estimated: runs, largest error [ppm] | CPU per estimate '
          '[ms] |')
    print('| --- | --- | --- | --- | --- | --- | --- | --- |')
    total = bad = 0
    for name in names:
        r = scenario(name, range(1, args.seeds + 1), machine=machine, axis=axis)
        total += r['runs']
        bad += r['misaligned']
        d = np.abs(np.array(r['drift']))
        drift = f'{d.size}, {d.max():.0f}' if d.size else '0'
        print(f'| `{name}` | {r["runs"]} | {r["misaligned"]} | {r["hard"]} | '
              + ', '.join(f'{k} {v}' for k, v in sorted(r['status'].items()))
              + f' | {1e3 * r["worst_ok"]:.1f} | {drift} | {1e3 * r["cpu"] / r["runs"]:.0f} |')
        for line in r['bad'][:5]:
            print(f'  {name}: {line}', file=sys.stderr)
    print(f'\nmisaligned: {bad} of {total} runs (offset error > 12.5 ms)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
