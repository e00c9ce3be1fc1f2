"""``analyze`` on a ball-screw test stand's force campaign, scored against the truth (issue 24).

``PYTHONPATH=. .venv/bin/python bench/truth_stand_analyze.py [--seeds 1 2 3] [--variants ...]``

The stand is :mod:`truth_stand`'s (asymmetric Coulomb and viscous friction, an exponential
Stribeck excess, a constant offset force ``F0`` that also acts at rest; 1 kHz force from the
controller output, first-order filtered). Each cell writes a campaign of positioning programs
at several feeds and strokes in both directions: the *calibration* runs and the *held-out*
runs (other feeds and targets, never seen by any fit). Then:

1. the *reference identification*, the classic inverse-model fit of mass, symmetric Coulomb
   and viscous friction (``fit-loss --method samples``'s core on the calibration runs), gives
   the declared machine;
2. ``analyze`` (its core ``analyze_campaign``, leave-one-run-out on the calibration runs)
   looks for what that machine misses, on the force trace;
3. the held-out runs are compared (``compare``'s core) with the reference machine and with the
   augmented machine ``analyze`` writes: power RMSE ``F·v`` and net energy error.

Scored per cell: the effects named (alone or in an ambiguous group) against the truth's, false
attributions (an effect the truth lacks that is no correction of the reference fit's own
figures), the noise estimate used, the held-out figures before/after and their ratio (target
``after <= 0.95 x reference`` and ``|net energy error| <= 2 %``). Variants make it a class:
``full`` (every term), ``no_offset``, ``no_stribeck``, ``meter`` (white meter noise on top of
the filtered one: a noisy sensor instead of a controller output), ``power`` (the full stand's
force times the measured velocity analysed as a shaft power: the rest samples are gone, so
the offset force and the asymmetric Coulomb part are one shape and may be named as one
group), ``loads`` (the full stand with a different load on the carriage in each run:
a weight would follow the mass, the offset force does not, so ``offset_force`` must be told
from ``gravity``) and ``clean`` (a symmetric stand, the reference fit's own class: nothing
may be named).
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass, replace
import math
from pathlib import Path
import sys
import tempfile
import time

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
import truth_stand as ts  # noqa: E402

# calibration programs: truth_stand's; held out: other feeds and targets, both directions
CALIBRATE = dict(ts.PROGRAMS)
HELD_OUT = {
    'v150': (0.15, [0.10, 0.30, 0.05, 0.0]),
    'v250': (0.25, [0.20, 0.08, 0.30, 0.0]),
    'v350': (0.35, [0.30, 0.02, 0.15, 0.0]),
}
VARIANTS = {
    'full': ts.StandTruth(),
    'no_offset': replace(ts.StandTruth(), offset_n=0.0),
    'no_stribeck': replace(ts.StandTruth(), stribeck_n=0.0),
    'meter': ts.StandTruth(),
    'power': ts.StandTruth(),
    'loads': ts.StandTruth(),
    'clean': replace(ts.StandTruth(), f_pos_n=26.0, f_neg_n=26.0, c_pos_n_s_m=55.0,
                     c_neg_n_s_m=55.0, stribeck_n=0.0, offset_n=0.0),
}
LOADS_KG = (0.0, 12.0, 25.0)
"""Loads on the carriage of the ``loads`` variant, in turn over the runs [kg]."""
METER_NOISE_N = 2.0
"""White noise [N] of the ``meter`` variant (per sample, unfiltered)."""
FRICTION = ('coulomb', 'viscous_asymmetry', 'stribeck')
"""Catalog names of the truth's missing friction terms (``coulomb``: its asymmetric part)."""
OFFSET = ('offset_force', 'gravity')
"""The offset force and its alias (the moved mass is the same in every run)."""
CORRECTIONS = ('viscous', 'mass_error')
"""Corrections of the reference fit's own figures (its symmetric fit absorbs part of the
missing terms): neither required nor false."""


