"""Issue 24 §8: the truth matrix — every catalog shape at large and small sizes, periodic
programs with record offsets up to +-2 strokes, and smooth force-like signals.

``PYTHONPATH=. .venv/bin/python bench/truth_matrix.py [--seeds N] [--first-seed K]
[--cases A,B] [--classes large,small,smooth]``

The truth is ``bench/truth_model.py`` (its own physics, nothing of the package's dynamics,
loss models or effect catalog). Campaign per cell and seed: the paper's 15 runs (loads 0,
17.336, 22.711 kg x feeds 100 ... 500 mm/s), two reciprocating 400 mm strokes with 1 s
dwells, clock drift uniform in +-50 ppm, and a start offset per run uniform in +-2 stroke
periods (one stroke = the 400 mm move at the run's feed + its dwell: +-3.6 s at 500 mm/s),
capped at +-4.4 s (the truth is padded by 4.5 s), inside ``compare``'s +-5 s search. So
the truth offset may lie one or two strokes away from 0, and the up and down strokes differ
only through the missing effect.

Classes (the failing classes of issue 24):

* ``large``: the effect's energy share drawn uniformly in 5 ... 20 %;
* ``small``: 0.5 ... 2 %;
* ``smooth``: a large effect recorded as a smooth signal (10 ms samples, 0.05 W noise, no
  quantisation, a 5 ms first-order lag: a controller output, not a power meter);
* ``power``: a large effect (5 ... 20 %) on records of the power alone (the manifest maps no
  position or velocity column: no motion anchor, the runs are aligned on the power).

Share of the energy: ``sum |P_truth - P_without| / sum |P_without|`` over every truth
sample of the campaign (absolute, so that shapes whose net energy is zero over a cycle,
``gravity``, ``offset_force``, ``mass_error``, have a size too); the 50 ms meter (1.5 W
noise, 1 W quantisation) of ``truth_targets.py`` records the other classes.

Scores per analysis: *right* (the true effect named, nothing else; a ``time_offset`` under
5 ms is not an effect), *group* (every named effect lies in one ambiguous finding of
``analyze`` that holds the true effect, or in one of the catalog's alias groups with it:
``coulomb``/``offset_force`` exactly, ``offset_force``/``gravity`` when the mass does not
vary, ``iron``/``coulomb``/``viscous`` in the speed, ``stribeck``/``stribeck_exp``), *missed*
(nothing named), *false* (anything else). Per run *misaligned*: the offset ``analyze`` used
last (``offset_after``, else ``offset_before``) is off the truth (at the record's middle) by
more than 12.5 ms (a quarter of the 50 ms period; 2.5 ms for ``smooth``), unless the run was
left out with a reason (``left_out``); a first-order meter filter that ``analyze``
estimated (``meter_filter_s``) counts as a delay of its time constant. Progress on stderr,
the table on stdout.
"""
from __future__ import annotations

import argparse
import ast
from collections import Counter, defaultdict
from pathlib import Path
import re
import shutil
import sys
import tempfile
import time

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
import truth_model as tm  # noqa: E402
import truth_targets as tt  # noqa: E402

from feed_axis_energy.identify.analyze import analyze_campaign  # noqa: E402,I100
from feed_axis_energy.measured.manifest import load_campaign  # noqa: E402

CASES = ('standby', 'coulomb', 'viscous', 'viscous_asymmetry', 'load_friction',
         'clamped_load_friction', 'stribeck', 'stribeck_exp', 'position_friction',
         'thermal_drift', 'gravity', 'offset_force', 'iron', 'copper', 'mass_error',
         'torque_ripple')
# braking_loss is not a case: the demonstrator's loss exceeds its inertial power at every
# feed, so its power is never negative and a share of it burned adds nothing.
CLASSES = {'large': (0.05, 0.20), 'small': (0.005, 0.02), 'smooth': (0.05, 0.20),
           'power': (0.05, 0.20)}
MAX_OFFSET_S = 4.4
STROKES = 2.0
ALIAS_GROUPS = (frozenset({'coulomb', 'offset_force'}), frozenset({'offset_force', 'gravity'}),
                frozenset({'iron', 'coulomb', 'viscous'}),
                frozenset({'stribeck_exp', 'stribeck'}))
CATALOG_ID = {'stribeck_exp': 'stribeck'}     # the truth's case -> the catalog effect it is
SMOOTH = tm.Meter(period_s=0.01, noise_w=0.05, quantum_w=0.0, lag_s=0.005)


