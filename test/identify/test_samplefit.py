"""fit-loss --method samples: Coulomb + viscous loss and motor inertia from every moving sample."""
import math
from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.physics.dynamics import compute_dynamics
from feed_axis_energy.physics.energy import compute_power
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.identify.fit.samplefit import (fit_loss_samples, machine_with_sample_fits,
                                                     SampleFitOptions)
from feed_axis_energy.machine.losses import CoulombViscousLoss
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.machine.mass import moved_mass_kg
from feed_axis_energy.measured.run import MeasuredRun
from feed_axis_energy.plan.motion import Motion

ROOT = Path(__file__).resolve().parents[2]


def _machine(*, eta=1.0, incl=0.0, braking='regenerative', motor=1.0e-4):
    d = machine_to_dict(load_machine(ROOT / 'config' / 'demonstrator.yaml'))
    d['braking'] = braking
    d['axes']['X']['screw']['efficiency'] = eta
    d['axes']['X']['inclination_deg'] = incl
    d['axes']['X']['inertias']['motor_kg_m2'] = motor
    return machine_from_dict(d, file='<test>')


def _profile(*, rate_hz=50.0, accel=1.5):
    """Strokes at 10..200 mm/s both ways: ramps of ``accel`` [m/s²], holds, pauses."""
    dt = 1.0 / rate_hz
    parts = [np.zeros(5)]
    for feed in (0.01, 0.05, 0.1, 0.2):
        for sign in (1.0, -1.0):
            ramp = np.arange(0.0, feed, accel * dt)
            parts += [sign * ramp, np.full(20, sign * feed), sign * ramp[::-1], np.zeros(5)]
    v = np.concatenate(parts)
    t = np.arange(v.size) * dt
    return t, v, np.gradient(v, t)


def _run(t, v, acc, power, *, load_kg=0.0, name='syn'):
    pos = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))))
    return MeasuredRun(name=name, file=f'<{name}>', t=t, axes=('X',), power_axes=('X',),
                       power_w=power[:, None], load_kg=load_kg, position_m=pos[:, None],
                       velocity_m_s=v[:, None], acceleration_m_s2=acc[:, None])


def test_hand_calculated_power_gives_back_loss_and_inertia():
    # eta = 1, horizontal: P = (m + J·(2·pi/L)²)·a·v + Fc·|v| + cv·v², written out by hand
    machine = _machine()
    spec = machine.axis('X')
    fc, cv, motor = 30.0, 500.0, 2.5e-4
    j_total = motor + spec.inertias.coupling_kg_m2 + spec.screw_inertia_kg_m2
    mass = moved_mass_kg(machine, 'X', 0.0) + j_total * (2.0 * math.pi / spec.screw.lead_m) ** 2
    t, v, acc = _profile()
    power = mass * acc * v + fc * np.abs(v) + cv * v * v
    fit = fit_loss_samples([_run(t, v, acc, power)], machine=machine, velocity='actual')['X']
    assert fit.ok and fit.inertia_fitted, fit.message
    assert_allclose([fit.coulomb_n, fit.viscous_n_s_m, fit.motor_kg_m2], [fc, cv, motor],
                    rtol=1e-6)
    assert fit.effective_mass_kg == pytest.approx(mass, rel=1e-6)
    assert fit.rmse_w < 1e-6 and fit.r2 == pytest.approx(1.0)
    assert fit.calibrated.feed_mm_s == pytest.approx((10.0, 200.0))
    assert fit.loss() == CoulombViscousLoss(coulomb_n=fit.coulomb_n,
                                            viscous_n_s_m=fit.viscous_n_s_m)


@pytest.mark.parametrize('braking', ['regenerative', 'dissipated'])
def test_fit_inverts_the_dynamics_with_efficiency_weight_and_braking(braking):
    # inclined, eta < 1, a load: drive and back-drive samples differ by eta², and with
    # dissipated braking the negative samples read 0; the fit must undo all of it
    truth = _machine(eta=0.85, incl=20.0, braking=braking, motor=3.0e-4)
    d = machine_to_dict(truth)
    d['axes']['X']['loss'] = CoulombViscousLoss(coulomb_n=40.0, viscous_n_s_m=300.0).to_dict()
    truth = machine_from_dict(d, file='<test>')
    t, v, acc = _profile()
    motion = Motion(t=t, axes=('X',), pos=np.cumsum(v)[:, None] / 50.0, vel=v[:, None],
                    acc=acc[:, None], line=np.zeros(t.size, dtype=int))
    power = compute_power(compute_dynamics(motion, truth, load_kg=8.0),
                          braking=braking).power_w[:, 0]
    assert np.any(power < 0.0) == (braking == 'regenerative')
    guessed = _machine(eta=0.85, incl=20.0, braking=braking, motor=1.0e-4)
    fit = fit_loss_samples([_run(t, v, acc, power, load_kg=8.0)], machine=guessed,
                           velocity='actual')['X']
    assert fit.ok, fit.message
    assert_allclose([fit.coulomb_n, fit.viscous_n_s_m, fit.motor_kg_m2], [40.0, 300.0, 3.0e-4],
                    rtol=1e-6)
    # the machine written from the fit reproduces the measured power
    fitted = machine_with_sample_fits(guessed, {'X': fit})
    again = compute_power(compute_dynamics(motion, fitted, load_kg=8.0),
                          braking=braking).power_w[:, 0]
    assert_allclose(again, power, atol=1e-6)
    reloaded = machine_from_dict(machine_to_dict(fitted), file='<test>')
    assert reloaded.axis('X').inertias.motor_kg_m2 == pytest.approx(3.0e-4, rel=1e-6)
    assert reloaded.axis('X').loss_calibrated.load_kg == (8.0, 8.0)


