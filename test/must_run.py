"""Skips for a missing dependency, and the list of dependencies whose tests must not skip.

Some tests need something outside the Python environment: LinuxCNC's reference interpreter,
rclpy with loopback DDS, Chromium, the shared data, the mosquitto MQTT broker. On a
developer's machine they skip with a message when it is absent; on CI they must run. Every
such skip goes through this module: :func:`skip`, :func:`skipif`, :func:`import_or_skip`,
:func:`need_linuxcnc` and :func:`oracle_script` put the dependency's name into the skip
reason (``[needs NAME] ...``), and ``test/conftest.py`` hands every skipped report to
:func:`enforce`.

``FAE_MUST_RUN=linuxcnc,rclpy,chromium,shared,mosquitto`` (set by ``.ci/run``) names the
dependencies that must be there: a test that would skip for one of them fails instead, with
the name of the missing dependency. An unknown name in the list is a usage error (a typo must
not turn the rule off). Without the variable every such test skips, as before.

Tests import it as ``import must_run`` (``test/`` is on ``sys.path`` through
``test/conftest.py``).
"""
from __future__ import annotations

import functools
import importlib
import os
from pathlib import Path
import re
import subprocess
from types import ModuleType
from typing import NoReturn

import pytest

__all__ = ['DEPENDENCIES', 'ENV', 'required', 'reason', 'skip', 'skipif', 'import_or_skip',
           'has_linuxcnc', 'need_linuxcnc', 'oracle_script', 'enforce']

ENV = 'FAE_MUST_RUN'
DEPENDENCIES = {
    'linuxcnc': "LinuxCNC's reference G-code interpreter (/usr/bin/python3 -c 'import gcode'; "
                'Debian package linuxcnc-uspace)',
    'rclpy': 'rclpy with loopback DDS (the ROS 2 Python client library; test/nodes)',
    'chromium': 'Chromium, which renders the report pages (Debian package chromium)',
    'shared': 'the shared data (../shared beside the clone, or FAE_SHARED)',
    'mosquitto': 'the mosquitto MQTT broker (Debian package mosquitto; test/bridge)',
}
"""Name in ``FAE_MUST_RUN`` -> what it is (used in the failure message)."""

_TAG = re.compile(r'\[needs ([a-z]+)\] ')
SYSTEM_PYTHON = '/usr/bin/python3'


def required(environ: dict[str, str] | None = None) -> frozenset[str]:
    """The dependencies named in ``FAE_MUST_RUN`` (comma or space separated).

    Raises
    ------
    ValueError
        A name that is not a key of :data:`DEPENDENCIES`.
    """
    text = (os.environ if environ is None else environ).get(ENV, '')
    names = frozenset(n for n in re.split(r'[\s,]+', text) if n)
    unknown = sorted(names - DEPENDENCIES.keys())
    if unknown:
        raise ValueError(f'{ENV} names unknown dependencies {unknown}; known: '
                         f'{sorted(DEPENDENCIES)}')
    return names


def reason(dep: str, text: str) -> str:
    """The skip reason of a test that lacks ``dep``: tagged so :func:`enforce` finds it."""
    if dep not in DEPENDENCIES:
        raise ValueError(f'unknown dependency {dep!r}; known: {sorted(DEPENDENCIES)}')
    return f'[needs {dep}] {text}'


def skip(dep: str, text: str) -> NoReturn:
    """Skip the calling test (or module, at import) because ``dep`` is missing."""
    pytest.skip(reason(dep, text), allow_module_level=True)


def skipif(dep: str, missing: bool, text: str) -> pytest.MarkDecorator:
    """A ``skipif`` mark for a test that lacks ``dep`` when ``missing``."""
    return pytest.mark.skipif(missing, reason=reason(dep, text))


def import_or_skip(module: str, dep: str) -> ModuleType:
    """``pytest.importorskip`` for a module that belongs to ``dep`` (e.g. ``rclpy.qos``)."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        skip(dep, f'cannot import {module}: {exc}')


@functools.lru_cache(maxsize=None)
def has_linuxcnc() -> bool:
    """True when the system Python imports LinuxCNC's ``gcode`` module."""
    if not Path(SYSTEM_PYTHON).exists():
        return False
    try:
        proc = subprocess.run([SYSTEM_PYTHON, '-c', 'import gcode; gcode.parse'],
                              capture_output=True, cwd='/', timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return proc.returncode == 0


def need_linuxcnc() -> None:
    """Skip the calling test unless LinuxCNC's reference interpreter is installed."""
    if not has_linuxcnc():
        skip('linuxcnc', "LinuxCNC's reference interpreter is not installed "
                         '(apt-get install linuxcnc-uspace)')


def oracle_script() -> Path:
    """``tools/run_oracle.py`` of the shared data, with LinuxCNC installed to run it; or skip.

    Both the shared data and the reference interpreter are named when missing.
    """
    from shared_data import shared_path     # test/shared_data.py; imported late (no cycle)
    script = shared_path('tools', 'run_oracle.py')
    if script is None:
        skip('shared', 'tools/run_oracle.py not found in the shared data (set FAE_SHARED)')
    need_linuxcnc()
    return script


def _skip_message(report) -> str | None:
    longrepr = report.longrepr
    if isinstance(longrepr, tuple) and len(longrepr) == 3:
        return str(longrepr[2])
    return None


def enforce(report, names: frozenset[str] | None = None) -> None:
    """Turn ``report`` (a skipped test or collection report) into a failure when its skip
    reason names a dependency of ``names`` (default: :func:`required`)."""
    if not report.skipped:
        return
    message = _skip_message(report)
    found = _TAG.search(message or '')
    if found is None:
        return
    dep = found.group(1)
    if dep not in (required() if names is None else names):
        return
    report.outcome = 'failed'
    report.longrepr = (f'{ENV} requires {dep} ({DEPENDENCIES.get(dep, "?")}), but this test '
                       f'would skip without it: {message}')
