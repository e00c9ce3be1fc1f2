"""Loss-function fit (paper section 2.1): steady segments, power regression, fitted machine."""
import math
from pathlib import Path

import must_run
import numpy as np
from numpy.testing import assert_allclose
import pytest
import yaml

from feed_axis_energy.physics.dynamics import compute_dynamics
from feed_axis_energy.physics.energy import compute_power
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.identify.fit.lossfit import fit_loss, machine_with_losses
from feed_axis_energy.identify.fit.steady import steady_segments, SteadyOptions
from feed_axis_energy.machine.losses import PowerRegressionLoss
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.measured.run import MeasuredRun
from feed_axis_energy.plan.motion import Motion

ROOT = Path(__file__).resolve().parents[2]
UMICH = ROOT.parent / 'shared' / 'data' / 'umich-cnc-mill'


def _velocity_profile(feeds_m_s, *, rate_hz=100.0, accel=2.0, hold_s=3.0, pause_s=0.5):
    """Back-and-forth strokes: ramp up, hold each feed, ramp down, pause, then reverse."""
    dt = 1.0 / rate_hz
    v = [np.zeros(int(pause_s * rate_hz))]
    for feed in feeds_m_s:
        for sign in (1.0, -1.0):
            ramp = np.arange(0.0, feed, accel * dt)
            v += [sign * ramp, sign * np.full(int(hold_s * rate_hz), feed),
                  sign * ramp[::-1], np.zeros(int(pause_s * rate_hz))]
    v = np.concatenate(v)
    t = np.arange(v.shape[0]) * dt
    return t, v, np.gradient(v, t)


def _run(t, v, acc, power, *, name='syn', load_kg=0.0):
    pos = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))))
    return MeasuredRun(name=name, file=f'<{name}>', t=t, axes=('X',), power_axes=('X',),
                       power_w=power[:, None], load_kg=load_kg, position_m=pos[:, None],
                       command_velocity_m_s=v[:, None], command_acceleration_m_s2=acc[:, None])


def _synthetic(a, b, feeds_mm_s, *, noise_w=0.0, seed=0, inertia_kg=40.0):
    """Power = a·x^(1+b) at steady feed plus an inertial m·a·v term on the ramps."""
    t, v, acc = _velocity_profile(np.asarray(feeds_mm_s) / 1000.0)
    x = np.abs(v) * 1000.0
    power = a * x ** (1.0 + b) + inertia_kg * acc * v
    power += np.random.default_rng(seed).normal(0.0, noise_w, power.shape)
    return _run(t, v, acc, power)


def test_steady_segments_of_a_hand_made_profile():
    # 0.5 s still, ramp 0->10 mm/s over 0.1 s, 2 s at 10 mm/s, ramp down, 1 s at -20 mm/s
    t = np.arange(0, 500) * 0.01
    v = np.zeros_like(t)
    v[50:60] = np.linspace(0, 0.01, 10)
    v[60:260] = 0.01
    v[260:270] = np.linspace(0.01, 0, 10)
    v[300:400] = -0.02
    acc = np.gradient(v, t)
    opts = SteadyOptions(trim_s=0.1, min_duration_s=0.5)
    segs = steady_segments(t, v, acc, options=opts)
    assert len(segs) == 2
    (a0, a1), (b0, b1) = segs
    # the plateau, less the samples next to the ramps (gradient) and 0.1 s at both ends
    assert 60 <= a0 <= 72 and 248 <= a1 <= 260
    assert np.all(v[a0:a1] == 0.01)
    assert np.all(v[b0:b1] == -0.02) and b1 - b0 >= 70
    # longer minimum duration drops the 1 s segment
    assert len(steady_segments(t, v, acc, options=SteadyOptions(min_duration_s=1.5))) == 1


def test_speed_tolerance_splits_a_slow_drift():
    t = np.arange(0, 1000) * 0.01
    v = np.linspace(0.010, 0.013, 1000)             # +30 % over 10 s, acceleration tiny
    segs = steady_segments(t, v, np.gradient(v, t),
                           options=SteadyOptions(rel_speed_tol=0.03, trim_s=0.0))
    assert len(segs) >= 4
    for i0, i1 in segs:
        mean = v[i0:i1].mean()
        assert np.all(np.abs(v[i0:i1] - mean) <= 0.03 * mean + 1e-15)


@pytest.mark.parametrize('a, b', [(0.2505, 0.3471), (0.05, 0.1), (1.3, 0.8)])
def test_fit_recovers_known_power_regression(a, b):
    feeds = [100, 200, 300, 400, 500]
    fit = fit_loss([_synthetic(a, b, feeds, noise_w=0.5, seed=3)])['X']
    assert fit.status == 'ok', fit.message
    assert_allclose(fit.a, a, rtol=0.03)
    assert_allclose(fit.b, b, atol=0.01)
    assert fit.r2_log > 0.99
    assert len(fit.used) == 2 * len(feeds)             # one segment per stroke
    assert_allclose(sorted(fit.feeds_mm_s), feeds, rtol=1e-9)
    # the inertial power on the ramps must not leak in: segments are pure steady motion
    for s in fit.used:
        assert abs(s.feed_mm_s - round(s.feed_mm_s, -2)) < 1e-6


