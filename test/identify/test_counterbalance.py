"""The weight a vertical axis carries, fitted from a drive trace: the counterbalance.

A truth machine whose vertical Y has a weight compensation (``counterbalance_n``: 50 N of its
78.5 N weight) is simulated and written as a current trace (test_torquefit's rig); the fit
starts from the same machine without it. With ``fit_counterbalance`` it finds the 50 N (with
the torque constant declared, and with it fitted), without it the weight is the configured
mass's and the fit is worse. The machine file and the dynamics are checked by hand.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import test_torquefit as rig
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.identify import (fit_drive_samples, machine_with_sample_fits,
                                       SampleFitOptions)
from feed_axis_energy.machine import machine_to_dict
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured import load_campaign, load_run
from feed_axis_energy.physics import compute_dynamics
from feed_axis_energy.plan import motion_from_samples

BALANCE_N = 50.0
G0 = 9.80665


@pytest.fixture
def balanced(monkeypatch, tmp_path):
    truth = rig.TRUTH.replace('    inclination_deg: 90.0\n',
                              f'    inclination_deg: 90.0\n    counterbalance_n: {BALANCE_N}\n')
    monkeypatch.setattr(rig, 'TRUTH', truth)
    manifest, _ = rig.write_fit_campaign(tmp_path, noise=0.005)
    # the machine the fit starts from: no friction and no counterbalance
    start = load_machine(tmp_path / 'machine.yaml')
    assert start.axis('Y').counterbalance_n == BALANCE_N
    axes = tuple(a if a.name != 'Y' else _without_balance(a) for a in start.axes)
    start = dataclasses.replace(start, axes=axes)
    run = load_run(load_campaign(manifest).runs[0])
    return start, run


def _without_balance(axis):
    return dataclasses.replace(axis, counterbalance_n=0.0)


@pytest.mark.parametrize('declared_kt', [True, False])
def test_counterbalance_is_fitted(balanced, declared_kt):
    machine, run = balanced
    gains = dict(rig.KT) if declared_kt else {'X': None, 'Y': None}
    fits = fit_drive_samples([run], machine=machine, measures='current', gains=gains,
                             velocity='commanded',
                             options=SampleFitOptions(fit_counterbalance=True))
    y = fits['Y']
    assert y.ok, y.message
    assert y.counterbalance_n == pytest.approx(BALANCE_N, rel=0.02), y.message
    assert y.coulomb_n == pytest.approx(rig.LOSS['Y'][0], rel=0.05)
    assert y.gain == pytest.approx(rig.KT['Y'], rel=0.02)
    assert y.counterbalance_se is not None and y.counterbalance_se < 2.0
    assert 'counterbalance' in y.message
    # a horizontal axis has no weight to compensate
    assert fits['X'].counterbalance_n is None
    fitted = machine_with_sample_fits(machine, fits)
    assert fitted.axis('Y').counterbalance_n == pytest.approx(y.counterbalance_n)
    assert machine_to_dict(fitted)['axes']['Y']['counterbalance_n'] == y.counterbalance_n
    # without the counterbalance the configured weight does not fit the trace
    plain = fit_drive_samples([run], machine=machine, measures='current', gains=gains,
                              velocity='commanded')
    assert plain['Y'].counterbalance_n is None
    assert plain['Y'].rmse > 3.0 * y.rmse


def test_dynamics_carry_the_weight_less_the_counterbalance(tmp_path):
    text = rig._machine_text(rig.LOSS).replace(
        '    inclination_deg: 90.0\n', '    inclination_deg: 90.0\n    counterbalance_n: 30\n')
    file = tmp_path / 'm.yaml'
    file.write_text(text, encoding='utf-8')
    axis = load_machine(file).axis('Y')
    assert axis.weight_force_n(8.0) == pytest.approx(8.0 * G0 - 30.0)
    down = file.read_text(encoding='utf-8').replace('inclination_deg: 90.0',
                                                    'inclination_deg: -90.0')
    file.write_text(down, encoding='utf-8')
    # the positive direction points down: the weight pulls in +, the balance in -
    assert load_machine(file).axis('Y').weight_force_n(8.0) == pytest.approx(-8.0 * G0 + 30.0)
    t = np.arange(10) * 0.01
    motion = motion_from_samples(t, np.zeros((10, 1)), axes=('Y',))
    dyn = compute_dynamics(motion, load_machine(file))
    np.testing.assert_allclose(dyn.gravity_force_n[:, 0], -8.0 * G0 + 30.0)
    np.testing.assert_allclose(dyn.torque_nm[:, 0],
                               (-8.0 * G0 + 30.0) * 0.005 / (2.0 * math.pi))


@pytest.mark.parametrize('value, text', [(-5.0, '>= 0'), ('heavy', 'number')])
def test_bad_counterbalance_names_the_key(tmp_path, value, text):
    file = tmp_path / 'm.yaml'
    line = f'    inclination_deg: 90.0\n    counterbalance_n: {value}\n'
    file.write_text(rig._machine_text(rig.LOSS).replace('    inclination_deg: 90.0\n', line),
                    encoding='utf-8')
    with pytest.raises(ConfigError) as err:
        load_machine(file)
    assert 'axes.Y.counterbalance_n' in str(err.value) and text in str(err.value)


def test_counterbalance_on_a_horizontal_axis_is_refused(tmp_path):
    file = tmp_path / 'm.yaml'
    file.write_text(rig._machine_text(rig.LOSS).replace(
        '    inclination_deg: 0.0\n', '    inclination_deg: 0.0\n    counterbalance_n: 10\n'),
        encoding='utf-8')
    with pytest.raises(ConfigError) as err:
        load_machine(file)
    assert 'axes.X.counterbalance_n' in str(err.value) and 'horizontal' in str(err.value)
