"""Tests of the axis dynamics with hand-built motions and hand calculations."""
import math
from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.physics.dynamics import compute_dynamics
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.units import GRAVITY_M_S2
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.plan.motion import Motion

CONFIG = Path(__file__).resolve().parents[2] / 'config'
NO_LOSS = {'model': 'coulomb_viscous'}


def motion(t, pos, vel, acc, axes):
    t = np.asarray(t, dtype=float)
    cols = [np.broadcast_to(np.asarray(c, dtype=float), t.shape) for c in (pos, vel, acc)]
    return Motion(t=t, axes=axes, pos=cols[0].reshape(-1, 1), vel=cols[1].reshape(-1, 1),
                  acc=cols[2].reshape(-1, 1), line=np.ones(t.shape, dtype=np.int32),
                  source='hand')


@pytest.fixture(scope='module')
def demo():
    return load_machine(CONFIG / 'demonstrator.yaml')


@pytest.fixture(scope='module')
def mill():
    return load_machine(CONFIG / 'three_axis_mill.yaml')


def test_constant_velocity_torque_is_loss_only(demo):
    v = 0.3
    t = np.linspace(0.0, 1.0, 11)
    dyn = compute_dynamics(motion(t, v * t, v, 0.0, ('X',)), demo, load_kg=17.336)
    lead = 0.010
    f_loss = 1000.0 * 0.2505 * (v * 1000.0) ** 0.3471  # N, from y in W/(mm/s)
    assert_allclose(dyn.omega_rad_s, 2.0 * math.pi * v / lead)
    assert_allclose(dyn.alpha_rad_s2, 0.0)
    assert_allclose(dyn.loss_force_n, f_loss, rtol=1e-12)
    assert_allclose(dyn.force_n, f_loss, rtol=1e-12)
    assert_allclose(dyn.torque_nm, f_loss * lead / (2.0 * math.pi), rtol=1e-12)
    assert_allclose(dyn.angle_rad[:, 0], 2.0 * math.pi * v * t / lead)
    assert dyn.mass_kg[0] == pytest.approx(demo.axis('X').table_mass_kg + 17.336)


def test_acceleration_from_rest_by_hand(demo):
    d = machine_to_dict(demo)
    d['axes']['X']['loss'] = NO_LOSS
    m = machine_from_dict(d)
    a = 2.0
    t = np.linspace(0.0, 0.1, 5)
    dyn = compute_dynamics(motion(t, 0.5 * a * t ** 2, a * t, a, ('X',)), m, load_kg=10.0)
    spec = m.axis('X')
    mass = spec.table_mass_kg + 10.0
    lead = spec.screw.lead_m
    expected = spec.rotary_inertia_kg_m2 * 2.0 * math.pi * a / lead + mass * a * lead / (
        2.0 * math.pi)
    assert_allclose(dyn.torque_nm, expected, rtol=1e-12)
    assert_allclose(dyn.force_n, mass * a, rtol=1e-12)


def test_x_carries_y_and_load(mill):
    d = machine_to_dict(mill)
    for name in 'XYZ':
        d['axes'][name]['loss'] = NO_LOSS
    m = machine_from_dict(d)
    t = np.linspace(0.0, 0.2, 3)
    dyn = compute_dynamics(motion(t, 0.0, 0.0, 1.5, ('X',)), m, load_kg=30.0)
    assert_allclose(dyn.force_n, (120.0 + 90.0 + 30.0) * 1.5)
    dyn_y = compute_dynamics(motion(t, 0.0, 0.0, 1.5, ('Y',)), m, load_kg=30.0)
    assert_allclose(dyn_y.force_n, (90.0 + 30.0) * 1.5)


def test_vertical_axis_holds_its_weight(mill):
    t = np.linspace(0.0, 1.0, 3)
    up = compute_dynamics(motion(t, 0.1 * t, 0.1, 0.0, ('Z',)), mill, load_kg=30.0)
    weight = 150.0 * GRAVITY_M_S2  # the load is on Y, not on Z
    f_loss = 180.0 + 400.0 * 0.1
    assert_allclose(up.gravity_force_n, weight, rtol=1e-12)
    assert_allclose(up.force_n, weight + f_loss, rtol=1e-12)
    # driving: M = F lead / (2 pi eta)
    assert_allclose(up.torque_nm, (weight + f_loss) * 0.01 / (2.0 * math.pi * 0.9), rtol=1e-12)
    rest = compute_dynamics(motion(t, 0.0, 0.0, 0.0, ('Z',)), mill)
    assert_allclose(rest.force_n, weight, rtol=1e-12)
    assert_allclose(rest.omega_rad_s, 0.0)


def test_back_driven_torque_uses_eta_once(mill):
    # Lowering Z at constant speed: the weight back-drives the screw (F > 0, v < 0).
    t = np.linspace(0.0, 1.0, 3)
    dyn = compute_dynamics(motion(t, -0.1 * t, -0.1, 0.0, ('Z',)), mill)
    f = 150.0 * GRAVITY_M_S2 - (180.0 + 400.0 * 0.1)
    assert_allclose(dyn.force_n, f, rtol=1e-12)
    assert_allclose(dyn.torque_nm, f * 0.01 * 0.9 / (2.0 * math.pi), rtol=1e-12)


def test_sign_symmetry_of_horizontal_axis(demo):
    t = np.linspace(0.0, 1.0, 50)
    pos, vel, acc = np.sin(t), np.cos(t), -np.sin(t)
    fwd = compute_dynamics(motion(t, pos, vel, acc, ('X',)), demo)
    back = compute_dynamics(motion(t, -pos, -vel, -acc, ('X',)), demo)
    assert_allclose(back.torque_nm, -fwd.torque_nm, rtol=1e-12, atol=1e-15)


def test_unknown_axis_and_bad_load(demo):
    t = np.linspace(0.0, 1.0, 3)
    with pytest.raises(ConfigError, match="motion axis 'Y'"):
        compute_dynamics(motion(t, 0.0, 0.0, 0.0, ('Y',)), demo)
    with pytest.raises(ConfigError, match='load_kg'):
        compute_dynamics(motion(t, 0.0, 0.0, 0.0, ('X',)), demo, load_kg=-1.0)
