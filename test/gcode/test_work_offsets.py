"""Values of the settable work offsets G54..G59 from the machine config (gcode.work_offsets_m).

By hand: a move to ``X10 Y20 Z5`` [mm] in a system whose origin lies at ``o`` [m] in machine
coordinates ends at ``o + (0.010, 0.020, 0.005)``. LinuxCNC starts in G54 (its stored origin
applies from the first line); Sinumerik's settable offset applies once selected (G500, none,
before). A system the table lacks is 0 (the Sinumerik front warns, as before).
"""
from __future__ import annotations

import pytest

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.gcode import gcode_from_dict, parse_gcode
from feed_axis_energy.machine import load_machine
from feed_axis_energy.paths import config_dir

G57 = (0.512, 0.2843, -0.4833)
G54 = (0.01, -0.02, 0.03)
OFFSETS = {'G57': G57, 'G54': G54}
TARGET = (0.010, 0.020, 0.005)


def _end(text: str, dialect: str, offsets: dict | None) -> tuple[tuple[float, ...], tuple]:
    p = parse_gcode(text, dialect=dialect, work_offsets=offsets)
    return p.moves[-1].end, p.warnings


def _plus(a, b):
    return tuple(x + y for x, y in zip(a, b))


@pytest.mark.parametrize('dialect, head', [('sinumerik', 'G90 G710'), ('linuxcnc', 'G21 G90')])
def test_selected_offset_moves_the_path_by_its_value(dialect, head):
    end, warnings = _end(f'{head}\nG57\nG1 X10 Y20 Z5 F1000\nM30\n', dialect, OFFSETS)
    assert end == pytest.approx(_plus(G57, TARGET), abs=1e-12)
    assert not any('G57' in w for w in warnings)


def test_linuxcnc_starts_in_g54_and_sinumerik_in_g500():
    text = 'G1 X10 Y20 Z5 F1000\nM30\n'
    end, _ = _end('G21 G90\n' + text, 'linuxcnc', OFFSETS)
    assert end == pytest.approx(_plus(G54, TARGET), abs=1e-12)
    end, _ = _end('G90 G710\n' + text, 'sinumerik', OFFSETS)
    assert end == pytest.approx(TARGET, abs=1e-12)


def test_an_offset_not_given_is_zero_with_the_sinumerik_warning():
    end, warnings = _end('G90 G710\nG56\nG1 X10 Y20 Z5 F1000\nM30\n', 'sinumerik', OFFSETS)
    assert end == pytest.approx(TARGET, abs=1e-12)
    assert any('settable work offset G56' in w for w in warnings)


def test_machine_config_key_reaches_the_fronts(tmp_path):
    text = (config_dir() / 'three_axis_mill.yaml').read_text(encoding='utf-8')
    text += '\ngcode:\n  work_offsets_m:\n    G57: {X: 0.512, Y: 0.2843, Z: -0.4833}\n'
    file = tmp_path / 'm.yaml'
    file.write_text(text, encoding='utf-8')
    machine = load_machine(file)
    assert dict(machine.gcode.work_offsets_m) == {'G57': G57}
    kw = machine.gcode_keywords()
    program = parse_gcode('G90 G710\nG57\nG1 X10 Y20 Z5 F1000\nM30\n',
                          **{**kw, 'dialect': 'sinumerik'})
    assert program.moves[-1].end == pytest.approx(_plus(G57, TARGET), abs=1e-12)


@pytest.mark.parametrize('value, key, text', [
    ({'G53': {'X': 0.1}}, 'gcode.work_offsets_m.G53', 'unknown key'),
    ({'G54': {'Q': 0.1}}, 'gcode.work_offsets_m.G54.Q', 'unknown key'),
    ({'G54': {'X': 'far'}}, 'gcode.work_offsets_m.G54.X', 'finite number'),
    ({'G54': {'X': float('nan')}}, 'gcode.work_offsets_m.G54.X', 'finite number'),
    ({'G55': [0.1, 0.2]}, 'gcode.work_offsets_m.G55', 'mapping'),
])
def test_bad_values_name_the_key(value, key, text):
    with pytest.raises(ConfigError) as err:
        gcode_from_dict({'work_offsets_m': value}, file='m.yaml')
    assert key in str(err.value) and text in str(err.value)
