"""``launch --program-root``: the job mode's options, checked before any node starts."""
import argparse
import os
from pathlib import Path
import subprocess
import sys

import pytest

from feed_axis_energy.cli.launch import add_parser, graph_parameters

ROOT = Path(__file__).resolve().parents[2]


def _args(*argv):
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers())
    return parser.parse_args(['launch', *argv])


def test_job_mode_parameters(tmp_path):
    params = graph_parameters(_args('--program-root', str(tmp_path), '--machine-root',
                                    str(tmp_path), '--mode', 'realtime'))
    gt = params['gcode_trajectory']
    assert gt['program'] == '' and gt['program_root'] == str(tmp_path.resolve())
    assert gt['machine_root'] == str(tmp_path.resolve())
    assert params['energy_estimator']['exit_at_end'] is False
    assert params['energy_estimator']['live_clock'] == 'wall'
    assert 'mcap_recorder' not in params
    rec = graph_parameters(_args('--program-root', str(tmp_path), '--record',
                                 str(tmp_path / 'rec')))
    assert rec['mcap_recorder']['per_job'] is True
    assert rec['mcap_recorder']['exit_at_end'] is False
    assert rec['mcap_recorder']['output'] == str((tmp_path / 'rec').resolve())
    assert rec['gcode_trajectory']['record_root'] == str((tmp_path / 'rec').resolve())
    assert rec['gcode_trajectory']['ack_recorder'] is True
    one = graph_parameters(_args('--program', str(tmp_path / 'p.nc')))
    assert 'program_root' not in one['gcode_trajectory']
    assert one['energy_estimator']['exit_at_end'] is True
    assert one['energy_estimator']['live_clock'] == 'simulation'


@pytest.mark.parametrize('argv, words', [
    (['--program-root', '/nonexistent-cj'], 'not a directory'),
    (['--program-root', '.', '--program',
      str(ROOT / 'config' / 'programs' / 'demonstrator_f100.nc')],
     'excludes --program'),
    (['--program-root', '.', '--record', 'link'], 'a symbolic link'),
    (['--program-root', '.', '--record', 'file'], 'not a directory'),
    (['--program-root', '.', '--record', 'x_bag', '--start-time', '2026-01-01T00:00:00'],
     'only "now"'),
    (['--machine-root', '.'], 'give --program-root'),
])
def test_job_mode_option_errors_exit_2_before_anything_starts(argv, words, tmp_path):
    (tmp_path / 'file').write_text('')
    (tmp_path / 'elsewhere').mkdir()
    (tmp_path / 'link').symlink_to(tmp_path / 'elsewhere')
    out = subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'launch', *argv],
                         cwd=tmp_path, capture_output=True, text=True, timeout=60,
                         env={'PYTHONPATH': str(ROOT), 'PATH': '/usr/bin:/bin'})
    assert out.returncode == 2, out.stderr
    assert words in out.stderr and 'Traceback' not in out.stderr
    assert not (tmp_path / 'x_bag').exists()
    assert os.listdir(tmp_path / 'elsewhere') == []