def unit_powers(runs: list[tt.Run], axis: tm.AxisData, case: str) -> tuple[float, float]:
    """``(sum |P_without|, sum |P(case at amplitude 1) - P_without|)`` over the campaign."""
    base = extra = 0.0
    for run in runs:
        p0 = tm.true_power(run.state, axis, {})
        p1 = tm.true_power(run.state, axis, {case: 1.0})
        base += float(np.sum(np.abs(p0)))
        extra += float(np.sum(np.abs(p1 - p0)))
    return base, extra


def stroke_period_s(feed_mm_s: float) -> float:
    """One stroke of the program: the 400 mm move at the feed and its dwell [s]."""
    return tt.STROKE_M / (feed_mm_s / 1000.0) + tt.DWELL_S


def write_campaign(out: Path, *, case: str, amp: float, runs: list[tt.Run],
                   axis: tm.AxisData, seed: int, cls: str) -> dict[str, float]:
    """Manifest, machine, programs, CSVs; return the true offset per run [s]."""
    rng = np.random.default_rng([seed, sum(map(ord, case)), sum(map(ord, cls))])
    (out / 'programs').mkdir(parents=True)
    (out / 'runs').mkdir()
    shutil.copyfile(tt.MACHINE, out / 'machine.yaml')
    effects = {} if case == 'clean' else {case: amp}
    offsets, entries = {}, []
    for run in runs:
        prog = f'programs/f{run.feed_mm_s:g}.nc'
        if not (out / prog).exists():
            (out / prog).write_text(tt.program_text(run.feed_mm_s), encoding='utf-8')
        reach = min(STROKES * stroke_period_s(run.feed_mm_s), MAX_OFFSET_S)
        offset = float(rng.uniform(-reach, reach))
        drift = float(rng.uniform(-tt.DRIFT_PPM, tt.DRIFT_PPM))
        meter = (tm.Meter(period_s=SMOOTH.period_s, noise_w=SMOOTH.noise_w,
                          quantum_w=SMOOTH.quantum_w, lag_s=SMOOTH.lag_s, drift_ppm=drift)
                 if cls == 'smooth' else tm.Meter(noise_w=tt.NOISE_W, drift_ppm=drift))
        power = tm.true_power(run.state, axis, effects)
        stamps, y = tm.record(run.state, power, meter=meter, offset_s=offset, end_s=run.end_s,
                              rng=rng)
        scale = 1.0 + 1e-6 * meter.drift_ppm
        offsets[run.name] = offset + 0.5 * stamps[-1] * (1.0 - 1.0 / scale) + meter.lag_s
        t_true = stamps / scale - offset
        data = tm.write_record_csv(out, run.name, run.state, stamps, y, t_true)
        entries.append({'name': run.name, 'load_kg': run.load_kg, 'motion': {'program': prog},
                        'data': data})
    cols = {'power': {'column': 'X_power_kW', 'unit': 'kW'},
            'position': {'column': 'X_position_mm', 'unit': 'mm'},
            'velocity': {'column': 'X_velocity_mm_s', 'unit': 'mm/s'}}
    if cls == 'power':
        # the record's motion columns are not mapped: aligned on the power alone
        cols = {'power': cols['power']}
    defaults = {'time': {'column': 'time_ms', 'unit': 'ms'}, 'axes': {'X': cols}}
    manifest = {'name': f'matrix_{case}_{cls}_{seed}', 'machine': 'machine.yaml',
                'defaults': defaults, 'runs': entries}
    (out / 'manifest.yaml').write_text(yaml.safe_dump(manifest, sort_keys=False),
                                       encoding='utf-8')
    return offsets


def verdict(case: str, named: list[str], groups: list[set[str]]) -> str:
    """right / group / missed / false (module docstring); ``clean``: right or false."""
    if case == 'clean':
        return 'right' if not named else 'false'
    true_id = CATALOG_ID.get(case, case)
    if named == [true_id]:
        return 'right'
    if not named:
        return 'missed'
    if any(true_id in g and set(named) <= g for g in groups):
        return 'group'
    if any(true_id in g and set(named) <= g for g in ALIAS_GROUPS):
        return 'group'
    return 'false'


