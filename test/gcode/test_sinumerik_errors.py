"""Bad Sinumerik input: our error type naming file, line, column and the text; refusals of
what cannot be simulated, each place listed by ``check``."""
from __future__ import annotations

import json
from pathlib import Path
import random
import subprocess
import sys

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode import iter_moves, parse_gcode
from feed_axis_energy.gcode.siemens import reader

REPO = Path(__file__).resolve().parents[2]


def refused(text: str, **kw) -> GcodeError:
    with pytest.raises(GcodeError) as info:
        parse_gcode(text, dialect='sinumerik', file='P.MPF', **kw)
    return info.value


@pytest.mark.parametrize('text, line, column, message, near', [
    ('G0 X0\nFOOBAR X1\n', 2, 1, "unknown keyword or address 'FOOBAR'", 'FOOBAR'),
    ('G0 X0\nFOOBAR\n', 2, 1, "unknown keyword or subprogram 'FOOBAR'", 'FOOBAR'),
    ('R1=1\nIF R1==1\nG1 X1\n', 2, 1, 'IF without ENDIF', 'IF'),
    ('G1 X1\n  ENDIF\n', 2, 3, 'ENDIF without a matching IF', 'ENDIF'),
    ('WHILE R1<2\nR1=R1+1\nENDFOR\n', 3, 1, 'ENDFOR without a matching FOR', 'ENDFOR'),
    ('G0 X0\nGOTOF NOWHERE\nNOWHERE_B:\n', 2, 7, 'no label NOWHERE after this line',
     'NOWHERE'),
    ('BACK:\nIF R1==0 GOTOF BACK\n', 2, 16, 'no label BACK after this line', 'BACK'),
    ('TRANS X=ABC\n', 1, 9, "unknown variable 'ABC'", 'ABC'),
    ('ROT Z"45"\n', 1, 6, 'expected a number', '"45"'),
    ('G0 X0 Y0\nPOCKET3(100,0,2,-10,69,45,6,53,53,28,4)\n', 2, 1,
     'cycle POCKET3 cannot be simulated', 'POCKET3'),
    ('G0 X0\nN20 CYCLE800(1,"TC1",0,57,0,0,0,30,0,0,0,0,0,-1)\n', 2, 5,
     'cycle CYCLE800 cannot be simulated', 'CYCLE800'),
    ('G1 X10 ANG=30 F100\n', 1, 8, 'ANG= (contour definition', 'ANG=30'),
    ('G1 X=$AA_IW[X]\n', 1, 6, 'system variable $AA_IW is not simulated', '$AA_IW'),
    ('G0 X0\nG2 X10 Y10 CR=2 F100\n', 2, 12, 'CR=2 is shorter than half the chord', 'CR=2'),
    ('DEF REAL X\n', 1, 10, 'X is an address or keyword', 'X'),
    ('R1=1/0\n', 1, 5, 'division by zero', '/0'),
    ('G0 X0\n$P_UIFR[1]=CTRANS(X,10)\n', 2, 1, 'system variable $P_UIFR is not simulated',
     '$P_UIFR'),
    ('AROT X30\nG2 X10 Y0 CR=5 F100\n', 2, 4, 'rotates it out of the working plane', 'X10'),
    ('G0 X0\nCYCLE81(10, 0, 2, 5)\n', 2, 1, 'final depth (5) is not below', 'CYCLE81'),
    ('G0 X0\nCYCLE81(100,0,1,1.5,,0,10,1,11)\n', 2, 1, 'parameter 7 (10.0) is not simulated',
     'CYCLE81'),
])
def test_bad_input_names_the_place(text, line, column, message, near):
    err = refused(text)
    assert err.file == 'P.MPF'
    assert (err.line, err.column) == (line, column), str(err)
    assert message in err.reason, str(err)
    assert err.text.startswith(near), str(err)


