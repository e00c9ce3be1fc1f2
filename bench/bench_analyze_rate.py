"""``analyze`` on a 15-run campaign at drive-trace rates: wall, CPU and peak RSS against length.

Usage: ``PYTHONPATH=. .venv/bin/python bench/bench_analyze_rate.py [--minutes 1,3,10]
[--effect copper] [--share 0.05] [--noise-w W] [--seed K] [--drift-ppm D] [--timeout S]
[--keep DIR]``

For each length, a temporary directory (never the repository; ``--keep DIR`` writes there
instead and leaves it; a campaign of that length already there is analysed again) gets a
campaign of 15 runs, the paper's loads (0, 17.336, 22.711 kg) x feeds (100 ... 500 mm/s):

* per run, the demonstrator's reciprocating program as ``bench_compare_rate.py`` has it
  (400 mm strokes with a 1 s dwell after each, out and back at one feed, the next cycle at
  the next of the five feeds) until it fills that many minutes, each load's five runs
  starting at a different feed (the "feed" of a run is its first; a program that repeats
  every cycle would align one cycle off as well as right, and ``analyze`` fits only runs
  whose offset is pinned down: on 10-minute records of one feed every offset estimate is
  ``ambiguous`` by correlation);
* per run, a "measured" power CSV at 1 kHz made by the independent truth model
  (``bench/truth_model.py``: its own seven-phase strokes and physics, nothing of the
  project's planner, dynamics or effect catalog) with one missing effect (``--effect``,
  default ``copper``) scaled to ``--share`` (default 5 %) of the campaign's energy, a
  1 ms averaging meter stamped at the window's end, Gaussian noise (``--noise-w``, default
  1.5 W) and 0.1 W quantisation, a clock drift uniform in +-``--drift-ppm`` (default 0: a
  drive trace shares the controller's clock), and a record that
  starts 0.5 to 2 s before the program and ends 1.5 s after it (the program's start and end
  are on record, so every offset can be pinned);
* a manifest (time in s, power in W, the program as the motion).

``python -m feed_axis_energy analyze MANIFEST --json --quiet`` then runs as a child
process (process start included); it is reaped with ``os.wait4`` for its own peak RSS
(``ru_maxrss``) and CPU time, and its anonymous memory is sampled every 50 ms (``RssAnon``:
the part that must fit in RAM; the peak RSS also counts memory-mapped files' pages, which
the kernel may drop and read again). Printed per length: samples, wall and CPU time, peak RSS,
whether the hidden effect was named (and what else was), the status, the energy share the
tool gives the effect, and the held-out figures before and after (energy error and RMSE,
pooled over held-out runs), the worst offset error, and the cost relative to the first
length. A child that runs longer than ``--timeout`` is killed and reported as not
finished. The issue's target (issue 24): 15 runs of 10 minutes within 15 minutes.
"""
from __future__ import annotations

import argparse
from dataclasses import replace
import json
import math
import os
from pathlib import Path
import shutil
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from child_cli import run_cli  # noqa: E402
import truth_model as tm  # noqa: E402

from feed_axis_energy.paths import config_dir  # noqa: E402,I100

ROOT = Path(__file__).resolve().parents[1]
MACHINE = Path(config_dir()) / 'demonstrator.yaml'
LOADS_KG = (0.0, 17.336, 22.711)
FEEDS_MM_S = (100.0, 200.0, 300.0, 400.0, 500.0)
STROKE_M, DWELL_S = 0.4, 1.0
LEAD_S = (0.5, 2.0)       # the record starts this long before the program [s]
TAIL_S = 1.5              # and ends this long after it
PERIOD_S = 1e-3


def feed_cycle(minutes: float, first: int,
               axis: tm.AxisData) -> tuple[list[float], tm.Timeline]:
    """Feeds [mm/s] of the out-and-back cycles that fill ``minutes``, starting at the
    feed ``FEEDS_MM_S[first]``, and their truth timeline (dwell first)."""
    line = tm.Timeline()
    line.dwell(DWELL_S)
    feeds: list[float] = []
    while line.duration < minutes * 60.0:
        feed = FEEDS_MM_S[(first + len(feeds)) % len(FEEDS_MM_S)]
        line.move(STROKE_M, v=feed / 1000.0, axis=axis)
        line.dwell(DWELL_S)
        line.move(-STROKE_M, v=feed / 1000.0, axis=axis)
        line.dwell(DWELL_S)
        feeds.append(feed)
    return feeds, line


def program_text(feeds: list[float]) -> str:
    """The NC program of the strokes (what the declared model is simulated from)."""
    lines = ['( bench: reciprocating strokes )', 'G21 G90 G94 G61', 'G0 X0',
             f'G4 P{DWELL_S:g}']
    for feed in feeds:
        lines += [f'G1 X{STROKE_M * 1000:g} F{feed * 60:g}', f'G4 P{DWELL_S:g}', 'X0',
                  f'G4 P{DWELL_S:g}']
    return '\n'.join(lines + ['M30']) + '\n'


