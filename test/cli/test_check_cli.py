"""``feed-axis-energy check``: every problem of every program, exit codes, JSON."""
from __future__ import annotations

import json
from pathlib import Path
import subprocess
import sys

import pytest

from feed_axis_energy.cli import main

ROOT = Path(__file__).resolve().parents[2]
MILL = ROOT / 'config' / 'three_axis_mill.yaml'   # X +-600 mm, 30 m/min on X and Y
CONTOUR = ROOT / 'config' / 'programs' / 'three_axis_contour.nc'


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_help_exits_zero_and_documents_the_exit_codes():
    proc = subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'check', '--help'],
                          cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0
    assert 'usage: feed-axis-energy check' in proc.stdout
    assert 'Exit status: 0' in ' '.join(proc.stdout.split())


def test_good_program_exits_zero(capsys):
    assert main(['check', str(CONTOUR), '--machine', str(MILL), '--quiet']) == 0
    out = capsys.readouterr().out
    assert f'{CONTOUR}: ok, 0 warnings' in out
    assert 'checked 1 program on three_axis_mill: 0 with errors' in out


def test_every_program_is_checked_and_any_error_gives_exit_1(tmp_path, capsys):
    bad = _write(tmp_path, 'bad.nc', 'G21 G90\nG1 X10 F100\nG1 X1.2.3\nG1 X2.3.4\nM2\n')
    idle = _write(tmp_path, 'idle.nc', 'G21\n(nothing here)\nM2\n')
    far = _write(tmp_path, 'far.nc', 'G21 G90\nG1 X700 F1000\nG4 P4000\nM2\n')
    rc = main(['check', str(bad), str(idle), str(far), '--machine', str(MILL), '--quiet'])
    out = capsys.readouterr().out
    assert rc == 1
    # Every error of a program is listed with its line and column (checking goes on with
    # the next line), and checking goes on with the next programs.
    assert f"{bad}:3:5: error: bad number '1.2.3'" in out
    assert f"{bad}:4:5: error: bad number '2.3.4'" in out
    assert f'{idle}:0:0: warning: the program never moves the tool' in out
    assert f'{far}:2:0: warning: move goes beyond the X travel (max 600.000 mm)' in out
    assert "near 'G1 X700 F1000'" in out
    assert f'{far}:3:0: warning: dwell of 4000 s is longer than 3600 s' in out
    assert 'checked 3 programs on three_axis_mill: 1 with errors, 2 errors, 3 warnings' in out


def test_warnings_alone_exit_zero_and_the_dwell_threshold_is_an_option(tmp_path, capsys):
    prog = _write(tmp_path, 'dwell.nc', 'G21\nG1 X1 F100\nG4 P5\nM2\n')
    assert main(['check', str(prog), '--machine', str(MILL), '--max-dwell-s', '4']) == 0
    assert 'dwell of 5 s is longer than 4 s' in capsys.readouterr().out
    assert main(['check', str(prog), '--machine', str(MILL)]) == 0
    assert ': warning: ' not in capsys.readouterr().out


def test_json_lists_errors_and_warnings_per_program(tmp_path, capsys):
    bad = _write(tmp_path, 'bad.nc', 'G21\nG5 X1\n')
    far = _write(tmp_path, 'far.nc', 'G21 G90\nG1 X700 F90000\nM2\n')
    rc = main(['check', str(bad), str(far), '--machine', str(MILL), '--json', '--quiet'])
    doc = json.loads(capsys.readouterr().out)
    assert rc == 1
    assert (doc['errors'], doc['warnings']) == (1, 2)
    first, second = doc['programs']
    assert first['ok'] is False and first['summary'] is None
    assert first['errors'][0]['line'] == 2 and first['errors'][0]['column'] == 1
    assert first['errors'][0]['text'] == 'G5'
    assert second['ok'] is True
    assert sorted(w['kind'] for w in second['warnings']) == ['feed', 'travel']
    # Hand figures: 700 mm of feed from the origin, box from 0 to 700 mm on X.
    assert second['summary']['feed_length_m'] == pytest.approx(0.7, rel=1e-12)
    assert second['summary']['bbox_max_m'][0] == pytest.approx(0.7, rel=1e-12)