@dataclass(frozen=True)
class CellScore:
    """What one campaign's analysis found, against its truth."""

    variant: str
    seed: int
    status: str
    expected: tuple[str, ...]
    named: tuple[str, ...]
    missed: tuple[str, ...]
    false: tuple[str, ...]
    noise: str
    ref_rmse_w: float
    after_rmse_w: float
    ref_energy_pct: float
    after_energy_pct: float
    seconds: float
    params: dict[str, dict[str, float]]
    """Fitted linear and shape parameters of every effect added (named or offered)."""

    @property
    def ratio(self) -> float:
        """Held-out power RMSE after over the reference identification's."""
        return self.after_rmse_w / self.ref_rmse_w if self.ref_rmse_w > 0 else math.nan

    @property
    def passed(self) -> bool:
        """Named right, nothing false, and the held-out targets met."""
        if self.missed or self.false:
            return False
        if not self.expected:
            return self.status == 'clean'
        return self.ratio <= 0.95 and abs(self.after_energy_pct) <= 2.0


def expected_terms(truth: ts.StandTruth, *, power: bool = False) -> tuple[str, ...]:
    """The catalog terms the reference identification misses for ``truth``.

    ``power``: analysed as ``F·v``, where the Stribeck excess adds at most
    ``Fs·vs/e`` (0.018 W for the default stand, under the noise of its power) and is not
    required.
    """
    out = []
    if truth.f_pos_n != truth.f_neg_n:
        out.append('coulomb')
    if truth.c_pos_n_s_m != truth.c_neg_n_s_m:
        out.append('viscous_asymmetry')
    if truth.stribeck_n > 0.0 and not power:
        out.append('stribeck')
    if truth.offset_n != 0.0:
        out.append('offset_force')
    return tuple(out)


def write_campaign(out: Path, *, seed: int, truth: ts.StandTruth,
                   meter_noise_n: float = 0.0, loads: bool = False) -> Path:
    """Machine (truth_stand's guess), manifest and CSVs of the calibration and held-out runs.

    The CSVs also hold ``F·v`` [W] (``power_w``); ``power.yaml`` beside the manifest is the
    same campaign as a shaft power. ``loads``: run ``i`` carries ``LOADS_KG[i % 3]`` on the
    carriage (the truth's mass grows by it, the manifest says ``load_kg``).
    """
    rng = np.random.default_rng(seed)
    (out / 'runs').mkdir(parents=True)
    (out / 'machine.yaml').write_text(yaml.safe_dump(ts.machine_doc(), sort_keys=False),
                                      encoding='utf-8')
    entries = []
    programs = [(n, p, 'calibrate') for n, p in CALIBRATE.items()]
    programs += [(n, p, 'validate') for n, p in HELD_OUT.items()]
    for i, (name, (feed, targets), role) in enumerate(programs):
        load = LOADS_KG[i % len(LOADS_KG)] if loads else 0.0
        r = ts.record(name, feed, targets, replace(truth, mass_kg=truth.mass_kg + load), rng)
        force = r['force'] + rng.normal(0.0, meter_noise_n, size=r['t'].size)
        rows = ['time_s,x_mm,v_mm_s,a_mm_s2,force_n,power_w']
        rows += [f'{t:.3f},{x * 1e3:.6f},{v * 1e3:.6f},{a * 1e3:.6f},{f:.5f},{f * v:.6f}'
                 for t, x, v, a, f in zip(r['t'], r['x'], r['v'], r['a'], force)]
        (out / 'runs' / f'{name}.csv').write_text('\n'.join(rows) + '\n', encoding='utf-8')
        entries.append({'name': name, 'data': f'runs/{name}.csv', 'load_kg': load,
                        'role': role})
    axis = {'position': {'column': 'x_mm', 'unit': 'mm'},
            'velocity': {'column': 'v_mm_s', 'unit': 'mm/s'},
            'acceleration': {'column': 'a_mm_s2', 'unit': 'mm/s^2'},
            'force': {'column': 'force_n', 'unit': 'N'}}
    manifest = {'name': f'stand_{seed}', 'machine': 'machine.yaml',
                'defaults': {'time': {'column': 'time_s', 'unit': 's'},
                             'motion': {'from_data': 'actual', 'reconstruct': 'samples'},
                             'instrument': {'measures': 'force'}, 'axes': {'X': axis}},
                'runs': entries}
    path = out / 'manifest.yaml'
    path.write_text(yaml.safe_dump(manifest, sort_keys=False), encoding='utf-8')
    power = dict(manifest, name=f'stand_{seed}_power')
    power['defaults'] = dict(manifest['defaults'], instrument={'measures': 'shaft'},
                             axes={'X': {k: v for k, v in axis.items() if k != 'force'}
                                   | {'power': {'column': 'power_w', 'unit': 'W'}}})
    (out / 'power.yaml').write_text(yaml.safe_dump(power, sort_keys=False), encoding='utf-8')
    return path


