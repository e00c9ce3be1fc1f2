"""The nodes die with the launcher, even when the launcher is killed with SIGKILL."""
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

import must_run
import pytest

must_run.import_or_skip('rclpy', 'rclpy')

from feed_axis_energy import lifeline  # noqa: E402
from feed_axis_energy.record import bagio  # noqa: E402

PY = sys.executable


def _wait_for_power(bag, samples=100, timeout=30.0):
    """Wait until the recorder's flushed files hold ``samples`` power samples (the bag is
    readable at every moment), so the kill comes after data has reached the recorder, however
    slowly the graph starts on a busy machine."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if bagio.read_series(bag, bagio.TOPIC_POWER).t.shape[0] >= samples:
                return
        except Exception:  # noqa: B902 - not written yet, or a file being renamed
            pass
        time.sleep(0.1)
    raise AssertionError(f'no {samples} power samples in the recording after {timeout} s')


def _state(pid):
    """Scheduler state and kernel wait channel of each thread of a process (what a survivor
    was doing: which thread waits where)."""
    threads = []
    try:
        for task in sorted(Path(f'/proc/{pid}/task').iterdir(), key=lambda p: int(p.name)):
            try:
                name = (task / 'comm').read_text().strip()
                state = (task / 'stat').read_text().rsplit(')', 1)[1].split()[0]
                wchan = (task / 'wchan').read_text().strip() or '-'
            except OSError:
                continue
            threads.append(f'{name} {state} {wchan}')
    except OSError:
        return 'gone'
    return 'threads: ' + '; '.join(threads)


def _start_launcher(tmp_path, node_env, domain_id, *, record):
    prog = tmp_path / 'long.nc'
    prog.write_text('G21 G90 G94 G61\nG0 X0\nG1 X300 F600\n')   # 30 s in real time
    cmd = [PY, '-m', 'feed_axis_energy', 'launch', '--program', str(prog), '--mode',
           'realtime', '--domain-id', str(domain_id), '--timeout', '60']
    if record is not None:
        cmd += ['--record', str(record)]
    launcher = subprocess.Popen(cmd, env=node_env, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
    streaming = threading.Event()

    def _read():
        for line in launcher.stdout:
            if 'streaming starts' in line:
                streaming.set()
    threading.Thread(target=_read, daemon=True).start()
    want = 4 if record is not None else 3
    deadline = time.monotonic() + 30
    kids = []
    while time.monotonic() < deadline:
        kids = [k for k in lifeline.child_processes(launcher.pid)
                if 'feed_axis_energy.nodes.' in k[1]]
        if len(kids) == want:
            break
        time.sleep(0.1)
    return launcher, kids, want, streaming


@pytest.mark.parametrize('sig', [signal.SIGKILL, signal.SIGTERM])
def test_no_node_survives_the_launcher_by_2_s(tmp_path, node_env, domain_id, sig):
    bag = tmp_path / 'rec'
    launcher, kids, want, streaming = _start_launcher(tmp_path, node_env, domain_id,
                                                      record=bag)
    try:
        assert len(kids) == want, kids
        assert streaming.wait(timeout=30)
        _wait_for_power(bag)
        os.kill(launcher.pid, sig)
        # The 2 s count from the moment the launcher is gone: at once after SIGKILL; after
        # SIGTERM once its own orderly stop (stop the nodes, describe the bag) has ended,
        # which took 12-14 s with the machine at load ~7 (a 10 s wait here raised
        # TimeoutExpired). The launcher's own pace is not what this test is about.
        launcher.wait(timeout=90)
        t_gone = time.monotonic()
        while any(lifeline.alive(pid) for pid, _ in kids) and time.monotonic() - t_gone < 2.0:
            time.sleep(0.05)
        survivors = [f'{cmd} ({_state(pid)})' for pid, cmd in kids if lifeline.alive(pid)]
    finally:
        launcher.kill()
        for pid, _ in kids:   # never leave a node running, even when the test fails
            if lifeline.alive(pid):
                os.kill(pid, signal.SIGKILL)
    assert survivors == [], f'alive 2 s after {sig.name} of the launcher: {survivors}'
    # The recorder got SIGTERM and closed its bag: it is complete and readable.
    power = bagio.read_series(bag, bagio.TOPIC_POWER)
    assert power.t.shape[0] >= 100


def test_preexec_child_gets_sigterm_when_its_parent_dies(tmp_path):
    """The parent-death signal alone (no process group): a middle process killed by SIGKILL."""
    pid_file = tmp_path / 'grandchild.pid'
    middle = subprocess.Popen([PY, '-c', (
        'import os, subprocess, sys, time\n'
        'from feed_axis_energy import lifeline\n'
        f'p = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"],\n'
        '                      preexec_fn=lifeline.preexec(os.getpid()))\n'
        f'open({str(pid_file)!r}, "w").write(str(p.pid))\n'
        'time.sleep(60)\n')], env={**os.environ, 'PYTHONPATH': str(Path(
            __file__).resolve().parents[2])})
    try:
        deadline = time.monotonic() + 20
        while not pid_file.exists() or not pid_file.read_text():
            assert time.monotonic() < deadline
            time.sleep(0.05)
        grandchild = int(pid_file.read_text())
        assert lifeline.alive(grandchild)
        middle.kill()
        middle.wait()
        deadline = time.monotonic() + 2.0
        while lifeline.alive(grandchild) and time.monotonic() < deadline:
            time.sleep(0.02)
        assert not lifeline.alive(grandchild)
    finally:
        middle.kill()


def test_arm_from_env(monkeypatch):
    monkeypatch.delenv(lifeline.ENV, raising=False)
    assert lifeline.arm_from_env(sig=0) is None   # not started by the launcher: not armed
    monkeypatch.setenv(lifeline.ENV, str(os.getppid()))
    assert lifeline.arm_from_env(sig=0) is True
    monkeypatch.setenv(lifeline.ENV, str(os.getpid()))   # not our parent: it has gone
    assert lifeline.arm_from_env(sig=0) is False


def test_recorder_stopped_alone_fails_the_launch_before_the_stall_timeout(
        tmp_path, node_env, domain_id):
    """SIGTERM of the recorder only: it closes its bag and exits 0, the launcher exits 1.

    Without the finisher grace rule the launcher waited for gcode_trajectory's 30 s stall
    timeout (the recorder's acks never come again).
    """
    bag = tmp_path / 'rec'
    launcher, kids, want, streaming = _start_launcher(tmp_path, node_env, domain_id,
                                                      record=bag)
    try:
        assert len(kids) == want, kids
        assert streaming.wait(timeout=30)
        _wait_for_power(bag)
        rec = next(pid for pid, cmd in kids if 'nodes.mcap_recorder' in cmd)
        os.kill(rec, signal.SIGTERM)
        t_kill = time.monotonic()
        code = launcher.wait(timeout=40)
        took = time.monotonic() - t_kill
    finally:
        launcher.kill()
        for pid, _ in kids:
            if lifeline.alive(pid):
                os.kill(pid, signal.SIGKILL)
    assert code == 1
    assert took < 25.0   # grace 10 s + the stop; the stall timeout alone is 30 s
    assert bagio.read_series(bag, bagio.TOPIC_POWER).t.shape[0] >= 100


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_stop_while_importing_is_quiet(tmp_path, node_env, sig):
    """A launcher-started node stopped during its imports: no traceback, code 128 + signal."""
    env = {**node_env, lifeline.ENV: str(os.getpid())}
    proc = subprocess.Popen([PY, '-m', 'feed_axis_energy.nodes.mcap_recorder', '--ros-args',
                             '-p', f'output:={tmp_path / "rec"}'], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    # Signal once the child is inside its imports: numpy's extension is mapped (rclpy and
    # rosbags follow it), polled rather than slept for, so a loaded machine cannot make the
    # signal arrive before Python runs or after the node is up.
    maps = Path(f'/proc/{proc.pid}/maps')
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            if '_multiarray_umath' in maps.read_text():
                break
        except OSError:
            pass
        time.sleep(0.002)
    assert proc.poll() is None, 'the node ended before it was signalled'
    proc.send_signal(sig)
    out, _ = proc.communicate(timeout=30)
    assert 'Traceback' not in out, out
    assert proc.returncode == 128 + sig
    assert not (tmp_path / 'rec').exists()


def test_watch_parent_ends_a_child_that_ignores_its_stop(tmp_path):
    """A child whose orderly stop never comes (SIGTERM ignored, the main thread asleep in a
    call) is still ended ``grace_s`` after its parent has gone, with its stack on stderr."""
    pid_file = tmp_path / 'grandchild.pid'
    err_file = tmp_path / 'grandchild.err'
    grandchild_code = (
        'import signal, time\n'
        'from feed_axis_energy import lifeline\n'
        'signal.signal(signal.SIGTERM, signal.SIG_IGN)\n'
        'lifeline.watch_parent(grace_s=0.5)\n'
        'time.sleep(60)\n')
    middle = subprocess.Popen([PY, '-c', (
        'import os, subprocess, sys, time\n'
        f'err = open({str(err_file)!r}, "w")\n'
        f'p = subprocess.Popen([sys.executable, "-c", {grandchild_code!r}], stderr=err,\n'
        '                      env={**os.environ, "FAE_PARENT_PID": str(os.getpid())})\n'
        f'open({str(pid_file)!r}, "w").write(str(p.pid))\n'
        'time.sleep(60)\n')], env={**os.environ, 'PYTHONPATH': str(Path(
            __file__).resolve().parents[2])})
    grandchild = None
    try:
        deadline = time.monotonic() + 20
        while not pid_file.exists() or not pid_file.read_text():
            assert time.monotonic() < deadline
            time.sleep(0.05)
        grandchild = int(pid_file.read_text())
        time.sleep(1.0)   # the grandchild is past its imports and asleep
        assert lifeline.alive(grandchild)
        middle.kill()
        middle.wait()
        t_gone = time.monotonic()
        while lifeline.alive(grandchild) and time.monotonic() - t_gone < 5.0:
            time.sleep(0.02)
        took = time.monotonic() - t_gone
        assert not lifeline.alive(grandchild)
    finally:
        middle.kill()
        if grandchild is not None and lifeline.alive(grandchild):
            os.kill(grandchild, signal.SIGKILL)
    assert 0.4 <= took < 2.0, took   # not before the grace, not long after it
    assert 'time.sleep' in err_file.read_text() or 'line 5' in err_file.read_text()
