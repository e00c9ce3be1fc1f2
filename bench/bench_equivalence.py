"""Issue 23's equivalence: the sampled sums against the energy by phase, with the bound.

Usage: python bench/bench_equivalence.py [--corpus DIR] [--rates 1000,10000,100000]
                                         [--max-seconds S] [--only TEXT] [--programs]

For every program of the shared G-code corpus (``../shared/corpus/gcode``: those the
reference interpreter accepts, without rotary axes; parsed as ``bench/corpus.py`` does) and
the benchmark programs (``--programs``: the demonstrator strokes and a dense contour of
``bench_scale``, 0.02 h each), on ``config/three_axis_mill.yaml`` (the demonstrator's on
``config/demonstrator.yaml``): the energy by phase per axis
(:func:`feed_axis_energy.sim.bound.sampling_bound`), the sampled energy at each rate
(:func:`feed_axis_energy.sim.simulate_stream`), their difference and the bound derived for
that rate. A rate is skipped for programs longer than ``--max-seconds`` of program time at
rates above 1 kHz (default 600 s: 100 kHz over the corpus's 25 hours would take hours).

Printed per program and rate: the largest ``|difference| / bound`` over the axes (<= 1: the
bound holds), the difference and the bound of the total [J]; then per rate the count of
programs within the bound and the largest relative difference ``|difference| / energy``.
Exit status 1 when a difference exceeds its bound.
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
import sys
import tempfile
import time

sys.path.insert(0, str(Path(__file__).resolve().parent))
import corpus as corpus_tools  # noqa: E402
from bench_scale import contour_program, demonstrator_program  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from feed_axis_energy.errors import FeedAxisError  # noqa: E402
from feed_axis_energy.gcode.load import load_gcode  # noqa: E402
from feed_axis_energy.machine.file import load_machine  # noqa: E402
from feed_axis_energy.plan import estimate_plan  # noqa: E402
from feed_axis_energy.sim import simulate_stream  # noqa: E402
from feed_axis_energy.sim.bound import sampling_bound  # noqa: E402


def check(name: str, moves: list, machine, rates: list[float], max_seconds: float,
          tally: dict) -> bool:
    """Print one program's line per rate; return False when a difference exceeds its bound."""
    ok = True
    duration = estimate_plan(moves, machine.limits(), options=machine.planner.options(),
                             file=name).duration_s
    for rate in rates:
        if rate > 1000.0 and duration > max_seconds:
            print(f'  {rate:>8.0f} Hz  skipped ({duration:.0f} s of program time)')
            continue
        t0 = time.perf_counter()
        bound = sampling_bound(moves, machine, rate_hz=rate, file=name)
        summary, _ = simulate_stream(moves, replace(machine, planner=replace(
            machine.planner, rate_hz=rate)), file=name)
        sampled = np.array([summary['energy_j'][a] for a in bound.axes])
        diff = sampled - bound.energy_j
        ratio = np.max(np.abs(diff) / np.maximum(bound.bound_j, 1e-300))
        total = float(np.sum(bound.energy_j))
        row = tally.setdefault(rate, {'n': 0, 'within': 0, 'rel': 0.0, 'bound_rel': 0.0})
        row['n'] += 1
        within = bool(np.all(np.abs(diff) <= bound.bound_j))
        row['within'] += within
        if abs(total) > 1e-9:
            row['rel'] = max(row['rel'], float(np.sum(np.abs(diff))) / abs(total))
            row['bound_rel'] = max(row['bound_rel'], float(np.sum(bound.bound_j)) / abs(total))
        ok &= within
        print(f'  {rate:>8.0f} Hz  |diff|/bound {ratio:8.2e}  diff {np.sum(diff):+.3e} J  '
              f'bound {np.sum(bound.bound_j):.3e} J  of {total:.6g} J  '
              f'({time.perf_counter() - t0:.1f} s){"" if within else "  EXCEEDS"}')
    return ok


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--corpus', default=None, help='corpus folder (default: shared data)')
    ap.add_argument('--rates', default='1000,10000,100000', help='sample rates [Hz]')
    ap.add_argument('--max-seconds', type=float, default=600.0,
                    help='program time above which rates over 1 kHz are skipped [s]')
    ap.add_argument('--only', default='', help='only corpus files whose name contains this')
    ap.add_argument('--programs', action='store_true',
                    help='the benchmark programs too (demonstrator, dense contour)')
    args = ap.parse_args()
    rates = [float(r) for r in args.rates.split(',') if r]
    mill = load_machine(ROOT / 'config' / 'three_axis_mill.yaml')
    tally: dict = {}
    bad: list[str] = []
    t_start = time.perf_counter()
    if args.programs:
        with tempfile.TemporaryDirectory() as tmp:
            for name, text, machine in (
                    ('demonstrator 0.02 h', demonstrator_program(0.02),
                     load_machine(ROOT / 'config' / 'demonstrator.yaml')),
                    ('contour 0.02 h', contour_program(0.02), mill)):
                path = Path(tmp) / 'p.nc'
                path.write_text(text, encoding='utf-8')
                print(name)
                if not check(name, list(load_gcode(path).moves), machine, rates,
                             args.max_seconds, tally):
                    bad.append(name)
    root = corpus_tools.find_corpus(args.corpus)
    if root is None:
        print('no corpus (../shared/corpus/gcode)', file=sys.stderr)
    else:
        links = corpus_tools.SubroutineLinks()
        known = corpus_tools.known_dialects()
        try:
            for entry in corpus_tools.load_corpus(root):
                if (not entry.reference_accepts or entry.rotary
                        or args.only not in entry.file):
                    continue
                path = root / entry.file
                # as bench/corpus.py reads it: the program's dialect where we know it
                kw = corpus_tools._parse_keywords(corpus_tools._dialect_for(entry, known),
                                                  [links.for_folder(path.parent), path.parent])
                try:
                    moves = list(load_gcode(path, **kw).moves)
                    print(entry.file)
                    if not check(entry.file, moves, mill, rates, args.max_seconds, tally):
                        bad.append(entry.file)
                except FeedAxisError as err:
                    print(f'{entry.file}: refused ({err})')
                except Exception as err:  # noqa: B902 - a crash is a finding: go on, count it
                    print(f'{entry.file}: CRASHED ({type(err).__name__}: {err})')
                    bad.append(entry.file)
        finally:
            links.close()
    print(f'\n{time.perf_counter() - t_start:.0f} s')
    for rate, row in tally.items():
        print(f'{rate:>8.0f} Hz: {row["within"]}/{row["n"]} programs within the bound; '
              f'largest |difference| / energy {row["rel"]:.2e}, bound / energy up to '
              f'{row["bound_rel"]:.2e}')
    for name in bad:
        print(f'EXCEEDS: {name}')
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
