"""``feed-axis-energy launch`` hands parameters over in a parameter file (issue 12, s. 3).

ROS reads ``-p key:=value`` as YAML: a program path holding `` #`` ran a different program,
one holding ``: `` ended in a traceback. The parameter file quotes every string.
"""
from __future__ import annotations

import os
import subprocess
import sys

import must_run
import pytest
import yaml

from feed_axis_energy.cli.launch import params_yaml, write_params_file

NASTY = ["a b", "x #not a comment", "key: value", "it's", 'say "hi"', "true", "123",
         "0x1F", "~", "- item", "[1, 2]", "{a: b}", "tab\there", "ünïcode", "back\\slash",
         "*alias", "&anchor", "!tag", "%directive", "@at", "`tick`", "", " lead", "trail "]


@pytest.mark.parametrize('text', NASTY)
def test_every_string_reads_back_as_itself(text):
    data = yaml.safe_load(params_yaml({'gcode_trajectory': {'program': text}}))
    assert data == {'gcode_trajectory': {'ros__parameters': {'program': text}}}


def test_numbers_and_flags_keep_their_types():
    data = yaml.safe_load(params_yaml({'energy_estimator': {
        'load_kg': 17.336, 'exit_at_end': True, 'batch': 100, 'zero': 0.0}}))
    params = data['energy_estimator']['ros__parameters']
    assert params == {'load_kg': 17.336, 'exit_at_end': True, 'batch': 100, 'zero': 0.0}
    assert isinstance(params['zero'], float) and isinstance(params['batch'], int)


@pytest.mark.parametrize('bad', [{'no de': {}}, {'node': {'a:b': 1}},
                                 {'node': {'x': float('nan')}}])
def test_bad_names_and_values_refused(bad):
    with pytest.raises(ValueError):
        params_yaml(bad)


def test_params_file_is_new_and_private(tmp_path):
    path = write_params_file(tmp_path, {'axis_dynamics': {'load_kg': 1.0}})
    assert oct(path.stat().st_mode & 0o777) == '0o600'
    with pytest.raises(FileExistsError):
        write_params_file(tmp_path, {'axis_dynamics': {'load_kg': 2.0}})


@pytest.mark.ros
def test_launch_with_hostile_paths(tmp_path, node_env, domain_id):
    must_run.import_or_skip('rclpy', 'rclpy')
    folder = tmp_path / 'run a #b: c \'d" e'
    folder.mkdir()
    # the first line alone would be a different program if the path were cut at ' #'
    program = folder / 'prog #1: "x" \'y\'.nc'
    program.write_text('G21 G90 G94 G61\nG0 X0\nG1 X20 F3000\n', encoding='utf-8')
    bag = folder / 'bag #2: z'
    private_tmp = tmp_path / 'tmp'
    private_tmp.mkdir()
    env = dict(node_env, TMPDIR=str(private_tmp))
    out = subprocess.run(
        [sys.executable, '-m', 'feed_axis_energy', 'launch', '--program', str(program),
         '--record', str(bag), '--domain-id', str(domain_id), '--load-kg', '2',
         '--timeout', '60'], env=env, capture_output=True, text=True, timeout=90)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]
    assert f'recording: {bag}' in out.stdout
    assert f'planned {program}' in out.stdout, out.stdout[-3000:]
    assert (bag / 'metadata.yaml').is_file()
    assert not list(private_tmp.iterdir()), 'parameter directory left behind'


def test_launch_rejects_non_finite_load(tmp_path, node_env):
    out = subprocess.run(
        [sys.executable, '-m', 'feed_axis_energy', 'launch', '--load-kg', 'nan'],
        env=node_env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2
    assert '--load-kg' in out.stderr


def test_stale_parameter_dirs_of_dead_launchers_removed(tmp_path, monkeypatch):
    from feed_axis_energy.cli import launch
    monkeypatch.setattr(launch.tempfile, 'gettempdir', lambda: str(tmp_path))
    dead = subprocess.run([sys.executable, '-c', 'import os; print(os.getpid())'],
                          capture_output=True, text=True, check=True).stdout.strip()
    stale = tmp_path / f'fae-launch-{dead}-abc'
    stale.mkdir()
    (stale / 'launch_params.yaml').write_text('x: 1\n')
    mine = tmp_path / f'fae-launch-{os.getpid()}-def'     # a running launcher's: kept
    mine.mkdir()
    other = tmp_path / 'fae-launch-notapid-x'
    other.mkdir()
    assert launch.remove_stale_parameter_dirs() == 1
    assert not stale.exists() and mine.is_dir() and other.is_dir()


def test_recording_options_reach_the_recorder(tmp_path, node_env, domain_id):
    """--start-time stamps the bag from that instant; --plot-rate-hz thins the plot topics."""
    must_run.import_or_skip('rclpy', 'rclpy')
    from feed_axis_energy.record import bagio
    program = tmp_path / 'p.nc'
    program.write_text('G21 G90 G94 G61\nG0 X0\nG1 X100 F3000\nG1 X0\n', encoding='utf-8')
    counts = {}
    for rate in ('0', '2'):
        bag = tmp_path / f'bag{rate}'
        out = subprocess.run(
            [sys.executable, '-m', 'feed_axis_energy', 'launch', '--program', str(program),
             '--record', str(bag), '--domain-id', str(domain_id), '--timeout', '60',
             '--plot-rate-hz', rate, '--start-time', '2026-01-02T03:04:05Z'],
            env=node_env, capture_output=True, text=True, timeout=90)
        assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]
        meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
        # 2026-01-02T03:04:05Z in ns since the epoch
        assert meta['starting_time']['nanoseconds_since_epoch'] >= 1_767_323_045 * 10 ** 9
        counts[rate] = bagio.bag_topics(bag)['/plot/power'][1]
    # 4.2 s of program at 1 kHz: every sample at 0 Hz; at 2 Hz a few per half second
    assert counts['0'] > 1000 > 50 > counts['2'] > 0


def test_recording_options_need_a_recording(node_env):
    out = subprocess.run(
        [sys.executable, '-m', 'feed_axis_energy', 'launch', '--plot-rate-hz', '5'],
        env=node_env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and '--record' in out.stderr
    out = subprocess.run(
        [sys.executable, '-m', 'feed_axis_energy', 'launch', '--record', 'x',
         '--start-time', 'yesterday'], env=node_env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and '--start-time' in out.stderr
