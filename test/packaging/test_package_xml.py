"""package.xml declares exactly what the code imports (issue 12, section 1).

The imports are found by parsing every module of the package and the launch file with
:mod:`ast` (module level and inside functions alike); the standard library and the package
itself are left out; each remaining top-level module maps to its rosdep key, or is known
to be pip-only (then README's "ROS 2 workspace" section must name it).
"""
from __future__ import annotations

import ast
from pathlib import Path
import re
import sys
import xml.etree.ElementTree as ET

ROOT = Path(__file__).resolve().parents[2]

# import name -> rosdep key (ROS packages: the package name; Python: rosdep's python3-* keys)
ROSDEP_KEYS = {
    'rclpy': 'rclpy', 'rcl_interfaces': 'rcl_interfaces',
    'builtin_interfaces': 'builtin_interfaces', 'std_msgs': 'std_msgs',
    'trajectory_msgs': 'trajectory_msgs', 'diagnostic_msgs': 'diagnostic_msgs',
    'rosgraph_msgs': 'rosgraph_msgs', 'sensor_msgs': 'sensor_msgs',
    'geometry_msgs': 'geometry_msgs', 'lifecycle_msgs': 'lifecycle_msgs',
    'ament_index_python': 'ament_index_python', 'launch': 'launch', 'launch_ros': 'launch_ros',
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'yaml': 'python3-yaml',
    'matplotlib': 'python3-matplotlib', 'zstandard': 'python3-zstandard',
    'lz4': 'python3-lz4', 'paho': 'python3-paho-mqtt', 'cryptography': 'python3-cryptography',
}
# no rosdep key: installed with pip (README "ROS 2 workspace" says so)
PIP_ONLY = {'rosbags', 'mcap', 'distributed', 'pyarrow', 'asyncua'}


def _sources() -> list[Path]:
    return sorted((ROOT / 'feed_axis_energy').rglob('*.py')) + sorted(
        (ROOT / 'launch').glob('*.py'))


def third_party_imports() -> dict[str, set[str]]:
    """``{top-level module: {files importing it}}`` outside the stdlib and the package."""
    found: dict[str, set[str]] = {}
    for path in _sources():
        tree = ast.parse(path.read_text(encoding='utf-8'), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split('.')[0]
                if top in sys.stdlib_module_names or top == 'feed_axis_energy':
                    continue
                found.setdefault(top, set()).add(str(path.relative_to(ROOT)))
    return found


def package_xml() -> ET.Element:
    return ET.parse(ROOT / 'package.xml').getroot()


def test_package_xml_is_format_3():
    root = package_xml()
    assert root.tag == 'package' and root.get('format') == '3'
    assert root.findtext('name') == 'feed_axis_energy'
    assert root.findtext('export/build_type') == 'ament_python'


def test_scan_finds_known_imports():
    # the scanner itself: it must see imports at module level and inside functions
    found = third_party_imports()
    assert 'feed_axis_energy/nodes/runner.py' in found['rclpy']
    assert 'feed_axis_energy/record/mcapstream.py' in found['zstandard']   # inside a function
    assert 'launch/feed_axis_energy.launch.py' in found['launch_ros']


def test_every_import_is_mapped():
    unknown = {m: sorted(f) for m, f in third_party_imports().items()
               if m not in ROSDEP_KEYS and m not in PIP_ONLY}
    assert not unknown, f'imports without a rosdep key or pip-only entry: {unknown}'


def test_exec_depends_equal_imports():
    declared = [e.text.strip() for e in package_xml().findall('exec_depend')]
    assert len(declared) == len(set(declared)), 'duplicate exec_depend'
    wanted = {ROSDEP_KEYS[m] for m in third_party_imports() if m in ROSDEP_KEYS}
    missing = sorted(wanted - set(declared))
    unused = sorted(set(declared) - wanted)
    assert not missing, f'imported but not in package.xml: {missing}'
    assert not unused, f'in package.xml but never imported: {unused}'


def test_pip_only_dependencies_documented():
    readme = (ROOT / 'README.md').read_text(encoding='utf-8')
    section = re.search(r'^## ROS 2 workspace\n(.*?)(?=^## )', readme, re.S | re.M)
    assert section, 'README has no "## ROS 2 workspace" section'
    xml_text = (ROOT / 'package.xml').read_text(encoding='utf-8')
    for module in sorted(PIP_ONLY & set(third_party_imports())):
        assert module in section.group(1), f'README "ROS 2 workspace" does not name {module}'
        assert module in xml_text, f'package.xml comment does not name {module}'
