"""The program-reading options of simulate, check, sweep and batch: ``--strict-tools``,
``--allow-no-feed``, ``--subroutine-path DIR`` and their machine-config keys."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from feed_axis_energy.cli import main

ROOT = Path(__file__).resolve().parents[2]
MILL = ROOT / 'config' / 'three_axis_mill.yaml'
OPTIONS = ('--strict-tools', '--allow-no-feed', '--subroutine-path')
TOOL5 = 'G21 G90\nT5 M6\nG43 H5 G0 Z20\nG1 X20 F3000\nM30\n'      # the mill has no tool 5
NO_FEED = 'G21 G90\nG0 X1 Y1\nG1 X20\nM30\n'
CALLS = 'G21 G90\no<face> call\nM30\n'
FACE = 'o<face> sub\nG1 X10 Y5 F3000\no<face> endsub\nM2\n'


@pytest.mark.parametrize('command', ['simulate', 'check', 'sweep', 'batch'])
def test_help_documents_the_options(command, capsys):
    with pytest.raises(SystemExit) as exc:
        main([command, '--help'])
    assert exc.value.code == 0
    text = ' '.join(capsys.readouterr().out.split())
    for option in OPTIONS:
        assert option in text
    assert 'gcode.strict_tools' in text and 'gcode.allow_no_feed' in text
    assert 'SUBROUTINE_PATH' in text


def _write(folder: Path, name: str, text: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(text)
    return path


def _simulate(capsys, *argv: str):
    rc = main(['simulate', *argv, '--machine', str(MILL), '--quiet', '--json',
               '--rate-hz', '200'])
    out, err = capsys.readouterr()
    return rc, (json.loads(out) if rc == 0 else None), err


def test_simulate_missing_tool_warns_once_and_strict_tools_refuses(tmp_path, capsys):
    prog = _write(tmp_path, 'p.nc', TOOL5)
    rc, doc, _ = _simulate(capsys, str(prog))
    assert rc == 0
    warned = [w for w in doc['warnings'] if 'tool 5 is not in the tool table' in w]
    assert len(warned) == 1 and warned[0].startswith(f'{prog}:3: ')
    rc, _, err = _simulate(capsys, str(prog), '--strict-tools')
    assert rc == 1 and f'{prog}:2:1: ' in err and 'tool 5' in err and 'Traceback' not in err


def test_simulate_refuses_a_feed_move_without_f_unless_allowed(tmp_path, capsys):
    prog = _write(tmp_path, 'p.nc', NO_FEED)
    rc, _, err = _simulate(capsys, str(prog))
    assert rc == 1 and f'{prog}:3:1: ' in err and '--allow-no-feed' in err
    assert 'Traceback' not in err
    rc, doc, _ = _simulate(capsys, str(prog), '--allow-no-feed')
    assert rc == 0 and doc['duration_s'] > 0.0
    assert [w for w in doc['warnings'] if 'no feed rate' in w]


def test_simulate_finds_subroutines_on_the_path_in_order(tmp_path, capsys):
    prog = _write(tmp_path / 'job', 'main.ngc', CALLS)
    _write(tmp_path / 'lib', 'face.ngc', FACE)
    rc, _, err = _simulate(capsys, str(prog))
    assert rc == 1 and 'face' in err
    _write(tmp_path / 'other', 'face.ngc', FACE.replace('X10', 'X40'))
    rc, doc, _ = _simulate(capsys, str(prog), '--subroutine-path', str(tmp_path / 'lib'))
    assert rc == 0 and doc['duration_s'] > 0.0
    # the first directory that has the file wins: X40 is a longer move than X10
    rc, other, _ = _simulate(capsys, str(prog), '--subroutine-path', str(tmp_path / 'other'),
                             '--subroutine-path', str(tmp_path / 'lib'))
    assert rc == 0 and other['duration_s'] > doc['duration_s']


def test_a_missing_subroutine_directory_names_the_option(tmp_path, capsys):
    prog = _write(tmp_path, 'p.nc', 'G21\nG0 X1\nM30\n')
    for command in (['simulate', str(prog), '--machine', str(MILL)],
                    ['check', str(prog), '--machine', str(MILL)],
                    ['batch', str(prog), '--machine', str(MILL)]):
        rc = main(command + ['--quiet', '--subroutine-path', str(tmp_path / 'nope')])
        err = capsys.readouterr().err
        assert rc == 1, command
        assert '--subroutine-path' in err and 'does not exist' in err
        assert 'Traceback' not in err


def test_machine_config_keys_apply_like_the_options(tmp_path, capsys):
    from feed_axis_energy.machine import load_machine, machine_to_dict
    _write(tmp_path / 'cfg' / 'subs', 'face.ngc', FACE)
    d = machine_to_dict(load_machine(MILL))
    d['gcode'].update(strict_tools=True, allow_no_feed=True, subroutine_path=['subs'])
    machine = _write(tmp_path / 'cfg', 'm.yaml', yaml.safe_dump(d))
    argv = ['--machine', str(machine), '--quiet', '--json', '--rate-hz', '200']
    tool5 = _write(tmp_path, 't.nc', TOOL5)
    assert main(['simulate', str(tool5), *argv]) == 1
    assert f'{tool5}:2:1: ' in capsys.readouterr().err
    for text in (NO_FEED, CALLS):
        prog = _write(tmp_path / 'job', 'p.nc', text)
        assert main(['simulate', str(prog), *argv]) == 0
        capsys.readouterr()
    bad = dict(d, gcode=dict(d['gcode'], subroutine_path=['gone']))
    machine = _write(tmp_path / 'cfg', 'bad.yaml', yaml.safe_dump(bad))
    assert main(['simulate', str(tool5), '--machine', str(machine), '--quiet']) == 1
    err = capsys.readouterr().err
    assert 'gcode.subroutine_path[0]' in err and 'does not exist' in err


def test_check_reports_the_missing_tool_and_the_missing_feed(tmp_path, capsys):
    tool5 = _write(tmp_path, 't.nc', TOOL5)
    nofeed = _write(tmp_path, 'f.nc', NO_FEED)
    assert main(['check', str(tool5), '--machine', str(MILL), '--quiet', '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert any('tool 5' in w['message'] for w in doc['programs'][0]['warnings'])
    assert main(['check', str(tool5), str(nofeed), '--machine', str(MILL), '--quiet',
                 '--json', '--strict-tools']) == 1
    doc = json.loads(capsys.readouterr().out)
    # check goes on after an error: tool 5 at its T word and again at its H word
    places = [(e['line'], e['column']) for p in doc['programs'] for e in p['errors']]
    assert places == [(2, 1), (3, 5), (3, 1)]
    assert main(['check', str(nofeed), '--machine', str(MILL), '--quiet',
                 '--allow-no-feed']) == 0
    capsys.readouterr()


def test_batch_and_sweep_jobs_read_programs_with_the_options(tmp_path, capsys):
    prog = _write(tmp_path, 'p.nc', NO_FEED)
    base = ['--machine', str(MILL), '--quiet', '--json', '--rate-hz', '200']
    assert main(['batch', str(prog), *base]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc['failed'] == 1 and '--allow-no-feed' in doc['results'][0]['error']
    assert main(['batch', str(prog), *base, '--allow-no-feed']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc['failed'] == 0
    tool5 = _write(tmp_path, 't.nc', TOOL5)
    assert main(['batch', str(tool5), *base, '--strict-tools']) == 1
    assert 'tool 5' in json.loads(capsys.readouterr().out)['results'][0]['error']
    sweep = ['sweep', str(prog), '--vary', 'load_kg=0,10', *base]
    assert main(sweep) == 1
    capsys.readouterr()
    assert main(sweep + ['--allow-no-feed']) == 0
    capsys.readouterr()
