"""The ``feed-axis-energy rig`` command, run as a user runs it."""
import json
from pathlib import Path
import subprocess
import sys

import pytest

from feed_axis_energy.cli import main
from feed_axis_energy.effects.catalog import EFFECTS
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.csvload import load_run

ROOT = Path(__file__).resolve().parents[2]


def test_help_exits_zero() -> None:
    proc = subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'rig', '--help'],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0
    assert 'usage: feed-axis-energy rig' in proc.stdout
    for option in ('--effects', '--loads', '--feeds', '--seed', '--noise-w', '--offset-s',
                   '--drift', '--outside-catalog'):
        assert option in proc.stdout


@pytest.mark.parametrize('spec, named', [
    ('frictionless=mu:1', "unknown effect 'frictionless'"),
    ('coulomb=f_pos_n:1,f_sideways_n:2', "no parameter 'f_sideways_n'"),
])
def test_bad_effects_spec_exits_1_naming_it(tmp_path: Path, capsys, spec: str,
                                            named: str) -> None:
    out = tmp_path / 'rig'
    assert main(['rig', '--out', str(out), '--effects', spec]) == 1
    err = capsys.readouterr().err
    assert named in err
    assert 'effects' in err
    assert not out.exists()


def test_small_campaign(tmp_path: Path, capsys) -> None:
    out = tmp_path / 'rig'
    code = main(['rig', '--out', str(out), '--loads', '0,22.711', '--feeds', '250',
                 '--cycles', '1', '--effects', 'viscous=c_n_s_m:80', '--seed', '5',
                 '--offset-s', '0.4', '--drift', '1e-4,0.01', '--outside-catalog'])
    assert code == 0
    assert 'manifest.yaml' in capsys.readouterr().out
    truth = json.loads((out / 'truth.json').read_text())
    assert truth['effects'] == [{'id': 'viscous', 'params': {'c_n_s_m': 80.0}}]
    assert truth['outside']['kind'] == 'periodic'
    assert truth['instrument']['gain_drift_per_s'] == 1e-4
    assert [r['offset_s'] for r in truth['runs']] == [0.4, 0.4]
    campaign = load_campaign(out / 'manifest.yaml')
    assert [r.load_kg for r in campaign.runs] == [0.0, 22.711]
    assert load_run(campaign.runs[1]).t.size > 100


def test_bad_numbers_exit_1(tmp_path: Path, capsys) -> None:
    assert main(['rig', '--out', str(tmp_path / 'a'), '--loads', '0,heavy']) == 1
    assert 'loads' in capsys.readouterr().err
    assert main(['rig', '--out', str(tmp_path / 'b'), '--feeds', '0']) == 1
    assert 'feeds' in capsys.readouterr().err


def test_list_effects_shows_the_catalog(capsys) -> None:
    assert main(['rig', '--list-effects']) == 0
    out = capsys.readouterr().out
    for effect_id in EFFECTS:
        assert effect_id in out
