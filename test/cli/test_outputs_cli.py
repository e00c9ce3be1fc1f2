"""Output safety of every command that writes: refused targets, confined names, no leftovers.

Each case snapshots the whole tmp_path (names and file contents, links not followed) before
the command and checks that a refused command changed nothing, inside or outside the
requested place.
"""
from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest
import yaml

from feed_axis_energy.cli import main
from feed_axis_energy.record import bagio, StreamBagWriter
from feed_axis_energy.interrupt import Terminated
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.record.recording import SUMMARY_KEY

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / 'test' / 'fixtures' / 'measured'
MANIFEST = FIXTURES / 'campaign.yaml'
PROGRAM = ROOT / 'config' / 'programs' / 'demonstrator_f300.nc'


def _snapshot(root: Path) -> dict[str, object]:
    """Every entry under ``root``: file bytes, link targets, directories (links not followed)."""
    out: dict[str, object] = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            path = Path(dirpath) / name
            rel = str(path.relative_to(root))
            if path.is_symlink():
                out[rel] = ('link', os.readlink(path))
            elif path.is_dir():
                out[rel] = 'dir'
            else:
                out[rel] = path.read_bytes()
    return out


# command -> (argv with {out} for the target, option named in the message, target kind)
COMMANDS = {
    'simulate': (['simulate', str(PROGRAM), '--out', '{out}', '--quiet'], '--out', 'dir'),
    'demo': (['demo', '--out', '{out}', '--quiet'], '--out', 'dir'),
    'rig': (['rig', '--out', '{out}', '--quiet', '--feeds', '300', '--loads', '0',
             '--cycles', '1'], '--out', 'dir'),
    'compare': (['compare', str(MANIFEST), '--report', '{out}', '--quiet'], '--report', 'dir'),
    'analyze-report': (['analyze', str(MANIFEST), '--report', '{out}', '--quiet'], '--report',
                       'dir'),
    'analyze-machine': (['analyze', str(MANIFEST), '--out-machine', '{out}', '--quiet'],
                        '--out-machine', 'file'),
    'fit-loss': (['fit-loss', str(MANIFEST), '--out-machine', '{out}'], '--out-machine',
                 'file'),
}


def _place(tmp_path: Path, case: str) -> Path:
    """Make the target of ``case`` in ``tmp_path / 'work'``; ``tmp_path / 'outside'`` holds
    what a link points to."""
    outside = tmp_path / 'outside'
    outside.mkdir()
    (outside / 'precious.txt').write_text('keep me')
    work = tmp_path / 'work'
    work.mkdir()
    target = work / 'target'
    if case == 'existing file':
        target.write_text('earlier')
    elif case == 'existing directory':
        target.mkdir()
        (target / 'notes.txt').write_text('mine')
    elif case == 'link to a directory outside':
        target.symlink_to(outside)
    elif case == 'link to a file outside':
        target.symlink_to(outside / 'precious.txt')
    elif case == 'dangling link':
        target.symlink_to(outside / 'not_yet')
    elif case == 'parent is a file':
        (work / 'file').write_text('x')
        target = work / 'file' / 'target'
    return target


CASES = ['existing file', 'existing directory', 'link to a directory outside',
         'link to a file outside', 'dangling link', 'parent is a file']


@pytest.mark.parametrize('case', CASES)
@pytest.mark.parametrize('command', sorted(COMMANDS))
@pytest.mark.parametrize('force', [False, True])
def test_refused_targets_exit_1_and_change_nothing(tmp_path: Path, capsys, command: str,
                                                   case: str, force: bool) -> None:
    argv, option, kind = COMMANDS[command]
    if force and kind == 'file' and case == 'existing file':
        pytest.skip('--force replaces an existing file (test_outputs.py)')
    target = _place(tmp_path, case)
    before = _snapshot(tmp_path)
    argv = [a.replace('{out}', str(target)) for a in argv] + (['--force'] if force else [])
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 1, err
    assert option in err and 'Traceback' not in err
    assert len(err.strip().splitlines()) == 1, err
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize('command', ['simulate', 'rig', 'demo'])
def test_force_replaces_only_the_commands_own_output(tmp_path: Path, capsys,
                                                     command: str) -> None:
    argv, option, _ = COMMANDS[command]
    target = tmp_path / 'target'
    argv = [a.replace('{out}', str(target)) for a in argv]
    assert main(argv) == 0
    first = _snapshot(target)
    capsys.readouterr()
    assert main(argv) == 1
    assert 'exists already' in capsys.readouterr().err
    assert main(argv + ['--force']) == 0
    assert _snapshot(target).keys() == first.keys()
    assert sorted(p.name for p in tmp_path.iterdir()) == ['target']     # no temporary left


