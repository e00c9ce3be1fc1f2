"""The KIT wbk DMC 60H air cut: a real drive trace in current (skipped without ../shared).

What is checked is what the data can say without the machine's masses: the sign convention
of each axis's current (X and Y count against the model, which the tool must find), the
holding current of the vertical Y, and that the model fitted on the first half of the record
predicts the held-out second half better than the issue's anchor (a 4-parameter regression on
the trace's own kinematics, computed here from the file).
"""
import csv
import dataclasses
import json
from pathlib import Path

import must_run
import numpy as np
import pytest

from feed_axis_energy.cli import main
from feed_axis_energy.measured.compare import compare_campaign
from feed_axis_energy.measured.manifest import load_campaign

REPO = Path(__file__).resolve().parents[2]
MANIFEST = REPO / 'config' / 'campaigns' / 'kit_dmc60h.yaml'
DATA = (REPO.parent / 'shared' / 'data' / 'kit-dmc60h').resolve()

pytestmark = must_run.skipif(
    'shared', not (DATA / 'I40_St_Val_Air_1_alldata_allcurrent.csv').exists(),
    f'KIT DMC 60H data not found at {DATA} (clone the repository next to shared/)')


def test_sign_convention_of_x_and_y_is_found():
    campaign = load_campaign(MANIFEST)
    spec = campaign.runs[0]
    assert spec.instrument.invert == ('X', 'Y')
    # without the manifest's invert, the tool reports exactly the two axes it names
    raw = dataclasses.replace(spec, instrument=dataclasses.replace(spec.instrument, invert=()))
    result = compare_campaign(dataclasses.replace(campaign, runs=(raw,)))
    flagged = sorted(w.split(': ')[1] for w in result.sign_warnings)
    assert flagged == ['X', 'Y']
    run = compare_campaign(campaign, runs=['val_air_1']).runs[0]
    assert not run.sign_warnings
    # the guessed config has no friction: the correlation is the inertia's and gravity's
    assert all(run.signal_metrics[a].correlation > 0.3 for a in ('X', 'Y', 'Z'))
    assert run.offset_used_s == pytest.approx(0.0, abs=0.02)     # motion from the same record


def _anchor_r2() -> dict[str, float]:
    """The issue's anchor, computed here from the file alone: per axis a least-squares fit of
    the current on (1, a, v, sgn(v) with a 0.1 mm/s dead band) over the first half of the
    rows, its R^2 on the second half."""
    with (DATA / 'I40_St_Val_Air_1_alldata_allcurrent.csv').open(newline='') as fh:
        rows = list(csv.reader(fh))
    head, table = rows[0], np.array(rows[1:], dtype=float)
    col = {name: table[:, i] for i, name in enumerate(head)}
    half = table.shape[0] // 2
    out = {}
    for axis in 'xyz':
        i, v, a = col[f'curr_{axis}'], col[f'v_{axis}'], col[f'a_{axis}']
        sgn = np.where(np.abs(v) > 0.1, np.sign(v), 0.0)
        x = np.column_stack([np.ones_like(v), a, v, sgn])
        coef, *_ = np.linalg.lstsq(x[:half], i[:half], rcond=None)
        res = i[half:] - x[half:] @ coef
        out[axis.upper()] = 1.0 - float(res @ res) / float(
            np.sum((i[half:] - i[half:].mean()) ** 2))
    return out


def test_held_out_half_beats_the_anchor(tmp_path, capsys):
    out = tmp_path / 'fitted.yaml'
    # fit-loss takes the calibrate run: the first half of the record (window)
    assert main(['fit-loss', str(MANIFEST), '--method', 'samples', '--fit-kt',
                 '--fit-counterbalance', '--json', '--out-machine', str(out)]) == 0
    doc = json.loads(capsys.readouterr().out)
    fits = doc['fits']
    for axis in ('X', 'Y', 'Z'):
        f = fits[axis]
        assert f['status'] == 'ok' and f['torque_per_unit_fitted']
        assert f['r2'] > 0.95, (axis, f['r2'])
        assert f['standstill_hold_n'] > 0.0
    # gravity on Y: the vertical axis's weight is fitted (a counterbalance of the guessed mass)
    assert fits['Y']['counterbalance_n'] > 0.0 and fits['X']['counterbalance_n'] is None
    assert main(['compare', str(MANIFEST), '--machine', str(out), '--role', 'validate',
                 '--json', '--quiet']) == 0
    run = json.loads(capsys.readouterr().out)['runs']
    assert [r['name'] for r in run] == ['val_air_1_second']
    q = run[0]['quantity']
    anchor = _anchor_r2()
    assert anchor == pytest.approx({'X': 0.894, 'Y': 0.886, 'Z': 0.969}, abs=0.001)
    for axis in ('X', 'Y', 'Z'):
        assert q['metrics'][axis]['r2'] > anchor[axis] + 0.02, (axis, q['metrics'][axis])
    # Y holds about -5.4 A at rest (README of the data): the fitted model predicts it
    assert abs(q['metrics']['Y']['bias_a']) < 0.1
    assert q['torque_per_unit']['Y'] == pytest.approx(fits['Y']['torque_per_unit'])
