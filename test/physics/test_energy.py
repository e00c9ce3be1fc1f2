"""Tests of power and energy: energy balance, hand calculations, braking, streaming, blocks."""
import math
from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose
import pytest
from scipy.integrate import cumulative_trapezoid, quad

from feed_axis_energy.physics.dynamics import compute_dynamics
from feed_axis_energy.physics.energy import (compute_power, energy_by_line, EnergyIntegrator,
                                             PowerResult)
from feed_axis_energy.errors import ConfigError, DataError
from feed_axis_energy.units import GRAVITY_M_S2
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.plan.motion import Motion

CONFIG = Path(__file__).resolve().parents[2] / 'config'


def two_axis_machine(*, loss_x, loss_z, eta=1.0, incl_z=30.0):
    def axis(mass, incl, loss, rides_on=None):
        return {'table_mass_kg': mass, 'rides_on': rides_on, 'inclination_deg': incl,
                'screw': {'diameter_m': 0.025, 'lead_m': 0.01, 'length_m': 0.8,
                          'efficiency': eta},
                'inertias': {'motor_kg_m2': 2.0e-4, 'coupling_kg_m2': 3.0e-5},
                'limits': {'velocity_m_s': 1.0, 'acceleration_m_s2': 5.0, 'jerk_m_s3': 100.0},
                'loss': loss}
    return machine_from_dict({'name': 'test', 'braking': 'regenerative', 'load_axis': 'X',
                              'axes': {'X': axis(40.0, 0.0, loss_x),
                                       'Z': axis(25.0, incl_z, loss_z)}})


def sampled(funcs, t, axes):
    cols = [np.column_stack([f[i](t) for f in funcs]) for i in range(3)]
    return Motion(t=t, axes=axes, pos=cols[0], vel=cols[1], acc=cols[2],
                  line=np.ones(t.shape, dtype=np.int32), source='hand')


def sine(amp, w, phase=0.0):
    return (lambda t: amp * np.sin(w * t + phase), lambda t: amp * w * np.cos(w * t + phase),
            lambda t: -amp * w * w * np.sin(w * t + phase))


def test_energy_balance_of_a_whole_motion():
    """integral P dt = dE_kin (translational + rotary) + integral P_loss dt + dE_pot."""
    paper = {'model': 'power_regression', 'a': 0.2505, 'b': 0.3471}
    cv = {'model': 'coulomb_viscous', 'coulomb_n': 30.0, 'viscous_n_s_m': 150.0, 'mu': 0.02}
    m = two_axis_machine(loss_x=paper, loss_z=cv)
    load = 17.336
    fx, fz = sine(0.1, 4.0), sine(0.05, 7.0, phase=0.3)
    t_end, dt = 0.9, 1.0e-4
    t = np.linspace(0.0, t_end, int(round(t_end / dt)) + 1)
    dyn = compute_dynamics(sampled([fx, fz], t, ('X', 'Z')), m, load_kg=load)
    res = compute_power(dyn, braking='regenerative')

    expected = 0.0
    for j, (name, f) in enumerate((('X', fx), ('Z', fz))):
        spec = m.axis(name)
        mass = spec.table_mass_kg + (load if name == 'X' else 0.0)
        m_eq = mass + spec.rotary_inertia_kg_m2 * (2.0 * math.pi / spec.screw.lead_m) ** 2
        v0, v1 = f[1](0.0), f[1](t_end)
        kinetic = 0.5 * m_eq * (v1 ** 2 - v0 ** 2)
        potential = mass * GRAVITY_M_S2 * math.sin(math.radians(spec.inclination_deg)) * (
            f[0](t_end) - f[0](0.0))
        normal = mass * GRAVITY_M_S2 * math.cos(math.radians(spec.inclination_deg))
        lost, _ = quad(lambda s: float(spec.loss.power_w(np.array([f[1](s)]),
                                                         normal_force_n=normal)[0]),
                       0.0, t_end, limit=400)
        assert lost > 1.0  # the loss term is really exercised
        axis_expected = kinetic + potential + lost
        # Trapezoid error <= T dt^2 / 12 max|P''|; P'' estimated from second differences.
        p = res.power_w[:, j]
        p2 = np.max(np.abs(np.diff(p, 2))) / dt ** 2
        tol = 2.0 * t_end * dt ** 2 / 12.0 * p2
        assert tol < 1e-2 * abs(axis_expected)  # the bound is meaningful
        assert res.energy_j[-1, j] == pytest.approx(axis_expected, abs=tol)
        expected += axis_expected
    assert res.total_energy_j[-1] == pytest.approx(expected, rel=1e-4)
    assert_allclose(res.total_w, res.power_w.sum(axis=1))
    assert res.energy_j[0].tolist() == [0.0, 0.0] and res.total_energy_j[0] == 0.0