# --- import: run names and --manifest-name -------------------------------------------------

def _campaign_with_names(tmp_path: Path, names: list[str]) -> Path:
    for name in ('run_a.csv', 'run_b.csv', 'machine.yaml'):
        (tmp_path / name).write_bytes((FIXTURES / name).read_bytes())
    doc = yaml.safe_load(MANIFEST.read_text())
    doc.pop('split')
    doc['runs'] = [dict(doc['runs'][1], name=n) for n in names]
    (tmp_path / 'c.yaml').write_text(yaml.safe_dump(doc))
    return tmp_path / 'c.yaml'


BAD_RUN_NAMES = [str(Path('/tmp') / 'escaped_abs'), '..', '.', './x', '../escaped', 'a/b',
                 'campaign.yaml', 'Campaign.YAML', '']


@pytest.mark.parametrize('bad', BAD_RUN_NAMES)
def test_import_refuses_a_run_name_that_is_not_a_plain_name(tmp_path: Path, capsys,
                                                            bad: str) -> None:
    manifest = _campaign_with_names(tmp_path, ['good', bad])
    out = tmp_path / 'deep' / 'out'
    before = _snapshot(tmp_path)
    code = main(['import', str(manifest), '--out', str(out), '--quiet'])
    err = capsys.readouterr().err
    assert code == 1, err
    assert 'Traceback' not in err and len(err.strip().splitlines()) == 1
    # the message names the manifest key (or, for names the manifest itself refuses, the key
    # too); nothing is written anywhere, not even the --out directory
    assert 'runs[1]' in err, err
    assert _snapshot(tmp_path) == before
    assert not Path('/tmp/escaped_abs').exists()


@pytest.mark.parametrize('bad', ['../../x.yaml', '/tmp/escaped.yaml', '.', '..', 'sub/m.yaml',
                                 'good', 'GOOD', '', 'x\ny.yaml'])
def test_import_confines_manifest_name(tmp_path: Path, capsys, bad: str) -> None:
    manifest = _campaign_with_names(tmp_path, ['good'])
    out = tmp_path / 'out'
    before = _snapshot(tmp_path)
    code = main(['import', str(manifest), '--out', str(out), '--manifest-name', bad,
                 '--quiet'])
    err = capsys.readouterr().err
    assert code == 1, err
    assert '--manifest-name' in err and 'Traceback' not in err
    assert _snapshot(tmp_path) == before
    assert not Path('/tmp/escaped.yaml').exists()


@pytest.mark.parametrize('failure, code, said', [
    (OSError(28, 'No space left on device (simulated)'), 1, 'No space'),
    (Terminated(signal.SIGTERM), 143, 'signal 15'),     # what the SIGTERM handler raises
])
def test_import_failure_part_way_removes_every_bag_of_the_invocation(
        tmp_path, capsys, monkeypatch, failure, code, said) -> None:
    manifest = _campaign_with_names(tmp_path, ['one', 'two', 'three'])
    out = tmp_path / 'out'
    real = StreamBagWriter.write_series
    calls = []

    def fails_in_the_second_bag(self, topic, series, *, batch=100):
        calls.append(self.path.name)
        if len(set(calls)) == 2:
            raise failure
        return real(self, topic, series, batch=batch)

    monkeypatch.setattr(StreamBagWriter, 'write_series', fails_in_the_second_bag)
    before = _snapshot(tmp_path)
    assert main(['import', str(manifest), '--out', str(out), '--quiet']) == code
    assert said in capsys.readouterr().err
    assert _snapshot(tmp_path) == before                # bag 'one' was removed again
    monkeypatch.setattr(StreamBagWriter, 'write_series', real)
    assert main(['import', str(manifest), '--out', str(out), '--quiet']) == 0
    assert sorted(p.name for p in out.iterdir()) == ['campaign.yaml', 'one', 'three', 'two']
    runs = load_campaign(out / 'campaign.yaml').runs
    assert [r.name for r in runs] == ['one', 'two', 'three']


# --- failures part-way: injected exceptions and signals ------------------------------------