def test_recursive_subprogram_is_bounded(tmp_path: Path):
    (tmp_path / 'AGAIN.SPF').write_text('G91 G1 X1 F100\nAGAIN\nM17\n')
    main = tmp_path / 'MAIN.MPF'
    main.write_text('G1 X0 F100\nAGAIN\nM30\n')
    with pytest.raises(GcodeError, match='16 levels deep') as info:
        list(iter_moves(main))
    assert info.value.file.endswith('AGAIN.SPF') and info.value.line == 2


def test_missing_subprogram_file_names_the_directory(tmp_path: Path):
    main = tmp_path / 'MAIN.MPF'
    main.write_text('G1 X0 F100\nL200\nM30\n')
    with pytest.raises(GcodeError, match=r"subprogram 'L200'.*L200\.SPF") as info:
        list(iter_moves(main))
    assert (info.value.line, info.value.column) == (2, 1)


def test_proc_with_too_many_arguments(tmp_path: Path):
    (tmp_path / 'TWO.SPF').write_text('PROC TWO(REAL A_1, REAL B_1)\nG1 X=A_1 Y=B_1\nRET\n')
    main = tmp_path / 'MAIN.MPF'
    main.write_text('F100\nTWO(1, 2, 3)\nM30\n')
    with pytest.raises(GcodeError, match='takes 2 arguments, got 3'):
        list(iter_moves(main))


def test_endless_loop_stops_with_an_error(monkeypatch):
    monkeypatch.setattr(reader, 'MAX_LOOP_PASSES', 1000)    # the limit, not its size
    with pytest.raises(GcodeError, match='more than 1000 times') as info:
        parse_gcode('LOOP\nR1=R1+1\nENDLOOP\n', dialect='sinumerik')
    assert info.value.line == 3


def test_check_lists_every_refused_place(tmp_path: Path):
    prog = tmp_path / 'REFUSE.MPF'
    prog.write_text('G0 X0 Y0 Z10\n'
                    'POCKET4(100,0,2,-16,27,53,53,2.5)\n'       # line 2
                    'G1 X10 F100\n'
                    'CYCLE800(1,"TC1",0,57)\n'                   # line 4
                    'LAB: SLOT1(1,2,3)\n'                        # line 5
                    'REPEATB LAB P2\n'                           # the same place again
                    'G1 X20 RND=2\n'                             # line 7
                    'M30\n')
    out = subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'check', '--json',
                          '--quiet', str(prog)], capture_output=True, text=True, cwd=REPO,
                         timeout=120)
    assert out.returncode == 1, out.stderr
    doc = json.loads(out.stdout)
    errors = doc['programs'][0]['errors']
    assert [(e['line'], e['column']) for e in errors] == [(2, 1), (4, 1), (5, 6), (7, 8)]
    assert 'POCKET4' in errors[0]['message'] and 'CYCLE800' in errors[1]['message']
    assert 'Traceback' not in out.stderr


@pytest.mark.parametrize('text, message', [
    ('R1=' + '(' * 500 + '1' + ')' * 500 + '\n', 'nested more than 32 deep'),
    ('R1=' + '-' * 500 + '1\n', 'nested more than 32 deep'),
    ('GOTOF INBODY\nFOR R1=1 TO 3\nINBODY:\nENDFOR\n', 'ENDFOR reached without its FOR'),
    ('R1=1EX400\n', 'out of range'),
    ('G4 F-1\n', 'negative dwell'),
])
def test_limits_of_the_reader(text, message):
    assert message in refused(text).reason


