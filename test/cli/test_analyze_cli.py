"""The ``feed-axis-energy analyze`` command on a small virtual-rig campaign."""
from __future__ import annotations

import json
from pathlib import Path
import subprocess
import sys

import pytest

from feed_axis_energy.cli import main
from feed_axis_energy.effects.catalog import get_effect
from feed_axis_energy.identify.design import statestore
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.identify.rig import Instrument, parse_effects
from feed_axis_energy.identify.rig import make_campaign, RigConfig

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def manifest(tmp_path_factory) -> Path:
    cfg = RigConfig(machine=ROOT / 'config' / 'demonstrator.yaml', loads_kg=(0.0, 22.711),
                    feeds_mm_s=(200.0, 400.0), cycles=1,
                    effects=parse_effects('load_friction=mu:0.2'),
                    instrument=Instrument(noise_w=1.0), seed=5)
    return make_campaign(tmp_path_factory.mktemp('rig') / 'rig', cfg)


def test_help_lists_the_options() -> None:
    proc = subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'analyze', '--help'],
                          cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0
    for option in ('--json', '--report', '--out-machine', '--runs', '--quiet', '--holdout',
                   '--min-share', '--noise-w', '--state-memory'):
        assert option in proc.stdout


def test_json_out_machine_and_report(manifest, tmp_path, capsys) -> None:
    out_machine = tmp_path / 'augmented.yaml'
    report = tmp_path / 'report'
    code = main(['analyze', str(manifest), '--json', '--quiet', '--out-machine',
                 str(out_machine), '--report', str(report)])
    assert code == 0
    d = json.loads(capsys.readouterr().out)
    assert [e['id'] for e in d['effects'] if e['id'] != 'time_offset'] == ['load_friction']
    mu = d['effects'][0]['parameters'][0]
    assert mu['name'] == 'mu' and mu['value'] == pytest.approx(0.2, rel=0.05)
    assert d['after']['total']['avg_pct_error_pct'] < 0.5 * d['before']['total'][
        'avg_pct_error_pct']
    assert len(d['before']['runs']) == 4
    m = load_machine(out_machine)
    assert m.effects[0].id == 'load_friction'
    # the rate the analysis simulated at (a power-of-two multiple of the planner's); the
    # augmented machine keeps the declared rate
    declared = load_machine(manifest.parent / 'machine.yaml').planner.rate_hz
    assert d['sim_rate_hz'] / declared in (1, 2, 4, 8)
    assert m.planner.rate_hz == declared
    assert d['out_machine'] == str(out_machine)
    index = Path(d['report'])
    html = index.read_text()
    assert 'load_friction' in html
    # every candidate's fate is in the JSON and the report
    fates = {(c['effect'], c['fate']) for c in d['candidates']}
    assert ('load_friction', 'accepted') in fates
    assert len(d['candidates']) == len({(c['effect'], c['axis']) for c in d['candidates']})
    assert 'Every candidate' in html and 'copper' in html and 'rejected' in html
    for name in ('residual_states.png', 'spectrum.png'):
        assert (report / name).stat().st_size > 1000
    assert len(list(report.glob('*_after.png'))) == 4
    # the augmented config feeds simulate unchanged
    program = manifest.parent / 'programs' / 'f200.nc'
    assert main(['simulate', str(program), '--machine', str(out_machine), '--json']) == 0
    with_effect = json.loads(capsys.readouterr().out)['energy_j']['total']
    assert main(['simulate', str(program), '--machine', str(manifest.parent / 'machine.yaml'),
                 '--json']) == 0
    plain = json.loads(capsys.readouterr().out)['energy_j']['total']
    assert with_effect > plain


def test_tables_and_bad_run_name(manifest, capsys) -> None:
    assert main(['analyze', str(manifest), '--quiet']) == 0
    text = capsys.readouterr().out
    assert 'load_friction@X' in text
    assert 'all held-out runs' in text and 'after' in text
    assert 'every candidate (consistency loop: 1 round(s)):' in text
    assert 'load_friction@X: accepted: round 1: held-out gain' in text
    assert 'copper@X: rejected: ' in text
    assert main(['analyze', str(manifest), '--quiet', '--runs', 'nope']) == 1
    assert 'nope' in capsys.readouterr().err


def test_out_machine_is_removed_when_the_report_fails(manifest, tmp_path, capsys,
                                                      monkeypatch) -> None:
    import feed_axis_energy.report.analyze_report as analyze_report

    def broken(*args, **kwargs):
        raise OSError(28, 'No space left on device (simulated)')

    monkeypatch.setattr(analyze_report, '_spectrum', broken)
    out_machine = tmp_path / 'new' / 'augmented.yaml'
    report = tmp_path / 'report'
    code = main(['analyze', str(manifest), '--quiet', '--out-machine', str(out_machine),
                 '--report', str(report)])
    err = capsys.readouterr().err
    assert code == 1 and '--report' in err and 'No space' in err
    assert list(tmp_path.iterdir()) == []          # neither output, no temporary, no 'new'


