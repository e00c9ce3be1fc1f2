"""Issue 11, section 7, on the UMich mill: every validate run's energy error within +-5 % and the
held-out RMSE at least 30 % below the guessed config's, with loss and inertia fitted on the
calibrate runs only (``fit-loss --method samples``) and motion from the actual kinematics.
"""
from dataclasses import replace
from pathlib import Path

import must_run

from feed_axis_energy.identify.fit.samplefit import fit_loss_samples, machine_with_sample_fits
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.measured.compare import compare_campaign
from feed_axis_energy.measured.metrics import group_metrics
from shared_data import shared_path, SKIP_REASON

ROOT = Path(__file__).resolve().parents[2]
MANIFEST = ROOT / 'config' / 'campaigns' / 'umich_mill.yaml'


DATA = shared_path('data', 'umich-cnc-mill', needs=('experiment_03.csv',))


@must_run.skipif('shared', DATA is None, f'UMich CNC mill data: {SKIP_REASON}')
def test_samples_fit_on_calibrate_runs_meets_the_validate_targets():
    campaign = load_campaign(MANIFEST, check_files=False)
    campaign = replace(campaign, runs=tuple(replace(r, data=DATA / r.data.name)
                                            for r in campaign.runs))
    guessed = load_machine(campaign.machine)
    specs = campaign.runs_with_role('calibrate')
    validate = [s.name for s in campaign.runs_with_role('validate')]
    assert validate and not set(validate) & {s.name for s in specs}
    fits = fit_loss_samples([load_run(s) for s in specs], machine=guessed,
                            velocity=[s.motion_from_data or 'auto' for s in specs])
    assert all(f.ok and f.inertia_fitted for f in fits.values())
    fitted = machine_with_sample_fits(guessed, fits)
    before = compare_campaign(campaign, machine=guessed, runs=validate)
    after = compare_campaign(campaign, machine=fitted, runs=validate)
    for run in after.runs:
        assert abs(run.metrics.energy_error_pct) <= 5.0, (run.name, run.metrics)
    rmse_before = group_metrics([r.metrics for r in before.runs]).rmse_w
    rmse_after = group_metrics([r.metrics for r in after.runs]).rmse_w
    assert rmse_after <= 0.7 * rmse_before, (rmse_before, rmse_after)
