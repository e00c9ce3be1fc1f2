"""Tests of the machine model: paper values, stacking, validation messages, round trip."""
import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.machine.losses import PowerRegressionLoss
from feed_axis_energy.machine.mass import carried_axes, moved_mass_kg
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.plan.trajectory import AxisLimits

CONFIG = Path(__file__).resolve().parents[2] / 'config'


@pytest.fixture(scope='module')
def demo():
    return load_machine(CONFIG / 'demonstrator.yaml')


@pytest.fixture(scope='module')
def mill():
    return load_machine(CONFIG / 'three_axis_mill.yaml')


def test_demonstrator_has_the_papers_numbers(demo):
    assert demo.axis_names == ('X',)
    x = demo.axis('X')
    assert x.screw.diameter_m == 0.020 and x.screw.lead_m == 0.010
    assert x.screw.efficiency == 1.0
    assert x.loss == PowerRegressionLoss(a=0.2505, b=0.3471, x_unit='mm/s', y_unit='W/(mm/s)')
    assert demo.braking == 'regenerative' and demo.load_axis == 'X'
    # screw inertia omitted in the file: solid steel cylinder pi/32 rho L d^4
    solid = math.pi / 32.0 * 7850.0 * x.screw.length_m * 0.020 ** 4
    assert x.screw_inertia_kg_m2 == pytest.approx(solid, rel=1e-12)
    assert x.rotary_inertia_kg_m2 == pytest.approx(
        x.inertias.motor_kg_m2 + x.inertias.coupling_kg_m2 + solid, rel=1e-12)
    assert moved_mass_kg(demo, 'X', 17.336) == pytest.approx(x.table_mass_kg + 17.336)


def test_stacking_of_the_mill(mill):
    mx, my, mz = (mill.axis(n).table_mass_kg for n in 'XYZ')
    assert carried_axes(mill, 'X') == ('X', 'Y')
    assert moved_mass_kg(mill, 'X', 25.0) == pytest.approx(mx + my + 25.0)
    assert moved_mass_kg(mill, 'Y', 25.0) == pytest.approx(my + 25.0)
    assert moved_mass_kg(mill, 'Z', 25.0) == pytest.approx(mz)
    assert mill.axis('Z').inclination_deg == 90.0


def test_deep_stacking_is_recursive(mill):
    d = machine_to_dict(mill)
    d['axes']['Z']['rides_on'] = 'Y'
    m = machine_from_dict(d)
    total = sum(m.axis(n).table_mass_kg for n in 'XYZ')
    assert moved_mass_kg(m, 'X', 5.0) == pytest.approx(total + 5.0)


@pytest.mark.parametrize('name', ['demonstrator.yaml', 'three_axis_mill.yaml'])
def test_round_trip(name, tmp_path):
    m = load_machine(CONFIG / name)
    assert machine_from_dict(machine_to_dict(m), file='copy') == m
    out = tmp_path / name
    out.write_text(yaml.safe_dump(machine_to_dict(m), sort_keys=False))
    assert load_machine(out) == m


def test_explicit_screw_inertia_survives_round_trip(demo):
    d = machine_to_dict(demo)
    d['axes']['X']['inertias']['screw_kg_m2'] = 3.0e-5
    m = machine_from_dict(d)
    assert m.axis('X').screw_inertia_kg_m2 == 3.0e-5
    assert machine_from_dict(machine_to_dict(m)) == m


def _set(d, dotted, value):
    *head, last = dotted.split('.')
    for part in head:
        d = d[part]
    if value is _DELETE:
        del d[last]
    else:
        d[last] = value


_DELETE = object()