# Token soup: random lines of Sinumerik words, keywords and operators. Whatever they make, the
# answer is a program or a GcodeError, never another exception.
_TOKENS = [
    'G0', 'G1', 'G2', 'G3', 'G4', 'G17', 'G18', 'G90', 'G91', 'G110', 'G111', 'G112', 'G53',
    'G57', 'G505', 'G70', 'G700', 'G41', 'G40', 'X10', 'Y-5', 'Z=R1', 'X=AC(3)', 'Y=IC(-2)',
    'I5', 'J=AC(2)', 'CR=5', 'CR=-3', 'AP=30', 'RP=4', 'CIP', 'I1=3', 'J1=4', 'CT', 'TURN=1',
    'F100', 'F=R2*3', 'S1000', 'M3', 'M30', 'M17', 'R1=', 'R2=', '5', '(', '(R1+2)', ')', '*',
    '-', '/', 'DIV', '==', 'IF', 'ELSE', 'ENDIF', 'WHILE', 'ENDWHILE', 'FOR', 'TO', 'ENDFOR',
    'REPEAT', 'UNTIL', 'LOOP', 'ENDLOOP', 'GOTOF', 'GOTOB', 'LBL', 'LBL:', 'DEF', 'REAL',
    'VAR1', 'VAR1=', 'TRANS', 'ATRANS', 'ROT', 'AROT', 'SCALE', 'MIRROR', 'RPL=45', 'SUPA',
    'L100', 'P2', 'CALL', '"SUB"', 'MCALL', 'CYCLE81(10,0,1,-5)', 'HOLES1(0,0,0,5,5,3)',
    'CYCLE83(10,0,1,-20,,-5,,1,0,0,1,1)', 'POCKET3(1)', 'MSG("x")', 'T="A"', 'D1', ',', ';c',
    '$AA', 'SQRT(', '1EX400', '.', 'N10', '/', '%', 'RET', 'PROC', 'B0']


@pytest.mark.parametrize('seed', range(4))
def test_token_soup_gives_a_program_or_our_error(seed):
    rng = random.Random(seed)
    for _ in range(150):
        text = '\n'.join(' '.join(rng.choice(_TOKENS) for _ in range(rng.randint(1, 6)))
                         for _ in range(rng.randint(1, 12))) + '\n'
        try:
            parse_gcode(text, dialect='sinumerik', ignore_axes=['B'])
        except GcodeError:
            pass


def test_check_with_dialect_option_on_a_plain_name(tmp_path: Path):
    prog = tmp_path / 'part.nc'           # nothing in the name or text says Sinumerik
    prog.write_text('G0 X0 Y0 Z5\nN10 CYCLE800(1,"TC1",0,57)\nG1 X=AC(10) F100\n'
                    'N20 POCKET4(1,2)\nM30\n')
    cmd = [sys.executable, '-m', 'feed_axis_energy', 'check', '--json', '--quiet', str(prog)]
    plain = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, timeout=120)
    siemens = subprocess.run(cmd + ['--dialect', 'sinumerik'], capture_output=True, text=True,
                             cwd=REPO, timeout=120)
    assert plain.returncode == siemens.returncode == 1
    errors = json.loads(siemens.stdout)['programs'][0]['errors']
    assert [(e['line'], e['column'], e['text'].split('(')[0]) for e in errors] == [
        (2, 5, 'CYCLE800'), (4, 5, 'POCKET4')]
    assert 'Traceback' not in siemens.stderr + plain.stderr


def test_loop_limit_is_per_run_of_a_loop(monkeypatch):
    monkeypatch.setattr(reader, 'MAX_LOOP_PASSES', 50)
    # an inner WHILE of 40 passes run 30 times: 1200 passes in all, each run within 50
    prog = parse_gcode('FOR R1=1 TO 30\nR2=0\nWHILE R2<40\nR2=R2+1\nENDWHILE\nENDFOR\n'
                       'G1 X=R1+R2 F100\nM30\n', dialect='sinumerik')
    assert prog.moves[0].end[0] == pytest.approx(0.071)     # R1 ends at 31, R2 at 40


def test_var_parameters_are_refused(tmp_path: Path):
    (tmp_path / 'BYREF.SPF').write_text('PROC BYREF(VAR REAL OUT_1)\nOUT_1=5\nRET\n')
    main = tmp_path / 'MAIN.MPF'
    main.write_text('DEF REAL HERE\nBYREF(HERE)\nG1 X=HERE F100\nM30\n')
    with pytest.raises(GcodeError, match='VAR parameters .call by reference. of BYREF') as info:
        list(iter_moves(main))
    assert info.value.file.endswith('BYREF.SPF') and (info.value.line, info.value.column) == (
        1, 12)
