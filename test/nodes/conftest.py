"""Helpers of the node tests: a private ROS domain per test, subprocess environment."""
import itertools
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
_COUNTER = itertools.count()


@pytest.fixture
def domain_id():
    """A ROS_DOMAIN_ID no other test (or concurrent test run) is likely to use."""
    return 20 + (os.getpid() * 7 + next(_COUNTER) * 13) % 200


@pytest.fixture
def node_env(domain_id):
    """Environment for node subprocesses: source tree importable, private domain."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join([str(ROOT)] + (
        [env['PYTHONPATH']] if env.get('PYTHONPATH') else []))
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['PYTHONUNBUFFERED'] = '1'
    return env


@pytest.fixture
def short_program(tmp_path):
    """A 2-second G1 move (100 mm at 50 mm/s) and a short dwell."""
    path = tmp_path / 'short.nc'
    path.write_text('G21 G90 G94 G61\nG0 X0\nG1 X100 F3000\nG4 P0.2\nG1 X80 F3000\n')
    return path
