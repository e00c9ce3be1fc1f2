"""Prediction from the live motion equals the whole-record one (measured/live/motion.py)."""
import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.machine import load_machine
from feed_axis_energy.measured import predicted_signal
from feed_axis_energy.measured.live import KINEMATICS, LiveMotionPredictor
from feed_axis_energy.measured.motiondata import reconstruct_motion
from feed_axis_energy.sim import simulate_motion
from shared_data import REPO

AXES = ('X', 'Y', 'Z')


@pytest.fixture(scope='module')
def machine():
    return load_machine(REPO / 'config' / 'umich_mill.yaml')


def kinematics(n=123, period=0.1, seed=2):
    """Coarse samples of a smooth 3-axis motion: positions, velocities, accelerations."""
    t = 5.0 + period * np.arange(n)
    w = np.array([0.7, 1.1, 0.4])
    amp = np.array([0.02, 0.015, 0.01])
    pos = amp * np.sin(w * t[:, None])
    vel = amp * w * np.cos(w * t[:, None])
    acc = -amp * w * w * np.sin(w * t[:, None])
    return t, pos, vel, acc


@pytest.mark.parametrize('chunk_rows', [1, 7, 10, 200])
def test_chunked_prediction_equals_the_whole_record(machine, chunk_rows):
    t, pos, vel, acc = kinematics()
    whole = simulate_motion(reconstruct_motion(t, pos, axes=AXES, rate_hz=1000.0, vel=vel,
                                               acc=acc), machine, load_kg=0.0)
    expected = predicted_signal('shaft', whole, machine, ('X', 'Y'))
    live = LiveMotionPredictor(machine, axes=AXES, measured_axes=('X', 'Y'),
                               chunk_rows=chunk_rows)
    got_t, got_p = [], []
    for i in range(t.size):
        row = np.stack([pos[i], vel[i], acc[i]], axis=1).ravel()   # axis by axis
        out = live.add(t[i], row)
        if out is not None:
            got_t.append(out[0])
            got_p.append(out[1])
    out = live.flush()
    if out is not None:
        got_t.append(out[0])
        got_p.append(out[1])
    times, power = np.concatenate(got_t), np.vstack(got_p)
    assert np.all(np.diff(times) > 0)
    # each chunk's grid starts at its first stamp: the whole grid within rounding, where a
    # chunk's end may add a stamp 1e-12 s from a grid point (at most one per chunk)
    whole_t = whole.power.t
    extra = times.size - whole_t.size
    assert 0 <= extra <= len(got_t)
    on_grid = np.column_stack([np.interp(whole_t, times, power[:, j]) for j in range(2)])
    assert_allclose(on_grid, expected, rtol=1e-9, atol=1e-9)


def test_without_accelerations_they_are_zero_at_the_stamps(machine):
    t, pos, vel, _ = kinematics(n=30)
    live = LiveMotionPredictor(machine, axes=AXES, measured_axes=('X',),
                               quantities=KINEMATICS[:2], chunk_rows=100)
    for i in range(t.size):
        live.add(t[i], np.stack([pos[i], vel[i]], axis=1).ravel())
    got = live.flush()
    whole = simulate_motion(reconstruct_motion(t, pos, axes=AXES, rate_hz=1000.0, vel=vel),
                            machine, load_kg=0.0)
    assert_allclose(got[1], predicted_signal('shaft', whole, machine, ('X',)), rtol=1e-12)


def test_bad_configuration_is_refused(machine):
    with pytest.raises(ConfigError, match='not an axis'):
        LiveMotionPredictor(machine, axes=('X', 'Q'), measured_axes=('X',))
    with pytest.raises(ConfigError, match='position_m, velocity_m_s'):
        LiveMotionPredictor(machine, axes=AXES, measured_axes=('X',),
                            quantities=('velocity_m_s',))


def test_a_calibrated_machine_sets_the_alarm_band(machine):
    """With the loss parameters' covariance (fit-loss), the band is 2 standard uncertainties
    of the predicted energy, and the comparison says it came from the calibration."""
    from feed_axis_energy.machine import machine_from_dict, machine_to_dict
    from feed_axis_energy.measured.live import LiveMonitor
    data = machine_to_dict(machine)
    for axis in ('X', 'Y'):
        units = list(machine.axis(axis).loss.param_units().values())
        data['axes'][axis]['loss_covariance'] = {
            'params': ['a', 'b'], 'units': units, 'matrix': [[1e-4, 0.0], [0.0, 1e-4]]}
    calibrated = machine_from_dict(data)
    t, pos, vel, acc = kinematics(n=200)
    out = {}
    for name, m in (('default', machine), ('calibrated', calibrated)):
        predictor = LiveMotionPredictor(m, axes=AXES, measured_axes=('X', 'Y'))
        monitor = LiveMonitor(('X', 'Y'), source='live_motion', predictor=predictor)
        for i in range(t.size):
            ns = 10 ** 18 + int(round(t[i] * 1e9))
            for j, axis in enumerate(AXES):
                for q, v in zip(KINEMATICS, (pos[i, j], vel[i, j], acc[i, j])):
                    monitor.add_sample(axis, q, ns, float(v))
            for axis in ('X', 'Y'):
                monitor.add_sample(axis, 'power_w', ns, 1.0)
        out[name] = (monitor.finish()['alarm'], predictor.relative_sd_pct())
    assert out['default'][0]['band_source'] == 'default' and np.isnan(out['default'][1])
    alarm, rel = out['calibrated']
    assert alarm['band_source'] == 'calibration' and rel > 0.0
    assert_allclose(alarm['band_pct'], 2.0 * rel, rtol=1e-12)
