"""UMich mill: which loss fit and which kinematics, judged on held-out runs.

``PYTHONPATH=. .venv/bin/python bench/bench_umich_fit.py``

Loads ``config/campaigns/umich_mill.yaml`` with its data files looked up in the shared data
directory (env ``FAE_SHARED``, else ``../shared`` beside the repository; see
``bench/shared_lookup.py``). For motion from the commanded and from the actual kinematics,
and for the two ``fit-loss`` methods (``steady``: the paper's power regression on steady
segments found as ``fit-loss`` finds them by default, with the configured inertia;
``samples``: Coulomb + viscous loss and motor inertia fitted to every moving sample), it
prints

1. the choice, made on the calibrate runs only: each calibrate run compared with a fit on
   the other two (leave one run out; the steady fit with ``--min-feeds 2``, since two runs
   may hold only two distinct feeds), RMSE [W] and energy error [%] per held-out run;
2. the check on the validate runs: the guessed config and the fit on all calibrate runs,
   pooled RMSE [W], its change against the guessed config [%], and each run's energy error.

CPU time at the end (``time.process_time``).
"""
from __future__ import annotations

from dataclasses import replace
import time

from feed_axis_energy.identify.fit.lossfit import fit_loss, machine_with_losses
from feed_axis_energy.identify.fit.steady import SteadyOptions
from feed_axis_energy.identify.fit.samplefit import fit_loss_samples, machine_with_sample_fits
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.machine.spec import Machine
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.measured.campaign import Campaign
from feed_axis_energy.measured.compare import compare_campaign
from feed_axis_energy.measured.metrics import group_metrics
from bench_umich_motion import umich_campaign  # bench/ is sys.path[0]


def fitted(campaign: Campaign, guessed: Machine, names: list[str], method: str,
           kind: str) -> Machine:
    """The machine fitted on the named runs with the method, kinematics ``kind``."""
    runs = [load_run(campaign.run(n)) for n in names]
    if method == 'samples':
        return machine_with_sample_fits(guessed, fit_loss_samples(runs, machine=guessed,
                                                                  velocity=kind))
    # steady segments as fit-loss finds them by default (commanded velocity, else actual)
    fits = fit_loss(runs, machine=guessed, options=SteadyOptions(min_feeds=2))
    return machine_with_losses(guessed, fits)


def main() -> int:
    """Print both tables."""
    c0 = time.process_time()
    base = umich_campaign()
    if base is None:
        return 1
    guessed = load_machine(base.machine)
    calibrate = [s.name for s in base.runs_with_role('calibrate')]
    validate = [s.name for s in base.runs_with_role('validate')]
    print(f'1. leave one calibrate run out ({", ".join(calibrate)}): RMSE [W], dE [%] of the '
          'held-out run')
    print(f'{"motion":10} {"method":8} ' + ' '.join(f'{n:>16}' for n in calibrate))
    rows = []
    for kind in ('commanded', 'actual'):
        campaign = replace(base, runs=tuple(replace(r, motion_from_data=kind)
                                            for r in base.runs))
        for method in ('steady', 'samples'):
            cells = []
            for held in calibrate:
                machine = fitted(campaign, guessed, [n for n in calibrate if n != held],
                                 method, kind)
                m = compare_campaign(campaign, machine=machine, runs=[held]).runs[0].metrics
                cells.append(f'{m.rmse_w:6.3f} {m.energy_error_pct:+8.2f}')
            print(f'{kind:10} {method:8} ' + ' '.join(f'{c:>16}' for c in cells))
            rows.append((kind, method, campaign))
    print(f'\n2. validate runs ({", ".join(validate)}), fitted on all calibrate runs')
    print(f'{"motion":10} {"machine":8} {"RMSE [W]":>9} {"vs guessed":>10}  dE per run [%]')
    for kind, method, campaign in rows:
        if method == 'steady':
            res = compare_campaign(campaign, machine=guessed, runs=validate)
            ref = group_metrics([r.metrics for r in res.runs]).rmse_w
            des = ' '.join(f'{r.name} {r.metrics.energy_error_pct:+.2f}' for r in res.runs)
            print(f'{kind:10} {"guessed":8} {ref:9.3f} {"":>10}  {des}')
        machine = fitted(campaign, guessed, calibrate, method, kind)
        res = compare_campaign(campaign, machine=machine, runs=validate)
        rmse = group_metrics([r.metrics for r in res.runs]).rmse_w
        des = ' '.join(f'{r.name} {r.metrics.energy_error_pct:+.2f}' for r in res.runs)
        print(f'{kind:10} {method:8} {rmse:9.3f} {100 * (rmse / ref - 1):+9.1f}%  {des}')
    print(f'CPU time {time.process_time() - c0:.1f} s')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
