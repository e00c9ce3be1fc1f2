"""The electrical side of a machine config: values, physical bounds, error keys, round trip."""
import copy
import math
from pathlib import Path

import pytest

from feed_axis_energy.machine.drives import COPPER_FACTOR
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict

CONFIG = Path(__file__).resolve().parents[2] / 'config'


@pytest.fixture(scope='module')
def drives():
    return load_machine(CONFIG / 'three_axis_mill_drives.yaml')


def test_example_config_has_drives_on_every_axis(drives):
    assert drives.electrical
    assert drives.supply.standby_w == 60.0 and drives.supply.measured_at == 'supply'
    x = drives.axis('X').drive
    assert (x.kt_nm_a, x.resistance_ohm, x.resistance_between) == (1.3, 1.9, 'terminals')
    # IEC 60034-2-1: P = 1.5 R_terminals I^2, I = M / kt
    assert x.copper_k_w_nm2 == pytest.approx(1.5 * 1.9 / 1.3 ** 2, rel=1e-15)
    # no-load power 20 W at 3000 rpm, half of it eddy currents
    w0 = 3000.0 * 2.0 * math.pi / 60.0
    assert x.iron.k_h_w_s_rad * w0 == pytest.approx(10.0, rel=1e-12)
    assert x.iron.k_e_w_s2_rad2 * w0 ** 2 == pytest.approx(10.0, rel=1e-12)
    assert x.converter_efficiency == 0.96 and x.regeneration_limit_w == 250.0


def test_the_mechanical_part_is_the_three_axis_mill(drives):
    plain = machine_to_dict(load_machine(CONFIG / 'three_axis_mill.yaml'))
    data = machine_to_dict(drives)
    for axis in data['axes'].values():
        del axis['drive']
    for name in ('name', 'braking', 'supply'):
        data.pop(name)
        plain.pop(name, None)
    assert data == plain


def test_shipped_configs_without_drives_have_no_electrical_side():
    for name in ('demonstrator.yaml', 'three_axis_mill.yaml', 'umich_mill.yaml'):
        machine = load_machine(CONFIG / name)
        assert not machine.electrical and machine.supply is None
        assert 'supply' not in machine_to_dict(machine)


def test_round_trip(drives):
    again = machine_from_dict(machine_to_dict(drives))
    assert again == drives


def test_per_phase_resistance_doubles_the_factor(drives):
    data = machine_to_dict(drives)
    data['axes']['X']['drive']['resistance_between'] = 'phase'
    x = machine_from_dict(data).axis('X').drive
    assert COPPER_FACTOR['phase'] == 2 * COPPER_FACTOR['terminals']
    assert x.copper_k_w_nm2 == pytest.approx(3.0 * 1.9 / 1.3 ** 2, rel=1e-15)


def test_coefficients_instead_of_no_load(drives):
    data = machine_to_dict(drives)
    data['axes']['Y']['drive']['iron'] = {'k_h_w_s_rad': 0.02, 'k_e_w_s2_rad2': 3e-5}
    machine = machine_from_dict(data)
    y = machine.axis('Y').drive
    assert (y.iron.k_h_w_s_rad, y.iron.k_e_w_s2_rad2, y.iron.no_load) == (0.02, 3e-5, None)
    assert machine_from_dict(machine_to_dict(machine)) == machine


def _set(data, path, value):
    *head, last = path.split('.')
    node = data
    for part in head:
        node = node[part]
    if value is _DELETE:
        del node[last]
    else:
        node[last] = value


_DELETE = object()


@pytest.mark.parametrize('path,value,key,words', [
    ('axes.X.drive.resistance_ohm', -0.1, 'axes.X.drive.resistance_ohm', '>= 0'),
    ('axes.X.drive.kt_nm_a', 0.0, 'axes.X.drive.kt_nm_a', '>='),
    ('axes.X.drive.converter_efficiency', 0.0, 'axes.X.drive.converter_efficiency', '>='),
    ('axes.X.drive.converter_efficiency', 1.2, 'axes.X.drive.converter_efficiency', '<= 1'),
    ('axes.X.drive.standby_w', -1.0, 'axes.X.drive.standby_w', '>= 0'),
    ('axes.X.drive.regeneration_limit_w', -5.0, 'axes.X.drive.regeneration_limit_w', '>= 0'),
    ('axes.X.drive.resistance_between', 'star', 'axes.X.drive.resistance_between',
     'terminals, phase'),
    ('axes.X.drive.resistance_between', _DELETE, 'axes.X.drive.resistance_between',
     'missing'),
    ('axes.X.drive.kt_nm_a', float('nan'), 'axes.X.drive.kt_nm_a', 'finite'),
    ('axes.X.drive.torque', 1.0, 'axes.X.drive.torque', 'unknown key'),
    ('axes.X.drive.iron.no_load_w', -3.0, 'axes.X.drive.iron.no_load_w', '>= 0'),
    ('axes.X.drive.iron.eddy_share', 1.5, 'axes.X.drive.iron.eddy_share', '<= 1'),
    ('axes.X.drive.iron.speed_rpm', 0.0, 'axes.X.drive.iron.speed_rpm', '>= 1'),
    ('axes.X.drive.iron.k_h_w_s_rad', 0.1, 'axes.X.drive.iron', 'either'),
    ('axes.Y.drive', _DELETE, 'axes.Y.drive', 'every axis'),
    ('supply.measured_at', 'meter', 'supply.measured_at', 'motor, supply'),
    ('supply.standby_w', -2.0, 'supply.standby_w', '>= 0'),
    ('supply.volts', 400, 'supply.volts', 'unknown key'),
])
def test_invalid_values_name_the_key(drives, path, value, key, words):
    data = copy.deepcopy(machine_to_dict(drives))
    _set(data, path, value)
    with pytest.raises(ConfigError) as info:
        machine_from_dict(data, file='m.yaml')
    assert info.value.key == key
    assert words in str(info.value)
    assert 'm.yaml' in str(info.value)


def test_supply_without_drives_is_refused():
    data = machine_to_dict(load_machine(CONFIG / 'demonstrator.yaml'))
    data['supply'] = {'standby_w': 10.0}
    with pytest.raises(ConfigError) as info:
        machine_from_dict(data, file='m.yaml')
    assert info.value.key == 'axes.X.drive' and 'supply block' in str(info.value)
