"""The G28 reference point of a machine config and its use by the commands."""
import json
from pathlib import Path

import pytest
import yaml

from feed_axis_energy.cli import main
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict

ROOT = Path(__file__).resolve().parents[2]
MILL = ROOT / 'config' / 'three_axis_mill.yaml'
DEMONSTRATOR = ROOT / 'config' / 'demonstrator.yaml'


def test_home_point_round_trips_and_fills_missing_program_axes():
    mill = load_machine(MILL)
    assert mill.home_point() == (0.0, 0.0, 0.1)
    assert machine_from_dict(machine_to_dict(mill), file='x') == mill
    d = machine_to_dict(load_machine(DEMONSTRATOR))
    assert 'home_m' not in d and load_machine(DEMONSTRATOR).home_point() is None
    d['home_m'] = {'X': 0.25}
    assert machine_from_dict(d, file='x').home_point() == (0.25, 0.0, 0.0)


@pytest.mark.parametrize('home, key', [({'Q': 0.0}, 'home_m'), ({'X': 'up'}, 'home_m.X'),
                                       ([0.0], 'home_m')])
def test_bad_home_names_the_key(home, key):
    d = machine_to_dict(load_machine(DEMONSTRATOR))
    d['home_m'] = home
    with pytest.raises(ConfigError) as err:
        machine_from_dict(d, file='m.yaml')
    assert err.value.key.startswith(key) and err.value.file == 'm.yaml'


def test_simulate_runs_a_program_ending_with_g28_on_a_machine_with_home(tmp_path, capsys):
    prog = tmp_path / 'cam.nc'
    prog.write_text('G21 G90 G17\nG0 Z50\nG1 X100 Y50 F3000\nG1 Z10\nG91 G28 Z0\nG90 M30\n')
    assert main(['simulate', str(prog), '--machine', str(MILL), '--json', '--quiet']) == 0
    summary = json.loads(capsys.readouterr().out)
    # the last block (line 5) lifts Z from 10 mm to the 100 mm reference: the weight goes up
    assert any(b['line'] == 5 and b['energy_j'] > 0.0 for b in summary['top_blocks'])
    # without a reference point G28 goes to the stored position #5161..#5163, which is 0 as
    # in LinuxCNC's fresh parameter file, and says so
    from feed_axis_energy.gcode.load import load_gcode
    program = load_gcode(prog, home=load_machine(DEMONSTRATOR).home_point())
    assert program.moves[-2].end == pytest.approx((0.1, 0.05, 0.0))
    assert len(program.warnings) == 1 and 'cam.nc:5: G28' in program.warnings[0]
    assert 'home_m' in program.warnings[0]


def test_machine_yaml_with_home_is_valid_yaml_for_users(tmp_path):
    d = machine_to_dict(load_machine(MILL))
    path = tmp_path / 'm.yaml'
    path.write_text(yaml.safe_dump(d))
    assert load_machine(path).home_point() == (0.0, 0.0, 0.1)
