"""Lint checks: the standard ament linters where installed, plain flake8 always."""
from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ['feed_axis_energy', 'test', 'bench', 'launch', 'setup.py']


def test_flake8_plain() -> None:
    """flake8 with the ament settings from setup.cfg (line length 99)."""
    existing = [s for s in SOURCES if (ROOT / s).exists()]
    proc = subprocess.run([sys.executable, '-m', 'flake8', *existing], cwd=ROOT,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


@pytest.mark.linter
def test_ament_flake8() -> None:
    """The ament_flake8 check of a ROS 2 install."""
    main_with_errors = pytest.importorskip('ament_flake8.main').main_with_errors
    rc, errors = main_with_errors(argv=[str(ROOT / s) for s in SOURCES if (ROOT / s).exists()])
    assert rc == 0, f'Found {len(errors)} code style errors / warnings:\n' + '\n'.join(errors)


@pytest.mark.linter
def test_ament_pep257() -> None:
    """The ament_pep257 docstring check of a ROS 2 install."""
    main = pytest.importorskip('ament_pep257.main').main
    assert main(argv=[str(ROOT / 'feed_axis_energy')]) == 0, 'Found code style errors / warnings'


@pytest.mark.copyright
@pytest.mark.linter
def test_ament_copyright() -> None:
    """The ament_copyright check of a ROS 2 install."""
    main = pytest.importorskip('ament_copyright.main').main
    assert main(argv=[str(ROOT / 'feed_axis_energy'), str(ROOT / 'test')]) == 0