def test_missing_program_is_an_error_of_that_program(tmp_path, capsys):
    rc = main(['check', str(tmp_path / 'nope.nc'), str(CONTOUR), '--machine', str(MILL),
               '--quiet'])
    out = capsys.readouterr().out
    assert rc == 1
    assert f'{tmp_path / "nope.nc"}:0:0: error: cannot read the program' in out
    assert f'{CONTOUR}: ok' in out


@pytest.mark.parametrize('argv', [
    ['check'],                                     # no program
    ['check', 'x.nc', '--max-dwell-s', 'nan'],
    ['check', 'x.nc', '--max-dwell-s', '-1'],
    ['check', 'x.nc', '--dialect', 'heidenhain'],
    ['check', 'x.nc', '--ignore-axes', 'X'],
])
def test_usage_errors_exit_2(argv):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2


def test_bad_machine_config_exits_1(tmp_path, capsys):
    cfg = _write(tmp_path, 'm.yaml', 'name: x\naxes: 3\n')
    assert main(['check', str(CONTOUR), '--machine', str(cfg)]) == 1
    assert 'error: ' in capsys.readouterr().err


def test_simulate_json_carries_the_warnings(tmp_path, capsys):
    far = _write(tmp_path, 'far.nc', 'G21 G90\nG1 X700 F1000\nG4 P4000\nM2\n')
    assert main(['simulate', str(far), '--machine', str(MILL), '--json', '--quiet',
                 '--rate-hz', '1']) == 0
    captured = capsys.readouterr()
    warnings = json.loads(captured.out)['warnings']
    assert len(warnings) == 2
    assert warnings[0].startswith(f'{far}:2: move goes beyond the X travel')
    assert warnings[1].startswith(f'{far}:3: dwell of 4000 s')
    assert f'warning: {warnings[0]}' in captured.err
    assert main(['simulate', str(CONTOUR), '--machine', str(MILL), '--json', '--quiet',
                 '--rate-hz', '10']) == 0
    assert json.loads(capsys.readouterr().out)['warnings'] == []


def test_dialect_sets_the_unit_of_g4_p(tmp_path, capsys):
    # G4 P4000: 4000 s in LinuxCNC (a warning above 3600 s), 4 s where P is milliseconds.
    prog = _write(tmp_path, 'dwell.nc', 'G21 G90 F100\nG1 X1\nG4 P4000\nM2\n')
    for dialect, dwell, warnings in (('linuxcnc', 4000.0, 1), ('fanuc', 4.0, 0)):
        assert main(['check', str(prog), '--machine', str(MILL), '--dialect', dialect,
                     '--json']) == 0
        doc = json.loads(capsys.readouterr().out)
        assert doc['programs'][0]['summary']['dwell_s'] == pytest.approx(dwell, rel=1e-12)
        assert doc['warnings'] == warnings


