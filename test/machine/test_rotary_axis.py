"""Rotary axes in a machine file (machine/rotary.py): reading, checks naming the key,
the equivalent feed axis, masses and the round trip."""
from __future__ import annotations

import copy
import math

import pytest

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.machine import (load_machine, machine_from_dict, machine_to_dict,
                                      moved_mass_kg)
from feed_axis_energy.paths import config_dir

LINEAR = {'table_mass_kg': 100.0, 'screw': {'diameter_m': 0.02, 'lead_m': 0.01,
                                            'length_m': 0.5},
          'inertias': {'motor_kg_m2': 1e-4},
          'limits': {'velocity_m_s': 0.5, 'acceleration_m_s2': 2.0, 'jerk_m_s3': 20.0},
          'loss': {'model': 'coulomb_viscous', 'coulomb_n': 10.0}}
ROTARY = {'rides_on': 'X', 'mass_kg': 40.0, 'table_inertia_kg_m2': 0.2,
          'load_inertia_kg_m2': 0.05, 'gear_ratio': 50.0, 'efficiency': 0.8,
          'inertias': {'motor_kg_m2': 1e-4, 'coupling_kg_m2': 1e-5},
          'limits': {'velocity_deg_s': 360.0, 'acceleration_deg_s2': 720.0,
                     'jerk_deg_s3': 7200.0},
          'friction': {'coulomb_nm': 3.0, 'viscous_nm_s_rad': 0.5}}


def _machine_dict(**rotary):
    c = copy.deepcopy(ROTARY)
    c.update(rotary)
    return {'name': 't', 'braking': 'regenerative', 'load_axis': 'C',
            'axes': {'X': copy.deepcopy(LINEAR), 'C': c}}


def test_rotary_axis_is_the_equivalent_feed_axis():
    m = machine_from_dict(_machine_dict())
    c = m.axis('C')
    assert c.is_rotary and m.rotary_axes == ('C',)
    assert c.screw.lead_m == pytest.approx(2 * math.pi / 50.0)     # rad per motor turn
    assert c.screw.efficiency == 0.8
    assert c.rotary_inertia_kg_m2 == pytest.approx(1.1e-4)         # motor + coupling only
    assert c.limits.velocity_m_s == pytest.approx(2 * math.pi)     # 360 deg/s in rad/s
    assert c.limits.acceleration_m_s2 == pytest.approx(4 * math.pi)
    assert c.loss.coulomb_n == 3.0 and c.loss.viscous_n_s_m == 0.5 and c.loss.mu == 0.0
    # C turns table + load; X moves its own table, the rotary unit and the workpiece
    assert moved_mass_kg(m, 'C', 20.0) == pytest.approx(0.25)
    assert moved_mass_kg(m, 'X', 20.0) == pytest.approx(100.0 + 40.0 + 20.0)
    assert m.gcode_keywords()['rotary_axes'] == ('C',)
    assert machine_from_dict(machine_to_dict(m)) == m


def test_shipped_rotary_configs_load_and_round_trip():
    for name, rotary in (('four_axis_mill.yaml', ('A',)), ('five_axis_mill.yaml', ('B', 'C'))):
        m = load_machine(config_dir() / name)
        assert m.rotary_axes == rotary
        assert machine_from_dict(machine_to_dict(m)) == m


@pytest.mark.parametrize('change, key, words', [
    ({'table_inertia_kg_m2': -0.1}, 'axes.C.table_inertia_kg_m2', 'expected a number >= 0'),
    ({'load_inertia_kg_m2': -1.0}, 'axes.C.load_inertia_kg_m2', 'expected a number >= 0'),
    ({'gear_ratio': 0.0}, 'axes.C.gear_ratio', 'expected a number >= 0.001'),
    ({'efficiency': 1.5}, 'axes.C.efficiency', 'expected a number <= 1.0'),
    ({'limits': None}, 'axes.C.limits', 'missing required value'),
    ({'limits': {'velocity_deg_s': 10.0, 'acceleration_deg_s2': 10.0}},
     'axes.C.limits.jerk_deg_s3', 'missing required value'),
    ({'limits': {'velocity_m_s': 1.0}}, 'axes.C.limits.velocity_m_s', 'unknown key'),
    ({'friction': {'coulomb_nm': -2.0}}, 'axes.C.friction.coulomb_nm', 'expected a number'),
    ({'travel_deg': [90.0, -90.0]}, 'axes.C.travel_deg', 'min < max'),
    ({'screw': {'lead_m': 0.01}}, 'axes.C.screw', 'unknown key'),
])
def test_invalid_rotary_values_name_the_key(change, key, words):
    d = _machine_dict(**change)
    if change.get('limits', 0) is None:
        del d['axes']['C']['limits']
    with pytest.raises(ConfigError, match=words) as info:
        machine_from_dict(d, file='m.yaml')
    assert info.value.key == key
    assert 'm.yaml' in str(info.value)


def test_an_axis_riding_on_a_rotary_axis_is_refused():
    d = _machine_dict()
    d['axes']['Y'] = dict(copy.deepcopy(LINEAR), rides_on='C')
    with pytest.raises(ConfigError, match='carries no other axis') as info:
        machine_from_dict(d)
    assert info.value.key == 'axes.Y.rides_on'
