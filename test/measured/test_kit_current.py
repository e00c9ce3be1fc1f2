"""The KIT wbk DMC 60H air cut: a real drive trace in current (skipped without ../shared).

What is checked is what the data can say without the machine's masses: the sign convention
of each axis's current (X and Y count against the model, which the tool must find), the
holding current of the vertical Y, and that the fitted model explains the moving samples.
"""
import dataclasses
import json
from pathlib import Path

import must_run
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
    run = compare_campaign(campaign).runs[0]
    assert not run.sign_warnings
    # the guessed config has no friction: the correlation is the inertia's and gravity's
    assert all(run.signal_metrics[a].correlation > 0.3 for a in ('X', 'Y', 'Z'))
    assert run.offset_used_s == pytest.approx(0.0, abs=0.02)     # motion from the same record


def test_fitted_kt_explains_the_moving_samples(tmp_path, capsys):
    out = tmp_path / 'fitted.yaml'
    assert main(['fit-loss', str(MANIFEST), '--method', 'samples', '--fit-kt', '--json',
                 '--out-machine', str(out)]) == 0
    fits = json.loads(capsys.readouterr().out)['fits']
    for axis in ('X', 'Y', 'Z'):
        f = fits[axis]
        assert f['status'] == 'ok' and f['torque_per_unit_fitted']
        assert f['r2'] > 0.85, (axis, f['r2'])
    assert main(['compare', str(MANIFEST), '--machine', str(out), '--json', '--quiet']) == 0
    run = json.loads(capsys.readouterr().out)['runs'][0]
    q = run['quantity']
    # Y holds about -5.4 A at rest (README of the data): the fitted model predicts it
    assert abs(q['metrics']['Y']['bias_a']) < 0.1
    assert q['torque_per_unit']['Y'] == pytest.approx(fits['Y']['torque_per_unit'])
