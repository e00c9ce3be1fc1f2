"""UMich validate runs: motion from data as sampled vs rebuilt, point samples vs a window.

``PYTHONPATH=. .venv/bin/python bench/bench_umich_motion.py``

Loads ``config/campaigns/umich_mill.yaml`` with its data files looked up in the shared data
directory (env ``FAE_SHARED``, else ``../shared`` beside the repository; see
``bench/shared_lookup.py``), fits the loss on the calibrate runs (as ``fit-loss``) and
compares the validate runs with the guessed and the fitted machine for every combination of
``motion.reconstruct`` (samples, pulses) and instrument (point samples, a trailing window of
one period). Prints pooled RMSE [W] and energy error [%], and CPU time.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
import sys
import time

from feed_axis_energy.identify.fit.lossfit import fit_loss, machine_with_losses
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.measured.campaign import Campaign, InstrumentSpec
from feed_axis_energy.measured.compare import compare_campaign
from feed_axis_energy.measured.metrics import group_metrics
from shared_lookup import HINT, umich_data  # bench/shared_lookup.py

ROOT = Path(__file__).resolve().parents[1]


def umich_campaign() -> Campaign | None:
    """``config/campaigns/umich_mill.yaml`` with its data files in the shared data directory,
    or None (said on stderr, naming ``FAE_SHARED``) when the data is not found."""
    data = umich_data()
    if data is None:
        print(f'UMich data not found: {HINT}', file=sys.stderr)
        return None
    campaign = load_campaign(ROOT / 'config' / 'campaigns' / 'umich_mill.yaml',
                             check_files=False)
    return replace(campaign, runs=tuple(replace(r, data=data / r.data.name)
                                        for r in campaign.runs))


def main() -> int:
    """Print the table."""
    c0 = time.process_time()
    campaign = umich_campaign()
    if campaign is None:
        return 1
    guessed = load_machine(campaign.machine)
    calibrate = [load_run(s) for s in campaign.runs_with_role('calibrate')]
    fitted = machine_with_losses(guessed, fit_loss(calibrate, machine=guessed))
    validate = [s.name for s in campaign.runs_with_role('validate')]
    print(f'validate runs {", ".join(validate)}; loss fitted on '
          f'{", ".join(r.name for r in calibrate)}')
    print(f'{"motion":8} {"instrument":22} {"machine":8} {"RMSE [W]":>9} {"dE [%]":>8}')
    meters = (('point samples', InstrumentSpec(window_s=0.0)),
              ('100 ms window, end', InstrumentSpec(window_s=None, stamp='end')))
    for mode in ('samples', 'pulses'):
        for label, meter in meters:
            runs = tuple(replace(r, motion_reconstruct=mode, instrument=meter)
                         for r in campaign.runs)
            cc = replace(campaign, runs=runs)
            for name, machine in (('guessed', guessed), ('fitted', fitted)):
                res = compare_campaign(cc, machine=machine, runs=validate)
                g = group_metrics([r.metrics for r in res.runs])
                print(f'{mode:8} {label:22} {name:8} {g.rmse_w:9.3f} {g.energy_error_pct:+8.2f}')
    print(f'CPU time {time.process_time() - c0:.1f} s')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
