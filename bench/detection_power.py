"""Detection power of ``analyze``: the smallest effect it names, and what it names wrongly.

``PYTHONPATH=. .venv/bin/python bench/detection_power.py [--campaign paper|three_axis]
[--effects ID,...] [--sizes S,...] [--seeds N] [--first-seed K] [--noise-w W] [--period-ms T]``

For every catalog effect that describes the machine (all but ``time_offset``), a campaign of
the virtual rig (``identify/rig/``) is made with the effect's example parameters scaled so that
the RMS of its extra power over every simulated sample of the campaign is ``size`` times the
noise level, and ``analyze`` runs on it with default options, once per seed. Campaigns:

* ``paper``: the paper's single axis (``config/demonstrator.yaml``), loads 0, 17.336,
  22.711 kg, feeds 100..500 mm/s, one 400 mm stroke each;
* ``three_axis``: ``config/three_axis_mill.yaml`` (cross table X/Y, vertical Z), loads 0,
  50, 100 kg on Y, feeds 100, 250, 400 mm/s (Z's limit is 400 mm/s); each run moves X by
  200 mm, then Y by 200 mm, then Z down 150 mm, and back in reverse order, 0.5 s dwells.
  The truth effect acts on every axis with the same parameters; every axis is measured.

Both with a 50 ms meter (``--period-ms``: its averaging window and report period; 1 for a
1 kHz trace), ``--noise-w`` Gaussian noise plus 1 W quantisation and random start
offsets. Each size is also printed as the effect's share of the campaign's energy (its
energy over the declared model's, every run, at the simulation rate). Per size the script
prints how often the effect was *named* alone (``named``: on some axis, not part of an
ambiguous finding), how often it was part of an ambiguous finding (``group``: ``analyze``
reports a loss of one power shape with several equivalent forms, the true effect among
them), how often another effect was named in its place with the true one among its
pairwise ``aliases`` (``alias``), and how often anything else was named (``false``: an
effect, or an ambiguous finding, that does not contain the true effect, except a
``time_offset`` under 5 ms, which corrects the alignment). An effect ``analyze`` *offers*
(an improvement it does not attribute, ``offered`` in its result) is counted apart:
``offered`` when the true effect is among them, else it counts as false. The summary gives,
per effect, the smallest size named alone in at least 90 % of the seeds, the smallest size
named alone or as a group in 90 %, and the false-attribution rate at each; a clean campaign
(no effect) gives the false rate of the noise alone. Progress goes to stderr, the tables to
stdout; the figures depend only on the seeds.
"""
from __future__ import annotations

import argparse
from collections.abc import Callable
import math
from pathlib import Path
import sys
import tempfile
import time
from typing import NamedTuple

import numpy as np

from feed_axis_energy.effects.catalog import EFFECTS, get_effect
from feed_axis_energy.physics.effectstate import state_from_simulation
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.identify.analyze import analyze_campaign
from feed_axis_energy.identify.results import AnalyzeOptions
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.identify.rig import EffectSpec, Instrument
from feed_axis_energy.identify.rig import (make_campaign, PAPER_FEEDS_MM_S, PAPER_LOADS_KG,
                                           RigConfig, stroke_program)
from feed_axis_energy.sim.simulate import simulate_program
from feed_axis_energy.paths import config_dir

MACHINE = Path(config_dir()) / 'demonstrator.yaml'
SIZES = (0.25, 0.5, 1.0, 2.0)
NAMED_SHARE = 0.9


def three_axis_program(feed_mm_s: float) -> str:
    """NC text of the 3-axis campaign: X, Y, Z one after the other and back."""
    f = f'F{feed_mm_s * 60.0:g}'
    moves = ['X200', 'Y200', 'Z-150', 'Z0', 'Y0', 'X0']
    lines = [f'( 3-axis campaign: X, Y, Z strokes at {feed_mm_s:g} mm/s )',
             'G21 G90 G94 G61', 'G0 X0 Y0 Z0', 'G4 P0.5']
    for m in moves:
        lines += [f'G1 {m} {f}', 'G4 P0.5']
    return '\n'.join(lines + ['M30']) + '\n'


