"""The paper's workflow on real data: loss function fitted on some runs, checked on others.

University of Michigan SMART lab "CNC Mill Tool Wear" measurements (CC0), loaded through
``config/campaigns/umich_mill.yaml`` alone. The loss function is fitted (section 2.1 of the
paper) on the runs with role ``calibrate`` and judged on the ``validate`` runs only.
"""
from pathlib import Path

import must_run

from feed_axis_energy.identify.fit.lossfit import fit_loss, machine_with_losses
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.measured.compare import compare_campaign
from feed_axis_energy.measured.metrics import group_metrics

ROOT = Path(__file__).resolve().parents[2]
MANIFEST = ROOT / 'config' / 'campaigns' / 'umich_mill.yaml'
DATA = (ROOT.parent / 'shared' / 'data' / 'umich-cnc-mill').resolve()


@must_run.skipif('shared', not (DATA / 'experiment_03.csv').exists(),
                 f'UMich CNC mill data not found at {DATA}')
def test_loss_fitted_on_calibrate_runs_improves_held_out_validate_runs():
    campaign = load_campaign(MANIFEST)
    guessed = load_machine(campaign.machine)
    calibrate = [load_run(s) for s in campaign.runs_with_role('calibrate')]
    fits = fit_loss(calibrate, machine=guessed)
    assert all(f.status == 'ok' for f in fits.values()), {a: f.message for a, f in fits.items()}
    fitted = machine_with_losses(guessed, fits)

    validate = [s.name for s in campaign.runs_with_role('validate')]
    assert validate and not set(validate) & {r.name for r in calibrate}
    before = group_metrics([r.metrics for r in
                            compare_campaign(campaign, machine=guessed, runs=validate).runs])
    after = group_metrics([r.metrics for r in
                           compare_campaign(campaign, machine=fitted, runs=validate).runs])
    # Runs the fit never saw: energy error and average errors must drop clearly.
    assert abs(after.energy_error_pct) < 0.5 * abs(before.energy_error_pct)
    assert after.avg_pct_error_pct < before.avg_pct_error_pct
    assert after.avg_diff_error_w < before.avg_diff_error_w
