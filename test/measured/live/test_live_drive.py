"""Current, torque and force compared live: in the trace's unit and as q·g·omega [W]."""
import json
import math

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.errors import ConfigError, DataError
from feed_axis_energy.machine import load_machine
from feed_axis_energy.measured import align_simulated, predicted_signal, torque_per_unit
from feed_axis_energy.measured.live import (comparison_text, COMPARISON_KEYS,
                                            LiveComparison, LiveMonitor, LiveMotionPredictor,
                                            LiveSettings, parse_live)
from feed_axis_energy.measured.motiondata import reconstruct_motion
from feed_axis_energy.measured.quantity import omega_columns
from feed_axis_energy.paths import config_dir
from feed_axis_energy.sim import simulate_motion

T0_NS = 1764280000 * 10 ** 9
AXES = ('X', 'Y', 'Z')
MEASURED = ('X', 'Y')


def motion(seconds=40.0, seed=5):
    """A smooth 3-axis motion every 100 ms (positions, velocities, accelerations)."""
    t = 0.1 * np.arange(int(seconds * 10))
    rng = np.random.default_rng(seed)
    w = rng.uniform(0.5, 2.0, size=3)
    amp = np.array([0.02, 0.015, 0.01])
    pos = amp * np.sin(w * t[:, None])
    vel = amp * w * np.cos(w * t[:, None])
    acc = -amp * w * w * np.sin(w * t[:, None])
    return t, pos, vel, acc


def whole_record(machine, measures, t, pos, vel, acc):
    """The offline prediction of the whole record: trace in its unit, omega, gains."""
    sim = simulate_motion(reconstruct_motion(t, pos, axes=AXES, rate_hz=1000.0, vel=vel,
                                             acc=acc), machine, load_kg=0.0)
    gains = torque_per_unit(measures, machine, MEASURED)
    q = predicted_signal(measures, sim, machine, MEASURED, gains=gains)
    return sim.power.t, q, omega_columns(sim, MEASURED), np.array(gains)


def stream(monitor, t, pos, vel, acc, measured, name, *, named=True):
    for i in range(t.size):
        ns = T0_NS + int(round(t[i] * 1e9))
        for j, axis in enumerate(AXES):
            for quantity, v in (('position_m', pos), ('velocity_m_s', vel),
                                ('acceleration_m_s2', acc)):
                monitor.add_sample(axis, quantity, ns, float(v[i, j]))
        for j, axis in enumerate(MEASURED):
            sample = {'axis': axis, 'stamp': ns / 1e9, 'value': float(measured[i, j])}
            if named:
                sample['quantity'] = name
            for parsed in parse_live(json.dumps(sample))[0]:
                monitor.add_sample(*parsed)
    return monitor.finish()


CASES = [('current', 'three_axis_mill_drives.yaml', 'current_a', 'A'),
         ('torque', 'umich_mill.yaml', 'torque_nm', 'N·m'),
         ('force', 'umich_mill.yaml', 'force_n', 'N')]