def paper_program(feed_mm_s: float) -> str:
    """NC text of the paper's campaign: one 400 mm stroke on X and back, 1 s dwells."""
    return stroke_program(feed_mm_s, axis='X', cycles=1, dwell_s=1.0)


class Campaign(NamedTuple):
    """A campaign of the study: machine, loads, feeds and the program of each feed."""

    name: str
    machine: Path
    loads_kg: tuple[float, ...]
    feeds_mm_s: tuple[float, ...]
    program: Callable[[float], str]
    description: str


CAMPAIGNS = {
    'paper': Campaign('paper', MACHINE, PAPER_LOADS_KG, PAPER_FEEDS_MM_S, paper_program,
                      'paper single axis, 3 loads x 5 feeds, one 400 mm stroke'),
    'three_axis': Campaign('three_axis', Path(config_dir()) / 'three_axis_mill.yaml',
                           (0.0, 50.0, 100.0), (100.0, 250.0, 400.0), three_axis_program,
                           '3-axis mill, 3 loads x 3 feeds, X/Y/Z strokes'),
}


def catalog_ids() -> list[str]:
    """Every effect that describes the machine (``time_offset`` describes the records)."""
    return [i for i, cls in EFFECTS.items() if cls.machine_property]


def example_params(effect_id: str) -> dict[str, float]:
    """The catalog's example values (``rig --effects ID`` uses the same)."""
    return {p.name: p.example for p in get_effect(effect_id).params}


def unit_rms_w(effect_id: str, *, campaign: str = 'paper') -> float:
    """RMS of the effect's extra power at its example values over the campaign [W]."""
    return unit_figures(effect_id, campaign=campaign)[0]


def unit_figures(effect_id: str, *, campaign: str = 'paper') -> tuple[float, float]:
    """RMS [W] and energy share [-] of the effect at its example values over the campaign.

    The share is the effect's energy over the declared model's energy (sum of the runs).
    """
    camp = CAMPAIGNS[campaign]
    machine = load_machine(camp.machine)
    effect = get_effect(effect_id)
    params = example_params(effect_id)
    total, count, extra_j, base_j = 0.0, 0, 0.0, 0.0
    for feed in camp.feeds_mm_s:
        program = parse_gcode(camp.program(feed), file=f'f{feed:g}.nc')
        for load in camp.loads_kg:
            sim = simulate_program(program, machine, load_kg=load)
            p = effect.power_w(state_from_simulation(sim), params)
            total += float(np.sum(p * p))
            count += p.size
            dt = float(np.median(np.diff(sim.power.t))) if sim.power.t.size > 1 else 0.0
            extra_j += float(np.sum(p)) * dt
            base_j += float(np.sum(sim.power.total_w)) * dt
    rms = math.sqrt(total / count) if count else 0.0
    return rms, (extra_j / base_j if base_j > 0.0 else math.nan)


def scaled_params(effect_id: str, size: float, noise_w: float, rms_w: float) -> dict | None:
    """Example values with the linear ones scaled to an RMS of ``size * noise_w``.

    ``None`` when a scaled value would leave the parameter's physical bounds.
    """
    effect = get_effect(effect_id)
    params = example_params(effect_id)
    if rms_w <= 0.0:
        return None
    k = size * noise_w / rms_w
    for p in effect.params:
        if p.linear:
            params[p.name] = params[p.name] * k
            if not p.bounds[0] <= params[p.name] <= p.bounds[1]:
                return None
    return params


