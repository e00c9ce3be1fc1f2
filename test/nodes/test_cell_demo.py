"""README's ``scripts/cell_demo`` runs as written: the service on loopback (with mosquitto
where installed), two jobs from the Python OPC UA client, their results printed with units,
everything it started stopped."""
import os
import subprocess

import must_run

must_run.import_or_skip('rclpy', 'rclpy')
must_run.import_or_skip('asyncua', 'asyncua')
from conftest import ROOT  # noqa: E402


def test_cell_demo_runs_two_jobs_and_prints_their_results(node_env):
    done = subprocess.run([str(ROOT / 'scripts' / 'cell_demo')], env=node_env, cwd=ROOT,
                          capture_output=True, text=True, timeout=300)
    print(done.stdout, done.stderr)
    assert done.returncode == 0, done.stderr[-3000:]
    out = done.stdout
    assert out.count(': ended (program completed)') == 2
    assert out.count('  energy       ') == 2 and ' J (' in out and ' Wh)' in out
    assert '  peak power   ' in out and ' W\n' in out and '  duration     ' in out
    assert 'OPC UA opc.tcp://127.0.0.1:' in out
    assert 'Traceback' not in done.stderr


def test_cell_demo_help():
    done = subprocess.run([str(ROOT / 'scripts' / 'cell_demo'), '--help'],
                          env=dict(os.environ), capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and 'cell-client' in done.stdout