def reference_machine(manifest: Path, out: Path) -> Path:
    """The reference identification (mass, symmetric Coulomb and viscous) as a machine file."""
    from feed_axis_energy.identify import fit_drive_samples, machine_with_sample_fits
    from feed_axis_energy.machine import load_machine, machine_to_dict
    from feed_axis_energy.measured import load_campaign, load_run
    campaign = load_campaign(manifest)
    machine = load_machine(campaign.machine)
    runs = [load_run(s) for s in campaign.runs if s.role == 'calibrate']
    fits = fit_drive_samples(runs, machine=machine, measures='force',
                             gains={'X': ts.LEAD_M / (2.0 * math.pi)}, velocity='actual')
    fitted = machine_with_sample_fits(machine, fits)
    out.write_text(yaml.safe_dump(machine_to_dict(fitted), sort_keys=False), encoding='utf-8')
    return out


def heldout_figures(manifest: Path, machine) -> tuple[float, float]:
    """Pooled power RMSE [W] and net energy error [%] of the held-out runs."""
    from feed_axis_energy.measured import compare_campaign, load_campaign
    campaign = load_campaign(manifest)
    names = [s.name for s in campaign.runs if s.role == 'validate']
    cmp = compare_campaign(campaign, machine=machine, runs=names)
    n = sum(r.metrics.n_samples for r in cmp.runs)
    sse = sum(r.metrics.rmse_w ** 2 * r.metrics.n_samples for r in cmp.runs)
    e_meas = sum(r.metrics.energy_meas_j for r in cmp.runs)
    e_sim = sum(r.metrics.energy_sim_j for r in cmp.runs)
    return math.sqrt(sse / n), 100.0 * (e_sim - e_meas) / abs(e_meas)


def named_terms(result) -> tuple[set[str], set[str]]:
    """Effect ids named alone, and those named only inside an ambiguous group."""
    alone = {e.id for e in result.effects if e.axis == 'X'}
    grouped = {m.rsplit('@', 1)[0] for g in result.ambiguous for m in g.members}
    return alone, grouped - alone


def score(result, truth: ts.StandTruth, *, variant: str, seed: int,
          before: tuple[float, float], after: tuple[float, float],
          seconds: float) -> CellScore:
    """Compare what ``analyze`` named with the truth's missing terms."""
    expected = expected_terms(truth, power=variant == 'power')
    alone, grouped = named_terms(result)
    found = alone | grouped
    missed = []
    # an incline's weight follows the moved mass: with loads that vary it is no alias
    offset = ('offset_force',) if variant == 'loads' else OFFSET
    # on power, the asymmetric Coulomb part and the offset force are one shape
    joined = variant == 'power' and {'coulomb', 'offset_force'} <= set(expected)
    for term in expected:
        group = offset if term == 'offset_force' else (term,)
        if joined and term in ('coulomb', 'offset_force'):
            group = OFFSET + ('coulomb',)
        if not found & set(group):
            missed.append(term)
    allowed = set(expected) | set(CORRECTIONS) | (set(offset) if 'offset_force' in expected
                                                  else set())
    if truth.stribeck_n > 0.0:
        allowed |= {'coulomb', 'stribeck'}  # Stribeck, and the Coulomb level it moves
    false = sorted(alone - allowed) + sorted(e.id for e in result.offered
                                             if e.id not in allowed)
    n = result.noise['X']
    noise = f'{n.method} {n.sigma_w:.3g} {result.residual_unit} (white {n.white_w:.3g})'
    return CellScore(variant=variant, seed=seed, status=result.status, expected=expected,
                     named=tuple(sorted(alone)) + tuple(f'[{g}]' for g in sorted(grouped)),
                     missed=tuple(missed), false=tuple(false), noise=noise,
                     ref_rmse_w=before[0], after_rmse_w=after[0], ref_energy_pct=before[1],
                     after_energy_pct=after[1], seconds=seconds,
                     params={e.id: {q.name: q.value for q in e.params}
                             for e in result.effects + result.offered if e.axis == 'X'})