class Outcome(NamedTuple):
    """What one analysis named, against the truth.

    Attributes
    ----------
    named
        The true effect named alone (on some axis, outside every ambiguous finding).
    group
        The true effect is a member of an ambiguous finding.
    false
        Effects or findings named that do not contain the true effect.
    aliasing
        Effects named in its place with the true one among their pairwise aliases.
    offered
        The true effect is among the effects offered (an improvement not attributed).
    """

    named: bool
    group: bool
    false: tuple[str, ...]
    aliasing: tuple[str, ...]
    offered: bool = False


def trial(effect_id: str | None, params: dict | None, *, seed: int, noise_w: float,
          work: Path, campaign: str = 'paper', period_s: float = 0.05) -> Outcome:
    """One campaign and its analysis, scored against the truth."""
    camp = CAMPAIGNS[campaign]
    effects = () if effect_id is None else (EffectSpec(effect_id, params),)
    meter = Instrument(noise_w=noise_w, window_s=period_s, period_s=period_s)
    cfg = RigConfig(machine=camp.machine, loads_kg=camp.loads_kg, feeds_mm_s=camp.feeds_mm_s,
                    effects=effects, instrument=meter, seed=seed, program=camp.program)
    out = work / f'{effect_id or "clean"}_{seed}_{time.perf_counter_ns()}'
    # the findings only: the re-aligned before/after figures are not needed here
    res = analyze_campaign(load_campaign(make_campaign(out, cfg)),
                           options=AnalyzeOptions(realign=False))
    return score(res, effect_id)


def score(res, effect_id: str | None) -> Outcome:
    """Score an :class:`AnalysisResult` against the true effect (``None``: a clean campaign)."""
    truth = {f'{effect_id}@{a}' for a in res.axes} if effect_id is not None else set()
    in_group = {m for g in res.ambiguous for m in g.members}
    grouped = {m for g in res.ambiguous for m in g.selected}
    group = any(truth & set(g.members) for g in res.ambiguous)
    named = any(f'{e.id}@{e.axis}' in truth and f'{e.id}@{e.axis}' not in grouped
                for e in res.effects)
    false = ['group(' + ', '.join(g.members) + ')' for g in res.ambiguous
             if not truth & set(g.members)]
    aliasing = []
    for e in res.effects:
        name = f'{e.id}@{e.axis}'
        if name in truth or name in in_group:
            continue
        if e.id == 'time_offset' and abs(e.values()['delta_s']) < 0.005:
            continue
        if truth & set(e.aliases):
            aliasing.append(e.id)
        else:
            false.append(e.id)
    offered_names = {f'{e.id}@{e.axis}' for e in getattr(res, 'offered', ())
                     if not (e.id == 'time_offset' and abs(e.values()['delta_s']) < 0.005)}
    offered = bool(truth & offered_names)
    if offered_names and not offered:
        false.append('offered(' + ', '.join(sorted(offered_names)) + ')')
    return Outcome(named=named, group=group, false=tuple(false), aliasing=tuple(aliasing),
                   offered=offered)


def _parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--campaign', choices=sorted(CAMPAIGNS), default='paper',
                   help='campaign: the paper single axis or the 3-axis mill (default paper)')
    p.add_argument('--effects', default=','.join(catalog_ids()),
                   help='catalog ids (default: every machine effect)')
    p.add_argument('--sizes', default=','.join(f'{s:g}' for s in SIZES),
                   help='RMS power of the effect over the noise level (default: %(default)s)')
    p.add_argument('--seeds', type=int, default=3, help='seeds per case (default: 3)')
    p.add_argument('--noise-w', type=float, default=1.5, help='meter noise [W] (default 1.5)')
    p.add_argument('--first-seed', type=int, default=1, help='first seed (default: 1)')
    p.add_argument('--period-ms', type=float, default=50.0,
                   help='meter window and report period [ms] (default 50; 1 = a 1 kHz trace)')
    p.add_argument('--no-clean', action='store_true', help='skip the clean campaigns')
    return p.parse_args()


