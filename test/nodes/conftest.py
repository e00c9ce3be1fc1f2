"""Helpers of the node tests: a private ROS domain per test, subprocess environment."""
import itertools
import os
from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[2]
_COUNTER = itertools.count()


def _domain_range() -> tuple[int, int]:
    """``FAE_DOMAIN_IDS=LO-HI`` confines the tests to those domain ids (one range per person
    sharing a machine); default 20-219."""
    text = os.environ.get('FAE_DOMAIN_IDS', '')
    try:
        lo, hi = (int(v) for v in text.split('-'))
    except ValueError:
        return 20, 219
    return (lo, hi) if 0 <= lo <= hi <= 232 else (20, 219)


@pytest.fixture
def domain_id():
    """A ROS_DOMAIN_ID no other test (or concurrent test run) is likely to use."""
    lo, hi = _domain_range()
    return lo + (os.getpid() * 7 + next(_COUNTER) * 13) % (hi - lo + 1)


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
def context(domain_id):
    """An rclpy context of its own on the test's private domain (in-process node tests)."""
    from rclpy.context import Context
    import rclpy
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    yield ctx
    rclpy.shutdown(context=ctx)


@pytest.fixture
def short_program(tmp_path):
    """A 2-second G1 move (100 mm at 50 mm/s) and a short dwell."""
    path = tmp_path / 'short.nc'
    path.write_text('G21 G90 G94 G61\nG0 X0\nG1 X100 F3000\nG4 P0.2\nG1 X80 F3000\n')
    return path


IN_CHILD = os.environ.get('FAE_NODE_TEST_CHILD') == '1'
"""True inside the interpreter :func:`run_module_in_child` starts."""
child_only = pytest.mark.skipif(not IN_CHILD, reason='runs in its own interpreter '
                                '(the test_in_a_child_process of its module)')
"""Mark of tests that create rclpy contexts in the test process: they run in a child."""


def run_module_in_child(module: str, tests: tuple[str, ...] = ()) -> None:
    """Run the ``child_only`` tests of ``module`` (a file path) in a fresh interpreter;
    only the test functions named in ``tests`` when given (the module's other tests run in
    the suite's own process and need not run twice).

    In-process rclpy tests create and destroy contexts and nodes in the pytest process; a
    crash there (one segmentation fault in a full suite run after several in-process
    contexts) would end the whole suite. In a child, it fails this one test instead.
    """
    env = dict(os.environ, FAE_NODE_TEST_CHILD='1', PYTHONUNBUFFERED='1')
    proc = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
                           *([f'{module}::{name}' for name in tests] or [module])],
                          cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, (f'exit {proc.returncode}\n{proc.stdout[-4000:]}\n'
                                  f'{proc.stderr[-2000:]}')
