"""``simulate`` with a rotary axis: the JSON keys, CSV columns and recorded topics carry the
rotary axis as they carry X, Y, Z (contract: README "Rotary axes"); a machine without
the axis keeps refusing the program (or drops the words with ``--ignore-axes``)."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from feed_axis_energy.cli import main
from feed_axis_energy.record import bagio

ROOT = Path(__file__).resolve().parents[2]
FIVE = ROOT / 'config' / 'five_axis_mill.yaml'
THREE = ROOT / 'config' / 'three_axis_mill.yaml'
PROGRAM = 'G21 G90 G94\nG0 X0 Y0 Z0\nG1 X20 C90 F1200\nG1 B30 F3600\nG0 B0 C0\nM2\n'


def _simulate(tmp_path, capsys, machine, *extra):
    prog = tmp_path / 'p.nc'
    prog.write_text(PROGRAM)
    code = main(['simulate', str(prog), '--machine', str(machine), '--json', '--quiet',
                 '--rate-hz', '200', *extra])
    out = capsys.readouterr()
    return code, (json.loads(out.out) if code == 0 else None), out.err


def test_rotary_axes_appear_in_json_csv_and_bag(tmp_path, capsys):
    code, summary, _ = _simulate(tmp_path, capsys, FIVE, '--csv', str(tmp_path / 'c'),
                                 '--out', str(tmp_path / 'bag'), '--report', str(tmp_path / 'r'))
    assert code == 0
    for key in ('energy_j', 'peak_power_w'):
        assert list(summary[key]) == ['X', 'Y', 'Z', 'B', 'C', 'total']
    assert summary['energy_j']['B'] > 0.0 and summary['energy_j']['C'] > 0.0
    assert math.isclose(sum(v for k, v in summary['energy_j'].items() if k != 'total'),
                        summary['energy_j']['total'], rel_tol=1e-12)
    with open(tmp_path / 'c' / 'timeseries.csv', newline='', encoding='utf-8') as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    assert {'C position [rad]', 'C velocity [rad/s]', 'C power [W]', 'C energy [J]',
            'X position [m]', 'X velocity [m/s]'} <= set(header)
    last = dict(zip(header, rows[-1]))
    assert float(last['C position [rad]']) == 0.0          # G0 B0 C0 at the end
    data = np.array(rows[1:], dtype=float)
    # C holds 90 degrees while B turns (line 4): samples sit on it
    assert math.isclose(np.max(data[:, header.index('C position [rad]')]), math.pi / 2,
                        rel_tol=1e-12)
    series = bagio.read_series(tmp_path / 'bag', bagio.TOPIC_SETPOINTS)
    assert series.names == ('X', 'Y', 'Z', 'B', 'C')
    # B reaches 30 degrees between two 5 ms samples (it rests there only at one instant)
    assert math.isclose(np.max(series.positions[:, 3]), math.radians(30.0), abs_tol=1e-6)
    # the report's travel table gives a rotary axis in degrees, a linear one in mm
    html = (tmp_path / 'r' / 'index.html').read_text(encoding='utf-8')
    assert '<td class="num">90.000 °</td>' in html and '<td class="num">20.0 mm</td>' in html
    power = bagio.read_series(tmp_path / 'bag', bagio.TOPIC_POWER)
    assert power.names == ('X', 'Y', 'Z', 'B', 'C', 'total')
    # the summary is by phase (rotary axes included), the recording's samples at 200 Hz
    # approach it as the rate rises: here within 1e-4 (observed 9e-6)
    assert summary['method'] == 'phases'
    assert math.isclose(power.positions[-1, 4], summary['energy_j']['C'], rel_tol=1e-4)


def test_machine_without_the_axis_refuses_then_ignores(tmp_path, capsys):
    code, _, err = _simulate(tmp_path, capsys, THREE)
    assert code != 0
    assert 'p.nc:3:8' in err and 'axis C is not supported' in err and '--ignore-axes C' in err
    assert 'Traceback' not in err
    code, summary, _ = _simulate(tmp_path, capsys, THREE, '--ignore-axes', 'B,C')
    assert code == 0 and list(summary['energy_j']) == ['X', 'Y', 'Z', 'total']
