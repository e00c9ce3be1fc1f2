"""Issue 24, the UMich measure: ``analyze`` with the guessed machine on unseen runs, against
``fit-loss --method samples`` under the same protocol (each run held out, fitted on the
other four). Both computed here; nothing copied from a previous output."""
from dataclasses import replace
from pathlib import Path

import must_run

from feed_axis_energy.identify.analyze import analyze_campaign
from feed_axis_energy.identify.fit.samplefit import fit_loss_samples, machine_with_sample_fits
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.compare import compare_campaign
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.metrics import group_metrics
from shared_data import shared_path, SKIP_REASON

ROOT = Path(__file__).resolve().parents[2]
MANIFEST = ROOT / 'config' / 'campaigns' / 'umich_mill.yaml'
DATA = shared_path('data', 'umich-cnc-mill', needs=('experiment_03.csv',))


@must_run.skipif('shared', DATA is None, f'UMich CNC mill data: {SKIP_REASON}')
def test_analyze_on_unseen_runs_is_near_fit_loss_and_offers_the_inertia():
    campaign = load_campaign(MANIFEST, check_files=False)
    campaign = replace(campaign, runs=tuple(replace(r, data=DATA / r.data.name)
                                            for r in campaign.runs))
    names = [r.name for r in campaign.runs]
    res = analyze_campaign(campaign)
    after = {r.name: r.after for r in res.runs if r.heldout}
    assert sorted(after) == sorted(names)
    for name, m in after.items():
        assert abs(m.energy_error_pct) <= 3.0, (name, m.energy_error_pct)
    # the guessed masses are ~120 kg short on both axes: the summed power of unseen runs
    # supports a mass correction on X and Y together, per axis it is not supported
    offered = {(e.id, e.axis) for e in res.offered}
    assert {('mass_error', 'X'), ('mass_error', 'Y')} <= offered, res.message
    assert all(e.id != 'mass_error' for e in res.effects)
    dm = {e.axis: e.values()['dm_kg'] for e in res.offered if e.id == 'mass_error'}
    assert all(40.0 < v < 200.0 for v in dm.values()), dm

    guessed = load_machine(campaign.machine)
    fitloss = {}
    for held in names:
        specs = [campaign.run(n) for n in names if n != held]
        fits = fit_loss_samples([load_run(s) for s in specs], machine=guessed,
                                velocity=[s.motion_from_data or 'auto' for s in specs])
        cmp = compare_campaign(campaign, machine=machine_with_sample_fits(guessed, fits),
                               runs=[held])
        fitloss[held] = cmp.runs[0].metrics
    rmse_analyze = group_metrics([after[n] for n in names]).rmse_w
    rmse_fitloss = group_metrics([fitloss[n] for n in names]).rmse_w
    before = group_metrics([r.before for r in res.runs]).rmse_w
    # within 3 % of fit-loss (1.1 % measured, docs/analyze.md), far below the guessed 0.82 W
    assert rmse_analyze <= 1.03 * rmse_fitloss, (rmse_analyze, rmse_fitloss)
    assert rmse_analyze <= 0.85 * before, (rmse_analyze, before)
