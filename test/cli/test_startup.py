"""Start-up: the top-level help and ``simulate`` import only what they use."""
import importlib
from pathlib import Path
import subprocess
import sys

import pytest

from feed_axis_energy.cli import _MODULES, build_parser, SUBCOMMANDS

ROOT = Path(__file__).resolve().parents[2]


def _modules_after(code: str) -> set[str]:
    script = (f'import sys\n{code}\n'
              'print("\\n".join(sorted(sys.modules)))')
    proc = subprocess.run([sys.executable, '-c', script], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return set(proc.stdout.split())


def test_top_level_help_imports_no_subcommand():
    mods = _modules_after('from feed_axis_energy.cli import main\n'
                          'try:\n    main(["--help"])\nexcept SystemExit:\n    pass')
    assert not any(m.startswith(('scipy', 'rosbags', 'matplotlib', 'numpy')) for m in mods)
    assert not any(m.startswith('feed_axis_energy.cli.') for m in mods)


def test_simulate_imports_no_scipy_rosbags_or_matplotlib(tmp_path):
    prog = tmp_path / 'ten.nc'
    prog.write_text('G1 X0.01 F600\nG1 X0\nM2\n')
    mods = _modules_after('from feed_axis_energy.cli import main\n'
                          f'main(["simulate", {str(prog)!r}, "--json", "--quiet"])')
    assert not any(m.startswith(('scipy', 'rosbags', 'matplotlib')) for m in mods)
    # the shipped machine config lies in yamlsubset's subset: PyYAML is not imported
    assert not any(m == 'yaml' or m.startswith('yaml.') for m in mods)


@pytest.mark.parametrize('name', list(SUBCOMMANDS))
def test_listed_help_is_the_subcommands_own(name):
    module = importlib.import_module(
        f'feed_axis_energy.cli.{_MODULES.get(name, name.replace("-", "_"))}')
    source = Path(module.__file__).read_text()
    assert repr(SUBCOMMANDS[name])[1:-1] in source or SUBCOMMANDS[name] in source
    assert name in build_parser().format_help()
