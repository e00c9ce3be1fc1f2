"""Every command README shows runs as written (issue 12, section 4).

README's code blocks are tagged: ```sh blocks are commands, ```console blocks are
transcripts (``$ command`` followed by its output, copied unchanged), ```python is the
"Python API" example, ```text and ```yaml are neither. The commands run in document order
in one temporary directory that holds a copy of ``config/`` and ``bags/`` (the paths README
uses are relative to the clone) and ``shared`` -> the shared data beside the clone, with
the venv's ``bin`` first on PATH. Blocks that cannot run here are recognised and skipped with
the reason: ROS 2 workspace commands (colcon, rosdep, ros2: no ROS 2 install), ``scripts/test``
(this suite), ``scripts/demo`` (the node graph and the 15-run campaign: minutes; the graph is
covered by test/nodes, the campaign by test/cli), ``scripts/cell_demo`` (run as written by
test/nodes/test_cell_demo.py) and benchmarks (run by hand).
"""
from __future__ import annotations

import os
from pathlib import Path
import re
import shutil
import subprocess
import sys

import must_run
import pytest
from shared_data import shared_path

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / 'README.md'
TIMEOUT_S = 900
SKIPS = [
    (re.compile(r'^\s*(?:cd [^&]*&& )?(?:ros2|colcon|rosdep)\b|source install/', re.M),
     'needs a ROS 2 install (colcon, rosdep, ros2); checked against the files by '
     'test_readme_ros.py'),
    (re.compile(r'^\s*scripts/test\b', re.M), 'scripts/test is this test suite'),
    (re.compile(r'^\s*scripts/demo\b', re.M),
     'scripts/demo runs the node graph and the 15-run campaign (minutes)'),
    (re.compile(r'\bbench/'), 'benchmark, run by hand (figures in README "Benchmarks")'),
    (re.compile(r'^\s*scripts/cell_demo\b', re.M),
     'scripts/cell_demo starts the node graph, OPC UA and mosquitto; it runs in '
     'test/nodes/test_cell_demo.py'),
]


def readme_blocks() -> list[tuple[str, int, str, str]]:
    """``(language, line, text, section)`` of every fenced block of README."""
    blocks = []
    lang, start, body, section = None, 0, [], ''
    for number, line in enumerate(README.read_text(encoding='utf-8').splitlines(), 1):
        if lang is None and line.startswith('## '):
            section = line[3:].strip()
        if line.startswith('```'):
            if lang is None:
                lang, start, body = line[3:].strip(), number, []
            else:
                blocks.append((lang, start, '\n'.join(body) + '\n', section))
                lang = None
            continue
        if lang is not None:
            body.append(line)
    assert lang is None, f'README: block at line {start} is not closed'
    return blocks


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env['PATH'] = f'{Path(sys.executable).parent}{os.pathsep}{env.get("PATH", "")}'
    env['PYTHONPATH'] = os.pathsep.join([str(ROOT)] + (
        [env['PYTHONPATH']] if env.get('PYTHONPATH') else []))
    return env


@pytest.fixture(scope='module')
def workdir(tmp_path_factory) -> Path:
    """A stand-in clone: copies of config/ and bags/, and ../shared when it exists."""
    base = tmp_path_factory.mktemp('readme')
    clone = base / 'clone'
    clone.mkdir()
    for name in ('config', 'bags'):
        shutil.copytree(ROOT / name, clone / name)
    shared = shared_path()
    if shared is not None:
        (base / 'shared').symlink_to(shared, target_is_directory=True)
    return clone


COMMAND_BLOCKS = [b for b in readme_blocks() if b[0] in ('sh', 'console')]


def test_readme_tags_every_block():
    langs = {lang for lang, _, _, _ in readme_blocks()}
    assert langs <= {'sh', 'console', 'python', 'text', 'yaml'}, langs
    assert len(COMMAND_BLOCKS) >= 5


def _console_steps(text: str) -> list[tuple[str, str]]:
    steps: list[tuple[str, list[str]]] = []
    for line in text.splitlines():
        if line.startswith('$ '):
            steps.append((line[2:], []))
        else:
            assert steps, f'console block starts without a command: {line[:60]!r}'
            steps[-1][1].append(line)
    return [(cmd, '\n'.join(out) + '\n') for cmd, out in steps]


@pytest.mark.parametrize('lang,line,text,section', COMMAND_BLOCKS,
                         ids=[f'line{b[1]}' for b in COMMAND_BLOCKS])
def test_readme_command_block(workdir, lang, line, text, section):
    reasons = [reason for pattern, reason in SKIPS if pattern.search(text)]
    if reasons:
        pytest.skip(f'README line {line}: {"; ".join(reasons)}')
    if '../shared' in text or 'campaigns/umich_mill' in text:
        if not (workdir.parent / 'shared').exists():
            must_run.skip('shared', f'README line {line}: the shared data is not beside the '
                                    'clone (set FAE_SHARED)')
    if lang == 'sh':
        done = subprocess.run(['bash', '-e', '-o', 'pipefail', '-c', text], cwd=workdir,
                              env=_env(), capture_output=True, text=True, timeout=TIMEOUT_S)
        assert done.returncode == 0, (f'README line {line} ({section}) exit '
                                      f'{done.returncode}:\n{done.stderr[-3000:]}')
        return
    for command, want in _console_steps(text):
        done = subprocess.run(['bash', '-e', '-o', 'pipefail', '-c', command], cwd=workdir,
                              env=_env(), capture_output=True, text=True, timeout=TIMEOUT_S)
        assert done.returncode == 0, f'README line {line}: {command}\n{done.stderr[-3000:]}'
        assert done.stdout == want, f'README line {line}: the output of {command} changed'


def test_python_api_section(tmp_path):
    blocks = [b for b in readme_blocks() if b[3] == 'Python API']
    code = [text for lang, _, text, _ in blocks if lang == 'python']
    output = [text for lang, _, text, _ in blocks if lang == 'text']
    assert len(code) == 1 and len(output) == 1, 'Python API: one python and one text block'
    done = subprocess.run([sys.executable, '-c', code[0]], cwd=tmp_path, env=_env(),
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout == output[0]
