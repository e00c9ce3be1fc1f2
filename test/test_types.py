"""mypy over the pure packages (mypy.ini): no error, and a planted one is found."""
from __future__ import annotations

from pathlib import Path
import shutil
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[1]


def _mypy(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'mypy', '--no-incremental', *args], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


def test_the_pure_packages_type_check() -> None:
    proc = _mypy(ROOT)
    assert proc.returncode == 0, proc.stdout[-6000:] + proc.stderr[-2000:]
    assert 'Success: no issues found' in proc.stdout


def test_a_planted_type_error_fails(tmp_path: Path) -> None:
    """A copy of the package with one wrong return type in a checked module fails mypy."""
    shutil.copytree(ROOT / 'feed_axis_energy', tmp_path / 'feed_axis_energy',
                    ignore=shutil.ignore_patterns('__pycache__'))
    shutil.copy(ROOT / 'mypy.ini', tmp_path / 'mypy.ini')
    units = tmp_path / 'feed_axis_energy' / 'units.py'
    units.write_text(units.read_text(encoding='utf-8')
                     + '\n\ndef _planted() -> int:\n    return "not an int"\n',
                     encoding='utf-8')
    proc = _mypy(tmp_path)
    assert proc.returncode == 1, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert 'units.py' in proc.stdout and '[return-value]' in proc.stdout, proc.stdout[-4000:]