def test_parameters_stay_physical():
    # a power that falls with speed would need a negative viscous coefficient: bounded at 0
    machine = _machine()
    t, v, acc = _profile()
    power = 50.0 * np.abs(v) - 150.0 * v * v
    fit = fit_loss_samples([_run(t, v, acc, power)], machine=machine, velocity='actual')['X']
    assert fit.ok
    assert fit.viscous_n_s_m == 0.0 and fit.coulomb_n > 0.0 and fit.motor_kg_m2 >= 0.0


def test_without_accelerating_samples_the_configured_inertia_is_kept():
    machine = _machine(motor=1.7e-4)
    t = np.arange(100) * 0.1
    v = np.where(t < 5.0, 0.02, -0.04)
    acc = np.zeros_like(v)
    power = 25.0 * np.abs(v) + 100.0 * v * v
    fit = fit_loss_samples([_run(t, v, acc, power)], machine=machine, velocity='actual')['X']
    assert fit.ok and not fit.inertia_fitted
    assert fit.motor_kg_m2 == 1.7e-4 and fit.motor_se is None
    assert_allclose([fit.coulomb_n, fit.viscous_n_s_m], [25.0, 100.0], rtol=1e-6)
    assert 'inertia kept as configured' in fit.message


def test_too_few_moving_samples_is_a_result():
    machine = _machine()
    t = np.arange(50) * 0.1
    v = np.zeros_like(t)
    v[10:15] = 0.01
    fit = fit_loss_samples([_run(t, v, np.zeros_like(v), 0.3 * np.abs(v))], machine=machine,
                           velocity='actual')['X']
    assert fit.status == 'insufficient' and not fit.ok and '5 moving sample' in fit.message
    with pytest.raises(ValueError, match='no usable fit'):
        fit.loss()
    assert machine_with_sample_fits(machine, {'X': fit}) == machine


def test_bad_options_name_the_key():
    t, v, acc = _profile()
    run = _run(t, v, acc, np.abs(v))
    with pytest.raises(ConfigError, match='velocity'):
        fit_loss_samples([run], machine=_machine(), velocity='measured')
    with pytest.raises(ConfigError, match='velocity'):
        fit_loss_samples([run], machine=_machine(), velocity=['actual', 'actual'])
    with pytest.raises(ConfigError, match='min_samples'):
        SampleFitOptions(min_samples=0)


def test_dissipated_braking_without_driving_samples_is_insufficient():
    # every sample brakes hard (a·v < 0): with dissipated braking the meter reads 0 there and
    # nothing is left to fit
    machine = _machine(braking='dissipated')
    t = np.arange(60) * 0.01
    v = 0.2 - 0.3 * t
    acc = np.full_like(t, -0.3)
    fit = fit_loss_samples([_run(t, v, acc, np.zeros_like(t))], machine=machine,
                           velocity='actual')['X']
    assert fit.status == 'insufficient' and 'positive model power' in fit.message


@pytest.mark.parametrize('with_accel', [True, False])
def test_loss_covariance_matches_the_scatter_of_refits_and_is_written(with_accel):
    # noisy power from a known loss: the covariance the fit reports for (coulomb, viscous)
    # is the spread of the fitted values over noise seeds, and fit-loss writes it to the
    # machine as loss_covariance, the block of the loss parameters (inertia left out)
    machine = _machine()
    spec = machine.axis('X')
    j_total = 1.0e-4 + spec.inertias.coupling_kg_m2 + spec.screw_inertia_kg_m2
    mass = moved_mass_kg(machine, 'X', 0.0) + j_total * (2.0 * math.pi / spec.screw.lead_m) ** 2
    t, v, acc = _profile()
    if not with_accel:
        acc = np.zeros_like(acc)
    clean = mass * acc * v + 30.0 * np.abs(v) + 500.0 * v * v
    rng = np.random.default_rng(7)
    fits = [fit_loss_samples([_run(t, v, acc, clean + rng.normal(0.0, 0.5, t.size))],
                             machine=machine, velocity='actual')['X'] for _ in range(300)]
    assert all(f.ok and f.inertia_fitted == with_accel for f in fits)
    got = np.array([[f.coulomb_n, f.viscous_n_s_m] for f in fits])
    scatter = np.cov(got.T)
    reported = np.mean([np.array(f.cov_loss) for f in fits], axis=0)
    assert_allclose(np.sqrt(np.diag(reported)), np.sqrt(np.diag(scatter)), rtol=0.15)
    corr = (lambda c: c[0, 1] / math.sqrt(c[0, 0] * c[1, 1]))
    assert corr(reported) == pytest.approx(corr(scatter), abs=0.1)
    fit = fits[0]
    assert_allclose(np.sqrt(np.diag(np.array(fit.cov_loss))), [fit.coulomb_se, fit.viscous_se],
                    rtol=1e-12)
    fitted = machine_with_sample_fits(machine, {'X': fit})
    cov = machine_from_dict(machine_to_dict(fitted), file='<test>').axis('X').loss_covariance
    assert cov.params == ('coulomb_n', 'viscous_n_s_m') and cov.units == ('N', 'N*s/m')
    assert_allclose(cov.array(), np.array(fit.cov_loss), rtol=1e-12)
