"""``simulate --ignore-axes`` as a user runs it (exit codes, messages, warnings)."""
from __future__ import annotations

import json
from pathlib import Path
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[2]
ROTARY = 'G21 G90 G0 X0 Y0 Z0\nG1 X50 A90 F3000\nG1 X0 A0\nM30\n'


def _run(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'feed_axis_energy', *argv], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


def test_rotary_axis_refused_then_ignored(tmp_path: Path) -> None:
    prog = tmp_path / 'rotary.nc'
    prog.write_text(ROTARY)
    refused = _run('simulate', str(prog), '--quiet')
    assert refused.returncode == 1
    assert f'{prog}:2:' in refused.stderr and '--ignore-axes A' in refused.stderr
    assert 'Traceback' not in refused.stderr
    ok = _run('simulate', str(prog), '--quiet', '--json', '--ignore-axes', 'a')
    assert ok.returncode == 0, ok.stderr
    summary = json.loads(ok.stdout)
    assert any('axis A words are ignored' in w for w in summary['warnings'])
    assert summary['duration_s'] > 0


def test_ignore_axes_usage_error(tmp_path: Path) -> None:
    prog = tmp_path / 'rotary.nc'
    prog.write_text(ROTARY)
    bad = _run('simulate', str(prog), '--ignore-axes', 'X')
    assert bad.returncode == 2
    assert '--ignore-axes' in bad.stderr and 'A,B,C,U,V,W' in bad.stderr