def test_constant_velocity_power_equals_loss_power():
    demo = load_machine(CONFIG / 'demonstrator.yaml')
    v = 0.1
    t = np.linspace(0.0, 2.0, 201)
    ones = np.ones((t.size, 1))
    mot = Motion(t=t, axes=('X',), pos=v * t[:, None], vel=v * ones, acc=0.0 * ones,
                 line=np.ones(t.size, dtype=np.int32))
    res = compute_power(compute_dynamics(mot, demo, load_kg=22.711), braking='regenerative')
    by_hand = 0.2505 * 100.0 ** 1.3471  # W at x = 100 mm/s, eq. (3) in our unit reading
    assert_allclose(res.power_w, by_hand, rtol=1e-12)
    assert_allclose(res.loss_power_w, by_hand, rtol=1e-12)
    assert res.total_energy_j[-1] == pytest.approx(2.0 * by_hand, rel=1e-12)


def reciprocating(m, *, vmax=0.4, period=2.0, n=20001):
    """x = A (1 - cos(w t)): forth and back to the start, at rest at both ends."""
    w = 2.0 * math.pi / period
    amp = vmax / w
    t = np.linspace(0.0, period, n)
    f = (lambda s: amp * (1.0 - np.cos(w * s)), lambda s: amp * w * np.sin(w * s),
         lambda s: amp * w * w * np.cos(w * s))
    return compute_dynamics(sampled([f], t, ('X',)), m)


@pytest.mark.parametrize('eta', [1.0, 0.9])
def test_closed_cycle_without_losses(eta):
    none = {'model': 'coulomb_viscous'}
    m = two_axis_machine(loss_x=none, loss_z=none, eta=eta)
    dyn = reciprocating(m, vmax=0.4)
    spec = m.axis('X')
    m_trans = spec.table_mass_kg
    m_rot = spec.rotary_inertia_kg_m2 * (2.0 * math.pi / spec.screw.lead_m) ** 2
    e_trans, e_rot = 0.5 * m_trans * 0.4 ** 2, 0.5 * m_rot * 0.4 ** 2
    regen = compute_power(dyn, braking='regenerative')
    dissip = compute_power(dyn, braking='dissipated')
    # Two strokes, each: accelerate (drive, E/eta) and brake (back-driven, eta*E returned).
    net = 2.0 * e_trans * (1.0 / eta - eta)
    gross = 2.0 * (e_trans / eta + e_rot)
    assert regen.total_energy_j[-1] == pytest.approx(net, abs=1e-6 * gross)
    assert dissip.total_energy_j[-1] == pytest.approx(gross, rel=1e-6)
    assert regen.regenerated_energy_j == pytest.approx(2.0 * (eta * e_trans + e_rot), rel=1e-6)
    assert dissip.regenerated_energy_j == pytest.approx(regen.regenerated_energy_j)
    assert np.all(dissip.power_w >= 0.0)
    assert np.min(regen.power_w) < 0.0