def trial(case: str, cls: str, runs: list[tt.Run], axis: tm.AxisData, seed: int,
          work: Path, sums: dict[str, tuple[float, float]]) -> dict:
    """One campaign of one cell, its analysis and the scores."""
    rng = np.random.default_rng([seed, 24, sum(map(ord, case)), sum(map(ord, cls))])
    share = 0.0 if case == 'clean' else float(rng.uniform(*CLASSES[cls]))
    amp = 0.0
    if case != 'clean':
        base, extra = sums[case]
        if extra <= 0.0:
            msg = (f'{case} adds no power to this campaign (braking_loss: the declared '
                   'machine never brakes with negative power here); leave it out (--cases)')
            raise ValueError(msg)
        amp = share * base / extra
        if case == 'braking_loss':
            amp = min(amp, 1.0)     # a share of the braking power cannot exceed all of it
    out = work / f'{case}_{cls}_{seed}'
    offsets = write_campaign(out, case=case, amp=amp, runs=runs, axis=axis, seed=seed,
                             cls=cls)
    res = analyze_campaign(load_campaign(out / 'manifest.yaml'))
    shutil.rmtree(out)
    named = sorted(e.id for e in res.effects
                   if not (e.id == 'time_offset' and abs(e.values()['delta_s']) < 0.005))
    groups = [{m.split('@')[0] for m in g.members} for g in getattr(res, 'ambiguous', ())]
    left = {lo.name for lo in getattr(res, 'left_out', ())}
    tol = 0.25 * (SMOOTH.period_s if cls == 'smooth' else tm.Meter().period_s)
    errors = {}
    for r in res.runs:
        if r.name in left:
            continue
        used = r.offset_after or r.offset_before
        if used is None or used.get('found_s') is None:
            continue
        # a meter filter analyze estimated delays like a lag of its time constant
        errors[r.name] = (float(used['found_s']) + float(getattr(res, 'meter_filter_s', 0.0))
                          - offsets[r.name])
    return {'case': case, 'cls': cls, 'seed': seed, 'share': share, 'named': named,
            'offered': sorted(e.id for e in getattr(res, 'offered', ())),
            'status': res.status, 'verdict': verdict(case, named, groups),
            'misaligned': sorted(k for k, e in errors.items() if abs(e) > tol),
            'aligned_runs': len(errors), 'left_out': sorted(left),
            'largest_error_s': max((abs(e) for e in errors.values()), default=0.0),
            'meter_filter_s': float(getattr(res, 'meter_filter_s', 0.0)),
            'aligned_with': getattr(res, 'aligned_with', None),
            'sim_rate_hz': float(getattr(res, 'sim_rate_hz', 0.0)),
            'augmented_rate_hz': float(res.augmented_machine().planner.rate_hz)}


def run_cells(cells: list[tuple[str, str]], seeds: range, *, log=None) -> list[dict]:
    """Every (case, class) cell for every seed."""
    axis = tm.read_axis(tt.MACHINE)
    runs = tt.make_runs(axis)
    sums = {c: unit_powers(runs, axis, c) for c in {case for case, _ in cells}
            if c != 'clean'}
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for case, cls in cells:
            for seed in seeds:
                t0 = time.perf_counter()
                r = trial(case, cls, runs, axis, seed, Path(tmp), sums)
                results.append(r)
                if log is not None:
                    log(f'{case} {cls} seed {seed}: {r["verdict"]} named {r["named"] or "-"} '
                        f'status {r["status"]} share {100 * r["share"]:.2f} % misaligned '
                        f'{len(r["misaligned"])}/{r["aligned_runs"]} left out '
                        f'{len(r["left_out"])} ({time.perf_counter() - t0:.0f} s)')
    return results


def print_table(results: list[dict], cells: list[tuple[str, str]], seeds: int,
                wall_s: float) -> None:
    """Markdown table per cell and the totals."""
    print(f'truth matrix: up to {seeds} seed(s) per cell, offsets up to +-{STROKES:g} strokes '
          f'(capped at +-{MAX_OFFSET_S:g} s), drift +-{tt.DRIFT_PPM:g} ppm; {wall_s:.0f} s')
    print()
    print('| case | class | named right % (alone / in a group) | false | missed | misaligned '
          'runs | left out | named instead / beside | status |')
    print('| --- | --- | --- | --- | --- | --- | --- | --- | --- |')
    total: Counter = Counter()
    by_class: dict[str, Counter] = defaultdict(Counter)
    for case, cls in cells:
        rs = [r for r in results if r['case'] == case and r['cls'] == cls]
        if not rs:
            continue
        v = Counter(r['verdict'] for r in rs)
        mis = sum(len(r['misaligned']) for r in rs)
        runs = sum(r['aligned_runs'] + len(r['left_out']) for r in rs)
        left = sum(len(r['left_out']) for r in rs)
        true_id = CATALOG_ID.get(case, case)
        other = Counter(n for r in rs for n in r['named'] if n != true_id)
        ok = v['right'] + v['group']
        statuses = Counter(r['status'] for r in rs)
        print(f'| `{case}` | {cls} | {100.0 * ok / len(rs):.0f} % ({v["right"]} / {v["group"]} '
              f'of {len(rs)}) | {v["false"]} | {v["missed"]} | {mis}/{runs} | {left} | '
              + (', '.join(f'{k} {n}' for k, n in sorted(other.items())) or '-') + ' | '
              + ', '.join(f'{k} {n}' for k, n in sorted(statuses.items())) + ' |')
        for key, val in (('n', len(rs)), ('ok', ok), ('false', v['false']), ('mis', mis),
                         ('runs', runs), ('left', left)):
            total[key] += val
            by_class[cls][key] += val
    print()
    for cls, c in by_class.items():
        print(f'{cls}: named right {c["ok"]}/{c["n"]} ({100.0 * c["ok"] / c["n"]:.0f} %), false '
              f'attributions {c["false"]}, misaligned runs {c["mis"]}/{c["runs"]}, left out '
              f'{c["left"]}')
    print(f'all: named right {total["ok"]}/{total["n"]}, false attributions {total["false"]}, '
          f'misaligned runs {total["mis"]}/{total["runs"]}')


