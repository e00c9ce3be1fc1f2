"""README's "ROS 2 workspace" section (and every ros2 command in the docs) against the files.

No ROS 2 install here, so the commands cannot run; what they name is checked instead: the
executables of ``ros2 run`` are console scripts, the launch file of ``ros2 launch`` exists and
declares every ``name:=`` argument given, ``-p name:=`` parameters are declared by the node,
colcon's package name is package.xml's, pip pins equal requirements.txt, and the install
layout the section describes is what setup.cfg and setup.py ask colcon for.
"""
from __future__ import annotations

import configparser
import re
import shlex
import xml.etree.ElementTree as ET

import pytest

from pkgscan import console_scripts, declared_parameters, launch_arguments, ROOT

DOCS = [ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md'))]
PACKAGE = 'feed_axis_energy'


def _section(title: str) -> str:
    text = (ROOT / 'README.md').read_text(encoding='utf-8')
    found = re.search(rf'^## {re.escape(title)}\n(.*?)(?=^## )', text, re.S | re.M)
    assert found, f'README has no "## {title}" section'
    return found.group(1)


def _ros2_commands() -> list[tuple[str, list[str]]]:
    """``(where, argv)`` of every ``ros2 run|launch feed_axis_energy ...`` in the docs."""
    found = []
    for path in DOCS:
        text = path.read_text(encoding='utf-8').replace('\\\n', ' ')
        for match in re.finditer(r'ros2 (?:run|launch) feed_axis_energy [^`\n]*', text):
            words = shlex.split(match.group(0).replace('...', ''))
            found.append((f'{path.name}: {match.group(0)[:60]}', words))
    return found


def test_docs_have_ros2_commands():
    kinds = {argv[1] for _, argv in _ros2_commands()}
    assert kinds == {'run', 'launch'}


@pytest.mark.parametrize('where,argv', _ros2_commands(), ids=lambda v: str(v)[:40])
def test_ros2_command_matches_package(where, argv):
    if argv[1] == 'run':
        exe = argv[3].strip('<>')
        if exe == 'node':   # the placeholder of `ros2 run feed_axis_energy <node>`
            return
        assert exe in console_scripts(), f'{where}: no executable {exe}'
        for word in argv[4:]:
            if ':=' in word and exe in declared_parameters():
                name = word.split(':=')[0]
                assert name in declared_parameters()[exe], f'{where}: {exe} has no {name}'
    else:
        launch_file = ROOT / 'launch' / argv[3]
        assert launch_file.is_file(), f'{where}: no launch/{argv[3]}'
        declared = launch_arguments(launch_file)
        for word in argv[4:]:
            if ':=' in word:
                name = word.split(':=')[0]
                assert name in declared, f'{where}: the launch file has no argument {name}'


def test_workspace_section_matches_build_files():
    section = _section('ROS 2 workspace')
    assert '```sh' in section
    name = ET.parse(ROOT / 'package.xml').getroot().findtext('name')
    assert f'colcon build --packages-select {name}' in section
    assert 'rosdep install --from-paths src' in section
    # pip pins in the section are the project's pins
    pins = dict(line.split('==') for line in
                (ROOT / 'requirements.txt').read_text(encoding='utf-8').splitlines()
                if '==' in line and not line.startswith('#'))
    for dist, version in re.findall(r'\b([A-Za-z][\w.-]*)==([\w.]+)', section):
        assert pins.get(dist) == version, f'{dist}=={version} but requirements.txt pins ' \
                                          f'{pins.get(dist)}'
    # the layout the section describes: colcon's script dir and the share directory
    cfg = configparser.ConfigParser()
    cfg.read(ROOT / 'setup.cfg')
    assert cfg['install']['install_scripts'] == f'$base/lib/{PACKAGE}'
    assert cfg['develop']['script_dir'] == f'$base/lib/{PACKAGE}'
    assert f'install/{PACKAGE}/lib/{PACKAGE}/' in section
    setup_py = (ROOT / 'setup.py').read_text(encoding='utf-8')
    for share in ("'share/' + PACKAGE + '/launch'", "'share/' + PACKAGE + '/config'",
                  "('share/' + PACKAGE, ['package.xml'])"):
        assert share in setup_py, share
    assert 'feed-axis-energy' in console_scripts()
