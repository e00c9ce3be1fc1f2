"""The moves of simulate's first pass, kept in an unnamed temporary file and read back."""
import json
import math
import os
from pathlib import Path
import tempfile

import pytest

from feed_axis_energy.cli import main
from feed_axis_energy.core import movespool
from feed_axis_energy.core.errors import PlanningError
from feed_axis_energy.core.gcode import iter_moves
from feed_axis_energy.core.movespool import MoveSpool
from feed_axis_energy.core.program import make_move, Move, MoveKind

ROOT = Path(__file__).resolve().parents[2]

# every field away from its default somewhere, and the values a naive encoding would lose:
# None centres/sweeps, -0.0, inf feeds, huge lines and turns, other planes, booleans
MOVES = [
    make_move(MoveKind.RAPID, 1, (0.0, 0.0, 0.0), (0.1, -0.0, 5e-3), length_m=0.1),
    make_move(MoveKind.LINEAR, 2, (0.1, -0.0, 5e-3), (0.2, 0.1, 5e-3), feed_m_s=0.02,
              exact_stop=True, length_m=math.hypot(0.1, 0.1)),
    make_move(MoveKind.ARC_CCW, 3, (0.2, 0.1, 5e-3), (0.2, 0.3, 5e-3), feed_m_s=0.02,
              center=(0.2, 0.2, 5e-3), length_m=math.pi * 0.1, sweep_rad=math.pi),
    make_move(MoveKind.ARC_CW, 4, (0.2, 0.3, 5e-3), (0.2, 0.3, 6e-3), feed_m_s=0.01,
              center=(0.25, 0.3, 5e-3), plane=18, turns=3, length_m=1.0),
    make_move(MoveKind.DWELL, 5, (0.2, 0.3, 6e-3), (0.2, 0.3, 6e-3), dwell_s=604800.0),
    make_move(MoveKind.LINEAR, 6, (0.2, 0.3, 6e-3), (0.2, 0.3, -0.01), feed_m_s=0.005,
              tap_return=True, length_m=0.016),
    make_move(MoveKind.LINEAR, 2**40, (0.2, 0.3, -0.01), (0.2, 0.3, -0.01),
              feed_m_s=1e-300, dwell_s=-0.0, turns=2**40),
    make_move(MoveKind.STOP, 8, (0.2, 0.3, -0.01), (0.2, 0.3, -0.01)),
]


def _same(a: Move, b: Move) -> None:
    assert a == b
    assert repr(a) == repr(b)
    for name in Move.__dataclass_fields__:
        x, y = getattr(a, name), getattr(b, name)
        assert type(x) is type(y), name
        if isinstance(x, float):
            assert math.copysign(1.0, x) == math.copysign(1.0, y), name


def test_round_trip_keeps_every_field_and_type(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(movespool, 'BATCH_MOVES', 3)        # batches end inside the list
    monkeypatch.setattr(tempfile, 'tempdir', str(tmp_path))
    with MoveSpool(file='p.nc') as spool:
        passed = list(spool.record(iter(MOVES)))
        assert passed == MOVES and all(a is b for a, b in zip(passed, MOVES))
        assert spool.count == len(MOVES)
        assert os.listdir(tmp_path) == []       # the temporary file has no name
        for _ in range(2):                      # read back any number of times
            back = list(spool)
            assert len(back) == len(MOVES)
            for a, b in zip(MOVES, back):
                _same(a, b)


def test_parsed_program_round_trip(tmp_path) -> None:
    program = ROOT / 'config' / 'programs'
    path = sorted(program.glob('*.nc'))[0]
    moves = list(iter_moves(path))
    assert moves
    with MoveSpool(file=str(path)) as spool:
        assert list(spool.record(moves)) == moves
        for a, b in zip(moves, spool):
            _same(a, b)


def test_read_before_written_is_refused() -> None:
    spool = MoveSpool()
    with pytest.raises(RuntimeError):
        list(spool)


def test_unwritable_temporary_directory_names_the_place(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(tempfile, 'tempdir', str(tmp_path / 'missing'))
    with pytest.raises(PlanningError) as info:
        list(MoveSpool(file='p.nc').record(iter(MOVES)))
    text = str(info.value)
    assert text.startswith('p.nc: ') and 'missing' in text and 'TMPDIR' in text


def _program(axes: int) -> str:
    lines = ['G21 G90 G17 G64', 'G0 X0' + (' Y0 Z5' if axes == 3 else ''), 'G4 P0.25']
    for k in range(300):
        y = f' Y{3 * math.sin(k / 9):.4f}' if axes == 3 else ''
        lines.append(f'G1 X{k * 0.7 + (k % 3) * 0.05:.3f}{y} F{900 + (k % 7) * 100}')
    if axes == 3:
        lines += ['G1 X210 Y0', 'G2 X230 Y0 I10 J0', 'G3 X250 Y0 R10', 'G0 Z5']
    lines += ['G4 P2', 'G0 X0', 'M2']
    return '\n'.join(lines) + '\n'


@pytest.mark.parametrize('machine,axes', [('demonstrator.yaml', 1),
                                          ('three_axis_mill.yaml', 3)])
def test_simulate_two_passes_equal_one_pass(tmp_path, capsys, machine, axes) -> None:
    """--max-samples plans first and simulates the spooled moves: the summary is the one
    pass's, to the bit."""
    prog = tmp_path / 'p.nc'
    prog.write_text(_program(axes))
    base = ['simulate', str(prog), '--machine', str(ROOT / 'config' / machine), '--json',
            '--quiet']
    out = []
    for extra in ([], ['--max-samples', '100000000']):
        assert main(base + extra) == 0
        out.append(json.loads(capsys.readouterr().out))
    assert out[0]['samples'] > 10_000
    assert out[0] == out[1]