_LOG = re.compile(r'^(\S+) (\S+) seed (\d+): (\S+) named (.+?) status (\S+) share '
                  r'([\d.]+) % misaligned (\d+)/(\d+) left out (\d+) ')


def parse_log(lines) -> list[dict]:
    """Results from the progress lines of earlier runs (``--from-log``; a cell and seed
    logged twice keeps its last line)."""
    out: dict[tuple[str, str, int], dict] = {}
    for line in lines:
        m = _LOG.match(line)
        if m is None:
            continue
        case, cls, seed, verd, named, status, share, mis, aligned, left = m.groups()
        out[case, cls, int(seed)] = {
            'case': case, 'cls': cls, 'seed': int(seed), 'verdict': verd,
            'named': [] if named == '-' else ast.literal_eval(named), 'status': status,
            'share': float(share) / 100.0, 'misaligned': [''] * int(mis),
            'aligned_runs': int(aligned), 'left_out': [''] * int(left)}
    return list(out.values())


def main(argv: list[str] | None = None) -> int:
    """Run the matrix, print the table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--seeds', type=int, default=3, help='seeds per cell (default 3)')
    p.add_argument('--first-seed', type=int, default=1, help='first seed (default 1)')
    p.add_argument('--cases', default=None, help='comma-separated cases (default: all + clean)')
    p.add_argument('--classes', default='large,small,smooth,power',
                   help='comma-separated classes (default: large,small,smooth,power)')
    p.add_argument('--truth-hz', type=float, default=tm.RATE_HZ,
                   help=f'sample rate of the truth model [Hz] (default {tm.RATE_HZ:g}; its '
                   'meter integrates on that grid by the rectangle rule)')
    p.add_argument('--from-log', nargs='+', type=Path, default=None, metavar='FILE',
                   help='print the table of earlier runs from their progress lines (stderr)')
    args = p.parse_args(argv)
    if args.from_log is not None:
        results = parse_log(line for f in args.from_log
                            for line in f.read_text(encoding='utf-8').splitlines())
        order = {c: i for i, c in enumerate(('clean',) + CASES)}
        cells = sorted(dict.fromkeys((r['case'], r['cls']) for r in results),
                       key=lambda c: (order.get(c[0], len(order)), list(CLASSES).index(c[1])))
        seeds = max(Counter((r['case'], r['cls']) for r in results).values(), default=0)
        print_table(results, cells, seeds, 0.0)
        return 0
    cases = (('clean',) + CASES if args.cases is None
             else tuple(c.strip() for c in args.cases.split(',') if c.strip()))
    classes = tuple(c.strip() for c in args.classes.split(',') if c.strip())
    bad = [c for c in cases if c != 'clean' and c not in CASES] + [
        c for c in classes if c not in CLASSES]
    if bad or args.seeds < 1:
        p.error(f'unknown case or class: {", ".join(bad)}' if bad else '--seeds must be >= 1')
    if not 1000.0 <= args.truth_hz <= 200_000.0:
        p.error(f'--truth-hz must be within 1000 and 200000 Hz, got {args.truth_hz:g}')
    tm.RATE_HZ = float(args.truth_hz)
    cells = [(case, cls) for case in cases for cls in classes
             if not (case == 'clean' and cls == 'small')]
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    t0 = time.perf_counter()
    results = run_cells(cells, seeds, log=lambda m: print(m, file=sys.stderr, flush=True))
    print_table(results, cells, len(seeds), time.perf_counter() - t0)
    return 0


if __name__ == '__main__':
    sys.exit(main())
