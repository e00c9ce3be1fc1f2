"""A UMich run streamed sample by sample: the final live figures equal offline compare's.

Skipped without ../shared. The stream carries what the MQTT bridge accepts: per axis and
stamp, ``position_m``, ``velocity_m_s``, ``acceleration_m_s2`` and ``power_w`` (X, Y).
"""
from pathlib import Path

import must_run
import numpy as np
import pytest

from feed_axis_energy.machine import load_machine
from feed_axis_energy.measured import (compare_campaign, load_campaign, load_run,
                                       measured_signal)
from feed_axis_energy.measured.live import LiveMonitor, LiveMotionPredictor, LiveSettings

REPO = Path(__file__).resolve().parents[3]
MANIFEST = REPO / 'config' / 'campaigns' / 'umich_mill.yaml'
DATA = (REPO.parent / 'shared' / 'data' / 'umich-cnc-mill').resolve()

pytestmark = must_run.skipif(
    'shared', not (DATA / 'experiment_08.csv').exists(),
    f'UMich CNC mill data not found at {DATA} (clone the repository next to shared/)')


def stream(monitor, spec, run, *, shuffle_seed=None):
    vel, acc = run.derivatives('actual')
    pos = run.positions('actual')
    power = measured_signal(run, measures='shaft', axes=spec.measured_axes,
                            invert=spec.instrument.invert)
    rng = np.random.default_rng(shuffle_seed)
    for i, t in enumerate(run.t):
        ns = 1764280000 * 10 ** 9 + int(round(t * 1e9))
        samples = []
        for j, axis in enumerate(run.axes):
            samples += [(axis, 'position_m', ns, float(pos[i, j])),
                        (axis, 'velocity_m_s', ns, float(vel[i, j])),
                        (axis, 'acceleration_m_s2', ns, float(acc[i, j]))]
        samples += [(a, 'power_w', ns, float(power[i, j]))
                    for j, a in enumerate(spec.measured_axes)]
        if shuffle_seed is not None:
            rng.shuffle(samples)
        for sample in samples:
            monitor.add_sample(*sample)
    return monitor.finish()


@pytest.mark.parametrize('shuffle_seed', [None, 4])
def test_live_energy_error_equals_offline_compare(shuffle_seed):
    campaign = load_campaign(MANIFEST)
    machine = load_machine(campaign.machine)
    spec = campaign.run('exp08')
    offline = compare_campaign(campaign, machine=machine, runs=['exp08']).runs[0]
    run = load_run(spec)
    predictor = LiveMotionPredictor(machine, axes=run.axes, measured_axes=spec.measured_axes,
                                    load_kg=spec.load_kg)
    monitor = LiveMonitor(spec.measured_axes, source='live_motion', predictor=predictor,
                          settings=LiveSettings(window_s=offline.window_s, stamp=offline.stamp))
    final = stream(monitor, spec, run, shuffle_seed=shuffle_seed)
    assert abs(final['lag']['lag_s'] - offline.offset_used_s) < 1e-6
    assert abs(final['measured_energy_j']['total'] - offline.metrics.energy_meas_j) < 1e-9
    assert abs(final['energy_error_pct']['total'] - offline.metrics.energy_error_pct) < 1e-4
    counters = final['counters']
    assert counters['measured']['rows'] == run.t.size
    assert counters['kinematics']['rows'] == run.t.size
    assert counters['measured']['incomplete'] == 0 and counters['prediction_unusable'] == 0
