"""Only ``feed_axis_energy.nodes`` may pull in rclpy or a ``*_msgs`` package.

Every other package (the pure core, the command line, reports) runs without ROS 2.
"""
import ast
import json
from pathlib import Path
import pkgutil
import subprocess
import sys

import feed_axis_energy

PACKAGE_DIR = Path(feed_axis_energy.__file__).resolve().parent
REPO = PACKAGE_DIR.parent
ROS_PACKAGES = ('nodes',)   # the rclpy shells


def _forbidden(name: str) -> bool:
    top = name.split('.')[0]
    return top == 'rclpy' or any(part.endswith('_msgs') for part in name.split('.'))


def _core_modules() -> list[str]:
    found = pkgutil.walk_packages([str(PACKAGE_DIR)], prefix='feed_axis_energy.')
    return sorted(m.name for m in found
                  if m.name.split('.')[1] not in ROS_PACKAGES + ('__main__',))


def _core_files() -> list[Path]:
    return sorted(p for p in PACKAGE_DIR.rglob('*.py')
                  if p.relative_to(PACKAGE_DIR).parts[0] not in ROS_PACKAGES)


def test_importing_every_core_module_loads_no_ros():
    modules = _core_modules()
    assert {'feed_axis_energy.machine.file', 'feed_axis_energy.physics.energy'} <= set(modules)
    code = (
        'import importlib, json, sys\n'
        f'for name in {modules!r}:\n'
        '    importlib.import_module(name)\n'
        'print(json.dumps(sorted(sys.modules)))\n')
    out = subprocess.run([sys.executable, '-c', code], cwd=REPO, capture_output=True,
                         text=True, timeout=120, check=True)
    loaded = json.loads(out.stdout.strip().splitlines()[-1])
    assert set(modules) <= set(loaded)
    assert [m for m in loaded if _forbidden(m)] == []


def test_no_ros_import_statement_in_core_sources():
    found = []
    files = _core_files()
    assert files
    for path in files:
        tree = ast.parse(path.read_text(encoding='utf-8'), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            found += [f'{path.name}:{node.lineno}: {n}' for n in names if _forbidden(n)]
    assert found == []


def test_forbidden_names():
    assert _forbidden('rclpy.node') and _forbidden('std_msgs.msg') and _forbidden('rclpy')
    assert not _forbidden('rosbags.typesys') and not _forbidden('numpy')
