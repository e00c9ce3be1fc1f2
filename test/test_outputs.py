"""Output safety primitives: confined names, refused targets, atomic writes, cleanup."""
from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest

from feed_axis_energy.interrupt import Terminated, terminate_on_signals
from feed_axis_energy.outputs import (check_component, check_target, confined, is_bag_directory,
                                      marked_or_empty, remove_stale_temporaries, Rollback,
                                      staged_directory, write_text_atomic)
from feed_axis_energy.errors import OutputError


def _tree(root: Path) -> list[str]:
    """Every entry under ``root`` (links not followed), relative, sorted."""
    return sorted(str(p.relative_to(root)) for p in root.rglob('*'))


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, '-c', 'pass'])
    proc.wait()
    return proc.pid


BAD_NAMES = ['', '   ', '.', '..', 'a/b', './x', '../x', '/abs', 'a\\b', 'x\x00y', 'x\ny',
             'tab\there', 'a' * 256, 'é' * 128, '.run.tmp-123', 'campaign.yaml',
             'CAMPAIGN.yaml']


@pytest.mark.parametrize('name', BAD_NAMES)
def test_unsafe_names_are_refused_naming_the_option(name: str) -> None:
    with pytest.raises(OutputError) as info:
        check_component(name, option='--manifest-name', reserved=('campaign.yaml',))
    message = str(info.value)
    assert message.startswith('--manifest-name: ')
    assert len(message) < 200                       # the name is cut, never shown whole
    assert '\n' not in message and '\x00' not in message


@pytest.mark.parametrize('name', ['run_1', 'f100_load0kg', '.hidden', 'é' * 127, 'a b',
                                  'x' * 255])
def test_plain_names_pass_and_stay_inside(tmp_path: Path, name: str) -> None:
    path = confined(tmp_path, name, option='run name')
    assert path == tmp_path / name
    assert Path(os.path.normpath(os.path.abspath(path))).parent == tmp_path


def test_a_name_that_is_not_text_is_refused() -> None:
    with pytest.raises(OutputError, match='type int'):
        check_component(5, option='runs[0].name')   # type: ignore[arg-type]


def test_existing_targets_are_refused_unless_forced(tmp_path: Path) -> None:
    f = tmp_path / 'f.yaml'
    f.write_text('old')
    d = tmp_path / 'd'
    d.mkdir()
    with pytest.raises(OutputError, match='exists already.*--force'):
        check_target(f, option='--out-machine')
    with pytest.raises(OutputError, match='exists already; choose a new name$'):
        check_target(d, option='--out', kind='directory', forceable=False)
    assert check_target(f, option='--out-machine', force=True) == f
    with pytest.raises(OutputError, match='is a directory'):
        check_target(d, option='--out-machine', force=True)
    with pytest.raises(OutputError, match='is not a directory'):
        check_target(f, option='--out', force=True, kind='directory')
    with pytest.raises(OutputError, match='not an earlier output'):
        check_target(d, option='--out', force=True, kind='directory',
                     replaceable=lambda p: False)
    with pytest.raises(OutputError, match='parent .* is not a directory'):
        check_target(f / 'x', option='--out')


def test_links_are_refused_even_forced_and_even_dangling(tmp_path: Path) -> None:
    outside = tmp_path / 'outside'
    outside.mkdir()
    secret = outside / 'secret.txt'
    secret.write_text('keep')
    out = tmp_path / 'out'
    out.mkdir()
    (out / 'to_file').symlink_to(secret)
    (out / 'to_dir').symlink_to(outside)
    (out / 'dangling').symlink_to(outside / 'not_yet')
    for name in ('to_file', 'dangling'):
        for force in (False, True):
            with pytest.raises(OutputError, match='symbolic link'):
                write_text_atomic(out / name, 'x', option='--out-machine', force=force)
    for force in (False, True):
        with pytest.raises(OutputError, match='symbolic link'):
            with staged_directory(out / 'to_dir', option='--out', force=force) as staged:
                staged.mkdir()
    assert secret.read_text() == 'keep'
    assert _tree(outside) == ['secret.txt']            # nothing written through a link
    assert sorted(p.name for p in out.iterdir()) == ['dangling', 'to_dir', 'to_file']


def test_write_text_atomic_writes_and_replaces_only_when_forced(tmp_path: Path) -> None:
    path = tmp_path / 'new' / 'deeper' / 'm.yaml'
    write_text_atomic(path, 'one\n', option='--out-machine')
    assert path.read_text() == 'one\n'
    with pytest.raises(OutputError, match='exists already'):
        write_text_atomic(path, 'two\n', option='--out-machine')
    assert path.read_text() == 'one\n'
    write_text_atomic(path, 'two\n', option='--out-machine', force=True)
    assert path.read_text() == 'two\n'
    assert _tree(tmp_path) == ['new', 'new/deeper', 'new/deeper/m.yaml']


def test_a_failed_write_leaves_nothing_not_even_the_directories_it_made(tmp_path, monkeypatch):
    def broken(fd):
        raise OSError(28, 'No space left on device (simulated)')

    monkeypatch.setattr(os, 'fsync', broken)
    with pytest.raises(OutputError, match=r'^--out-machine .*m\.yaml: could not be written '
                                          r'\(No space left on device \(simulated\)\)'):
        write_text_atomic(tmp_path / 'a' / 'b' / 'm.yaml', 'x', option='--out-machine')
    assert _tree(tmp_path) == []
    old = tmp_path / 'm.yaml'
    old.write_text('earlier')
    with pytest.raises(OutputError, match='No space'):
        write_text_atomic(old, 'new', option='--out-machine', force=True)
    assert old.read_text() == 'earlier' and _tree(tmp_path) == ['m.yaml']