def test_simulate_failure_after_the_first_chunk_leaves_nothing(tmp_path, capsys,
                                                               monkeypatch) -> None:
    from feed_axis_energy.record.recording import SimulationBagWriter
    real = SimulationBagWriter.write
    calls = []

    def fails_after_first(self, chunk):
        calls.append(1)
        if len(calls) > 1:
            raise OSError(28, 'No space left on device (simulated)')
        return real(self, chunk)

    monkeypatch.setattr(SimulationBagWriter, 'write', fails_after_first)
    long = tmp_path / 'long.nc'
    long.write_text('G21 G90\nG1 X100 F60\nG1 X0\nM2\n')       # 200 s: several chunks
    out = tmp_path / 'bags' / 'bag'
    assert main(['simulate', str(long), '--out', str(out), '--quiet']) == 1
    assert 'No space' in capsys.readouterr().err
    assert len(calls) > 1                                   # it did fail part-way
    assert sorted(p.name for p in tmp_path.iterdir()) == ['long.nc']
    monkeypatch.setattr(SimulationBagWriter, 'write', real)
    assert main(['simulate', str(long), '--out', str(out), '--quiet', '--json']) == 0
    summary = bagio.read_custom_data(out, SUMMARY_KEY)      # complete, with its summary
    assert summary['samples'] > 65_536                      # more than one chunk
    # every sample is in the bag: 100 samples per message
    messages = bagio.bag_topics(out)[bagio.TOPIC_POWER][1]
    assert messages == -(-summary['samples'] // 100)


def test_demo_failure_part_way_leaves_nothing(tmp_path, capsys, monkeypatch) -> None:
    import feed_axis_energy.cli.demo as demo
    out = tmp_path / 'demo'
    real = demo.write_simulation_bag
    calls = []

    def fails_third(path, result, **kwargs):
        calls.append(path)
        if len(calls) == 3:
            raise OSError(28, 'No space left on device (simulated)')
        return real(path, result, **kwargs)

    monkeypatch.setattr(demo, 'write_simulation_bag', fails_third)
    assert main(['demo', '--out', str(out), '--quiet']) == 1
    assert 'No space' in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def _wait_for(pattern: str, where: Path, proc: subprocess.Popen, timeout_s: float) -> Path:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        found = [p for p in where.glob(pattern) if any(p.rglob('*.mcap'))]
        if found:
            return found[0]
        if proc.poll() is not None:
            pytest.fail(f'finished before it could be stopped: {proc.communicate()}')
        time.sleep(0.05)
    proc.kill()
    pytest.fail(f'no {pattern} appeared in {timeout_s} s')


def _start_long_simulation(tmp_path: Path, out: Path) -> subprocess.Popen:
    program = tmp_path / 'long.nc'
    program.write_text('G21 G90\nG1 X100 F6\nG1 X0\nM2\n')         # about 2000 s of motion
    return subprocess.Popen([sys.executable, '-m', 'feed_axis_energy', 'simulate',
                             str(program), '--out', str(out), '--quiet'], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize('signum', [signal.SIGTERM, signal.SIGINT])
def test_signal_during_simulate_out_leaves_nothing_and_the_rerun_succeeds(
        tmp_path: Path, signum) -> None:
    out = tmp_path / 'bag'
    proc = _start_long_simulation(tmp_path, out)
    _wait_for('.bag.tmp-*', tmp_path, proc, 60.0)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signum, err
    assert 'Traceback' not in err and f'signal {int(signum)}' in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ['long.nc']
    proc = subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'simulate', str(PROGRAM),
                           '--out', str(out), '--quiet'], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr


def test_sigkill_leaves_only_a_hidden_temporary_that_the_rerun_removes(tmp_path) -> None:
    out = tmp_path / 'bag'
    proc = _start_long_simulation(tmp_path, out)
    stale = _wait_for('.bag.tmp-*', tmp_path, proc, 60.0)
    proc.kill()
    proc.communicate(timeout=60)
    assert stale.name == f'.bag.tmp-{proc.pid}'
    assert sorted(p.name for p in tmp_path.iterdir()) == [stale.name, 'long.nc']
    rerun = subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'simulate', str(PROGRAM),
                            '--out', str(out), '--quiet'], capture_output=True, text=True,
                           timeout=120)
    assert rerun.returncode == 0, rerun.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ['bag', 'long.nc']
