"""The G-code section of a machine config (dialect, tool table) and axis travel limits."""
from pathlib import Path

import pytest
import yaml

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.gcode.settings import GcodeSettings, ToolSpec
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict

CONFIG = Path(__file__).resolve().parents[2] / 'config'


@pytest.fixture()
def mill_dict():
    return machine_to_dict(load_machine(CONFIG / 'three_axis_mill.yaml'))


def test_defaults_when_the_section_is_absent():
    demo = load_machine(CONFIG / 'demonstrator.yaml')
    assert demo.gcode == GcodeSettings()
    assert demo.gcode.dialect == 'linuxcnc' and dict(demo.gcode.tools) == {}
    assert demo.gcode.tool(1) is None
    assert demo.axis('X').travel_m is None
    assert 'gcode' not in machine_to_dict(demo)


def test_tools_dialect_and_travel_are_read_and_round_trip(mill_dict, tmp_path):
    mill_dict['gcode'] = {'dialect': 'fanuc',
                          'tools': {2: {'radius_m': 0.005}, '1': {'length_m': -0.01}}}
    mill_dict['axes']['Z']['travel_m'] = [-0.4, 0]
    mill_dict['axes']['X'].pop('travel_m', None)
    m = machine_from_dict(mill_dict, file='m.yaml')
    assert m.gcode.dialect == 'fanuc'
    assert m.gcode.tools[1] == ToolSpec(radius_m=0.0, length_m=-0.01)
    assert m.gcode.tools[2].radius_m == 0.005 and m.gcode.tools[2].length_m == 0.0
    assert list(m.gcode.tools) == [1, 2]
    assert m.axis('Z').travel_m == (-0.4, 0.0) and m.axis('X').travel_m is None
    path = tmp_path / 'm.yaml'
    path.write_text(yaml.safe_dump(machine_to_dict(m)))
    assert load_machine(path) == m
    with pytest.raises(TypeError):
        m.gcode.tools[3] = ToolSpec()          # the table is read-only


@pytest.mark.parametrize('gcode, key, words', [
    ({'dialect': 'heidenhain'}, 'gcode.dialect', 'expected one of linuxcnc'),
    ({'dialekt': 'fanuc'}, 'gcode.dialekt', 'unknown key'),
    ([1], 'gcode', 'expected a mapping'),
    ({'tools': {0: {}}}, 'gcode.tools', 'tool number'),
    ({'tools': {'T1': {}}}, 'gcode.tools', 'tool number'),
    ({'tools': {True: {}}}, 'gcode.tools', 'tool number'),
    ({'tools': {1: {'radius_m': -0.001}}}, 'gcode.tools.1.radius_m', '>= 0.0'),
    ({'tools': {1: {'length_m': 1e400}}}, 'gcode.tools.1.length_m', 'finite'),
    ({'tools': {1: {'length_m': 10 ** 400}}}, 'gcode.tools.1.length_m', 'finite'),
    ({'tools': {1: {'diameter_m': 0.01}}}, 'gcode.tools.1.diameter_m', 'unknown key'),
    ({'tools': {1: {}, '1': {}}}, 'gcode.tools.1', 'twice'),
    ({'tools': {1: 0.003}}, 'gcode.tools.1', 'expected a mapping'),
])
def test_bad_gcode_section_names_the_key(mill_dict, gcode, key, words):
    mill_dict['gcode'] = gcode
    with pytest.raises(ConfigError) as err:
        machine_from_dict(mill_dict, file='m.yaml')
    assert err.value.key == key and err.value.file == 'm.yaml'
    assert words in str(err.value) and len(str(err.value)) < 300


def test_too_many_tools_is_refused_before_reading_them(mill_dict):
    mill_dict['gcode'] = {'tools': {n: {} for n in range(1, 10_002)}}
    with pytest.raises(ConfigError, match='at most 10000 tools'):
        machine_from_dict(mill_dict, file='m.yaml')


@pytest.mark.parametrize('travel, key', [
    ([0.1, 0.1], 'axes.X.travel_m'), ([0.2, -0.1], 'axes.X.travel_m'),
    ([0.0], 'axes.X.travel_m'), (0.3, 'axes.X.travel_m'), ('0..1', 'axes.X.travel_m'),
    ([0.0, 'far'], 'axes.X.travel_m[1]'), ([-2000.0, 0.0], 'axes.X.travel_m[0]'),
    ([float('nan'), 1.0], 'axes.X.travel_m[0]'), ([False, 1.0], 'axes.X.travel_m[0]'),
])
def test_bad_travel_names_the_key(mill_dict, travel, key):
    mill_dict['axes']['X']['travel_m'] = travel
    with pytest.raises(ConfigError) as err:
        machine_from_dict(mill_dict, file='m.yaml')
    assert err.value.key == key


