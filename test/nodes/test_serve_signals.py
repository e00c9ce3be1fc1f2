"""``serve`` stops cleanly on SIGTERM (exit 0) and stops everything with the failing node's
own words when a node cannot start (exit 1)."""
import os
import signal
import socket
import subprocess
import sys
import time

import must_run

must_run.import_or_skip('rclpy', 'rclpy')
must_run.import_or_skip('asyncua', 'asyncua')

PY = sys.executable


def _free_port():
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def _serve(tmp_path, node_env, *extra):
    root = tmp_path / 'programs'
    root.mkdir(exist_ok=True)
    return subprocess.Popen(
        [PY, '-m', 'feed_axis_energy', 'serve', '--program-root', str(root), '--mode', 'fast',
         '--opcua-port', str(_free_port()), '--domain-id', node_env['ROS_DOMAIN_ID'], *extra],
        env=node_env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def test_sigterm_stops_every_process_with_exit_0(tmp_path, node_env):
    from feed_axis_energy.lifeline import alive, child_processes
    proc = _serve(tmp_path, node_env)
    lines = []
    for line in proc.stdout:
        lines.append(line)
        if line.startswith('Ctrl-C'):
            break
    kids = child_processes(proc.pid)
    children = [pid for pid, _ in kids]
    assert len(children) >= 4, (children, lines)     # the graph's three nodes + the bridge
    # the bridge yields the CPU to the graph: every thread of it (DDS, asyncua, paho) runs
    # at the launcher's niceness + 5 (serve --bridge-nice), the graph's nodes at the
    # launcher's own
    base = os.getpriority(os.PRIO_PROCESS, proc.pid)
    for pid, cmd in kids:
        want = base + 5 if 'nodes.opcua_bridge' in cmd else base
        tasks = [int(t) for t in os.listdir(f'/proc/{pid}/task')]
        assert {os.getpriority(os.PRIO_PROCESS, t) for t in tasks} == {min(want, 19)}, cmd
    proc.send_signal(signal.SIGTERM)
    out = ''.join(lines) + proc.communicate(timeout=60)[0]
    assert proc.returncode == 0, out
    assert 'stopped by SIGTERM; all nodes shut down' in out and 'Traceback' not in out
    time.sleep(0.5)
    assert not [pid for pid in children if alive(pid)], out


def test_a_node_that_cannot_start_stops_everything_with_its_reason(tmp_path, node_env):
    users = tmp_path / 'users'
    users.write_text('operator\n')
    params = tmp_path / 'params.yaml'
    # the bridge's users file through a parameter file: serve cannot check it beforehand
    params.write_text(f'opcua_bridge:\n  ros__parameters:\n    opcua_users_file: "{users}"\n')
    proc = _serve(tmp_path, node_env, '--params', str(params))
    out = proc.communicate(timeout=120)[0]
    assert proc.returncode == 1, out
    assert 'error: opcua_bridge exited with code 1; all nodes stopped' in out
    assert f'{users}:1' in out and 'expected name:password' in out
    assert 'Traceback' not in out