def truth_states(minutes: float, axis: tm.AxisData) -> list[tuple[str, float, float, tm.State,
                                                                  float, list[float]]]:
    """Per run: name, first feed [mm/s], load [kg], truth state, program end [s], feeds."""
    out = []
    for i, feed in enumerate(FEEDS_MM_S):
        feeds, line = feed_cycle(minutes, i, axis)
        base = tm.fine_state(line, axis=axis, load_kg=0.0, run_index=3 * i,
                             before_s=LEAD_S[1] + 0.5, after_s=TAIL_S + 0.5)
        for j, load in enumerate(LOADS_KG):
            state = replace(base, mass_kg=axis.table_kg + load, load_kg=load,
                            run_index=3 * i + j)
            out.append((f'f{feed:g}_load{load:g}kg', feed, load, state, line.duration, feeds))
    return out


def amplitude(effect: str, share: float, runs: list, axis: tm.AxisData) -> float:
    """Amplitude that makes the effect's energy ``share`` of the campaign's energy."""
    extra = total = 0.0
    for _, _, _, state, _, _ in runs:
        base = tm.true_power(state, axis, {})
        total += float(np.sum(np.abs(base)))
        extra += float(np.sum(tm.true_power(state, axis, {effect: 1.0}) - base))
    if extra == 0.0:
        raise SystemExit(f'effect {effect!r} adds no energy on this campaign')
    return share * total / extra


def build(root: Path, minutes: float, *, effect: str, share: float, noise_w: float,
          seed: int, drift_ppm: float = 0.0) -> tuple[Path, int, dict[str, float]]:
    """Programs, CSVs and manifest in ``root``; the manifest, the rows, the true offsets."""
    axis = tm.read_axis(MACHINE)
    runs = truth_states(minutes, axis)
    amp = amplitude(effect, share, runs, axis)
    rng = np.random.default_rng(seed)
    shutil.copyfile(MACHINE, root / 'machine.yaml')
    meter_rows, offsets, entries = 0, {}, []
    lines = ['name: rate', 'machine: machine.yaml', 'defaults:',
             '  time: {column: time_s, unit: s}',
             '  axes: {X: {power: {column: X_power_W, unit: W}}}', 'runs:']
    for name, feed, load, state, end, feeds in runs:
        prog = f'f{feed:g}.nc'
        if not (root / prog).exists():
            (root / prog).write_text(program_text(feeds), encoding='utf-8')
        lead = float(rng.uniform(*LEAD_S))
        meter = tm.Meter(period_s=PERIOD_S, noise_w=noise_w, quantum_w=0.1,
                         drift_ppm=float(rng.uniform(-drift_ppm, drift_ppm)))
        power = tm.true_power(state, axis, {effect: amp})
        # stamp 0 is the program's time -lead: the record starts ``lead`` before it
        stamps, y = tm.record(state, power, meter=meter, offset_s=lead, end_s=end + TAIL_S,
                              rng=rng)
        del power
        # the offset compare reports: the program starts at ``lead`` on the record's clock,
        # seen at the record's middle (drift)
        mid = 0.5 * float(stamps[-1])
        offsets[name] = lead + mid * (1.0 - 1.0 / (1.0 + 1e-6 * meter.drift_ppm))
        with open(root / f'{name}.csv', 'w', encoding='utf-8') as fh:
            fh.write('time_s,X_power_W\n')
            np.savetxt(fh, np.column_stack([stamps, y]), fmt=['%.3f', '%.1f'], delimiter=',')
        meter_rows += stamps.size
        lines.append(f'  - {{name: {name}, load_kg: {load:g}, data: {name}.csv, '
                     f'motion: {{program: {prog}}}}}')
        entries.append(name)
    path = root / 'campaign.yaml'
    path.write_text('\n'.join(lines) + '\n', encoding='utf-8')
    (root / 'truth.json').write_text(json.dumps({'rows': meter_rows, 'offsets': offsets}),
                                     encoding='utf-8')
    return path, meter_rows, offsets


def reuse(root: Path) -> tuple[Path, int, dict[str, float]] | None:
    """A campaign :func:`build` left in ``root`` (``--keep``), or ``None``."""
    if not (root / 'campaign.yaml').is_file() or not (root / 'truth.json').is_file():
        return None
    truth = json.loads((root / 'truth.json').read_text(encoding='utf-8'))
    return root / 'campaign.yaml', int(truth['rows']), dict(truth['offsets'])