def test_vertical_axis_draws_weight_times_speed():
    mill = load_machine(CONFIG / 'three_axis_mill.yaml')
    d = machine_to_dict(mill)
    d['axes']['Z']['loss'] = {'model': 'coulomb_viscous'}
    d['axes']['Z']['screw']['efficiency'] = 1.0
    m = machine_from_dict(d)
    v = 0.05
    t = np.linspace(0.0, 1.0, 11)
    ones = np.ones((t.size, 1))
    mot = Motion(t=t, axes=('Z',), pos=v * t[:, None], vel=v * ones, acc=0.0 * ones,
                 line=np.zeros(t.size, dtype=np.int32))
    res = compute_power(compute_dynamics(mot, m, load_kg=50.0), braking='regenerative')
    assert_allclose(res.power_w, 150.0 * GRAVITY_M_S2 * v, rtol=1e-12)
    down = Motion(t=t, axes=('Z',), pos=-v * t[:, None], vel=-v * ones, acc=0.0 * ones,
                  line=np.zeros(t.size, dtype=np.int32))
    res_down = compute_power(compute_dynamics(down, m), braking='regenerative')
    assert_allclose(res_down.power_w, -150.0 * GRAVITY_M_S2 * v, rtol=1e-12)
    assert_allclose(compute_power(compute_dynamics(down, m), braking='dissipated').power_w, 0.0)


def test_integrator_chunked_equals_offline():
    rng = np.random.default_rng(7)
    n = 5000
    t = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, n))
    p = rng.normal(0.0, 300.0, (n, 3)) + np.array([100.0, -50.0, 0.0])
    offline = EnergyIntegrator(3).update(t, p)
    reference = np.vstack([np.zeros((1, 3)), cumulative_trapezoid(p, t, axis=0)])
    assert_allclose(offline, reference, rtol=1e-12, atol=1e-12 * np.max(np.abs(reference)))
    for _ in range(5):
        cuts = np.sort(rng.choice(np.arange(1, n), size=rng.integers(1, 30), replace=False))
        integ = EnergyIntegrator(3)
        parts = [integ.update(t[a:b], p[a:b])
                 for a, b in zip(np.r_[0, cuts], np.r_[cuts, n])]
        chunked = np.vstack(parts)
        assert_allclose(chunked, offline, rtol=1e-12, atol=1e-12 * np.max(np.abs(offline)))
        assert_allclose(integ.energy_j, offline[-1], rtol=1e-12)
    single = EnergyIntegrator(1)
    assert_allclose(np.concatenate([single.update(t[:10], p[:10, 0]),
                                    single.update(t[10:20], p[10:20, 0])]), offline[:20, 0])


def test_integrator_rejects_bad_input():
    integ = EnergyIntegrator(2)
    with pytest.raises(DataError, match='shape'):
        integ.update(np.arange(3.0), np.zeros((3, 3)))
    integ.update(np.arange(3.0), np.zeros((3, 2)))
    with pytest.raises(DataError, match='does not increase'):
        integ.update(np.array([2.0, 3.0]), np.zeros((2, 2)))


def test_bad_braking_rule():
    m = two_axis_machine(loss_x={'model': 'coulomb_viscous'}, loss_z={'model': 'coulomb_viscous'})
    with pytest.raises(ConfigError, match='braking'):
        compute_power(reciprocating(m, n=11), braking='brake')


def test_energy_by_line_by_hand():
    t = np.array([0.0, 1.0, 2.0, 3.0, 5.0])
    line = np.array([0, 3, 3, 7, 9], dtype=np.int32)
    total = np.array([10.0, 10.0, 20.0, 20.0, 0.0])
    res = PowerResult(t=t, axes=('X',), power_w=total[:, None], total_w=total,
                      energy_j=np.zeros((5, 1)), total_energy_j=np.zeros(5),
                      mechanical_w=total[:, None], loss_power_w=np.zeros((5, 1)), line=line)
    # intervals belong to their end sample: [0,1]->3, [1,2]->3, [2,3]->7, [3,5]->9
    assert energy_by_line(res) == [(3, 10.0 + 15.0, 2.0), (7, 20.0, 1.0), (9, 20.0, 2.0)]
