"""The must-not-skip list (``test/must_run.py``): a listed dependency that is missing fails
the test that needs it, naming the dependency; an unlisted one still skips."""
from __future__ import annotations

import os
from pathlib import Path
import re
import subprocess
import sys

import must_run
import pytest

TEST = Path(__file__).resolve().parent
ROOT = TEST.parent

# A tiny suite of its own, run by a child pytest with test/'s conftest and helpers.
_PROBE = '''
import must_run
import pytest

pytestmark_never = must_run.skipif('chromium', True, 'no browser here (probe)')


def test_reference(monkeypatch):
    # LinuxCNC hidden: the system Python is taken to be a file that does not exist
    monkeypatch.setattr(must_run, 'SYSTEM_PYTHON', '/nonexistent/fae-probe/python3')
    must_run.has_linuxcnc.cache_clear()
    must_run.need_linuxcnc()


@pytestmark_never
def test_browser():
    pass


def test_missing_module():
    must_run.import_or_skip('fae_no_such_module_probe', 'rclpy')


def test_plain_skip():
    pytest.skip('not a listed dependency')
'''


def _run_probe(tmp_path: Path, must: str | None) -> subprocess.CompletedProcess:
    (tmp_path / 'conftest.py').write_text((TEST / 'conftest.py').read_text())
    (tmp_path / 'test_probe.py').write_text(_PROBE)
    env = dict(os.environ)
    env.pop(must_run.ENV, None)
    if must is not None:
        env[must_run.ENV] = must
    env['PYTHONPATH'] = os.pathsep.join([str(TEST), str(ROOT)] + (
        [env['PYTHONPATH']] if env.get('PYTHONPATH') else []))
    return subprocess.run([sys.executable, '-m', 'pytest', '-q', '-rfs', '-p',
                           'no:cacheprovider', '-c', os.devnull, '--rootdir', str(tmp_path),
                           str(tmp_path)],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)


def _counts(out: str) -> dict[str, int]:
    return {word: int(n) for n, word in re.findall(r'(\d+) (passed|failed|skipped|error)', out)}


def test_without_the_list_every_missing_dependency_skips(tmp_path):
    proc = _run_probe(tmp_path, None)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert _counts(proc.stdout) == {'skipped': 4}, proc.stdout


def test_a_listed_missing_dependency_fails_and_is_named(tmp_path):
    proc = _run_probe(tmp_path, 'linuxcnc,chromium')
    assert proc.returncode == 1, proc.stdout + proc.stderr
    counts = _counts(proc.stdout)       # a failing skipif mark is an error at setup
    assert counts.get('failed', 0) + counts.get('error', 0) == 2, proc.stdout
    assert counts['skipped'] == 2, proc.stdout
    assert 'FAE_MUST_RUN requires linuxcnc' in proc.stdout
    assert 'FAE_MUST_RUN requires chromium' in proc.stdout
    assert "reference interpreter is not installed" in proc.stdout


def test_a_module_level_skip_fails_too(tmp_path):
    (tmp_path / 'test_module_skip.py').write_text(
        'import must_run\n'
        "must_run.import_or_skip('fae_no_such_module_probe', 'rclpy')\n\n\n"
        'def test_never():\n    pass\n')
    proc = _run_probe(tmp_path, 'rclpy')
    assert proc.returncode != 0, proc.stdout + proc.stderr
    assert 'FAE_MUST_RUN requires rclpy' in proc.stdout
    assert 'cannot import fae_no_such_module_probe' in proc.stdout


def test_a_hidden_reference_interpreter_is_a_tagged_skip(tmp_path, monkeypatch):
    """With /usr/bin/python3 taken for a file that does not exist, need_linuxcnc skips with
    the linuxcnc tag (which enforce turns into a failure under FAE_MUST_RUN=linuxcnc)."""
    monkeypatch.setattr(must_run, 'SYSTEM_PYTHON', str(tmp_path / 'no-python3'))
    must_run.has_linuxcnc.cache_clear()
    try:
        assert not must_run.has_linuxcnc()
        with pytest.raises(pytest.skip.Exception, match=r'\[needs linuxcnc\]'):
            must_run.need_linuxcnc()
    finally:
        must_run.has_linuxcnc.cache_clear()


def test_an_unknown_name_is_a_usage_error(tmp_path):
    with pytest.raises(ValueError, match='unknown dependencies'):
        must_run.required({must_run.ENV: 'linuxcnc,chromuim'})
    proc = _run_probe(tmp_path, 'chromuim')
    assert proc.returncode == 4, proc.stdout + proc.stderr     # pytest's usage error
    assert 'chromuim' in proc.stderr


def test_the_list_parses():
    assert must_run.required({}) == frozenset()
    assert must_run.required({must_run.ENV: 'linuxcnc, rclpy chromium,shared mosquitto'}) == set(
        must_run.DEPENDENCIES)


def test_no_skip_of_a_listed_dependency_bypasses_the_helper():
    """Skips for rclpy, LinuxCNC, Chromium or our own modules go through must_run (or, for
    our own modules, are plain imports: a broken import must fail, not skip)."""
    bad = []
    pattern = re.compile(r"importorskip\(\s*'(rclpy|feed_axis_energy)|"
                         r"'import gcode; gcode.parse'|find_spec\('rclpy'\) is None, reason=")
    for path in sorted(TEST.rglob('*.py')):
        if path.name in ('must_run.py', 'test_must_run.py'):
            continue
        for n, line in enumerate(path.read_text(encoding='utf-8').splitlines(), 1):
            if pattern.search(line):
                bad.append(f'{path.relative_to(ROOT)}:{n}: {line.strip()}')
    assert not bad, '\n'.join(bad)
