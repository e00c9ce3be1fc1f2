"""Trajectory CSV files as the motion source of ``simulate``."""
from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.cli import main
from feed_axis_energy.errors import DataError
from feed_axis_energy.sim.trajcsv import load_trajectory_csv


def _write(path: Path, header: str, rows: list[str]) -> Path:
    path.write_text(header + '\n' + '\n'.join(rows) + '\n')
    return path


def test_units_are_converted_and_velocity_differentiated(tmp_path: Path) -> None:
    # 100 mm/s in X and 50 mm/min in Y, time in ms.
    rows = [f'{i},{0.1 * i:.6f},{50.0 * i / 60000.0:.9f}' for i in range(0, 1001)]
    f = _write(tmp_path / 'traj.csv', 'time [ms],X [mm],Y [mm]', rows)
    m = load_trajectory_csv(f, axes=('X', 'Y'))
    assert m.axes == ('X', 'Y') and m.t[-1] == pytest.approx(1.0)
    assert_allclose(m.pos[-1], [0.1, 50e-3 / 60.0], rtol=1e-6)
    assert_allclose(m.vel[:, 0], 0.1, rtol=1e-6)
    assert_allclose(m.vel[:, 1], 50e-3 / 60.0, rtol=1e-5)
    assert_allclose(m.acc, 0.0, atol=1e-6)


def test_measured_velocity_columns_are_used(tmp_path: Path) -> None:
    rows = [f'{0.1 * i:.1f},{round(5.0 * (0.1 * i) ** 2)},{10.0 * 0.1 * i:.3f}'
            for i in range(11)]
    f = _write(tmp_path / 'traj.csv', 'time [s],X [mm],X_vel [mm/s]', rows)
    m = load_trajectory_csv(f, axes=('X',))
    assert_allclose(m.vel[:, 0], 0.001 * np.arange(11), rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize('header,rows,column,row,text', [
    ('time [s],X', ['0,0'], 'X', None, r'NAME \[UNIT\]'),
    ('time [s],X [furlong]', ['0,0', '1,1'], 'X', None, "unit 'furlong'"),
    ('time [s],Y [mm]', ['0,0', '1,1'], 'Y', None, 'unknown column'),
    ('X [mm]', ['0', '1'], '', None, 'no time column'),
    ('time [s],X [mm]', ['0,0', '1,1', '1,2'], 'time', 3, 'not strictly increasing'),
    ('time [s],X [mm]', ['0,0', '1,abc'], 'X', 2, "'abc' is not a number"),
])
def test_bad_files_name_column_and_row(tmp_path: Path, header: str, rows: list[str],
                                       column: str, row, text: str) -> None:
    f = _write(tmp_path / 'bad.csv', header, rows)
    with pytest.raises(DataError, match=text) as err:
        load_trajectory_csv(f, axes=('X',))
    assert err.value.file == str(f)
    assert err.value.column == column
    assert err.value.row == row


def test_simulate_accepts_a_trajectory_csv(tmp_path: Path, capsys) -> None:
    import json
    # Constant 200 mm/s for 2 s: the power is the loss power of eq. (3) by hand,
    # P = 0.2505 * 200^1.3471 W, and the energy P * 2 s (the demonstrator's loss function).
    rows = [f'{i},{0.2 * i:.6f}' for i in range(0, 2001)]
    f = _write(tmp_path / 'traj.csv', 'time [ms],X [mm]', rows)
    assert main(['simulate', str(f), '--json', '--quiet']) == 0
    summary = json.loads(capsys.readouterr().out)
    p = 0.2505 * 200.0 ** 1.3471
    assert_allclose(summary['energy_j']['total'], 2.0 * p, rtol=1e-6)
    assert summary['top_blocks'] == []