def test_an_unwritable_place_names_the_argument_not_the_temporary(tmp_path, monkeypatch):
    real = os.mkdir

    def refused(path, mode=0o777):
        if '.tmp-' in str(path):
            raise PermissionError(13, 'Permission denied', str(path))
        return real(path, mode)

    monkeypatch.setattr(os, 'mkdir', refused)
    with pytest.raises(OutputError) as info:
        with staged_directory(tmp_path / 'new' / 'bag', option='--out') as staged:
            staged.mkdir()
    message = str(info.value)
    assert message.startswith('--out ') and message.endswith(
        'new/bag: could not be written (Permission denied); nothing was left')
    assert '.tmp-' not in message
    assert _tree(tmp_path) == []                   # the directory it made is gone too


def test_staged_directory_appears_only_when_complete(tmp_path: Path) -> None:
    out = tmp_path / 'bag'
    with staged_directory(out, option='--out') as staged:
        assert staged.name == 'bag' and staged.parent.name.startswith('.bag.tmp-')
        staged.mkdir()
        (staged / 'part').write_text('1')
        assert not out.exists()
    assert _tree(tmp_path) == ['bag', 'bag/part']


def test_staged_directory_failure_leaves_nothing_and_keeps_the_earlier_output(tmp_path):
    out = tmp_path / 'sub' / 'bag'
    with pytest.raises(RuntimeError, match='boom'):
        with staged_directory(out, option='--out') as staged:
            staged.mkdir()
            (staged / 'part').write_text('1')
            raise RuntimeError('boom')
    assert _tree(tmp_path) == []
    with staged_directory(out, option='--out') as staged:
        staged.mkdir()
        (staged / 'first').write_text('1')
    with pytest.raises(Terminated):
        with staged_directory(out, option='--out', force=True) as staged:
            staged.mkdir()
            (staged / 'second').write_text('2')
            raise Terminated(signal.SIGTERM)
    assert _tree(tmp_path) == ['sub', 'sub/bag', 'sub/bag/first']
    with staged_directory(out, option='--out', force=True) as staged:
        staged.mkdir()
        (staged / 'second').write_text('2')
    assert _tree(tmp_path) == ['sub', 'sub/bag', 'sub/bag/second']


def test_stale_temporaries_of_dead_processes_are_removed_others_kept(tmp_path: Path) -> None:
    out = tmp_path / 'bag'
    dead = tmp_path / f'.bag.tmp-{_dead_pid()}'
    (dead / 'bag').mkdir(parents=True)
    (dead / 'bag' / 'half.mcap').write_bytes(b'\x89MCAP0\r\n')
    alive = tmp_path / f'.bag.tmp-{os.getppid()}'      # our parent is running
    alive.mkdir()
    other = tmp_path / f'.other.tmp-{_dead_pid()}'      # another target's temporary
    other.write_text('x')
    with staged_directory(out, option='--out') as staged:   # not blocked by them
        staged.mkdir()
    assert not dead.exists() and alive.exists() and other.exists()
    assert remove_stale_temporaries(tmp_path / 'other') == 1 and not other.exists()


def test_replaceable_tests(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    bag.mkdir()
    assert is_bag_directory(bag)                          # empty
    (bag / 'bag_0.mcap').write_bytes(b'')
    assert not is_bag_directory(bag)                      # no metadata.yaml
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}\n')
    assert is_bag_directory(bag)
    (bag / 'sub').mkdir()
    assert not is_bag_directory(bag)
    marked = marked_or_empty('.mark')
    report = tmp_path / 'report'
    report.mkdir()
    assert marked(report)
    (report / 'notes.txt').write_text('x')
    assert not marked(report)
    (report / '.mark').write_text('')
    assert marked(report)


def test_rollback_removes_what_this_invocation_wrote(tmp_path: Path) -> None:
    out = tmp_path / 'a' / 'b'
    with pytest.raises(RuntimeError):
        with Rollback(created=out) as rollback:
            out.mkdir(parents=True)
            (out / 'one').mkdir()
            rollback.add(out / 'one')
            raise RuntimeError('second failed')
    assert _tree(tmp_path) == []
    with Rollback(created=out) as rollback:
        out.mkdir(parents=True)
        (out / 'one').mkdir()
        rollback.add(out / 'one')
    assert _tree(tmp_path) == ['a', 'a/b', 'a/b/one']


def test_sigterm_raises_terminated_once_and_the_handler_is_restored() -> None:
    before = signal.getsignal(signal.SIGTERM)
    cleaned = []
    with pytest.raises(Terminated) as info:
        with terminate_on_signals():
            try:
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(5)                               # the signal cuts this short
                pytest.fail('no exception after SIGTERM')
            finally:
                os.kill(os.getpid(), signal.SIGTERM)    # a second one: ignored
                cleaned.append(True)
    assert info.value.signum == signal.SIGTERM and info.value.exit_code == 143
    assert cleaned == [True]
    assert signal.getsignal(signal.SIGTERM) is before