def test_an_ambiguous_finding_is_reported_as_one_group(tmp_path, capsys) -> None:
    # iron's power k_h|w| + k_e w² is exactly symmetric coulomb + viscous: one finding with
    # its forms in the text, the JSON and the report, never iron (or coulomb) named alone
    cfg = RigConfig(machine=ROOT / 'config' / 'demonstrator.yaml', loads_kg=(0.0, 22.711),
                    feeds_mm_s=(150.0, 300.0, 450.0), cycles=1,
                    effects=parse_effects('iron=k_h_w_s_rad:0.04,k_e_w_s2_rad2:8e-5'),
                    instrument=Instrument(noise_w=1.0), seed=3)
    manifest = make_campaign(tmp_path / 'rig', cfg)
    report = tmp_path / 'report'
    assert main(['analyze', str(manifest), '--json', '--quiet', '--report', str(report)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert len(d['ambiguous']) == 1
    group = d['ambiguous'][0]
    assert group['selected'] == ['iron@X']
    forms = [f['members'] for f in group['forms']]
    assert ['coulomb@X', 'viscous@X'] in forms
    assert all(f['relative_residual'] <= f['limit'] for f in group['forms'])
    # a form is a physical alternative: its values within the catalog's plausible range
    for f in group['forms']:
        for member, values in f['parameters'].items():
            params = {p.name: p for p in get_effect(member.split('@')[0]).params}
            for name, value in values.items():
                assert params[name].low <= value <= params[name].high, (member, name, value)
    assert group['energy_j'] > 0.0 and group['power_rms_w'] > 0.0
    assert 'iron = ' in group['message'] and 'coulomb + viscous' in group['message']
    fates = {c['effect']: c for c in d['candidates']}
    assert fates['iron']['fate'] == 'accepted' and fates['iron']['group'] == 0
    assert fates['coulomb']['fate'] == 'equivalent' and fates['viscous']['fate'] == 'equivalent'
    assert 'cannot attribute to one effect' in d['message']
    assert 'added iron' not in d['message']
    html = Path(d['report']).read_text()
    assert 'cannot tell which it is' in html and 'coulomb@X + viscous@X' in html
    assert main(['analyze', str(manifest), '--quiet']) == 0
    text = capsys.readouterr().out
    assert 'iron@X (finding 1)' in text
    assert 'ambiguous findings' in text and 'iron@X = coulomb@X + viscous@X' in text


def test_min_share_marks_size_and_the_noise_is_stated(manifest, capsys) -> None:
    # the same effect is added at any --min-share: the threshold only marks its size
    assert main(['analyze', str(manifest), '--json', '--quiet']) == 0
    low = json.loads(capsys.readouterr().out)
    assert main(['analyze', str(manifest), '--json', '--quiet', '--min-share', '90']) == 0
    high = json.loads(capsys.readouterr().out)
    assert [e['id'] for e in low['effects']] == [e['id'] for e in high['effects']]
    friction = [e for e in low['effects'] if e['id'] == 'load_friction'][0]
    # energy of mu*(m_table + m_load)*g*|v| over the campaign, as a share of the measured:
    # a few per cent on this campaign, never more than the whole
    assert 0.01 < friction['energy_share'] < 0.5 and friction['energy_j'] > 0.0
    assert friction['matters'] is True
    assert [e for e in high['effects'] if e['id'] == 'load_friction'][0]['matters'] is False
    assert low['min_share'] == pytest.approx(0.01) and high['min_share'] == pytest.approx(0.9)
    assert 'detected, below 90 % of the energy: load_friction on X' in high['message']
    assert low['offered'] == [] and 'offered' not in low['message']
    noise = low['noise']['X']
    assert noise['method'] in ('white', 'slow')
    assert noise['sigma_w'] == pytest.approx(low['noise_sigma_w']['X'])
    # the rig's 1 W noise plus 1 W quantisation, white
    assert noise['sigma_w'] == pytest.approx((1.0 + 1.0 / 12.0) ** 0.5, rel=0.15)
    assert main(['analyze', str(manifest), '--quiet', '--noise-w', '2.5']) == 0
    text = capsys.readouterr().out
    assert 'noise X: 2.5 W per sample for every test (declared;' in text
    assert 'energy [%]' in text


@pytest.mark.parametrize('args, key', [(['--min-share', '100'], '--min-share'),
                                       (['--min-share', '-1'], '--min-share'),
                                       (['--noise-w', '0'], '--noise-w'),
                                       (['--noise-w', 'nan'], '--noise-w'),
                                       (['--state-memory', '-1'], '--state-memory'),
                                       (['--state-memory', 'nan'], '--state-memory')])
def test_bad_min_share_or_noise_is_refused(manifest, capsys, args, key) -> None:
    assert main(['analyze', str(manifest), '--quiet'] + args) == 1
    assert key in capsys.readouterr().err


def test_state_memory_reaches_the_store_and_keeps_the_result(manifest, capsys,
                                                             monkeypatch) -> None:
    budgets = []
    real = statestore.StateStore.__init__

    def init(self, budget_bytes=statestore.STATE_MEMORY_BYTES):
        budgets.append(budget_bytes)
        real(self, budget_bytes)

    monkeypatch.setattr(statestore.StateStore, '__init__', init)
    assert main(['analyze', str(manifest), '--quiet', '--json']) == 0
    held = json.loads(capsys.readouterr().out)
    assert budgets and set(budgets) == {statestore.STATE_MEMORY_BYTES}
    budgets.clear()
    assert main(['analyze', str(manifest), '--quiet', '--json', '--state-memory', '0']) == 0
    mapped = json.loads(capsys.readouterr().out)
    assert budgets and set(budgets) == {0}
    assert mapped == held
