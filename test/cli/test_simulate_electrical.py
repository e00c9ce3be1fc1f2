"""``simulate`` with declared drives: electrical power beside the mechanical one, everywhere."""
import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from feed_axis_energy.cli import main

ROOT = Path(__file__).resolve().parents[2]
DRIVES = ROOT / 'config' / 'three_axis_mill_drives.yaml'
MILL = ROOT / 'config' / 'three_axis_mill.yaml'
# arcs, a dwell left out of the rows (its samples come back in the export)
PROGRAM = """G21 G90 G94 G17 G64
G0 X0 Y0 Z20
G1 Z-2 F600
G1 X30 Y5 F2400
G2 X40 Y15 I0 J10
G4 P0.5
G3 X30 Y25 I-10 J0
G0 Z40
M30
"""


@pytest.fixture()
def program(tmp_path):
    path = tmp_path / 'p.nc'
    path.write_text(PROGRAM, encoding='utf-8')
    return path


def _json(capsys, *argv):
    assert main(['simulate', *argv, '--json', '--quiet']) == 0
    return json.loads(capsys.readouterr().out)


def test_table_names_the_point_and_adds_up(program, capsys):
    assert main(['simulate', str(program), '--machine', str(DRIVES), '--quiet']) == 0
    out = capsys.readouterr().out
    assert 'electrical energy (declared drives' in out
    assert "the meter's point (supply.measured_at): supply side" in out
    for word in ('motor terminals', 'copper', 'iron', 'converter', 'standby'):
        assert word in out
    top = out[out.index('blocks with the most energy'):].splitlines()
    assert 'supply energy [J]' in top[1]


def test_json_export_and_report_agree(program, tmp_path, capsys):
    out = tmp_path / 'csv'
    report = tmp_path / 'report'
    # --method samples: the summary integrated over the exported samples themselves
    s = _json(capsys, str(program), '--machine', str(DRIVES), '--csv', str(out),
              '--report', str(report), '--method', 'samples')
    e = s['electrical']
    # by phase (the default): the same figures within the samples' discretization error
    phases = _json(capsys, str(program), '--machine', str(DRIVES))['electrical']
    for key in ('motor_energy_j', 'supply_energy_j'):
        assert math.isclose(phases[key]['total'], e[key]['total'], rel_tol=1e-4)
        assert phases[key]['total'] != e[key]['total']
    assert e['measured_at'] == 'supply' and e['energy_j'] == e['supply_energy_j']
    with open(out / 'timeseries.csv', newline='', encoding='utf-8') as fh:
        rows = list(csv.reader(fh))
    head, body = rows[0], np.array(rows[1:], dtype=float)
    col = {name: i for i, name in enumerate(head)}
    assert len(body) == s['samples']
    last = body[-1]
    assert math.isclose(last[col['total supply energy [J]']], e['supply_energy_j']['total'],
                        rel_tol=1e-9)
    assert math.isclose(last[col['total motor energy [J]']], e['motor_energy_j']['total'],
                        rel_tol=1e-9)
    # per sample: the supply total is the axes' supply power plus the cabinet
    axes_sum = sum(body[:, col[f'{a} supply power [W]']] for a in 'XYZ')
    np.testing.assert_allclose(body[:, col['total supply power [W]']],
                               axes_sum + e['cabinet_standby_w'], rtol=1e-12, atol=1e-9)
    # per block: blocks.csv's electrical columns add up to the totals, and the table's
    # top blocks show the supply side
    with open(out / 'blocks.csv', newline='', encoding='utf-8') as fh:
        blocks = list(csv.DictReader(fh))
    for column, key in (('motor energy [J]', 'motor_energy_j'),
                        ('supply energy [J]', 'supply_energy_j')):
        assert math.isclose(math.fsum(float(b[column]) for b in blocks), e[key]['total'],
                            rel_tol=1e-9)
    assert all('supply_energy_j' in b for b in s['top_blocks'])
    with open(out / 'rollups.csv', newline='', encoding='utf-8') as fh:
        rolls = [r for r in csv.DictReader(fh) if r['group'] == 'tool']
    assert math.isclose(math.fsum(float(r['supply energy [J]']) for r in rolls),
                        e['supply_energy_j']['total'], rel_tol=1e-9)
    html = (report / 'index.html').read_text(encoding='utf-8')
    assert 'Electrical energy (declared drives)' in html
    assert 'Electrical energy by cause, supply side' in html


def test_drives_leave_the_mechanical_result_alone(program, tmp_path, capsys):
    # the drives config with the three-axis mill's braking rule: same mechanical summary
    data = yaml.safe_load(DRIVES.read_text(encoding='utf-8'))
    data['braking'] = 'dissipated'
    path = tmp_path / 'm.yaml'
    path.write_text(yaml.safe_dump(data), encoding='utf-8')
    # over samples: the same numbers
    with_drives = _json(capsys, str(program), '--machine', str(path), '--method', 'samples')
    plain = _json(capsys, str(program), '--machine', str(MILL), '--method', 'samples')
    assert 'electrical' not in plain
    for key in ('energy_j', 'peak_power_w', 'energy_by_cause_j', 'loss_energy_j'):
        assert with_drives[key] == plain[key], key
    # by phase (the default): the drives cut the pieces at more points (where the motor
    # power and v change sign), so the mechanical sums agree to the quadrature's error
    with_drives = _json(capsys, str(program), '--machine', str(path))
    plain = _json(capsys, str(program), '--machine', str(MILL))
    assert with_drives['method'] == plain['method'] == 'phases'
    assert 'electrical' in with_drives and 'electrical' not in plain
    for axis, value in plain['energy_j'].items():
        assert math.isclose(with_drives['energy_j'][axis], value, rel_tol=1e-9, abs_tol=1e-9)
    assert math.isclose(with_drives['loss_energy_j'], plain['loss_energy_j'], rel_tol=1e-9)


def test_bad_drive_value_exits_1_naming_the_key(program, tmp_path, capsys):
    data = yaml.safe_load(DRIVES.read_text(encoding='utf-8'))
    data['axes']['Z']['drive']['resistance_ohm'] = -1.0
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(data), encoding='utf-8')
    assert main(['simulate', str(program), '--machine', str(path), '--quiet']) == 1
    err = capsys.readouterr().err
    assert 'axes.Z.drive.resistance_ohm' in err and 'Traceback' not in err


def test_sweep_over_the_winding_resistance_compares_electrical_energy(program, tmp_path,
                                                                      capsys):
    # meter at the motor terminals: copper = 1.5 R (M/kt)^2 is linear in R at the same
    # torque, so the energy is too: E(4) - E(2) = 2 (E(2) - E(1))
    data = yaml.safe_load(DRIVES.read_text(encoding='utf-8'))
    data['supply']['measured_at'] = 'motor'
    path = tmp_path / 'm.yaml'
    path.write_text(yaml.safe_dump(data), encoding='utf-8')
    assert main(['sweep', str(program), '--machine', str(path), '--vary',
                 'axes.*.drive.resistance_ohm=1,2,4', '--json', '--quiet', '--jobs', '1']) == 0
    doc = json.loads(capsys.readouterr().out)
    rows = [r for r in doc['rows'] if not r['baseline']]
    assert [r['energy_point'] for r in rows] == ['motor'] * 3
    e1, e2, e4 = (r['energy_j'] for r in rows)
    assert e1 < e2 < e4
    assert math.isclose(e4 - e2, 2.0 * (e2 - e1), rel_tol=1e-9)
