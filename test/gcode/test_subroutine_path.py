"""Subroutine files in other folders: ``search_path`` (``--subroutine-path``,
``gcode.subroutine_path``) searched after the program's own folder, as LinuxCNC's
SUBROUTINE_PATH; a directory that does not exist is an error naming where it was given."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from feed_axis_energy.errors import ConfigError, GcodeError
from feed_axis_energy.gcode import gcode_from_dict, gcode_to_dict, load_gcode, parse_gcode

MAIN = 'G21 G90\no<face> call [5]\nG0 X0\nM2\n'


def _sub(folder: Path, x_mm: float) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / 'face.ngc').write_text(f'o<face> sub\nG0 X{x_mm} Y#1\no<face> endsub\nM2\n')


def _first_x_mm(program) -> float:
    return round(program.moves[0].end[0] * 1000.0, 9)


def test_a_subroutine_on_the_search_path_is_found(tmp_path):
    prog = tmp_path / 'job' / 'main.ngc'
    prog.parent.mkdir()
    prog.write_text(MAIN)
    with pytest.raises(GcodeError):                  # not beside the program, no path
        load_gcode(prog)
    _sub(tmp_path / 'lib', 7.0)
    program = load_gcode(prog, search_path=[tmp_path / 'lib'])
    assert _first_x_mm(program) == 7.0 and program.moves[0].end[1] == pytest.approx(0.005)


def test_the_programs_folder_comes_first_then_the_path_in_order(tmp_path):
    prog = tmp_path / 'job' / 'main.ngc'
    _sub(tmp_path / 'a', 1.0)
    _sub(tmp_path / 'b', 2.0)
    prog.parent.mkdir()
    prog.write_text(MAIN)
    assert _first_x_mm(load_gcode(prog, search_path=[tmp_path / 'a', tmp_path / 'b'])) == 1.0
    assert _first_x_mm(load_gcode(prog, search_path=[tmp_path / 'b', tmp_path / 'a'])) == 2.0
    _sub(prog.parent, 3.0)
    assert _first_x_mm(load_gcode(prog, search_path=[tmp_path / 'a'])) == 3.0


def test_a_missing_directory_is_a_config_error(tmp_path):
    (tmp_path / 'file').write_text('')
    cases = ((tmp_path / 'nope', 'does not exist'), (tmp_path / 'file', 'is not a directory'))
    for bad, what in cases:
        with pytest.raises(ConfigError) as err:
            parse_gcode('G0 X1\n', search_path=[bad])
        assert err.value.key == 'search_path' and what in str(err.value)


def test_machine_config_key_is_relative_to_the_config_file(tmp_path):
    _sub(tmp_path / 'cfg' / 'subs', 4.0)
    settings = gcode_from_dict({'subroutine_path': ['subs']},
                               file=str(tmp_path / 'cfg' / 'm.yaml'))
    assert settings.subroutine_path == (str(tmp_path / 'cfg' / 'subs'),)
    assert gcode_to_dict(settings)['subroutine_path'] == [str(tmp_path / 'cfg' / 'subs')]
    prog = tmp_path / 'main.ngc'
    prog.write_text(MAIN)
    assert _first_x_mm(load_gcode(prog, search_path=settings.subroutine_path)) == 4.0


@pytest.mark.parametrize('value, key, words', [
    (['missing'], 'gcode.subroutine_path[0]', 'does not exist'),
    ([''], 'gcode.subroutine_path[0]', 'expected a directory name'),
    ([3], 'gcode.subroutine_path[0]', 'expected a directory name'),
    ({'a': 1}, 'gcode.subroutine_path', 'expected a list of directories'),
])
def test_bad_config_entries_name_the_key(tmp_path, value, key, words):
    with pytest.raises(ConfigError) as err:
        gcode_from_dict({'subroutine_path': value}, file=str(tmp_path / 'm.yaml'))
    assert err.value.key == key and words in str(err.value)


@pytest.mark.parametrize('key', ['strict_tools', 'allow_no_feed'])
def test_flags_in_the_config_are_booleans_and_round_trip(tmp_path, key):
    settings = gcode_from_dict({key: True}, file='m.yaml')
    assert getattr(settings, key) is True
    assert gcode_from_dict(gcode_to_dict(settings), file='m.yaml') == settings
    with pytest.raises(ConfigError) as err:
        gcode_from_dict({key: 'yes'}, file='m.yaml')
    assert err.value.key == f'gcode.{key}'


def test_machine_file_carries_the_reading_options_to_gcode_keywords(tmp_path):
    from feed_axis_energy.machine import load_machine, machine_to_dict
    root = Path(__file__).resolve().parents[2]
    d = machine_to_dict(load_machine(root / 'config' / 'three_axis_mill.yaml'))
    d['gcode'].update(strict_tools=True, allow_no_feed=True, subroutine_path=['lib'])
    (tmp_path / 'lib').mkdir()
    path = tmp_path / 'm.yaml'
    path.write_text(yaml.safe_dump(d))
    kw = load_machine(path).gcode_keywords()
    assert kw['strict_tools'] is True and kw['allow_no_feed'] is True
    assert kw['search_path'] == (str(tmp_path / 'lib'),)