def main() -> int:
    """Run the study and print the tables."""
    args = _parse()
    ids = [i.strip() for i in args.effects.split(',') if i.strip()]
    unknown = [i for i in ids if i not in EFFECTS]
    if unknown:
        print(f'error: unknown effect(s) {", ".join(unknown)}', file=sys.stderr)
        return 2
    sizes = sorted(float(s) for s in args.sizes.split(','))
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    period_s = 1e-3 * args.period_ms
    camp = args.campaign
    rows, summary = [], []
    cpu0 = time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        if not args.no_clean:
            false = sum(bool(trial(None, None, seed=s, noise_w=args.noise_w, work=work,
                                   campaign=camp, period_s=period_s).false) for s in seeds)
            summary.append(['(clean)', '-', '-', '-', '-', f'{false}/{len(seeds)}'])
            print(f'clean: {false}/{len(seeds)} with an effect named', file=sys.stderr)
        for effect_id in ids:
            rms, share = unit_figures(effect_id, campaign=camp)
            alone = either = None
            for size in sizes:
                params = scaled_params(effect_id, size, args.noise_w, rms)
                if params is None:
                    why = 'beyond bounds' if rms > 0.0 else 'no power in this campaign'
                    rows.append([effect_id, f'{size:g}', why, '-', '-', '-', '-', '-'])
                    continue
                named = group = false = alias = offer = 0
                wrong: set[str] = set()
                for s in seeds:
                    o = trial(effect_id, params, seed=s, noise_w=args.noise_w, work=work,
                              campaign=camp, period_s=period_s)
                    named += o.named
                    group += o.group and not o.named
                    false += bool(o.false)
                    alias += bool(o.aliasing) and not (o.named or o.group)
                    offer += o.offered and not (o.named or o.group)
                    wrong.update(o.false)
                    wrong.update(f'{a} (alias)' for a in o.aliasing)
                n = len(seeds)
                energy = f'{size:g} ({100 * share * size * args.noise_w / rms:.2g} % of E)'
                rows.append([effect_id, energy, f'{named}/{n}', f'{group}/{n}',
                             f'{alias}/{n}', f'{offer}/{n}', f'{false}/{n}',
                             ', '.join(sorted(wrong)) or '-'])
                print(f'{effect_id} size {energy}: named {named}/{n}, group {group}/{n}, alias '
                      f'{alias}/{n}, offered {offer}/{n}, false {false}/{n} '
                      f'({time.process_time() - cpu0:.0f} s CPU)', file=sys.stderr)
                if alone is None and named >= NAMED_SHARE * n:
                    alone = (size, false)
                if either is None and named + group >= NAMED_SHARE * n:
                    either = (size, false)
            example = ', '.join(f'{k} {v:g}' for k, v in example_params(effect_id).items()
                                if v)
            summary.append([effect_id, f'{rms:.3g} W at {example}'] + [
                x for best in (alone, either)
                for x in ('-' if best is None else f'{best[0]:g}',
                          '-' if best is None else f'{best[1]}/{len(seeds)}')])
    print(f'campaign: {CAMPAIGNS[camp].description}, noise {args.noise_w:g} W + 1 W quantum, '
          f'meter {args.period_ms:g} ms; seeds {seeds.start}..{seeds.stop - 1}; '
          f'{time.process_time() - cpu0:.0f} s CPU')
    print()
    print('| effect | size (RMS / noise) | named alone | as group | alias only | offered | '
          'false | named instead |')
    print('| --- | --- | --- | --- | --- | --- | --- | --- |')
    for r in rows:
        print('| ' + ' | '.join(r) + ' |')
    print()
    share = f'{100 * NAMED_SHARE:.0f} %'
    print(f'| effect | RMS at example values | smallest size named alone in >= {share} | '
          f'false there | smallest size named alone or as group in >= {share} | false there |')
    print('| --- | --- | --- | --- | --- | --- |')
    for r in summary:
        print('| ' + ' | '.join(r) + ' |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