def run_cell(variant: str, seed: int, work: Path, *, effects: tuple[str, ...] | None = None,
             verbose: bool = False) -> CellScore:
    """Write, fit, analyse and score one campaign."""
    from feed_axis_energy.identify import analyze_campaign, AnalyzeOptions
    from feed_axis_energy.machine import load_machine
    from feed_axis_energy.measured import load_campaign
    truth = VARIANTS[variant]
    out = work / f'{variant}_{seed}'
    manifest = write_campaign(out, seed=seed, truth=truth,
                              meter_noise_n=METER_NOISE_N if variant == 'meter' else 0.0,
                              loads=variant == 'loads')
    ref_path = reference_machine(manifest, out / 'reference.yaml')
    reference = load_machine(ref_path)
    if variant == 'power':
        manifest = out / 'power.yaml'
    campaign = load_campaign(manifest)
    calibrate = [s.name for s in campaign.runs if s.role == 'calibrate']
    start = time.perf_counter()
    result = analyze_campaign(campaign, machine=reference, runs=calibrate,
                              options=AnalyzeOptions(effects=effects))
    seconds = time.perf_counter() - start
    if verbose:
        print(f'  {variant} seed {seed}: {result.status}: {result.message}')
        for e in result.effects + result.offered:
            values = ', '.join(f'{q.name} {q.value:.4g} {q.unit}' for q in e.params)
            print(f'    {e.id}@{e.axis}: {values}')
    return score(result, truth, variant=variant, seed=seed,
                 before=heldout_figures(manifest, reference),
                 after=heldout_figures(manifest, result.augmented_machine()), seconds=seconds)


def main(argv: list[str] | None = None) -> int:
    """Run the cells, print one row each and the class summary."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--seeds', type=int, nargs='+', default=[1, 2, 3])
    p.add_argument('--variants', nargs='+', default=list(VARIANTS), choices=list(VARIANTS))
    p.add_argument('--verbose', action='store_true', help="print analyze's message per cell")
    args = p.parse_args(argv)
    rows = []
    print('| variant | seed | status | named ([group]) | missed | false | noise used | '
          'held-out RMSE ref -> after [W] (ratio) | net energy ref -> after [%] | s |')
    print('| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |')
    with tempfile.TemporaryDirectory() as tmp:
        for variant in args.variants:
            for seed in args.seeds:
                c = run_cell(variant, seed, Path(tmp), verbose=args.verbose)
                rows.append(c)
                print(f'| {variant} | {seed} | {c.status} | {", ".join(c.named) or "-"} | '
                      f'{", ".join(c.missed) or "-"} | {", ".join(c.false) or "-"} | '
                      f'{c.noise} | {c.ref_rmse_w:.3g} -> {c.after_rmse_w:.3g} '
                      f'({c.ratio:.3f}) | {c.ref_energy_pct:+.2f} -> '
                      f'{c.after_energy_pct:+.2f} | {c.seconds:.0f} |', flush=True)
    ok = sum(c.passed for c in rows)
    false = sum(bool(c.false) for c in rows)
    missed = sum(bool(c.missed) for c in rows)
    print(f'{ok}/{len(rows)} cells pass (named right, 0 false, RMSE <= 0.95 x reference, '
          f'|net energy error| <= 2 %; clean: status clean); {missed} with a missed term, '
          f'{false} with a false attribution')
    return 0 if ok == len(rows) else 1


if __name__ == '__main__':
    sys.exit(main())