def test_tool_option_fills_the_tool_table(tmp_path, capsys):
    prog = _write(tmp_path, 'tool.nc', 'G21 G90 F100\nG43 H3 G0 Z10\nM2\n')
    assert main(['check', str(prog), '--machine', str(MILL), '--json', '--strict-tools']) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc['programs'][0]['errors'][0]['line'] == 2
    # without --strict-tools: tool 3 has length 0 (Z10 stays Z10) and one warning
    assert main(['check', str(prog), '--machine', str(MILL), '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [w['line'] for w in doc['programs'][0]['warnings'] if 'tool 3' in w['message']] \
        == [2]
    assert doc['programs'][0]['summary']['final_position_m'][2] == pytest.approx(0.01)
    assert main(['check', str(prog), '--machine', str(MILL), '--tool', '3:2:40', '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    # G43 H3 with a 40 mm tool: Z10 in the program is Z 50 mm in machine coordinates.
    assert doc['programs'][0]['summary']['final_position_m'][2] == pytest.approx(0.05)


def test_parser_warnings_are_listed_with_their_line_and_text(tmp_path, capsys):
    prog = _write(tmp_path, 'tail.nc', 'G21 G90\nG1 X1 F100\nM2\nG1 X5\n')
    assert main(['check', str(prog), '--machine', str(MILL), '--quiet']) == 0
    out = capsys.readouterr().out
    assert f"{prog}:4:0: warning: lines after the end of the program (line 3) are ignored " \
           f"near 'G1 X5'" in out


def test_rotary_axis_is_an_error_unless_ignored(tmp_path, capsys):
    prog = _write(tmp_path, 'rot.nc', 'G21 G90 F100\nG1 X10 A90\nM2\n')
    assert main(['check', str(prog), '--machine', str(MILL), '--quiet']) == 1
    assert f'{prog}:2:' in capsys.readouterr().out
    assert main(['check', str(prog), '--machine', str(MILL), '--ignore-axes', 'A',
                 '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc['warnings'] == 1 and doc['programs'][0]['warnings'][0]['line'] == 2
    assert doc['programs'][0]['summary']['feed_length_m'] == pytest.approx(0.01)


def test_errors_and_warnings_before_and_after_an_error_are_all_listed(tmp_path, capsys):
    prog = _write(tmp_path, 'many.nc',
                  'G21 G90\nG4 P4000\nG1 X1 F100 Q3\nG1 X700 F1000\n#1=[2+]\n'
                  'G38.2 Z-1 F10\nG1 X2 A5\nG4 P5000\nM2\n')
    rc = main(['check', str(prog), '--machine', str(MILL), '--quiet', '--json'])
    doc = json.loads(capsys.readouterr().out)
    assert rc == 1
    (program,) = doc['programs']
    assert program['ok'] is False and program['summary'] is None
    # Errors of the interpreter (lines 3, 7) and of the reader (line 5), in line order.
    assert [(e['line'], e['column']) for e in program['errors']] == [(3, 12), (5, 7), (7, 7)]
    # Warnings from both sides of the errors: the parser's (probing, line 6) and the
    # sanity checks' (dwells on lines 2 and 8, travel on line 4).
    kinds = sorted((w['line'], w['kind']) for w in program['warnings'])
    assert kinds == [(2, 'dwell'), (4, 'travel'), (6, 'parse'), (8, 'dwell')]


def test_checking_stops_after_max_errors(tmp_path, capsys):
    from feed_axis_energy.gcode.check import MAX_ERRORS
    prog = _write(tmp_path, 'bad.nc', 'G21\n' + 'G1 X1.2.3\n' * (MAX_ERRORS + 50) + 'M2\n')
    assert main(['check', str(prog), '--machine', str(MILL), '--quiet', '--json']) == 1
    (program,) = json.loads(capsys.readouterr().out)['programs']
    lines = [e['line'] for e in program['errors']]
    assert lines == list(range(2, MAX_ERRORS + 2))


def test_an_error_in_an_o_word_line_ends_the_check(tmp_path, capsys):
    prog = _write(tmp_path, 'flow.nc',
                  'G21\nG1 X1.2.3 F100\no100 if [1 GT]\nG1 X2\no100 endif\nG1 X3.4.5\nM2\n')
    assert main(['check', str(prog), '--machine', str(MILL), '--quiet', '--json']) == 1
    (program,) = json.loads(capsys.readouterr().out)['programs']
    assert [e['line'] for e in program['errors']] == [2, 3]


def test_simulate_still_stops_at_the_first_error(tmp_path, capsys):
    prog = _write(tmp_path, 'bad.nc', 'G21\nG1 X1.2.3 F100\nG1 X2.3.4\nM2\n')
    assert main(['simulate', str(prog), '--machine', str(MILL), '--quiet']) == 1
    err = capsys.readouterr().err
    assert ':2:' in err and ':3:' not in err