def test_simulate_takes_the_tool_table_from_the_machine_config(tmp_path, capsys):
    from feed_axis_energy.cli import main
    prog = tmp_path / 'cam.nc'
    prog.write_text('G21 G90\nT2 M6\nG43 H2 G0 Z50\nG1 X100 F3000\nM30\n')
    mill = load_machine(CONFIG / 'three_axis_mill.yaml')
    assert mill.gcode.tools[2] is not None
    d = machine_to_dict(mill)
    d['gcode']['tools'][2]['length_m'] = 0.04
    machine = tmp_path / 'm.yaml'
    machine.write_text(yaml.safe_dump(d))
    assert main(['simulate', str(prog), '--machine', str(machine), '--json', '--quiet']) == 0
    capsys.readouterr()
    from feed_axis_energy.gcode.load import load_gcode
    moves = load_gcode(prog, **load_machine(machine).gcode_keywords()).moves
    # G43 H2 Z50: machine Z = 50 mm + 40 mm tool length
    assert moves[0].end == pytest.approx((0.0, 0.0, 0.09))
    # the demonstrator has no tool table: with --strict-tools a clear error at the T word
    # (as LinuxCNC), exit 1; without it tool 2 runs with length 0 and one warning
    assert main(['simulate', str(prog), '--machine', str(CONFIG / 'demonstrator.yaml'),
                 '--quiet', '--strict-tools']) == 1
    err = capsys.readouterr().err
    assert 'cam.nc:2:1' in err and 'tool 2 is not in the tool table' in err
    assert 'Traceback' not in err
    bare = load_gcode(prog, **load_machine(CONFIG / 'demonstrator.yaml').gcode_keywords())
    assert bare.moves[0].end == pytest.approx((0.0, 0.0, 0.05))
    warned = [w for w in bare.warnings if 'tool 2 is not in the tool table' in w]
    assert len(warned) == 1 and 'cam.nc:3:' in warned[0]


@pytest.mark.parametrize('text, number, radius, length', [
    ('1:3', 1, 0.003, 0.0), ('12:2.5:45.2', 12, 0.0025, 0.0452), ('7:0:-10', 7, 0.0, -0.01),
])
def test_tool_option_is_read_in_millimetres(text, number, radius, length):
    from feed_axis_energy.gcode.settings import parse_tool_option
    t, spec = parse_tool_option(text)
    assert t == number
    assert spec.radius_m == pytest.approx(radius) and spec.length_m == pytest.approx(length)


@pytest.mark.parametrize('text, words', [
    ('1', 'T:RADIUS_MM'), ('1:2:3:4', 'T:RADIUS_MM'), ('0:1', 'tool number'),
    ('x:1', 'tool number'), ('1:-1', '0 ... 1000 mm'), ('1:nan', '0 ... 1000 mm'),
    ('1:2:inf', '-10000 ... 10000 mm'), ('1:abc', 'a number of millimetres'),
    ('1:' + '9' * 500, '0 ... 1000 mm'),
])
def test_bad_tool_option_says_why(text, words):
    from feed_axis_energy.gcode.settings import parse_tool_option
    with pytest.raises(ValueError) as err:
        parse_tool_option(text)
    assert words in str(err.value) and len(str(err.value)) < 250


def test_simulate_tool_option_adds_to_the_table(tmp_path, capsys):
    from feed_axis_energy.cli import main
    prog = tmp_path / 'cam.nc'
    prog.write_text('G21 G90\nG43 H5 G0 Z20\nG1 X50 F3000\nM30\n')
    mill = str(CONFIG / 'three_axis_mill.yaml')
    # tool 5 is not in the mill's table: refused (--strict-tools); given on the command
    # line: simulated
    assert main(['simulate', str(prog), '--machine', mill, '--quiet', '--strict-tools']) == 1
    assert 'tool 5 is not in the tool table' in capsys.readouterr().err
    assert main(['simulate', str(prog), '--machine', mill, '--quiet', '--json',
                 '--tool', '5:3:45']) == 0
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(['simulate', str(prog), '--machine', mill, '--tool', '5:3:abc'])
    assert exc.value.code == 2
    assert "argument --tool: expected a number of millimetres, got 'abc'" in \
        capsys.readouterr().err


def test_config_dialect_names_are_the_registry_of_the_gcode_package():
    # gcode.settings keeps its own tuple (gcode/settings must not import gcode)
    from feed_axis_energy.gcode.dialect import DIALECTS as REGISTRY
    from feed_axis_energy.gcode.settings import DIALECTS
    assert set(DIALECTS) == set(REGISTRY)


def test_simulate_dialect_from_the_config_or_the_command_line(tmp_path, capsys):
    # G4 P2000: 2000 s for LinuxCNC, 2 s for Fanuc (milliseconds)
    from feed_axis_energy.cli import main
    import json
    prog = tmp_path / 'dwell.nc'
    prog.write_text('G21 G90\nG1 X10 F600\nG4 P2000\nM30\n')
    d = machine_to_dict(load_machine(CONFIG / 'three_axis_mill.yaml'))
    d['gcode']['dialect'] = 'fanuc'
    fanuc = tmp_path / 'fanuc.yaml'
    fanuc.write_text(yaml.safe_dump(d))

    def duration(*extra):
        assert main(['simulate', str(prog), '--json', '--quiet', *extra]) == 0
        return json.loads(capsys.readouterr().out)['duration_s']

    assert duration('--machine', str(fanuc)) == pytest.approx(3.0, abs=0.5)
    assert duration('--machine', str(fanuc), '--dialect', 'linuxcnc') > 2000.0
    with pytest.raises(SystemExit) as exc:
        main(['simulate', str(prog), '--dialect', 'heidenhain'])
    assert exc.value.code == 2