@pytest.mark.parametrize('dotted, value, key, expected', [
    ('axes.X.screw.lead_m', _DELETE, 'axes.X.screw.lead_m', 'missing'),
    ('axes.X.screw.lead_m', -0.01, 'axes.X.screw.lead_m', '>= 1e-06'),
    # values that let the dynamics overflow to inf/NaN (found by the property tests)
    ('axes.X.screw.lead_m', 1e-300, 'axes.X.screw.lead_m', '>= 1e-06'),
    ('axes.X.screw.efficiency', 5e-324, 'axes.X.screw.efficiency', '>= 0.01'),
    ('axes.X.screw.diameter_m', 1e300, 'axes.X.screw.diameter_m', '<= 10'),
    ('axes.X.limits.velocity_m_s', 1e-30, 'axes.X.limits.velocity_m_s', '>= 0.001'),
    ('axes.X.loss.b', 1e12, 'axes.X.loss.b', '<= 10'),
    ('axes.X.screw.lead_m', '10mm', 'axes.X.screw.lead_m', 'finite number'),
    ('axes.X.screw.lead_m', True, 'axes.X.screw.lead_m', 'finite number'),
    ('axes.X.screw.lead_mm', 0.01, 'axes.X.screw.lead_mm', 'unknown key'),
    ('axes.X.screw.efficiency', 1.2, 'axes.X.screw.efficiency', '<= 1'),
    ('axes.X.screw.starts', 1.5, 'axes.X.screw.starts', 'whole number'),
    ('axes.X.table_mass_kg', _DELETE, 'axes.X.table_mass_kg', 'missing'),
    ('axes.X.inertias', _DELETE, 'axes.X.inertias', 'missing'),
    ('axes.X.limits.jerk_m_s3', 0.0, 'axes.X.limits.jerk_m_s3', '>= 0.001'),
    ('axes.X.inclination_deg', 120.0, 'axes.X.inclination_deg', '<= 90'),
    ('axes.X.rides_on', 'Y', 'axes.X.rides_on', 'not defined'),
    ('axes.X.rides_on', 'Q', 'axes.X.rides_on', 'one of'),
    ('axes.X.loss.model', 'magic', 'axes.X.loss.model', 'unknown loss model'),
    ('axes.U', {}, 'axes.U', 'unknown axis name'),
    ('axes.A', {}, 'axes.A.table_inertia_kg_m2', 'missing required value of a rotary axis'),
    ('braking', 'regen', 'braking', 'regenerative'),
    ('load_axis', 'Z', 'load_axis', 'one of X'),
    ('planner.profile', 'spline', 'planner.profile', 'jerk'),
    ('spindle', {}, 'spindle', 'unknown key'),
    ('axes', {}, 'axes', 'at least one axis'),
])
def test_config_errors_name_file_and_key(demo, dotted, value, key, expected):
    d = copy.deepcopy(machine_to_dict(demo))
    _set(d, dotted, value)
    with pytest.raises(ConfigError) as info:
        machine_from_dict(d, file='bad.yaml')
    assert info.value.key == key
    assert info.value.file == 'bad.yaml'
    assert str(info.value).startswith(f'bad.yaml: {key}: ')
    assert expected in str(info.value)


def test_stacking_loop_is_rejected(mill):
    d = machine_to_dict(mill)
    d['axes']['X']['rides_on'] = 'Y'
    with pytest.raises(ConfigError, match='loop'):
        machine_from_dict(d)


def test_file_errors(tmp_path):
    with pytest.raises(ConfigError, match='cannot read'):
        load_machine(tmp_path / 'missing.yaml')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('name: x\naxes: [\n')
    with pytest.raises(ConfigError, match='line 3, column 1: not valid YAML'):
        load_machine(bad)
    empty = tmp_path / 'empty.yaml'
    empty.write_text('')
    with pytest.raises(ConfigError, match='expected a mapping'):
        load_machine(empty)


def test_limits_as_planner_type(mill):
    limits = mill.limits()
    assert list(limits) == ['X', 'Y', 'Z']
    assert isinstance(limits['Z'], AxisLimits)
    assert limits['Z'].velocity_m_s == mill.axis('Z').limits.velocity_m_s
    assert limits['Z'].jerk_m_s3 == mill.axis('Z').limits.jerk_m_s3


