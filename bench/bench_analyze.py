"""Benchmark of ``analyze_campaign``: ``PYTHONPATH=. .venv/bin/python bench/bench_analyze.py``.

A virtual-rig campaign in a temporary directory: 5 feeds x 3 loads = 15 runs of about 60 s
(reciprocating 400 mm strokes, the cycle count chosen per feed so each program lasts about
60 s), simulated at 1 kHz, recorded at 50 ms with 2 W noise and load-dependent friction
(mu = 0.1) in the truth. Prints the wall time of the rig and of ``analyze_campaign``
(target < 30 s), what it found and the held-out average percentual error before/after.
"""
from __future__ import annotations

import math
from pathlib import Path
import tempfile
import time

from feed_axis_energy.identify.analyze import analyze_campaign
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.identify.rig import EffectSpec, Instrument
from feed_axis_energy.identify.rig import (make_campaign, PAPER_FEEDS_MM_S, PAPER_LOADS_KG,
                                           RigConfig)
from feed_axis_energy.paths import config_dir

TARGET_S = 60.0


def main() -> None:
    """Build the campaign, run the analysis, print the figures."""
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        manifest = None
        for feed in PAPER_FEEDS_MM_S:
            # one stroke there and back: 2 x (0.4 m / v + ramps) + 2 s of dwell
            cycles = max(1, math.floor(TARGET_S / (2.0 * 0.4 / (feed / 1000.0) + 2.4)))
            cfg = RigConfig(machine=Path(config_dir()) / 'demonstrator.yaml',
                            loads_kg=PAPER_LOADS_KG, feeds_mm_s=(feed,), cycles=cycles,
                            effects=(EffectSpec('load_friction', {'mu': 0.1}),),
                            instrument=Instrument(noise_w=2.0), seed=int(feed))
            manifest = _merge(Path(tmp), feed, cfg, manifest)
        t1 = time.perf_counter()
        campaign = load_campaign(manifest)
        t2 = time.perf_counter()
        res = analyze_campaign(campaign)
        t3 = time.perf_counter()
        durations = [r.t[-1] - r.t[0] for r in res.runs]
    print(f'runs: {len(res.runs)}, measured duration {min(durations):.1f} .. '
          f'{max(durations):.1f} s each ({sum(len(r.t) for r in res.runs)} samples at 50 ms)')
    print(f'rig (truth simulation + CSV): {t1 - t0:.2f} s')
    print(f'analyze_campaign: {t3 - t2:.2f} s (target < 30 s)')
    print(f'status: {res.status}: {res.message}')
    for e in res.effects:
        print('  ' + ', '.join(f'{e.id}.{p.name} = {p.value:.5g} +- {p.uncertainty or 0:.2g}'
                               for p in e.params))
    print(f'held-out avg percentual error: {res.before.avg_pct_error_pct:.2f} % -> '
          f'{res.after.avg_pct_error_pct:.2f} %')


def _merge(root: Path, feed: float, cfg: RigConfig, manifest: Path | None) -> Path:
    """Write one feed's rig campaign and append its runs to a combined manifest."""
    import yaml
    sub = root / f'f{feed:g}'
    part = make_campaign(sub, cfg)
    data = yaml.safe_load(part.read_text())
    for run in data['runs']:
        run['motion']['program'] = str(sub / run['motion']['program'])
        run['data'] = str(sub / run['data'])
    data['machine'] = str(sub / 'machine.yaml')
    out = root / 'manifest.yaml'
    if manifest is not None:
        old = yaml.safe_load(out.read_text())
        data['runs'] = old['runs'] + data['runs']
    out.write_text(yaml.safe_dump(data, sort_keys=False))
    return out


if __name__ == '__main__':
    main()