def test_fit_inverts_the_forward_model_with_efficiency_and_weight():
    # Inclined axis, eta < 1: steady power is not the loss power; the fit must undo both.
    true = PowerRegressionLoss(a=0.02, b=0.3)
    d = machine_to_dict(load_machine(ROOT / 'config' / 'demonstrator.yaml'))
    d['axes']['X']['inclination_deg'] = 30.0
    d['axes']['X']['screw']['efficiency'] = 0.9
    d['axes']['X']['loss'] = true.to_dict()
    machine = machine_from_dict(d, file='<test>')
    t, v, acc = _velocity_profile(np.array([20, 50, 100, 150, 200]) / 1000.0, accel=1.0)
    pos = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))))
    motion = Motion(t=t, axes=('X',), pos=pos[:, None], vel=v[:, None], acc=acc[:, None],
                    line=np.zeros(t.shape[0], dtype=int))
    power = compute_power(compute_dynamics(motion, machine, load_kg=5.0),
                          braking='regenerative').power_w[:, 0]
    assert np.any(power[v < -0.01] < 0.0)     # lowering at low speed back-drives the screw
    run = _run(t, v, acc, power, load_kg=5.0)
    fit = fit_loss([run], machine=machine)['X']
    assert fit.ok, fit.message
    assert_allclose([fit.a, fit.b], [true.a, true.b], rtol=1e-6)
    # without the machine (eta = 1, horizontal) the same data give another, wrong, answer
    naive = fit_loss([run], options=SteadyOptions(min_loss_power_w=0.0))['X']
    assert naive.status != 'ok' or abs(naive.a - true.a) > 0.01 * true.a


def test_too_few_feeds_is_a_result_not_an_exception():
    fit = fit_loss([_synthetic(0.25, 0.35, [100, 300])])['X']
    assert fit.status == 'insufficient' and not fit.ok
    assert fit.a is None and fit.b is None
    assert '2 distinct feed' in fit.message
    with pytest.raises(ValueError):
        fit.loss()
    assert fit_loss([_synthetic(0.25, 0.35, [100, 300])],
                    options=SteadyOptions(min_feeds=2))['X'].ok


def test_negative_and_tiny_power_segments_are_excluded_and_counted():
    run = _synthetic(0.25, 0.35, [100, 200, 300, 400])
    p = run.power_w[:, 0].copy()
    v = run.command_velocity_m_s[:, 0]
    p[(np.abs(v - 0.2) < 1e-12)] = -3.0          # forward stroke at 200 mm/s: negative
    p[(np.abs(v + 0.4) < 1e-12)] = 0.01          # backward stroke at 400 mm/s: tiny
    run = _run(run.t, v, run.command_acceleration_m_s2[:, 0], p)
    fit = fit_loss([run])['X']
    assert fit.excluded == {'negative power': 1, 'tiny power': 1}
    assert len(fit.used) == 6 and fit.ok
    assert_allclose([fit.a, fit.b], [0.25, 0.35], rtol=1e-9)


def test_falling_coefficient_is_out_of_range():
    # constant loss power 50 W: y = 50/x, b = -1, not representable by PowerRegressionLoss
    t, v, acc = _velocity_profile(np.array([100, 200, 300]) / 1000.0)
    fit = fit_loss([_run(t, v, acc, np.where(np.abs(acc) < 1e-9, 50.0, 0.0)
                         * (np.abs(v) > 0))])['X']
    assert fit.status == 'out_of_range'
    assert_allclose(fit.b, -1.0, atol=1e-9)


def test_fitted_machine_yaml_loads_and_reproduces_the_loss(tmp_path):
    a, b = 0.4, 0.25
    fits = fit_loss([_synthetic(a, b, [50, 150, 250, 350])])
    machine = load_machine(ROOT / 'config' / 'demonstrator.yaml')
    out = tmp_path / 'fitted.yaml'
    out.write_text(yaml.safe_dump(machine_to_dict(machine_with_losses(machine, fits))))
    loaded = load_machine(out)
    loss = loaded.axis('X').loss
    assert isinstance(loss, PowerRegressionLoss)
    assert (loss.x_unit, loss.y_unit) == ('mm/s', 'W/(mm/s)')
    v = np.array([0.05, 0.2, 0.35])
    assert_allclose(loss.power_w(v), a * (v * 1000) ** (1 + b), rtol=1e-9)
    assert loaded.axis('X').screw == machine.axis('X').screw


def test_options_are_checked():
    with pytest.raises(ConfigError, match='min_feeds'):
        SteadyOptions(min_feeds=1)
    with pytest.raises(ConfigError, match='velocity'):
        SteadyOptions(velocity='planned')


@must_run.skipif('shared', not (UMICH / 'experiment_01.csv').is_file(), 'UMich data absent')
def test_umich_calibrate_runs_fit_with_finite_r2():
    campaign = load_campaign(ROOT / 'config' / 'campaigns' / 'umich_mill.yaml')
    runs = [load_run(s) for s in campaign.runs_with_role('calibrate')]
    fits = fit_loss(runs, machine=load_machine(campaign.machine))
    assert set(fits) == {'X', 'Y'}                 # Z has no power column
    for fit in fits.values():
        assert fit.status in ('ok', 'insufficient', 'out_of_range')
        if fit.status != 'insufficient':
            assert math.isfinite(fit.r2_log) and math.isfinite(fit.r2_linear)
            assert len(fit.feeds_mm_s) >= 3
