"""A node executable without rclpy says what to install and exits 1 (no traceback)."""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[2]
BASE = getattr(sys, '_base_executable', '') or ''


def _run(args):
    env = {k: v for k, v in os.environ.items() if k not in ('PYTHONPATH', 'VIRTUAL_ENV')}
    env['PYTHONPATH'] = str(ROOT)
    return subprocess.run([BASE, '-s', *args], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=60, check=False)


@pytest.fixture(scope='module')
def bare_python():
    if not BASE or _run(['-c', 'import rclpy']).returncode == 0:
        pytest.skip('no interpreter without rclpy here')


@pytest.mark.parametrize('node', ['gcode_trajectory', 'mcap_recorder'])
def test_node_without_rclpy(bare_python, node):
    done = _run(['-m', f'feed_axis_energy.nodes.{node}', '--help'])
    assert done.returncode == 1
    assert 'Traceback' not in done.stderr
    assert "pip install 'feed_axis_energy[ros]'" in done.stderr


def test_import_without_rclpy_raises(bare_python):
    done = _run(['-c', 'import feed_axis_energy.nodes'])
    assert done.returncode == 1
    assert 'ImportError: the feed_axis_energy nodes need rclpy' in done.stderr