def run_analyze(manifest: Path, timeout_s: float) -> tuple[float, float, int, int,
                                                           dict | None, str]:
    """``analyze --json`` as a child: wall [s], CPU [s], peak RSS and peak anonymous RSS
    [bytes], JSON, stderr."""
    child = run_cli(['analyze', str(manifest), '--json', '--quiet'], timeout_s=timeout_s)
    errors = child.stderr
    result = (json.loads(child.stdout) if child.code == 0 and child.stdout.strip()
              else None)
    if result is None and child.wall_s <= timeout_s:
        errors = f'exit {child.code}: {errors[-800:]}'
    return child.wall_s, child.cpu_s, child.peak_rss_bytes, child.peak_anon_bytes, result, errors


def summary(res: dict, effect: str, offsets: dict[str, float]) -> str:
    """Named effects, status, held-out figures and offset errors of one analysis."""
    named = sorted(f'{e["id"]}@{e["axis"]}' for e in res['effects'])
    hit = any(e['id'] == effect for e in res['effects']) or any(
        f'{effect}@X' in g['members'] for g in res.get('ambiguous', ()))
    shares = ', '.join(f'{e["id"]} {100 * e["energy_share"]:.2f} %' for e in res['effects'])
    before, after = res['before']['total'], res['after']['total']
    errs = [abs(r['offset']['found_s'] - offsets[r['name']]) for r in res['before']['runs']]
    worst = 1e3 * max(errs) if errs else math.nan
    return (f'  {effect} named: {"yes" if hit else "NO"}  status {res["status"]}  '
            f'named {named or "nothing"} ({shares or "-"})  left out {len(res["left_out"])}  '
            f'pin rounds {res["pin_rounds"]}  samples per bin '
            f'{sorted(set(res["analysis_grid"]["samples_per_bin"].values()))}\n'
            f'  held-out energy error {before["energy_error_pct"]:+.3f} % -> '
            f'{after["energy_error_pct"]:+.3f} %, RMSE {before["rmse_w"]:.3f} W -> '
            f'{after["rmse_w"]:.3f} W; noise sigma '
            + ', '.join(f'{a} {s:.3f} W' for a, s in res['noise_sigma_w'].items())
            + f'; worst offset error {worst:.2f} ms')


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--minutes', default='1,3,10',
                    help='length of every run [min], comma-separated (default: 1,3,10)')
    ap.add_argument('--effect', default='copper',
                    help='the missing effect, a truth-model name (default: copper)')
    ap.add_argument('--share', type=float, default=0.05,
                    help="the effect's share of the energy (default: 0.05)")
    ap.add_argument('--noise-w', type=float, default=1.5, help='meter noise SD [W]')
    ap.add_argument('--seed', type=int, default=24, help='random seed (default: 24)')
    ap.add_argument('--drift-ppm', type=float, default=0.0,
                    help='clock drift of each record, uniform in +-this [ppm] (default: 0)')
    ap.add_argument('--timeout', type=float, default=1800.0,
                    help='kill an analyze after this many seconds (default: 1800)')
    ap.add_argument('--keep', type=Path, default=None,
                    help='write the campaigns under this directory and keep them; a campaign '
                         'of the same length already there is analysed again as it is')
    args = ap.parse_args()
    minutes = [float(m) for m in args.minutes.split(',') if m.strip()]
    print(f'load before: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} '
          f'{os.getloadavg()[2]:.2f} (1/5/15 min)', flush=True)
    first: tuple[float, float] | None = None
    ok = True
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)
    for m in minutes:
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(tmp) if args.keep is None else args.keep / f'm{m:g}'
            root.mkdir(exist_ok=True)
            t0 = time.perf_counter()
            kept = reuse(root) if args.keep is not None else None
            manifest, rows, offsets = kept or build(
                root, m, effect=args.effect, share=args.share, noise_w=args.noise_w,
                seed=args.seed, drift_ppm=args.drift_ppm)
            size = sum(p.stat().st_size for p in root.glob('*.csv'))
            print(f'{m:g} min x 15 runs: {rows:,} rows at 1 kHz ({size / 1e6:.0f} MB CSV), '
                  f'{args.effect} at {100 * args.share:g} % of the energy, '
                  + ('kept from before' if kept else
                     f'generated in {time.perf_counter() - t0:.1f} s'), flush=True)
            wall, cpu, rss, anon, res, errors = run_analyze(manifest, args.timeout)
        line = (f'  analyze: wall {wall:.1f} s  CPU {cpu:.1f} s  peak RSS {rss / 2**20:.0f} MiB'
                f' (anonymous {anon / 2**20:.0f} MiB)')
        if res is None:
            why = f'(killed after {args.timeout:g} s)' if wall > args.timeout else errors
            print(f'{line}  NOT FINISHED {why}', flush=True)
            ok = False
            continue
        if first is None:
            first = (wall, cpu)
        else:
            line += f'  x{wall / first[0]:.1f} wall, x{cpu / first[1]:.1f} CPU of the first'
        print(line, flush=True)
        print(summary(res, args.effect, offsets), flush=True)
    print(f'load after: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} '
          f'{os.getloadavg()[2]:.2f} (1/5/15 min)', flush=True)
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