def test_direct_axis_has_no_screw_and_round_trips(tmp_path):
    # a linear test stand: torque equals force, screw speed equals carriage speed
    m = load_machine(CONFIG / 'linear_stand.yaml')
    x = m.axis('X')
    assert x.direct
    assert x.screw.lead_m / (2.0 * math.pi) == pytest.approx(1.0, rel=1e-15)
    assert x.screw.efficiency == 1.0 and x.rotary_inertia_kg_m2 == 0.0
    d = machine_to_dict(m)
    assert d['axes']['X']['transmission'] == 'direct'
    assert 'screw' not in d['axes']['X'] and 'inertias' not in d['axes']['X']
    out = tmp_path / 'stand.yaml'
    out.write_text(yaml.safe_dump(d, sort_keys=False))
    assert load_machine(out) == m


@pytest.mark.parametrize('change, key, expected', [
    ({'screw': {'diameter_m': 0.02, 'lead_m': 0.01, 'length_m': 0.5}}, 'axes.X.screw',
     'has no screw'),
    ({'inertias': {'motor_kg_m2': 1e-4}}, 'axes.X.inertias', 'has no inertias'),
    ({'transmission': 'belt'}, 'axes.X.transmission', 'screw'),
])
def test_direct_axis_errors_name_the_key(change, key, expected):
    d = yaml.safe_load((CONFIG / 'linear_stand.yaml').read_text())
    d['axes']['X'].update(change)
    with pytest.raises(ConfigError, match=expected) as err:
        machine_from_dict(d, file='stand.yaml')
    assert key in str(err.value)


def test_missing_screw_names_the_direct_transmission(demo):
    d = machine_to_dict(demo)
    del d['axes']['X']['screw']
    with pytest.raises(ConfigError, match='transmission: direct'):
        machine_from_dict(d, file='m.yaml')


def test_direct_axis_force_is_the_dynamics_torque():
    # m a + F_loss: on a direct axis the screw torque of the dynamics is that force in N
    from feed_axis_energy.gcode.load import parse_gcode
    from feed_axis_energy.sim.simulate import simulate_program
    m = load_machine(CONFIG / 'linear_stand.yaml')
    prog = parse_gcode('G21 G90 G94 G61\nG1 X200 F6000\nM30\n', file='p.nc')
    res = simulate_program(prog, m, load_kg=2.0)
    v = res.motion.vel[:, 0]
    a = res.motion.acc[:, 0]
    force = 10.0 * a + (20.0 * np.sign(v) + 40.0 * v)
    np.testing.assert_allclose(res.dynamics.torque_nm[:, 0], force, atol=1e-9)
    np.testing.assert_allclose(res.power.power_w[:, 0] if res.power.power_w.ndim == 2
                               else res.power.power_w, force * v, atol=1e-9)


def test_new_friction_effects_are_machine_effects_that_round_trip(tmp_path):
    # an accepted finding of each new shape writes an augmented machine file that reads back
    d = yaml.safe_load((CONFIG / 'linear_stand.yaml').read_text())
    d['effects'] = [
        {'id': 'offset_force', 'axis': 'X', 'params': {'f0_n': -12.5}},
        {'id': 'viscous_asymmetry', 'axis': 'X', 'params': {'d_n_s_m': 7.0}},
        {'id': 'stribeck', 'axis': 'X', 'params': {'f_s_n': 9.0, 'v_s_m_s': 0.004,
                                                   'delta': 1.0}},
        {'id': 'coulomb', 'axis': 'X', 'params': {'f_pos_n': 3.0, 'f_neg_n': -3.0}},
    ]
    m = machine_from_dict(d, file='stand.yaml')
    assert [e.id for e in m.effects] == [
        'offset_force', 'viscous_asymmetry', 'stribeck', 'coulomb']
    out = tmp_path / 'augmented.yaml'
    out.write_text(yaml.safe_dump(machine_to_dict(m), sort_keys=False))
    assert load_machine(out) == m
    d['effects'][2]['params']['delta'] = 50.0
    with pytest.raises(ConfigError, match='delta') as err:
        machine_from_dict(d, file='stand.yaml')
    assert 'effects[2].params' in str(err.value)