@pytest.mark.parametrize('measures, machine_file, name, unit', CASES)
def test_a_drive_trace_is_compared_in_its_unit_and_in_watts(measures, machine_file, name,
                                                            unit):
    machine = load_machine(config_dir() / machine_file)
    t, pos, vel, acc = motion()
    t_sim, q_sim, omega, gains = whole_record(machine, measures, t, pos, vel, acc)
    # the drive reads 1.1 times the predicted trace
    q_true = np.column_stack([np.interp(t, t_sim, q_sim[:, j]) for j in range(2)])
    measured = 1.1 * q_true
    predictor = LiveMotionPredictor(machine, axes=AXES, measured_axes=MEASURED,
                                    measures=measures)
    assert predictor.gains == tuple(gains)
    monitor = LiveMonitor(MEASURED, source='live_motion', predictor=predictor,
                          settings=LiveSettings(max_lag_s=1.0))
    assert monitor.quantity_name == name
    out = stream(monitor, t, pos, vel, acc, measured, name)
    assert out['measures'] == measures
    assert out['counters']['measured']['rows'] == t.size
    assert out['counters']['unused_quantity'] == 0
    lag = out['lag']['lag_s']
    assert abs(lag) < 2e-3
    # the W figures: q·g·omega of both sides with the aligned predicted omega (compare's)
    om = align_simulated(t_sim, omega, t, offset_s=lag, window_s=0.0)
    pred_q = align_simulated(t_sim, q_sim, t, offset_s=lag, window_s=0.0)
    meas_w, pred_w = measured * gains * om, pred_q * gains * om
    for j, axis in enumerate(MEASURED):
        assert_allclose(out['measured_energy_j'][axis], np.trapezoid(meas_w[:, j], t),
                        rtol=1e-7)
        assert_allclose(out['predicted_energy_j'][axis], np.trapezoid(pred_w[:, j], t),
                        rtol=1e-7)
    assert_allclose(out['energy_error_pct']['total'], 100.0 * (1 / 1.1 - 1), atol=0.05)
    # the trace in its unit
    sig = out['signal']
    assert sig['quantity'] == measures and sig['unit'] == unit
    for j, axis in enumerate(MEASURED):
        assert_allclose(sig['measured'][axis], measured[-1, j])
        assert_allclose(sig['predicted'][axis], pred_q[-1, j], rtol=1e-9, atol=1e-12)
        rms = math.sqrt(np.mean((measured[:, j] - pred_q[:, j]) ** 2))
        assert_allclose(sig['residual_rms'][axis], rms, rtol=1e-6)
        assert sig['gain'][axis] == gains[j]
    assert_allclose(out['measured_power_w']['X'], meas_w[-1, 0], rtol=1e-9)
    data = json.loads(comparison_text(out))
    assert tuple(data) == COMPARISON_KEYS and data['signal']['unit'] == unit


def test_a_step_in_the_current_raises_the_alarm_the_same_way():
    machine = load_machine(config_dir() / 'three_axis_mill_drives.yaml')
    t, pos, vel, acc = motion(seconds=60.0)
    t_sim, q_sim, _, _ = whole_record(machine, 'current', t, pos, vel, acc)
    exact = np.column_stack([np.interp(t, t_sim, q_sim[:, j]) for j in range(2)])
    outs = []
    for step_a in (0.0, 0.2):      # 0.2 A: 70 % of the largest predicted current
        measured = exact.copy()
        # more current in the direction of motion (friction: a tool rubbing, say); q·g·omega
        # of the residual is then positive while the axis moves
        inside = (t >= 35.0) & (t < 45.0)
        measured[inside, 0] += step_a * np.sign(vel[inside, 0])
        predictor = LiveMotionPredictor(machine, axes=AXES, measured_axes=MEASURED,
                                        measures='current')
        monitor = LiveMonitor(MEASURED, source='live_motion', predictor=predictor,
                              settings=LiveSettings(max_lag_s=1.0, band_floor_w=2.0,
                                                    band_pct=10.0))
        outs.append(stream(monitor, t, pos, vel, acc, measured, 'current_a'))
    assert outs[0]['alarm']['count'] == 0 and outs[0]['alarm']['armed']
    assert outs[1]['alarm']['count'] == 1 and not outs[1]['alarm']['active']   # on, then off
    assert outs[1]['signal']['residual_rms']['X'] > outs[0]['signal']['residual_rms']['X']


def test_samples_without_a_quantity_are_power_and_power_comparisons_carry_no_signal():
    samples, rejects = parse_live(json.dumps({'axis': 'X', 'stamp': 1764280000.5,
                                              'value': 3.0}))
    assert samples == [('X', 'power_w', 1764280000_500_000_000, 3.0)] and rejects == {}
    monitor = LiveMonitor(('X',), source='job_live')
    monitor.add_sample('X', 'current_a', T0_NS, 1.0)      # not what this comparison uses
    out = monitor.snapshot()
    assert out['measures'] == 'shaft' and out['signal'] is None
    assert out['counters']['unused_quantity'] == 1


def test_bad_drive_settings_are_refused():
    machine = load_machine(config_dir() / 'umich_mill.yaml')
    with pytest.raises(ConfigError, match='torque constant'):
        LiveMotionPredictor(machine, axes=AXES, measured_axes=MEASURED, measures='current')
    with pytest.raises(ConfigError, match='measures must be one of'):
        LiveMotionPredictor(machine, axes=AXES, measured_axes=MEASURED, measures='volts')
    with pytest.raises(DataError, match='gain'):
        LiveComparison(MEASURED, measures='current', gains=(1.0,))
    with pytest.raises(DataError, match='gain'):
        LiveComparison(MEASURED, measures='torque', gains=(1.0, 0.0))
